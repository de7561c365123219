"""ft_msgs_py without a running graph: conversions, metrics, diagnostics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ft_core import robots
from ft_msgs_py import convert, diagnostics, metrics
from geometry_msgs.msg import Twist
from sensor_msgs.msg import JointState

JOINTS = ["a", "b", "c"]


def state(names, positions) -> JointState:
    return convert.joint_state(names, convert.stamp_from_nanoseconds(0), position=positions)


def test_joint_vectors_are_matched_by_name_in_any_order_ignoring_extras() -> None:
    msg = state(["c", "extra", "a", "b"], [3.0, 9.0, 1.0, 2.0])
    np.testing.assert_array_equal(convert.joint_vector(msg, JOINTS), [1.0, 2.0, 3.0])


@pytest.mark.parametrize(("names", "values", "message"), [
    (["a", "b"], [1.0, 2.0], "lacks ['c']"),
    (["a", "b", "x"], [1.0, 2.0, 3.0], "it has ['x']"),
    (["a", "b", "c", "a"], [1.0, 2.0, 3.0, 4.0], "duplicate"),
    (["a", "b", "c"], [1.0, 2.0], "3 names but 2"),
    (["a", "b", "c"], [1.0, math.nan, 3.0], "non-finite position for ['b']"),
    (["a", "b", "c"], [1.0, math.inf, 3.0], "non-finite"),
])
def test_bad_joint_states_raise_a_clear_error(names, values, message: str) -> None:
    with pytest.raises(convert.MessageError, match=message.replace("[", r"\[").replace("]", r"\]")):
        convert.joint_vector(state(names, values), JOINTS)


def test_stamps_round_trip() -> None:
    stamp = convert.stamp_from_nanoseconds(12_345_678_901)
    assert (stamp.sec, stamp.nanosec) == (12, 345_678_901)
    assert convert.stamp_seconds(stamp) == pytest.approx(12.345678901)


def test_locked_joint_messages() -> None:
    msg = convert.locked_message({"b": 0.5, "zz": 1.0}, convert.stamp_from_nanoseconds(5))
    locked, unknown = convert.locked_joints(msg, JOINTS)
    assert locked == {"b": 0.5} and unknown == ["zz"]
    bare = JointState(name=["a"])  # positions are optional
    assert math.isnan(convert.locked_joints(bare, JOINTS)[0]["a"])


def test_twists_and_poses() -> None:
    twist = Twist()
    twist.linear.x, twist.angular.z = 0.1, -0.2
    np.testing.assert_array_equal(convert.twist_vector(twist), [0.1, 0, 0, 0, 0, -0.2])
    twist.linear.y = math.nan
    with pytest.raises(convert.MessageError, match="non-finite"):
        convert.twist_vector(twist)
    pose = robots.load("panda").forward(np.array([0.1, -0.3, 0.2, -2.0, 0.3, 1.5, 0.4]))
    np.testing.assert_allclose(convert.pose_matrix(convert.pose_message(pose)), pose, atol=1e-12)
    zero = convert.pose_message(pose)
    zero.orientation.x = zero.orientation.y = zero.orientation.z = zero.orientation.w = 0.0
    with pytest.raises(convert.MessageError, match="zero quaternion"):
        convert.pose_matrix(zero)


def test_metrics_are_labelled_and_always_finite() -> None:
    labels = metrics.labels(JOINTS)
    assert labels[:5] == ["kfm", "sigma_min", "jump_index", "task_scale", "soft_limit_margin"]
    assert labels[5:] == ["s_a", "s_b", "s_c"]
    values = {label: float(i) for i, label in enumerate(labels)}
    msg = metrics.template(labels)
    assert msg.layout.dim[0].label == ",".join(labels)
    metrics.fill(msg, list(values.values()))
    assert metrics.values(msg) == values
    with pytest.raises(ValueError, match=r"non-finite metrics \['kfm'\]"):
        metrics.fill(msg, [math.nan, *list(values.values())[1:]])
    with pytest.raises(ValueError, match="8 labels"):
        metrics.fill(msg, [0.0])
    assert metrics.values(msg) == values  # a refused fill leaves the message as it was


def test_diagnostic_statuses_carry_key_values() -> None:
    status = diagnostics.status("controller", diagnostics.WARN, "limited",
                                {"kfm": 0.0123456789, "locked": ["b"], "ok": True})
    assert status.level == diagnostics.WARN
    assert {kv.key: kv.value for kv in status.values} == {
        "kfm": "0.0123457", "locked": "[b]", "ok": "True"}


def test_recurring_problems_are_counted_not_logged_again() -> None:
    """Issue 14: a late state flapped "no joint state" / "recovered" 20-80 times a minute."""
    from ft_msgs_py.episodes import Episodes

    lines: list[tuple[str, str]] = []

    class Logger:
        def error(self, text: str) -> None:
            lines.append(("error", text))

        def warning(self, text: str) -> None:
            lines.append(("warning", text))

        def info(self, text: str) -> None:
            lines.append(("info", text))

    episodes = Episodes(Logger())
    for _ in range(50):
        episodes.report("joint_states", "no joint state for 0.101 s")
        episodes.report("joint_states", None)
    assert lines == [("error", "joint_states: no joint state for 0.101 s"),
                     ("info", "joint_states: recovered")]
    episodes.report("frame", "frame 'camera' is not the base frame", warning=True)
    episodes.report("frame", None)
    episodes.report("twist", "twist has non-finite values")  # another severity, no crash
    assert lines[2:] == [("warning", "frame: frame 'camera' is not the base frame"),
                         ("info", "frame: recovered"),
                         ("error", "twist: twist has non-finite values")]
    assert episodes.active == {"twist": "twist has non-finite values"}


def test_array_vectors_are_put_in_chain_order_and_checked() -> None:
    np.testing.assert_array_equal(convert.array_vector([1.0, 2.0, 3.0], [2, 0, 1]),
                                  [2.0, 3.0, 1.0])
    with pytest.raises(convert.MessageError, match="2 values for 3 joints"):
        convert.array_vector([1.0, 2.0], [0, 1, 2])
    with pytest.raises(convert.MessageError, match="non-finite"):
        convert.array_vector([1.0, float("nan"), 3.0], [0, 1, 2])


def test_the_monitor_guard_fires_only_after_an_echo_went_missing() -> None:
    """Issue 31 item 12: the controller's guard of a dead monitor (ft_msgs_py.monitor_guard)."""
    from ft_msgs_py.monitor_guard import MonitorGuard

    guard = MonitorGuard(timeout=0.15)
    for k in range(100):  # no monitor in this graph: no echo ever, never silent
        guard.sent((k, 0), 0.01 * k, [0.1])
        assert guard.silent(0.01 * k) is None
    guard.received((5, 0), [0.1])  # an echo of a command sent long ago
    guard.received((99, 0), [0.1])  # the latest command's echo: the monitor is there
    assert not guard.received((1000, 0), [0.1])  # someone else's (the guard's own zeros)
    now = 1.0
    for k in range(100, 110):  # commands answered within a cycle: never silent
        guard.sent((k, 0), now, [0.1])
        guard.received((k, 0), [0.1])
        now += 0.01
        assert guard.silent(now) is None
    guard.sent((200, 0), now, [0.1])  # then the monitor dies
    assert guard.silent(now + 0.14) is None
    assert guard.silent(now + 0.2) == pytest.approx(0.2)
    guard.sent((201, 0), now + 0.21, [0.1])  # later commands do not restart the wait
    assert guard.silent(now + 0.22) == pytest.approx(0.22)
    guard.received((201, 0), [0.1])  # a restarted monitor answers
    assert guard.silent(now + 0.3) is None
    guard.timeout = 0.0  # off
    guard.sent((202, 0), now + 0.3, [0.1])
    assert guard.silent(now + 5.0) is None


