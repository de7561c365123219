"""Issue 29: the controller and monitor cores in closed loop with the MuJoCo plant.

What the three nodes do at their default parameters, without ROS: `ft_core.controller`
tracks pose goals (a new one every 1.5 s, as the separate-process tests' probe sends
them), `ft_core.monitor` filters its commands and watches the measured positions, and
`ft_core.physics.PhysicsPlant` (servo lag and overshoot, 90 % gravity compensation,
a brake as the lock) executes them behind a latency. Healthy goals first, in which
nothing may be declared; then a joint locks while it moves, and the monitor must
name that joint, and no other, within 1 s (issue 29's p99 target). Every chain joint
of the pose task, every joint but the flange's of the position task (which the
position of `panda_link8` does not depend on, so no task commands it), on two drivers:
a fast one and the slowest of the issue's targets (50 ms latency, 50 ms servo, the
last command held). The separate-process test on the same plant is in
`tests/processes/test_deployment.py`; `bench/detection.py` measures the latency (the loop:
`ft_sim.closed_loop`)
distribution over a grid of plants.
"""

from __future__ import annotations

import pytest
from ft_sim.closed_loop import DRIVERS, GOAL_PERIOD, ClosedLoop

#: s of healthy goals before the lock (the monitor identifies the plant meanwhile).
HEALTHY = 4.0
#: rad/s; the joint locks at the first moment after HEALTHY that it moves this fast and
#: is commanded as fast (a lock shows only while its joint is commanded: a joint that
#: overshoots briefly as the others ramp up, then is hardly commanded, is not the case
#: this test is about; docs/monitor.md "Locks the monitor cannot see").
LOCK_SPEED = 0.1


CASES = [(task, joint, driver) for task, joints in (("position", range(6)), ("pose", range(7)))
         for joint in joints for driver in DRIVERS]


@pytest.mark.parametrize(("task", "joint", "driver"), CASES)
def test_a_lock_on_a_physics_plant_is_named_within_a_second(task: str, joint: int,
                                                            driver: str) -> None:
    loop = ClosedLoop(task, DRIVERS[driver])
    loop.run(HEALTHY)
    loop.run(3 * GOAL_PERIOD, stop=lambda: min(abs(loop.plant.qd[joint]),
                                               abs(loop.sent[joint])) > LOCK_SPEED)
    assert abs(loop.plant.qd[joint]) > LOCK_SPEED, f"joint {joint} never moves"
    assert loop.declared == [] and loop.monitor.swinging == [], "declared in healthy motion"
    assert loop.monitor.plant_values()["observing"] == "yes", "the monitor never observed"
    locked_at = loop.t
    loop.plant.lock(joint)
    loop.run(1.0, stop=lambda: bool(loop.declared))
    name = loop.robot.joint_names[joint]
    assert loop.declared, f"{name} not found within 1 s"
    when, names = loop.declared[0]
    assert names == [name], f"{names} declared instead of {name}"
    assert when - locked_at <= 1.0
    assert loop.monitor.swinging == []
