"""Issue 16, part 2, in the nodes: the controller suspects, the monitor confirms or refuses."""

from __future__ import annotations

import numpy as np
from ft_core import selfmotion
from models import PLANAR, pseudoinverse_control
from rosutil import fresh_domain


def test_the_controller_suspects_and_the_monitor_confirms_a_lock_it_could_not_see() -> None:
    """The nodes in lock-step on a 20/30 ms plant, where fig. 4's arm got stuck.

    The planar 3R starts there with joint 1 locked and unknown to all. Only joint 1 is
    commanded, so the monitor has no witness of a plant that follows and declares
    nothing by itself; the controller's task channel suspects joint 1, and the monitor,
    seeing it still while commanded, declares it locked.
    """
    from ft_sim.scenario import Scenario, ScenarioConfig

    q0 = selfmotion.find_seed(PLANAR, np.array([-0.9, 1.8]), np.array([1.873, -0.708, 2.05]))
    stuck, *_ = pseudoinverse_control(q0, np.array([1.5, 1.5]), locked=0)
    config = ScenarioConfig(robot="planar3r", task_space="planar", points=((1.5, 1.5),),
                            soft_limits=False, resolution="least_norm", rate=125.0,
                            start=tuple(float(v) for v in stuck), command_latency=0.02,
                            response_time=0.03, hold_last_command=True)
    scenario = Scenario(config, domain_id=fresh_domain())
    try:
        scenario.start()
        scenario.inject("joint1")
        scenario.send_goal(0)
        suspected = None
        for _ in range(round(5.0 * config.rate)):
            scenario.step()
            if suspected is None and scenario.controller.loaded.suspected_lock is not None:
                suspected = (scenario.sim.t, scenario.controller.loaded.suspected_lock)
                assert scenario.monitor.locked == {}  # the monitor alone did not see it
            if scenario.record.detected:  # the locked set, as the controller receives it
                break
        assert suspected is not None and suspected[1] == "joint1"
        assert list(scenario.monitor.locked) == ["joint1"]
        assert scenario.record.detected == ["joint1"]
        assert scenario.record.detected_at - scenario.record.injected_at < 2.0
    finally:
        scenario.close()


def test_the_monitor_refuses_a_suspect_its_measurements_contradict() -> None:
    """A suspect for a joint seen following its command is not locked (the monitor decides)."""
    from ft_msgs_py import names, qos
    from ft_sim.scenario import TASK_POINTS, Scenario, ScenarioConfig
    from sensor_msgs.msg import JointState

    config = ScenarioConfig(points=TASK_POINTS["panda"][:2], soft_limits=False, rate=125.0,
                            command_latency=0.02, response_time=0.03)
    scenario = Scenario(config, domain_id=fresh_domain())
    try:
        suspect = scenario.driver.create_publisher(JointState, names.SUSPECTED_FAILURE,
                                                   qos.RELIABLE)
        scenario.start()
        assert scenario.reach(0, 2e-3, 10.0)
        scenario.send_goal(1)
        moving = 0
        for _ in range(round(1.5 * config.rate)):
            scenario.step()
            evidence = scenario.monitor.core.detector.joints[0]
            if evidence.following:
                moving += 1
                suspect.publish(JointState(name=["panda_joint1"]))
        assert moving > 10  # the suspect arrived while joint 1 visibly followed
        assert scenario.monitor.locked == {}
    finally:
        scenario.close()
