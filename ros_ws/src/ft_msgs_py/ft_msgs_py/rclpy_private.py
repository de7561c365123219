"""Every use the suite makes of rclpy beneath its public API, and of the wire format.

A new rclpy (or middleware) may change any of these without notice, so they are all
here, each with a canary in tests/nodes/test_rclpy_private.py that fails saying what
changed. For each: what it is for, the public way, and why that is not used.

- `set_as_declared` (`parameter_table.declare`): `Node._set_parameters_atomically_common`
  with the parameter's own descriptor and `allow_not_set_type=True`, as rclpy's
  `declare_parameter` calls it. It gives a typed array parameter nobody set an empty
  array of its type, read-only or not, instead of "not set" (rclpy's get_parameters
  service answers nothing at all to a request naming a parameter not set, so `ros2
  param dump` printed no parameter of the node). Public way: `declare_parameter`, but
  it takes `[]` for a BYTE_ARRAY, refuses a `ParameterValue` (TypeError) and leaves a
  parameter declared by its `Parameter.Type` not set; `set_parameters` then refuses a
  read-only parameter.
- `clock_nanoseconds` (`SuiteNode.now_ns`): `Clock.handle.get_now()`, rcl's clock
  through rclpy's C extension, read as integer nanoseconds. Public way:
  `Clock.now().nanoseconds`, the same value, but every reading builds an
  `rclpy.time.Time`, which checks its arguments in Python: several times the cost, and
  a control cycle reads the clock several times (docs/benchmarks.md).
- `message_taker` (`SuiteNode.take_on_demand`): `Subscription.handle.take_message`
  inside `with handle:`, as rclpy's executors take a message. It lets a control loop
  take a subscription's queued messages when it reads its inputs, at the top of each
  cycle, instead of being woken by every message. Public way: none, rclpy takes a
  subscription's messages only in an executor. `SuiteNode.take_on_demand` also relies
  on rclpy's executors (the SingleThreadedExecutor's and the EventsExecutor's) finding
  the subscriptions to dispatch in `Node.subscriptions`, which `SuiteNode` filters.
- `JointStateReader` and `CommandWriter` (named in `ft_msgs_py.wire`): a
  `sensor_msgs/JointState` read from and written to its serialized bytes, for
  rclpy's `raw=True` subscriptions and publishing of `bytes` (both public). Public
  way: `rclpy.serialization.deserialize_message` and `serialize_message` (or
  subscriptions and publishers of message objects), which convert every field in
  Python with a setter's type checks per field: a few times the cost of reading the
  bytes here, over ten times that of writing a command here (docs/benchmarks.md), for
  the one message each control cycle takes and the one it sends. rclpy's serializer
  still writes the writer's template once, and its deserializer reads any encapsulation
  other than plain little-endian CDR.

The wire format read and written is plain little-endian CDR (OMG CDR version 1, the
encapsulation `CDR_LE` that rmw_fastrtps writes for ROS 2 messages and rosbag2
records): after a 4-byte encapsulation header, each primitive is aligned to its size
(at most 8) from the start of the payload, a string is a uint32 length (with its
terminating NUL) and its bytes, a sequence a uint32 count and its elements. Bytes that
do not parse raise `MessageError` saying why, like any other message the suite refuses;
every length is checked against the bytes left before anything is read or allocated,
so a hostile count costs nothing.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from rclpy.clock import Clock
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState

from ft_msgs_py.messages import MAX_NAMES, Header, JointStateView, MessageError, Stamp


def set_as_declared(node: Node, parameter: Parameter) -> None:
    """Set a declared parameter's value as a declaration does: its descriptor, read-only too.

    A value of type NOT_SET is stored, not undeclared. The node's parameter callbacks
    run as for any change.
    """
    node._set_parameters_atomically_common(
        [parameter], {parameter.name: node.describe_parameter(parameter.name)},
        allow_not_set_type=True)


def clock_nanoseconds(clock: Clock) -> Callable[[], int]:
    """The call that reads `clock` (wall, steady or simulated, as it is) in integer ns."""
    handle = clock.handle

    def now_ns() -> int:
        return handle.get_now().nanoseconds
    return now_ns


def message_taker(subscription: Subscription) -> Callable[[], Any]:
    """The call that takes `subscription`'s oldest queued message, or None if none waits.

    The message as the subscription's callback gets it: a message object, or its bytes
    for a `raw=True` subscription.
    """
    handle, msg_type, raw = subscription.handle, subscription.msg_type, subscription.raw

    def take() -> Any:
        with handle:
            taken = handle.take_message(msg_type, raw)
        return None if taken is None else taken[0]
    return take


#: The encapsulation header of little-endian plain CDR (representation id CDR_LE).
CDR_LE = b"\x00\x01"
_HEADER = 4  # bytes before the payload; alignment counts from its end
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")


class _Reader:
    """A cursor over CDR_LE bytes; a read past the end raises MessageError."""

    def __init__(self, raw: bytes) -> None:
        self.raw, self.at = raw, _HEADER

    def u32(self) -> int:
        self.at += -(self.at - _HEADER) % 4
        if self.at + 4 > len(self.raw):
            raise MessageError(f"{len(self.raw)} bytes end inside a length")
        (value,) = _U32.unpack_from(self.raw, self.at)
        self.at += 4
        return value

    def string(self) -> str:
        size = self.u32()
        end = self.at + size
        if size == 0 or end > len(self.raw) or self.raw[end - 1] != 0:
            raise MessageError("a string runs past the end or lacks its NUL")
        try:
            text = self.raw[self.at:end - 1].decode()
        except UnicodeDecodeError as error:
            raise MessageError(f"a string is not UTF-8 ({error.reason})") from None
        self.at = end
        return text

    def doubles(self) -> np.ndarray:
        count = self.u32()
        if count:
            self.at += -(self.at - _HEADER) % 8
        if 8 * count > len(self.raw) - self.at:
            raise MessageError(f"{count} values run past the end")
        values = np.frombuffer(self.raw, "<f8", count, self.at)
        self.at += 8 * count
        return values


def _parse(reader: _Reader, known: tuple[bytes, tuple[str, ...]] = (b"", ()),
           ) -> tuple[JointStateView, bytes]:
    """A JointState from CDR_LE bytes, and the bytes of its names (from their count).

    Names whose bytes equal `known`'s are `known`'s strings, not decoded again.
    MessageError if the bytes are not a JointState.
    """
    raw = reader.raw
    if len(raw) < _HEADER + 8:
        raise MessageError(f"{len(raw)} bytes: too short")
    stamp = Stamp(*_STAMP.unpack_from(raw, _HEADER))
    reader.at = _HEADER + 8
    frame_id = reader.string()
    reader.at += -(reader.at - _HEADER) % 4
    start = reader.at
    blob, names = known
    if blob and raw.startswith(blob, start):
        reader.at += len(blob)
    else:
        count = reader.u32()
        if count > MAX_NAMES:
            raise MessageError(f"{count} joint names (more than {MAX_NAMES})")
        names = tuple(reader.string() for _ in range(count))
        blob = raw[start:reader.at]
    return (JointStateView(Header(stamp, frame_id), names, reader.doubles(), reader.doubles(),
                           reader.doubles()), blob)


class JointStateReader:
    """Reads the JointStates of one stream from their bytes (a `raw=True` subscription's).

    Keeps the names of the last message read: a driver sends the same names in every
    message, and bytes equal to those read as those, undecoded.
    """

    def __init__(self) -> None:
        self._names: tuple[bytes, tuple[str, ...]] = (b"", ())

    def read(self, raw: bytes) -> JointStateView:
        """The joint state in `raw`.

        Plain little-endian CDR is read here; another CDR encapsulation goes to rclpy's
        deserializer. Raises MessageError, saying why, for bytes that are not a
        JointState (not CDR, truncated, a length past the end, a name that is not
        UTF-8, more than `MAX_NAMES` names).
        """
        if raw[:2] == CDR_LE:
            view, blob = _parse(_Reader(raw), self._names)
            self._names = (blob, view.name)
            return view
        if raw[:1] != b"\x00":  # every CDR representation identifier starts so
            raise MessageError(f"{len(raw)} bytes that are not CDR (header {raw[:2].hex()})")
        try:
            msg = deserialize_message(raw, JointState)
        except Exception as error:  # whatever rclpy raises for bytes it cannot read
            raise MessageError(f"{len(raw)} bytes rclpy cannot read ({error})") from None
        return JointStateView(Header(Stamp(msg.header.stamp.sec, msg.header.stamp.nanosec),
                                     msg.header.frame_id), tuple(msg.name),
                              np.asarray(msg.position, dtype=float),
                              np.asarray(msg.velocity, dtype=float),
                              np.asarray(msg.effort, dtype=float))


class CommandWriter:
    """The serialized velocity command (a `JointState`) of fixed joints, rewritten in place.

    rclpy's serializer runs once, for the names; `serialize` writes the stamp and the
    velocities into those bytes and returns a copy to publish.
    """

    def __init__(self, joints: Sequence[str]) -> None:
        template = serialize_message(JointState(name=list(joints),
                                                velocity=[0.0] * len(joints)))
        reader = _Reader(template)
        _parse(reader)
        # Up to where the message ends: rclpy's buffer may hold a few bytes more, which
        # readers as strict as rosbags' refuse.
        self._bytes = bytearray(template[:reader.at])
        self._count = len(joints)
        # The velocities end where the last field, the empty efforts' count, begins.
        self._velocity_at = reader.at - 4 - 8 * self._count

    def serialize(self, sec: int, nanosec: int, velocity: np.ndarray) -> bytes:
        """The command's bytes with stamp `sec`, `nanosec` and `velocity` (rad/s, one per joint)."""
        if len(velocity) != self._count:
            raise ValueError(f"{len(velocity)} velocities for {self._count} joints")
        _STAMP.pack_into(self._bytes, _HEADER, sec, nanosec)
        start = self._velocity_at
        self._bytes[start:start + 8 * self._count] = np.asarray(velocity, "<f8").tobytes()
        return bytes(self._bytes)
