"""Keep the suite's processes off Fast DDS's shared-memory transport.

Fast DDS (Jazzy's default middleware) delivers to a reader on the same machine through a
shared-memory port guarded by a mutex shared between processes. A process killed while
it held that mutex (kill -9, a crash) leaves it locked: every writer to it then waits in
`publish` for the mutex's 1 s timeout, again at each publication, and rclpy keeps the
interpreter lock meanwhile. So a killed monitor can stall the controller's control
loop (and the sim's joint states) for about a second. On UDP no such lock exists
(docs/controller.md has the figures of both).

`avoid_shared_memory` sets this process's environment, before its participant is made,
so that Fast DDS uses UDPv4 alone:
- with `ROS_AUTOMATIC_DISCOVERY_RANGE` unset or `SUBNET`: `FASTDDS_BUILTIN_TRANSPORTS=UDPv4`;
- with `LOCALHOST`, where rmw_fastrtps adds a shared-memory transport whatever that
  variable or an XML profile says: the range becomes `SYSTEM_DEFAULT` and the participant
  takes `fastdds_udp_loopback.xml` (UDPv4 on 127.0.0.1 only, unicast discovery to
  127.0.0.1): the same reach, localhost, without shared memory.
It changes nothing under another middleware (`RMW_IMPLEMENTATION`), with a profile file
of the user's own (`FASTRTPS_DEFAULT_PROFILES_FILE`, `FASTDDS_DEFAULT_PROFILES_FILE`) or
a transport choice of the user's own (`FASTDDS_BUILTIN_TRANSPORTS`), or with the range
`OFF` or `SYSTEM_DEFAULT`. Nodes of other processes on shared memory still reach these
over UDP.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from importlib import resources

#: The participant profile for localhost without shared memory.
PROFILE = "fastdds_udp_loopback.xml"
_FAST_DDS = ("rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp")


def avoid_shared_memory(environ: MutableMapping[str, str] = os.environ) -> str | None:
    """Make this process's Fast DDS participant use UDPv4 only; what was set, or None.

    Call it before `rclpy.init` (the participant reads the environment when made).
    """
    if environ.get("RMW_IMPLEMENTATION", _FAST_DDS[0]) not in _FAST_DDS or any(
            environ.get(name) for name in ("FASTRTPS_DEFAULT_PROFILES_FILE",
                                           "FASTDDS_DEFAULT_PROFILES_FILE",
                                           "FASTDDS_BUILTIN_TRANSPORTS")):
        return None
    reach = environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "")
    if reach in ("", "SUBNET"):
        environ["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
        return "FASTDDS_BUILTIN_TRANSPORTS=UDPv4"
    if reach == "LOCALHOST":
        environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"
        environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(
            resources.files("ft_msgs_py").joinpath(PROFILE))
        return f"UDPv4 on 127.0.0.1 ({PROFILE})"
    return None
