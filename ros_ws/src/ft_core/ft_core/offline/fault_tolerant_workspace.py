"""The failure-tolerant workspace of the planar 3R (Lewis & Maciejewski 1997 sec. II, figs 1 and 3).

    ft-map fault-tolerant-workspace -o docs/fault_tolerant_workspace.png
    ft-map fault-tolerant-workspace --limits=-180:180,-180:180,-180:180 -o unrestricted.png

The arm is the 3-DOF planar manipulator with equal links of Lewis & Maciejewski 1997
fig. 1 (the built-in `planar3r`: unit links, task the tool's x-y position; lengths in
link lengths, which that model's links make metres, areas in m^2). Its joints are
continuous: sec. II says the self-motion manifolds of the points one link length from
the base "span the entire range of joint values for all three joints".

Sec. II-III and fig. 3: software joint limits are imposed on every joint before a
failure. For those limits, on a square grid of task positions, this module computes

(a) the restricted workspace: the points some configuration inside the limits reaches;
(b) for each joint i, the points reachable after joint i locks anywhere inside its
    restricted range: the intersection, over the locked value, of what the other two
    joints reach. Reading taken: after the failure the other joints move over their
    full (physical) ranges, as sec. II says the software limits "can be removed" after
    a failure;
(c) the failure-tolerant workspace, (a) intersected with every (b): the points that can
    be reached before any failure and after any one.

The reduction is 1 - area(c) / area(a). Reading taken: the paper's "penalty for requiring
failure tolerance" is a share of the restricted workspace (of the whole workspace, 9 pi,
it would be some 89% here).

Fig. 3 indicates its limits in its artwork; the text gives no numbers. Reading taken
(`FIG3_LIMITS`): joint 1 in [-15, 15] deg, joints 2 and 3 in [-90, 90] deg, i.e. the base
swings a little and neither elbow folds back past a right angle. These were chosen, among
symmetric ranges in multiples of 15 deg, as the pair closest to the text's "approximately
60% reduction" (docs/placement.md has the alternatives), so that agreement is by choice; the
independent checks are the unrestricted case (only the unit circle is failure tolerant,
fig. 1) and the shapes of (b), which follow from the geometry.

Every membership test is closed-form: with one joint fixed, the other two form a
two-link arm (the fixed joint merged into a rigid link) solved exactly, both elbow
branches, and the joint values are checked against their ranges (mod 2 pi). Only the
fixed joint's value is sampled (at most `ANGLE_STEP` apart): for (a) the joint with the
narrowest range (a point whose admissible values of that joint span less than one step
can be missed, so (a) is estimated from below near its boundary), for (b) the locked
value (the intersection over samples estimates (b) from above, by O(step^2)).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ft_core.offline import cli

#: The `ft-map` subcommand that runs `main`.
COMMAND = "fault-tolerant-workspace"
#: Link lengths of the fig. 1 arm (link lengths; 1 m each in the `planar3r` model).
LINKS = (1.0, 1.0, 1.0)
#: Largest spacing (rad) of the sampled values of the fixed joint.
ANGLE_STEP = math.radians(0.5)
#: Tolerance (rad, and on cosines) of the closed-form membership tests.
TOLERANCE = 1e-9
#: A full turn, the range of a continuous joint (rad).
FULL_TURN = (-math.pi, math.pi)
#: Reading of Lewis & Maciejewski 1997 fig. 3's software limits (rad): module notes.
FIG3_LIMITS = ((-math.radians(15), math.radians(15)), (-math.radians(90), math.radians(90)),
               (-math.radians(90), math.radians(90)))
#: Default grid: points per axis over [-reach, reach]^2.
GRID_COUNT = 301
#: Fewest and most grid points per axis.
GRID_RANGE = (21, 1001)
#: What Lewis & Maciejewski 1997 sec. II reports: "an approximately 60% reduction".
PAPER_REDUCTION = 0.6

Ranges = tuple[tuple[float, float], ...]


def joint_values(low: float, high: float) -> np.ndarray:
    """Values from low to high (rad) at most `ANGLE_STEP` apart, both ends included."""
    count = max(2, math.ceil((high - low) / ANGLE_STEP) + 1)
    return np.linspace(low, high, count)


def _within(angle: np.ndarray | float, low: float, high: float) -> np.ndarray:
    """Whether angles (rad) lie in [low, high] modulo 2 pi (within `TOLERANCE`)."""
    width = high - low
    if width >= 2 * math.pi - TOLERANCE:
        return np.ones(np.shape(angle), dtype=bool)
    return np.mod(np.asarray(angle) - low + TOLERANCE, 2 * math.pi) <= width + 2 * TOLERANCE


def _two_link(points: np.ndarray, first: float, second: float,
              ) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """Inverse kinematics of a two-link arm (lengths first, second) for points (..., 2).

    Returns the mask of points within its reach and, for both elbow branches, the
    absolute angle of the first link and the relative angle of the second (rad). A
    link of length 0 reaches nothing (a set of zero area of the plane).
    """
    squared = points[..., 0] ** 2 + points[..., 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        cosine = (squared - first ** 2 - second ** 2) / (2 * first * second)
    inside = np.abs(cosine) <= 1 + TOLERANCE
    elbow = np.arccos(np.clip(np.nan_to_num(cosine), -1.0, 1.0))
    direction = np.arctan2(points[..., 1], points[..., 0])
    branches = []
    for relative in (elbow, -elbow):
        absolute = direction - np.arctan2(second * np.sin(relative),
                                          first + second * np.cos(relative))
        branches.append((absolute, relative))
    return inside, branches


def reachable(points: np.ndarray, joint: int, value: float, ranges: Ranges) -> np.ndarray:
    """Mask of the points (..., 2) reached with `joint` (0-based) at `value` (rad).

    The other two joints within `ranges` ((low, high) per joint, rad). With joint 1
    fixed the arm is links 2-3 from the end of link 1; with joint 2 or 3 fixed, that
    joint's two links form one rigid link of length rho at angle beta to the first.
    """
    a, b, c = LINKS
    angles: list[tuple[np.ndarray | float, ...]]  # joints 1-3 per elbow branch
    if joint == 0:
        start = a * np.array([math.cos(value), math.sin(value)])
        inside, branches = _two_link(points - start, b, c)
        angles = [(value, absolute - value, relative) for absolute, relative in branches]
    else:
        near, far = (a, b) if joint == 1 else (b, c)
        rigid = near + far * complex(math.cos(value), math.sin(value))
        rho, beta = abs(rigid), math.atan2(rigid.imag, rigid.real)
        if joint == 1:
            inside, branches = _two_link(points, rho, c)
            angles = [(absolute - beta, value, relative - value + beta)
                      for absolute, relative in branches]
        else:
            inside, branches = _two_link(points, a, rho)
            angles = [(absolute, relative - beta, value) for absolute, relative in branches]
    found = np.zeros(points.shape[:-1], dtype=bool)
    for branch in angles:
        ok = inside.copy()
        for angle, (low, high) in zip(branch, ranges, strict=True):
            ok &= _within(angle, low, high)
        found |= ok
    return found


def restricted_workspace(points: np.ndarray, ranges: Ranges) -> np.ndarray:
    """(a): mask of the points some configuration within `ranges` reaches."""
    joint = int(np.argmin([high - low for low, high in ranges]))
    found = np.zeros(points.shape[:-1], dtype=bool)
    for value in joint_values(*ranges[joint]):
        found |= reachable(points, joint, value, ranges)
    return found


def failure_region(points: np.ndarray, joint: int, ranges: Ranges) -> np.ndarray:
    """(b): mask of the points reached after `joint` locks anywhere in its range.

    The other joints then move over a full turn (the software limits are removed).
    """
    free = (FULL_TURN,) * len(LINKS)
    found = np.ones(points.shape[:-1], dtype=bool)
    for value in joint_values(*ranges[joint]):
        found &= reachable(points, joint, value, free)
    return found


@dataclass(frozen=True)
class Workspaces:
    """The regions of fig. 3 on a square grid (masks indexed [y, x]).

    Attributes:
        limits: the software limits, (low, high) per joint, rad.
        axis: the grid's coordinates, the same for x and y (link lengths).
        restricted: (a), the workspace within the limits.
        failures: (b), one mask per locked joint (3, count, count).
        tolerant: (c), the failure-tolerant workspace.
    """

    limits: Ranges
    axis: np.ndarray
    restricted: np.ndarray
    failures: np.ndarray
    tolerant: np.ndarray

    def area(self, mask: np.ndarray) -> float:
        """Area of a mask: grid points times the cell (link lengths^2)."""
        return float(mask.sum()) * float(self.axis[1] - self.axis[0]) ** 2

    @property
    def reduction(self) -> float:
        """1 - area(c) / area(a), the share of (a) failure tolerance costs (NaN if (a) is empty)."""
        restricted = self.area(self.restricted)
        return 1.0 - self.area(self.tolerant) / restricted if restricted else math.nan


def compute(limits: Ranges = FIG3_LIMITS, count: int = GRID_COUNT) -> Workspaces:
    """(a), (b) and (c) for `limits` on a count x count grid over the reach."""
    reach = sum(LINKS)
    axis = np.linspace(-reach, reach, count)
    x, y = np.meshgrid(axis, axis)
    points = np.stack([x, y], axis=-1)
    restricted = restricted_workspace(points, limits)
    failures = np.array([failure_region(points, joint, limits) for joint in range(len(LINKS))])
    return Workspaces(limits, axis, restricted, failures, restricted & failures.all(axis=0))


def plot(workspaces: Workspaces, path: Path) -> None:
    """Fig. 3's panels: full and restricted workspace, the three (b), and (c)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    axis = workspaces.axis
    x, y = np.meshgrid(axis, axis)
    full = np.hypot(x, y) <= sum(LINKS)  # every joint turning: the disc of the whole reach
    degrees = ", ".join(f"[{math.degrees(low):g}, {math.degrees(high):g}]"
                        for low, high in workspaces.limits)
    panels = [
        ((0, 0), full, "workspace, no limits"),
        ((0, 2), workspaces.restricted, "(a) within the limits"),
        *[((1, i), workspaces.failures[i], f"(b) joint {i + 1} locked in its range")
          for i in range(3)],
        ((2, 1), workspaces.tolerant, "(c) failure tolerant: (a) and every (b)"),
    ]
    figure, grid = plt.subplots(3, 3, figsize=(9, 9.4))
    for row in grid:
        for panel in row:
            panel.axis("off")
    circle = np.linspace(0, 2 * math.pi, 200)
    for (row, column), mask, title in panels:
        panel = grid[row][column]
        panel.axis("on")
        panel.imshow(mask, origin="lower", extent=(axis[0], axis[-1], axis[0], axis[-1]),
                     cmap=ListedColormap(["white", "tab:blue"]), vmin=0, vmax=1,
                     interpolation="nearest")
        panel.plot(np.cos(circle), np.sin(circle), ":", color="k", linewidth=0.8)
        panel.set_title(f"{title}\narea {workspaces.area(mask):.2f}", fontsize=9)
        panel.set_aspect("equal")
        panel.tick_params(labelsize=7)
    figure.suptitle("planar 3R, unit links (Lewis & Maciejewski 1997 fig. 3); limits (deg) "
                    f"{degrees}\nrestricted {workspaces.area(workspaces.restricted):.2f}, "
                    f"failure tolerant {workspaces.area(workspaces.tolerant):.2f}: "
                    f"{100 * workspaces.reduction:.0f}% reduction (paper: about "
                    f"{100 * PAPER_REDUCTION:.0f}%); dotted: the unit circle", fontsize=9)
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)


