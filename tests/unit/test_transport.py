"""ft_msgs_py.transport: the suite's processes keep off Fast DDS's shared memory."""

from __future__ import annotations

from pathlib import Path

from ft_msgs_py import transport


def test_the_default_range_takes_udp_and_localhost_takes_the_loopback_profile() -> None:
    env: dict[str, str] = {}
    assert transport.avoid_shared_memory(env) == "FASTDDS_BUILTIN_TRANSPORTS=UDPv4"
    assert env == {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    assert transport.avoid_shared_memory(env) is not None
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    profile = Path(env["FASTRTPS_DEFAULT_PROFILES_FILE"])
    text = profile.read_text()  # shipped with the package
    assert "<useBuiltinTransports>false</useBuiltinTransports>" in text
    assert "127.0.0.1" in text and "SHM" not in text


def test_a_choice_of_the_users_own_is_left_alone() -> None:
    for env in ({"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"},
                {"FASTRTPS_DEFAULT_PROFILES_FILE": "/etc/mine.xml"},
                {"FASTDDS_BUILTIN_TRANSPORTS": "SHM"},
                {"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"},
                {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"}):
        before = dict(env)
        assert transport.avoid_shared_memory(env) is None
        assert env == before