def test_the_controllers_own_stall_is_not_the_monitors_silence() -> None:
    """A controller stopped for 0.3 s finds its echoes queued behind the guard's check.

    The gap between two checks longer than the timeout restarts the wait; a monitor that
    stays silent after it is still caught one timeout later.
    """
    from ft_msgs_py.monitor_guard import MonitorGuard

    guard = MonitorGuard(timeout=0.05)
    guard.sent((1, 0), 0.0, [0.1])
    guard.received((1, 0), [0.1])
    guard.sent((2, 0), 0.004, [0.1])
    assert guard.silent(0.004) is None
    assert guard.silent(0.304) is None  # back from a 0.3 s stop: the echo may be queued
    assert guard.silent(0.34) is None
    assert guard.silent(0.36) == pytest.approx(0.056)  # still nothing: the monitor is gone
    guard.received((2, 0), [0.1])
    assert guard.silent(0.37) is None


def test_the_monitors_echoes_show_the_joints_it_holds_locked() -> None:
    """The monitor zeros its locked joints in what it forwards.

    The controller's check of a contested locked set (ft_msgs_py.publishers).
    """
    from ft_msgs_py.monitor_guard import MonitorGuard

    guard = MonitorGuard(timeout=0.1)
    guard.sent((1, 0), 0.0, [0.1, 0.2, 0.0, -0.3])
    assert guard.received((1, 0), [0.12, 0.0, 0.0, -0.25])  # joint 1 zeroed (2 was 0 anyway)
    assert guard.zeroed == {1}
    guard.sent((2, 0), 0.01, [0.1, 0.2, 0.3, 0.4])
    assert guard.received((2, 0), [0.0, 0.0, 0.0, 0.0])  # a refused command: no news
    assert guard.zeroed == {1}
    assert not guard.received((3, 0), [0.0, 0.5, 0.0, 0.0])  # not an echo: no news
    assert guard.zeroed == {1}
