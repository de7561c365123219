"""The sim node's fault library and obstacle: `ft/inject_fault`, `ft/obstacle`, `~/reset`."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from ft_core.faults import Fault
from ft_msgs_py import faults as fault_messages
from ft_msgs_py import names, qos
from ft_msgs_py.spin import harness_node, spin_until
from ft_sim.sim_node import SimNode
from fuzzing import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosutil import ros_context
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker


class Log:
    """Stands in for a node's logger: keeps (level, text) of every line."""

    def __init__(self):
        self.lines: list[tuple[str, str]] = []

    def __getattr__(self, level: str):
        return lambda text, **_: self.lines.append((level, text))

    def warnings(self) -> list[str]:
        return [text for level, text in self.lines if level in ("warning", "warn")]


@contextmanager
def sim(plant: str = "physics") -> Iterator[tuple[SimNode, object, object, Log]]:
    """A stepped sim of the Panda with inertias, a harness node, and the sim's log."""
    with ros_context() as (context, executor):
        node = SimNode.stepped_by_hand(context, {"robot_model": "panda_inertial",
                                                 "plant": plant})
        harness = harness_node("harness", context)
        executor.add_node(node)
        executor.add_node(harness)
        log = Log()
        node.get_logger = lambda: log
        try:
            node.step()
            yield node, harness, executor, log
        finally:
            node.destroy_node()
            harness.destroy_node()


def status(joint: str, kind: str, **values: str) -> DiagnosticStatus:
    return DiagnosticStatus(name=joint, message=kind,
                            values=[KeyValue(key=k, value=v) for k, v in values.items()])


def test_faults_by_topic_add_up_and_reset_clears_them() -> None:
    with sim() as (node, harness, executor, log):
        publisher = harness.create_publisher(DiagnosticArray, names.INJECT_FAULT, qos.RELIABLE)
        states: list[JointState] = []
        harness.create_subscription(JointState, names.JOINT_STATES, states.append,
                                    qos.RELIABLE)
        publisher.publish(DiagnosticArray(status=[
            status("panda_joint4", "viscous", severity="50"),
            status("panda_joint6", "range", upper="2.0"),
            status("panda_joint4", "dry", severity="3")]))
        assert spin_until(executor, lambda: node.faults == {
            "panda_joint4": ["viscous", "dry"], "panda_joint6": ["range"]}, 5.0), node.faults
        dof = node.plant._dof[3]
        assert node.plant._model.dof_damping[dof] == pytest.approx(50.003)
        assert node.plant._model.dof_frictionloss[dof] == 3.0
        # A second failure later adds to those in force.
        publisher.publish(fault_messages.message([Fault("lock", "panda_joint2")]))
        assert spin_until(executor, lambda: "panda_joint2" in node.locked, 5.0)
        assert set(node.faults) == {"panda_joint2", "panda_joint4", "panda_joint6"}
        assert sum("joint panda_joint4: viscous 50 N m s/rad" in w for w in log.warnings()) == 1
        node.step()
        assert spin_until(executor, lambda: bool(states), 5.0)
        assert len(states[-1].effort) == 7 and np.all(np.isfinite(states[-1].effort))
        client = harness.create_client(Trigger, "sim/reset")
        future = client.call_async(Trigger.Request())
        assert spin_until(executor, future.done, 5.0)
        assert "panda_joint4" in future.result().message
        assert node.faults == {} and node.plant._model.dof_damping[dof] == pytest.approx(0.003)


@pytest.mark.parametrize("statuses, problem", [
    ([status("panda_joint9", "lock")], "unknown joint 'panda_joint9'"),
    ([status("panda_joint4", "rust")], "unknown fault kind 'rust'"),
    ([status("panda_joint4", "viscous", severity="nan")], "needs a severity"),
    ([status("panda_joint4", "viscous", severity="lots")], "'lots' is not a number"),
    ([status("panda_joint4", "dry", severity="1", sevrity="2")], "unknown key 'sevrity'"),
    ([status("panda_joint4", "authority", severity="1.5")], "fraction"),
    ([status("panda_joint4", "range", lower="-9")], "within the joint's range"),
    ([status("panda_joint4", "intermittent")], "needs a period"),
    ([status("panda_joint4", "viscous", severity="5"),
      status("panda_joint4", "viscous", severity="6")], "viscous given twice"),
    ([status("panda_joint4", "lock")] * 65, "66 faults (at most 64)"),
    ([status("panda_joint4", "lock", period="1")], "takes no period"),
])
def test_a_bad_fault_message_is_ignored_whole_with_a_warning(statuses, problem: str) -> None:
    with sim() as (node, _, _, log):
        good = status("panda_joint2", "viscous", severity="5")
        node._on_fault(DiagnosticArray(status=[good, *statuses]))
        assert node.faults == {}
        assert len(log.warnings()) == 1 and problem in log.warnings()[0], log.lines
        assert log.warnings()[0].startswith("ft/inject_fault ignored")


def test_the_old_injection_topics_are_lock_and_free_swing() -> None:
    with sim("kinematic") as (node, _, _, _):
        node._on_inject(JointState(name=["panda_joint3"]))
        node._on_free_swing(JointState(name=["panda_joint2"]))
        assert node.faults == {"panda_joint2": ["free_swing"], "panda_joint3": ["lock"]}


