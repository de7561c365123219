"""`ft_msgs_py.wire`: JointStates read from and written to their bytes, against rclpy's own."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from ft_msgs_py import wire
from ft_msgs_py.convert import MAX_NAMES, MessageError
from fuzzing import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import JointState

floats = st.floats(allow_nan=True, allow_infinity=True)


def read(raw: bytes) -> wire.JointStateView:
    """What a fresh reader reads in `raw`."""
    return wire.JointStateReader().read(raw)
#: What a ROS string holds: UTF-8 (no lone surrogates), ending at the first NUL.
texts = st.text(st.characters(exclude_characters="\x00", exclude_categories=("Cs",)), max_size=12)


@st.composite
def joint_states(draw) -> JointState:
    """Any JointState: stamps over their whole range, any text, arrays of any length."""
    msg = JointState(name=draw(st.lists(texts, max_size=9)))
    msg.header.stamp.sec = draw(st.integers(-(2**31), 2**31 - 1))
    msg.header.stamp.nanosec = draw(st.integers(0, 2**32 - 1))
    msg.header.frame_id = draw(texts)
    for field in ("position", "velocity", "effort"):
        setattr(msg, field, draw(st.lists(floats, max_size=9)))
    return msg


def same(view: wire.JointStateView, msg: JointState) -> bool:
    """Whether the view holds the message's every field (NaN equal to NaN)."""
    return (view.header.stamp == (msg.header.stamp.sec, msg.header.stamp.nanosec)
            and view.header.frame_id == msg.header.frame_id
            and view.name == tuple(msg.name)
            and all(np.array_equal(getattr(view, f), np.asarray(getattr(msg, f)), equal_nan=True)
                    for f in ("position", "velocity", "effort")))


@settings(max_examples=examples(300))
@given(st.lists(joint_states(), min_size=1, max_size=4))
def test_what_rclpy_serializes_reads_back_field_by_field(messages) -> None:
    """By one reader in sequence: names kept from the message before are never taken for these."""
    reader = wire.JointStateReader()
    for msg in messages:
        assert same(reader.read(serialize_message(msg)), msg)


def test_names_changing_between_messages_are_read_anew() -> None:
    reader = wire.JointStateReader()
    first, second = JointState(name=["a", "b"]), JointState(name=["a", "c"])
    for msg in (first, second, first, JointState(name=[]), second, second):
        assert reader.read(serialize_message(msg)).name == tuple(msg.name)


def big_endian(sec: int, nanosec: int, names: list[str], position: list[float]) -> bytes:
    """A JointState in big-endian CDR (encapsulation CDR_BE), which rclpy does not write."""
    payload = bytearray(struct.pack(">iII", sec, nanosec, 1) + b"\0")

    def align(size: int) -> None:
        payload.extend(b"\0" * (-len(payload) % size))

    align(4)
    payload += struct.pack(">I", len(names))
    for name in names:
        align(4)
        payload += struct.pack(">I", len(name) + 1) + name.encode() + b"\0"
    align(4)
    payload += struct.pack(">I", len(position))
    align(8)
    payload += struct.pack(f">{len(position)}d", *position)
    align(4)
    return b"\0\0\0\0" + bytes(payload) + struct.pack(">II", 0, 0)


def test_another_cdr_encapsulation_is_read_by_rclpy() -> None:
    view = read(big_endian(7, 9, ["a", "bc"], [1.5, -2.0]))
    assert view.header.stamp == (7, 9) and view.name == ("a", "bc")
    assert view.position.tolist() == [1.5, -2.0] and view.velocity.size == 0


