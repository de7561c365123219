"""Quality-of-service profiles of the suite's topics.

- Inputs that a plant or driver may publish best-effort (joint states, commands)
  are read with a best-effort subscription, which also accepts reliable publishers.
- Everything the suite publishes is reliable, which every subscriber accepts.
- User targets are reliable: a one-shot pose goal must not be dropped.
- `ft/locked_joints` and `robot_description` are reliable and transient local, depth 1:
  a node that starts later still gets the last message.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: Subscriptions to joint states and commands.
SENSOR_INPUT = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.VOLATILE)
#: Publishers of the suite and subscriptions to user targets.
RELIABLE = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
#: `ft/locked_joints` and `robot_description`, publishers and subscriptions alike.
LATCHED = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