def parse_limits(text: str) -> Ranges:
    """'L1:U1,L2:U2,L3:U3' in degrees -> ((low, high), ...) in rad.

    Raises:
        ValueError: not three ranges, a number that is not finite, low > high, or a
            range wider than a turn or outside [-360, 360] deg.
    """
    parts = text.split(",")
    try:
        pairs = [tuple(float(v) for v in part.split(":")) for part in parts]
    except ValueError:
        pairs = []
    if (len(pairs) != len(LINKS) or any(len(p) != 2 for p in pairs)
            or not all(-360 <= p[0] <= p[1] <= 360 and p[1] - p[0] <= 360 for p in pairs)):
        raise ValueError("--limits needs three ranges low:high in degrees, each low <= high, "
                         f"within [-360, 360] and at most a turn wide, got {text[:80]!r}")
    return tuple((math.radians(low), math.radians(high)) for low, high in pairs)


def parser() -> argparse.ArgumentParser:
    """The subcommand's arguments."""
    parser = argparse.ArgumentParser(
        prog=f"ft-map {COMMAND}", description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Draws fig. 3's panels and prints the areas; see the module docstring.")
    parser.add_argument("--limits", metavar="L1:U1,L2:U2,L3:U3",
                        help="software joint limits in degrees, a leading minus in the = "
                        "form, --limits=-15:15,... (default: the reading of fig. 3, "
                        + ",".join(f"{math.degrees(low):g}:{math.degrees(high):g}"
                                   for low, high in FIG3_LIMITS) + ")")
    parser.add_argument("--count", type=cli.bounded(int, *GRID_RANGE), default=GRID_COUNT,
                        help="grid points per axis (default %(default)s)")
    parser.add_argument("--output", "-o", type=Path, default=Path("fault_tolerant_workspace.png"),
                        help="the figure (PNG), default %(default)s")
    return parser


@cli.clear_file_errors(f"ft-map {COMMAND}")
def main(argv: list[str] | None = None) -> int:
    """Run the subcommand; return the exit status (0 ok, 1 bad input, 2 usage)."""
    args = parser().parse_args(argv)
    try:
        limits = FIG3_LIMITS if args.limits is None else parse_limits(args.limits)
    except ValueError as error:
        print(f"ft-map {COMMAND}: {error}", file=sys.stderr)
        return 1
    cli.check_folder(args.output.parent)
    workspaces = compute(limits, args.count)
    print(f"restricted workspace (a): {workspaces.area(workspaces.restricted):.3f}")
    for joint, mask in enumerate(workspaces.failures):
        print(f"joint {joint + 1} locked in its range (b): {workspaces.area(mask):.3f}")
    print(f"failure-tolerant workspace (c): {workspaces.area(workspaces.tolerant):.3f}, "
          f"a {100 * workspaces.reduction:.1f}% reduction of (a)")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    plot(workspaces, args.output)
    print(f"wrote {args.output}")
    return 0