@settings(max_examples=examples(300))
@given(joint_states(), st.data())
def test_cut_or_changed_bytes_raise_message_error_or_read_as_some_joint_state(msg, data) -> None:
    raw = bytes(wire.CommandWriter(msg.name)._bytes) if data.draw(st.booleans()) else \
        serialize_message(msg)
    if data.draw(st.booleans()):
        raw = raw[:data.draw(st.integers(0, len(raw) - 1))]
    else:
        at = data.draw(st.integers(0, len(raw) - 1))
        raw = raw[:at] + bytes([raw[at] ^ data.draw(st.integers(1, 255))]) + raw[at + 1:]
    try:
        view = read(raw)
    except MessageError as error:
        assert str(error)
        return
    assert isinstance(view.name, tuple) and all(isinstance(n, str) for n in view.name)
    assert all(getattr(view, f).dtype == np.float64 for f in ("position", "velocity", "effort"))


def test_every_cut_short_message_is_refused() -> None:
    raw = serialize_message(JointState(name=["a", "b"], position=[1.0, 2.0]))
    # 4 (encapsulation) + 8 (stamp) + 5 (frame, padded to 8) + 4 (count) + 6 + 2 + 6 ("a",
    # padding, "b") + 2 + 4 (padding, count) + 16 (positions) + 4 + 4 (two empty arrays)
    end = 68
    assert read(raw[:end]).position.tolist() == [1.0, 2.0]
    for cut in range(end):
        with pytest.raises(MessageError):
            read(raw[:cut])


@pytest.mark.parametrize(("raw", "words"), [
    (b"", "not CDR"),
    (b"\x01\x00\x00\x00" + bytes(40), "not CDR"),
    (b"\x00\x01\x00\x00" + bytes(4), "too short"),
    (b"\x00\x01\x00\x00" + struct.pack("<iII", 0, 0, 2**32 - 1) + bytes(20), "past the end"),
    (b"\x00\x01\x00\x00" + struct.pack("<iII", 0, 0, 1) + b"\0\0\0\0"
     + struct.pack("<I", MAX_NAMES + 1) + bytes(64), f"more than {MAX_NAMES}"),
    (b"\x00\x01\x00\x00" + struct.pack("<iII", 0, 0, 1) + b"\0\0\0\0"
     + struct.pack("<II", 1, 3) + b"\xff\xfe\0", "not UTF-8"),
    (b"\x00\x01\x00\x00" + struct.pack("<iII", 0, 0, 1) + b"\0\0\0\0"
     + struct.pack("<II", 0, 2**31) + bytes(16), "values run past the end"),
])
def test_hostile_bytes_are_refused_unread(raw: bytes, words: str) -> None:
    with pytest.raises(MessageError, match=words):
        read(raw)


@settings(max_examples=examples(200))
@given(st.lists(texts, max_size=9, unique=True), st.data())
def test_the_command_writer_writes_what_rclpy_and_rosbags_read(joints, data) -> None:
    writer = wire.CommandWriter(joints)
    sec, nanosec = data.draw(st.integers(0, 2**31 - 1)), data.draw(st.integers(0, 10**9 - 1))
    velocity = np.array(data.draw(st.lists(floats, min_size=len(joints), max_size=len(joints))))
    raw = writer.serialize(sec, nanosec, velocity)
    msg = deserialize_message(raw, JointState)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (sec, nanosec)
    assert list(msg.name) == joints and not msg.position and not msg.effort
    assert np.array_equal(np.asarray(msg.velocity), velocity, equal_nan=True)
    # Exactly the message's bytes: rosbags, which refuses trailing bytes, reads them too.
    recorded = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(raw, "sensor_msgs/msg/JointState")
    assert list(recorded.name) == joints


def test_the_command_writer_refuses_a_wrong_number_of_velocities() -> None:
    with pytest.raises(ValueError, match="2 velocities for 3 joints"):
        wire.CommandWriter(["a", "b", "c"]).serialize(0, 0, np.zeros(2))


def test_a_view_reads_like_the_message_where_the_suite_reads_one() -> None:
    from ft_msgs_py import convert

    msg = JointState(name=["b", "a"], position=[2.0, 1.0])
    msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 500_000_000
    view = read(serialize_message(msg))
    assert convert.joint_vector(view, ["a", "b"]).tolist() == [1.0, 2.0]
    assert math.isclose(convert.stamp_seconds(view.header.stamp), 3.5)