def test_the_sim_brakes_a_swinging_joint_the_monitor_declares_locked() -> None:
    """A driver acting on ft/locked_joints: braked where it is, freed when no longer declared."""
    with sim() as (node, harness, executor, log):
        declared = harness.create_publisher(JointState, names.LOCKED_JOINTS, qos.LATCHED)
        node._on_free_swing(JointState(name=["panda_joint2"]))
        for _ in range(20):
            node.step()
        declared.publish(JointState(name=["panda_joint2", "bogus"]))
        assert spin_until(executor, lambda: node.swinging == [], 5.0), "not braked"
        assert node.faults == {"panda_joint2": ["lock"]}
        at = node.q[1]
        for _ in range(100):
            node.step()
        assert abs(node.q[1] - at) < 1e-3
        assert any("panda_joint2 braked" in w for w in log.warnings())
        assert any("1 unknown joints rejected" in w for w in log.warnings())
        declared.publish(JointState())  # the monitor's ~/reset
        assert spin_until(executor, lambda: node.swinging == ["panda_joint2"], 5.0)
        for _ in range(100):
            node.step()
        assert abs(node.q[1] - at) > 0.01  # it falls again


def test_an_obstacle_is_placed_moved_and_removed_on_the_physics_plant() -> None:
    with sim() as (node, harness, executor, log):
        publisher = harness.create_publisher(Marker, names.OBSTACLE, qos.RELIABLE)
        pose = np.eye(4)
        pose[:3, 3] = [0.5, 0.2, 0.3]
        publisher.publish(fault_messages.obstacle_message(pose, [0.2, 0.1, 0.4], "panda_link0"))
        assert spin_until(executor, lambda: node.plant.obstacle is not None, 5.0)
        node.step()
        box = node.plant._model.geom("obstacle").id
        assert np.allclose(node.plant._data.geom_xpos[box], [0.5, 0.2, 0.3])
        assert np.allclose(node.plant._model.geom_size[box], [0.1, 0.05, 0.2])
        wrong = fault_messages.obstacle_message(pose, [0.2, 0.1, 0.4], "world")
        node._on_obstacle(wrong)
        bad = fault_messages.obstacle_message(pose, [0.2, float("nan"), 0.4])
        node._on_obstacle(bad)
        assert [w.split(":")[0] for w in log.warnings()] == ["ft/obstacle ignored"] * 2
        assert "is not the base link" in log.warnings()[0] and "scale" in log.warnings()[1]
        publisher.publish(Marker(action=Marker.DELETE))
        assert spin_until(executor, lambda: node.plant.obstacle is None, 5.0)


def test_the_kinematic_plant_has_no_obstacles_and_says_so() -> None:
    with sim("kinematic") as (node, _, _, log):
        node._on_obstacle(fault_messages.obstacle_message(np.eye(4), [0.1, 0.1, 0.1]))
        assert len(log.warnings()) == 1 and "need the physics plant" in log.warnings()[0]


def test_a_scenario_injects_faults_and_places_an_obstacle_once_the_sim_has_them() -> None:
    from ft_core.errors import SuiteError
    from ft_sim.scenario import TASK_POINTS, Scenario, ScenarioConfig
    from rosutil import fresh_domain

    config = ScenarioConfig(robot="panda_inertial", plant="physics", lock_joint="",
                            points=(TASK_POINTS["panda"][0],), soft_limits=False,
                            response_time=0.03)
    scenario = Scenario(config, domain_id=fresh_domain())
    try:
        scenario.start()
        scenario.step()
        scenario.inject_fault("viscous", "panda_joint4", severity=20.0)
        injected = scenario.record.injected_at
        scenario.step()
        scenario.inject_fault("intermittent", "panda_joint3", period=0.5)
        assert scenario.sim.faults == {"panda_joint3": ["intermittent"],
                                       "panda_joint4": ["viscous"]}
        assert scenario.record.injected_at == injected  # the first failure's time
        pose = np.eye(4)
        pose[:3, 3] = [0.5, 0.5, 0.5]
        scenario.place_obstacle(pose, (0.1, 0.2, 0.3))
        assert np.allclose(scenario.sim.plant.obstacle[1], [0.1, 0.2, 0.3])
        scenario.remove_obstacle()
        scenario.config.plant = "kinematic"
        with pytest.raises(SuiteError, match="physics plant"):
            scenario.place_obstacle(pose, (0.1, 0.1, 0.1))
    finally:
        scenario.close()


TEXT = st.sampled_from(["", "0", "0.5", "2", "50", "-1", "nan", "inf", "-inf", "1e308", "x",
                        "1" * 400])
STATUSES = st.lists(st.builds(
    lambda joint, kind, values: status(joint, kind, **dict(values)),
    st.sampled_from(["panda_joint2", "panda_joint4", "panda_joint9", "", "x" * 300]),
    st.sampled_from(["lock", "free_swing", "viscous", "dry", "authority", "range",
                     "intermittent", "", "LOCK"]),
    st.lists(st.tuples(st.sampled_from(["severity", "lower", "upper", "period", "other"]),
                       TEXT), max_size=5)), max_size=6)


@settings(max_examples=examples(60), deadline=None, suppress_health_check=list(HealthCheck))
@given(batches=st.lists(STATUSES, min_size=1, max_size=3))
def test_hostile_fault_messages_never_break_the_plant(batches) -> None:
    with sim() as (node, _, _, _):
        for statuses in batches:
            node._on_fault(DiagnosticArray(status=statuses))
            for _ in range(5):
                node.step()
        assert np.all(np.isfinite(node.q)) and np.all(np.isfinite(node.qd))
        assert np.all((node.q >= node.robot.lower - 0.01) & (node.q <= node.robot.upper + 0.01))
