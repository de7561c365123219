"""DH parameters from a Jacobian and the 7! designs of one optimal Jacobian (Xie 2019 ch. 2).

A revolute joint contributes the Jacobian column j_i = [z x p; z] (Xie 2019 eq 2.8,
eq 3.20): z the unit axis, p the vector from a point of the axis to the tool point.
With the tool point at the origin the axis is the line through r = z x v (|z| = 1,
v perpendicular to z), so a Jacobian fixes every joint axis, and the Denavit-Hartenberg
parameters follow from their definitions (sec. 2.2.2):

- alpha_i, a_i: twist and length of the common normal x_i from z_{i-1} to z_i
  (x_i points away from z_{i-1}). They depend on the unordered pair of columns
  (sec. 2.3.1), so the 7! column orders of a 7-column Jacobian share C(7, 2) = 21
  {alpha, a} pairs.
- d_i, theta_i: offset and angle from x_{i-1} to x_i along / about z_{i-1}; they
  depend on the ordered triple of columns i-1, i, i+1: P(7, 3) = 210 values, and
  reversing the triple negates both.

Readings taken where the chapter leaves a choice (docstrings say which):

- Rows: linear velocity first (3 rows, in units of the tool-point sphere radius),
  angular second, as in eqs 2.7 and 3.24.
- Joint i of a DH table (1-based, like the chapter) has axis z_{i-1} = column i.
  alpha = atan2((z_{i-1} x z_i) . x_i, z_{i-1} . z_i) in (-pi, pi]; with this sign
  the chapter's pairs {-1.32, 0.00}, {-1.72, 0.17} and {1.60, 0.50} come out with
  their printed signs.
- Intersecting axes (a = 0 exactly): x_i = z_{i-1} x z_i / |.|, so alpha is in
  [0, pi]. Parallel axes: x_i passes through the previous frame origin (or, with
  no previous frame, through the point of z_{i-1} closest to the tool point).
- The base frame is arbitrary: x_0 = x_1 and its origin on the foot of x_1, so
  d_1 = theta_1 = 0. The tool frame takes alpha_n = 0 and x_n from the last axis
  towards the tool point, so a_n is the distance of the last axis from the tool
  point (1 at an optimal 7R design; [35] in Xie 2019 sets alpha_7 = 0, a_7 = 1).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ft_core.measures import as_matrix

# Xie 2019 eq 2.7: the realisable 7R Jacobian closest to optimally fault tolerant
# (entries rounded to 0.01 in the text; rows vx, vy, vz, wx, wy, wz).
J_STAR = np.array([
    [1, 0.43, 0.75, -0.54, 0.14, 0.33, -0.38],
    [0, -0.60, 0.65, 0.46, -0.79, -0.19, -0.80],
    [0, -0.67, -0.14, -0.70, 0.60, -0.93, -0.46],
    [0, 0.77, 0.14, 0.84, 0.58, -0.69, -0.43],
    [1, -0.15, -0.36, 0.33, -0.42, -0.72, 0.59],
    [0, 0.62, -0.92, -0.43, -0.69, -0.10, -0.68],
])

# Sec. 2.4.4: the three nearly orthogonal, nearly intersecting {alpha (rad), a} pairs.
GOOD_PAIRS = ((-1.32, 0.00), (-1.72, 0.17), (1.60, 0.50))

_PARALLEL = 1e-9  # |z1 x z2| below which two axes are taken as parallel
_INTERSECT = 1e-12  # common-normal length below which two axes are taken as intersecting


@dataclass(frozen=True)
class Axis:
    """A joint axis: the line through `point` along the unit vector `direction`."""

    point: np.ndarray
    direction: np.ndarray


@dataclass(frozen=True)
class CommonNormal:
    """Common normal from axis 1 to axis 2: twist alpha (rad), length a, unit x, feet."""

    alpha: float
    a: float
    x: np.ndarray
    foot1: np.ndarray
    foot2: np.ndarray


@dataclass(frozen=True)
class DHTable:
    """Standard DH parameters of joints 1..n (row i-1 is joint i): radians and lengths.

    Lengths are in the units of the Jacobian's linear rows (the tool-point sphere
    radius for eqs 2.7 and 3.24).
    """

    alpha: np.ndarray
    a: np.ndarray
    d: np.ndarray
    theta: np.ndarray

    def as_rows(self) -> list[dict[str, float]]:
        """One {alpha, a, d, theta} dict per joint (for JSON)."""
        return [{"alpha": float(al), "a": float(a), "d": float(d), "theta": float(t)}
                for al, a, d, t in zip(self.alpha, self.a, self.d, self.theta, strict=True)]


def joint_axes(J: np.ndarray, tolerance: float = 0.05) -> list[Axis]:
    """Joint axes of a 6 x n revolute Jacobian with the tool point at the origin (eq 2.8).

    Column i is [v; w] with w the axis direction and v = z x p (z = w / |w|, eq 2.8
    has a unit axis), p from the axis to the tool point, so the axis passes through
    r = z x v. Reading taken for rounded Jacobians: z is normalised but v is used as
    printed (|v| is the axis's distance from the tool point). The nearly intersecting
    pair (3, 6) of eq 2.7 (a = 0.003) keeps the chapter's sign, alpha = -1.31, only
    with this reading; dividing by |w|^2 instead flips it to +1.31.

    Args:
        J: 6 x n Jacobian, linear rows first.
        tolerance: accepted | |w| - 1 | and |v . w| / |w| (rounded published
            Jacobians are off by up to ~0.01); the direction is normalised and the
            part of v along w, which no revolute joint produces, is ignored.

    Raises:
        ValueError: J is not 6 x n or a column is not a revolute joint's.
    """
    J = as_matrix(J)
    if J.shape[0] != 6:
        raise ValueError(f"a revolute Jacobian has 6 rows (linear, angular), got {J.shape[0]}")
    axes = []
    for i in range(J.shape[1]):
        v, w = J[:3, i], J[3:, i]
        norm = float(np.linalg.norm(w))
        if abs(norm - 1.0) > tolerance or abs(v @ w) / max(norm, 1e-300) > tolerance:
            raise ValueError(f"column {i + 1} is not a revolute joint's: |w| = {norm:.3f},"
                             f" v.w = {v @ w:.3f} (eq 3.20 needs |w| = 1, v perpendicular to w)")
        axes.append(Axis(np.cross(w / norm, v), w / norm))
    return axes


def common_normal(axis1: Axis, axis2: Axis, reference: np.ndarray | None = None) -> CommonNormal:
    """Common normal from axis1 to axis2 and the DH alpha, a of the pair (sec. 2.3.1).

    Args:
        axis1: z_{i-1}.
        axis2: z_i.
        reference: for parallel axes, the point of axis1 the normal starts from
            (default: the point of axis1 closest to the origin, the tool point).
    """
    z1, z2 = axis1.direction, axis2.direction
    cross = np.cross(z1, z2)
    sine = float(np.linalg.norm(cross))
    delta = axis2.point - axis1.point
    if sine < _PARALLEL:
        start = axis1.point if reference is None else reference
        foot1 = axis1.point + z1 * ((start - axis1.point) @ z1)
        normal = axis2.point - foot1
        normal -= z1 * (normal @ z1)
        foot2 = foot1 + normal
    else:
        # Closest points foot1 = p1 + t1 z1, foot2 = p2 + t2 z2 of the two lines.
        c = float(z1 @ z2)
        t1 = (delta @ z1 - c * (delta @ z2)) / sine**2
        t2 = (c * (delta @ z1) - delta @ z2) / sine**2
        foot1, foot2 = axis1.point + t1 * z1, axis2.point + t2 * z2
        normal = foot2 - foot1
    a = float(np.linalg.norm(normal))
    if a > _INTERSECT:
        x = normal / a
    elif sine >= _PARALLEL:
        x = cross / sine
    else:  # coincident axes: any direction perpendicular to z1
        x = np.cross(z1, [1.0, 0.0, 0.0] if abs(z1[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
    alpha = math.atan2(float(cross @ x), float(z1 @ z2))
    return CommonNormal(alpha, a, x, foot1, foot2)


def _angle_about(x1: np.ndarray, x2: np.ndarray, z: np.ndarray) -> float:
    """Angle (rad, in (-pi, pi]) from x1 to x2 about z."""
    return math.atan2(float(np.cross(x1, x2) @ z), float(x1 @ x2))


def dh_from_axes(axes: Sequence[Axis]) -> DHTable:
    """Standard DH table of the chain of `axes` with the tool point at the origin.

    Conventions of the module docstring: d_1 = theta_1 = 0 (base frame on x_1),
    alpha_n = 0 and x_n towards the tool point.
    """
    n = len(axes)
    alpha, a, d, theta = (np.zeros(n) for _ in range(4))
    normals: list[CommonNormal] = []
    origin = None
    for i in range(n - 1):
        normal = common_normal(axes[i], axes[i + 1], origin)
        normals.append(normal)
        alpha[i], a[i], origin = normal.alpha, normal.a, normal.foot2
    # Tool frame: z_n parallel to z_{n-1}, x_n from the last axis to the tool point.
    last = axes[-1]
    foot = last.point - last.direction * (last.point @ last.direction)
    a[-1] = float(np.linalg.norm(foot))
    x_tool = -foot / a[-1] if a[-1] > _INTERSECT else (normals[-1].x if normals else
                                                        common_normal(last, last).x)
    normals.append(CommonNormal(0.0, a[-1], x_tool, foot, np.zeros(3)))
    for i in range(1, n):  # joint i+1 (1-based) turns about axes[i] from x_i to x_{i+1}
        z = axes[i].direction
        previous, current = normals[i - 1], normals[i]
        d[i] = float((current.foot1 - previous.foot2) @ z)
        theta[i] = _angle_about(previous.x, current.x, z)
    return DHTable(alpha, a, d, theta)


def dh_from_jacobian(J: np.ndarray, tolerance: float = 0.05) -> DHTable:
    """DH parameters of the revolute robot whose Jacobian at the design pose is J (eq 2.8).

    Args:
        J: 6 x n Jacobian (linear rows first) at the design configuration, the tool
            point at the origin of the frame J is written in.
        tolerance: see `joint_axes`.

    Returns:
        The n-joint DHTable (radians; lengths in the units of J's linear rows).
    """
    return dh_from_axes(joint_axes(J, tolerance))


def forward_points(table: DHTable) -> np.ndarray:
    """Frame origins (n + 1, 3) of a DH chain at its table's angles, in the base frame.

    The last is the tool point. Used to check `dh_from_jacobian` (the tool point must
    sit at distance a_n from the last axis, and the chain must reproduce J).
    """
    T = np.eye(4)
    points = [T[:3, 3].copy()]
    for al, a, d, th in zip(table.alpha, table.a, table.d, table.theta, strict=True):
        ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0, sa, ca, d], [0, 0, 0, 1]])
        points.append(T[:3, 3].copy())
    return np.array(points)


def dh_jacobian(table: DHTable) -> np.ndarray:
    """6 x n Jacobian (linear rows first) of a DH chain at its design pose, in the base frame.

    Joint i turns about z_{i-1} of the chain; the tool point is the last frame's origin.
    """
    T = np.eye(4)
    axes, origins = [], []
    for al, a, d, th in zip(table.alpha, table.a, table.d, table.theta, strict=True):
        axes.append(T[:3, 2].copy())
        origins.append(T[:3, 3].copy())
        ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0, sa, ca, d], [0, 0, 0, 1]])
    tool = T[:3, 3]
    z = np.array(axes)
    return np.vstack([np.cross(z, tool - np.array(origins)).T, z.T])


def planar_links_from_jacobian(J: np.ndarray) -> np.ndarray:
    """Link lengths of the planar nR arm whose 2 x n position Jacobian is J (sec. 3.3.4).

    Column i is the tool point's velocity for joint i, the vector from joint i to the
    tool point turned by +90 degrees, so l_i = |j_{i+1} - j_i| and l_n = |j_n|.
    """
    J = as_matrix(J)
    if J.shape[0] != 2:
        raise ValueError(f"a planar position Jacobian has 2 rows, got {J.shape[0]}")
    columns = np.hstack([J, np.zeros((2, 1))])
    return np.linalg.norm(np.diff(columns, axis=1), axis=0)


@dataclass(frozen=True)
class PermutationFamily:
    """The n! column orders of one Jacobian, organised as in Xie 2019 sec. 2.3.

    Attributes:
        pairs: the C(n, 2) unordered column pairs (i, k), i < k (0-based).
        pair_alpha, pair_a: {alpha, a} of each pair.
        triples: the P(n, 3) ordered column triples.
        triple_d, triple_theta: {d, theta} of each triple (joint of the middle column).
        permutations: (n!, n) column orders, lexicographic.
        pair_index: (n!, n - 1) index into `pairs` of each design's alpha_1..alpha_{n-1}.
        triple_index: (n!, n - 2) index into `triples` of d_2..d_{n-1}.
        reverse: (n!,) index of each design's reverse version (sec. 2.3.3).
    """

    pairs: list[tuple[int, int]]
    pair_alpha: np.ndarray
    pair_a: np.ndarray
    triples: list[tuple[int, int, int]]
    triple_d: np.ndarray
    triple_theta: np.ndarray
    permutations: np.ndarray
    pair_index: np.ndarray
    triple_index: np.ndarray
    reverse: np.ndarray

    def tree_choices(self) -> list[int]:
        """Number of {alpha_k, a_k} choices at each level of the tree of Figure 2.3.

        Level k counts the distinct pairs that follow each distinct sequence of the
        first k - 1 pairs; the chapter's tree has the same count below every node
        (21, 10, 4, 3, 2, 1 for 7 columns). Raises ValueError if it does not.
        """
        counts = []
        for level in range(self.pair_index.shape[1]):
            children: dict[tuple[int, ...], set[int]] = {}
            for row in self.pair_index:
                children.setdefault(tuple(row[:level]), set()).add(int(row[level]))
            sizes = {len(c) for c in children.values()}
            if len(sizes) != 1:
                raise ValueError(f"level {level + 1} of the tree is uneven: {sorted(sizes)}")
            counts.append(sizes.pop())
        return counts

    def match_pairs(self, targets: Iterable[tuple[float, float]],
                    tolerance: float = 0.02) -> list[int]:
        """Index of the table pair nearest each target {alpha (rad), a}.

        Raises:
            ValueError: no pair lies within `tolerance` (max-norm) of a target.
        """
        found = []
        for alpha, a in targets:
            distance = np.maximum(np.abs(self.pair_alpha - alpha), np.abs(self.pair_a - a))
            best = int(np.argmin(distance))
            if distance[best] > tolerance:
                raise ValueError(f"no {{alpha, a}} pair within {tolerance} of ({alpha}, {a})")
            found.append(best)
        return found

    def group_sizes(self, pair_indices: Sequence[int]) -> list[int]:
        """Number of designs containing exactly 0, 1, ... of the given pairs (Figure 2.8)."""
        contains = np.isin(self.pair_index, list(pair_indices)).sum(axis=1)
        return np.bincount(contains, minlength=len(pair_indices) + 1).tolist()


def organise_permutations(J: np.ndarray, tolerance: float = 0.05) -> PermutationFamily:
    """Tabulate the {alpha, a} pairs and {d, theta} triples of every column order of J.

    Xie 2019 sec. 2.3: the pair table is computed once per unordered column pair and
    the triple table once per ordered triple; every design is a row of indices into
    them. `verify_family` recomputes designs from their own axes to check the tables.

    Args:
        J: 6 x n revolute Jacobian (n <= 8: n! rows are held in memory).
        tolerance: see `joint_axes`.
    """
    axes = joint_axes(J, tolerance)
    n = len(axes)
    if not 3 <= n <= 8:
        raise ValueError(f"the permutation family is built for 3 to 8 columns, got {n}")
    pairs = list(itertools.combinations(range(n), 2))
    normals = [common_normal(axes[i], axes[k]) for i, k in pairs]
    triples = list(itertools.permutations(range(n), 3))
    triple_d, triple_theta = np.zeros(len(triples)), np.zeros(len(triples))
    for row, (i, j, k) in enumerate(triples):
        first, second = common_normal(axes[i], axes[j]), common_normal(axes[j], axes[k])
        z = axes[j].direction
        triple_d[row] = float((second.foot1 - first.foot2) @ z)
        triple_theta[row] = _angle_about(first.x, second.x, z)
    permutations = np.array(list(itertools.permutations(range(n))))
    pair_lookup = {pair: index for index, pair in enumerate(pairs)}
    triple_lookup = {triple: index for index, triple in enumerate(triples)}
    pair_index = np.array([[pair_lookup[tuple(sorted(row[t:t + 2]))] for t in range(n - 1)]
                           for row in permutations.tolist()])
    triple_index = np.array([[triple_lookup[tuple(row[t:t + 3])] for t in range(n - 2)]
                             for row in permutations.tolist()])
    order = {tuple(row): index for index, row in enumerate(permutations.tolist())}
    reverse = np.array([order[tuple(row[::-1])] for row in permutations.tolist()])
    return PermutationFamily(pairs, np.array([c.alpha for c in normals]),
                             np.array([c.a for c in normals]), triples, triple_d,
                             triple_theta, permutations, pair_index, triple_index, reverse)


def verify_family(J: np.ndarray, family: PermutationFamily, designs: Iterable[int],
                  atol: float = 1e-9) -> int:
    """Recompute the DH tables of `designs` from scratch and check them against the family.

    For each design index: the table from `dh_from_jacobian(J[:, order])` must have
    alpha_k, a_k from its pair table entries, d_k, theta_k (k = 2..n-1) from its
    triple entries, and its reverse version must have the same alphas and a's in
    reverse order and d's and thetas negated in reverse order (sec. 2.3.3). Angles
    are compared modulo 2 pi.

    Returns:
        The number of designs checked.

    Raises:
        AssertionError: a design disagrees (the message names it).
    """
    checked = 0
    for index in designs:
        order = family.permutations[index]
        table = dh_from_jacobian(J[:, order])
        mirror = dh_from_jacobian(J[:, order[::-1]])
        pairs, triples = family.pair_index[index], family.triple_index[index]
        checks = {
            "alpha": (table.alpha[:-1], family.pair_alpha[pairs]),
            "a": (table.a[:-1], family.pair_a[pairs]),
            "d": (table.d[1:-1], family.triple_d[triples]),
            "theta": (table.theta[1:-1], family.triple_theta[triples]),
            "reverse alpha": (table.alpha[:-1], mirror.alpha[:-1][::-1]),
            "reverse a": (table.a[:-1], mirror.a[:-1][::-1]),
            "reverse d": (table.d[1:-1], -mirror.d[1:-1][::-1]),
            "reverse theta": (table.theta[1:-1], -mirror.theta[1:-1][::-1]),
        }
        for name, (got, expected) in checks.items():
            error = np.abs(got - expected)
            if "alpha" in name or "theta" in name:
                error = np.abs(np.angle(np.exp(1j * (got - expected))))
            if np.any(error > atol):
                raise AssertionError(f"design {index} {order.tolist()}: {name} {got} != {expected}")
        checked += 1
    return checked
