"""`sensor_msgs/JointState` as it travels: read from, and written to, its serialized bytes.

The nodes take and send `JointState` as bytes (rclpy's `raw=True` subscriptions and
publishing of `bytes`) through these names, instead of rclpy's conversion of every
field to and from a Python object, for the one message each control cycle takes and
the one it sends:

- `JointStateReader.read` gives a `JointStateView` that reads like the message
  (`header.stamp`, `name`, `position`, `velocity`, `effort`), its arrays numpy views of
  the bytes;
- `CommandWriter` keeps the serialized command of a fixed set of joints and writes
  only its stamp and velocities into it each cycle.

The codec itself, which knows the wire format (plain little-endian CDR, `CDR_LE`), is in
`ft_msgs_py.rclpy_private` with the suite's other uses of what lies beneath rclpy's
public API; `Stamp`, `Header` and `JointStateView` are `ft_msgs_py.messages`'s.
"""

from ft_msgs_py.messages import Header, JointStateView, Stamp
from ft_msgs_py.rclpy_private import CDR_LE, CommandWriter, JointStateReader

__all__ = ["CDR_LE", "CommandWriter", "Header", "JointStateReader", "JointStateView", "Stamp"]
