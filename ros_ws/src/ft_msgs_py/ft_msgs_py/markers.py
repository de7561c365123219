"""The live view: `visualization_msgs/MarkerArray` on a node's `~/markers`, for RViz or Foxglove.

The sim draws what is: the arm, its injected locks in red and its free-swinging joints
in orange, and the tool's path. The controller draws what it acts on: its goal, the
critical points, and the joints the monitor announced locked as larger red spheres, so
that a lock detected shows as a red halo round the sim's red joint (on a real arm, round
the joint of the robot model `robot_state_publisher` draws). Every marker is in the
chain's base link: a viewer whose fixed frame is that link shows them without TF. One
marker per namespace, id 0, replaced at each update; a namespace with nothing to show
is deleted (`docs/sim.md`, "Live view").
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

#: s between two updates of a node's markers (10 Hz: a viewer's refresh, not the loop's).
PERIOD = 0.1
#: Tool positions a trail keeps (a minute at `PERIOD`).
TRAIL_LENGTH = 600
#: Line width and joint diameter of the arm, diameter of a goal or a critical point, and
#: of the halo round a joint announced locked (m).
LINK_WIDTH, JOINT_DIAMETER, POINT_DIAMETER, HALO_DIAMETER = 0.02, 0.05, 0.04, 0.09

#: Colours as (r, g, b, a).
HEALTHY = (0.6, 0.6, 0.65, 1.0)
LOCKED = (0.9, 0.1, 0.1, 1.0)
ANNOUNCED = (0.9, 0.1, 0.1, 0.35)  #: the halo of a joint the monitor announced locked
SWINGING = (1.0, 0.55, 0.0, 1.0)
DEGRADED = (0.6, 0.2, 0.85, 1.0)  #: a joint with a fault other than a lock or a free swing
GOAL = (0.1, 0.8, 0.2, 0.9)
CRITICAL = (0.2, 0.4, 1.0, 0.7)
PATH = (0.9, 0.8, 0.1, 1.0)


def _color(rgba: Sequence[float]) -> ColorRGBA:
    return ColorRGBA(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))


def _points(positions: Iterable[Sequence[float]]) -> list[Point]:
    return [Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in positions]


def _marker(header: Header, ns: str, kind: int, positions: Iterable[Sequence[float]] | np.ndarray,
            size: float, rgba: Sequence[float]) -> Marker:
    marker = Marker(header=header, ns=ns, id=0, type=kind, action=Marker.ADD,
                    points=_points(positions), color=_color(rgba))
    marker.pose.orientation.w = 1.0
    marker.scale.x = marker.scale.y = marker.scale.z = size
    return marker


def arm(header: Header, ns: str, skeleton: np.ndarray, colours: dict[int, Sequence[float]],
        ) -> list[Marker]:
    """The chain: links as a line from the base, joints as spheres.

    `skeleton` is `Robot.skeleton` (each joint's origin, then the tool; m, base frame);
    `colours` gives joint index -> colour for joints not `HEALTHY`.
    """
    links = _marker(header, f"{ns}/links", Marker.LINE_STRIP,
                    np.vstack([np.zeros(3), skeleton]), LINK_WIDTH, HEALTHY)
    joints = _marker(header, f"{ns}/joints", Marker.SPHERE_LIST, skeleton[:-1],
                     JOINT_DIAMETER, HEALTHY)
    joints.colors = [_color(colours.get(j, HEALTHY)) for j in range(len(skeleton) - 1)]
    return [links, joints]


def spheres(header: Header, ns: str, positions: Sequence[Sequence[float]],
            rgba: Sequence[float], diameter: float = POINT_DIAMETER) -> Marker:
    """Points as spheres (m); none deletes the namespace's marker."""
    if not len(positions):
        return Marker(header=header, ns=ns, id=0, action=Marker.DELETE)
    return _marker(header, ns, Marker.SPHERE_LIST, positions, diameter, rgba)


def line(header: Header, ns: str, positions: Sequence[Sequence[float]],
         rgba: Sequence[float] = PATH, width: float = LINK_WIDTH / 2) -> Marker:
    """A polyline through the positions (m); fewer than two delete the namespace's marker."""
    if len(positions) < 2:
        return Marker(header=header, ns=ns, id=0, action=Marker.DELETE)
    return _marker(header, ns, Marker.LINE_STRIP, positions, width, rgba)


def array(frame: str, stamp: Time, build) -> MarkerArray:
    """`build(header)` -> markers, as one array in `frame` at `stamp`."""
    return MarkerArray(markers=list(build(Header(frame_id=frame, stamp=stamp))))


class Trail:
    """The last `TRAIL_LENGTH` tool positions (m), for the path a view draws."""

    def __init__(self, length: int = TRAIL_LENGTH):
        self._positions: deque[np.ndarray] = deque(maxlen=length)

    def add(self, position: np.ndarray) -> None:
        """One more tool position (m, base frame); a non-finite one is left out."""
        if np.all(np.isfinite(position)):
            self._positions.append(np.asarray(position, dtype=float))

    @property
    def positions(self) -> list[np.ndarray]:
        """The kept positions, oldest first."""
        return list(self._positions)
