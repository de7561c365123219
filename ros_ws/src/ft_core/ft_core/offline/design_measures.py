"""Batched kinematics and local dexterity of the 7! designs of eq 2.7 (Xie 2019 sec. 2.4).

`Designs` holds the DH parameters of many designs (`ft_core.offline.dh`); `chain` and
`jacobians` evaluate one configuration per design row at once (eq 2.8), and
`local_measures` gives 1/kappa, w and sigma_m and their worst cases after one locked
joint (eqs 2.3, 2.9-2.12). `reach` is the distance R the linear rows are divided by
(sec. 2.4.2), `sampled_measures` the measures over joint samples (eqs 2.13-2.14), and
`self_motion_maxima` their maxima along traced self-motion manifolds (sec. 2.4.3).
The readings behind these choices are in `ft_core.offline.global_dexterity`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ft_core.offline import dh

N_JOINTS = 7
#: Columns of `local_measures`, in the order of Table 2.1.
MEASURES = ("1/kappa", "w", "sigma_m", "1/kappa*", "w*", "sigma_m*")
#: Tracing step (rad of joint motion) and most steps along one self-motion manifold.
STEP = 0.1
MAX_STEPS = 1500
#: Joint samples and ascent of the reach R (`ft_core.offline.global_dexterity`).
REACH_SAMPLES = 1000
REACH_STARTS = 8
REACH_STEPS = np.geomspace(0.3, 1e-3, 40)  # rad, normalised-gradient steps
#: Configurations per batched decomposition (bounds memory: 4096 x 7 x 6 x 6 floats).
BLOCK = 4096

_OTHERS = np.array([[k for k in range(N_JOINTS) if k != f] for f in range(N_JOINTS)])
_COFACTOR_SIGN = (-1.0) ** np.arange(N_JOINTS)


@dataclass(frozen=True)
class Designs:
    """DH parameters alpha (rad), a, d (units of eq 2.7's linear rows) of D designs, (D, 7).

    theta is left out: it is the design configuration's joint angle, and every joint
    is sampled over its full circle.
    """

    alpha: np.ndarray
    a: np.ndarray
    d: np.ndarray

    @classmethod
    def of(cls, orders: np.ndarray, J: np.ndarray = dh.J_STAR) -> Designs:
        """The designs whose Jacobians at the design pose are J[:, order] (sec. 2.3)."""
        tables = [dh.dh_from_jacobian(J[:, list(order)]) for order in np.atleast_2d(orders)]
        return cls(*(np.array([getattr(t, name) for t in tables]) for name in ("alpha", "a", "d")))

    def __len__(self) -> int:
        return len(self.alpha)

    def rows(self, repeats: int) -> Designs:
        """Each design repeated `repeats` times in a row (one row per configuration)."""
        return Designs(*(np.repeat(x, repeats, axis=0) for x in (self.alpha, self.a, self.d)))

    def take(self, rows: np.ndarray | slice) -> Designs:
        """The designs of `rows`."""
        return Designs(self.alpha[rows], self.a[rows], self.d[rows])


def column_orders() -> np.ndarray:
    """The 7! column orders (0-based), lexicographic: row k is design k (as `dh`)."""
    return np.array(list(itertools.permutations(range(N_JOINTS))))


def design_index(columns: Sequence[int]) -> int:
    """Index of the design with these 1-based columns of eq 2.7 (as the thesis writes them)."""
    order = tuple(c - 1 for c in columns)
    for index, candidate in enumerate(itertools.permutations(range(N_JOINTS))):
        if candidate == order:
            return index
    raise ValueError(f"{list(columns)} is not an order of the columns 1..{N_JOINTS}")


def joint_samples(count: int, seed: int, stream: int = 0) -> np.ndarray:
    """(count, 7) joint angles (rad), each uniform on [-pi, pi); `stream` separates uses."""
    return np.random.default_rng((seed, stream)).uniform(-np.pi, np.pi, (count, N_JOINTS))


def chain(designs: Designs, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Forward kinematics of one configuration per design row (standard DH, theta = q).

    Args:
        designs: N rows (or one row for every configuration).
        q: (N, 7) joint angles (rad).

    Returns:
        (axes, origins, tool): axes z_0..z_6 (N, 7, 3) and origins o_0..o_6 (N, 7, 3)
        of the joint frames, and the tool frame (N, 4, 4), all in the base frame.
    """
    count = q.shape[0]
    T = np.broadcast_to(np.eye(4), (count, 4, 4)).copy()
    axes, origins = np.empty((count, N_JOINTS, 3)), np.empty((count, N_JOINTS, 3))
    A = np.zeros((count, 4, 4))
    A[:, 3, 3] = 1.0
    for i in range(N_JOINTS):
        axes[:, i], origins[:, i] = T[:, :3, 2], T[:, :3, 3]
        ct, st = np.cos(q[:, i]), np.sin(q[:, i])
        ca, sa = np.cos(designs.alpha[:, i]), np.sin(designs.alpha[:, i])
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = ct, -st * ca, st * sa, designs.a[:, i] * ct
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st, ct * ca, -ct * sa, designs.a[:, i] * st
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca, designs.d[:, i]
        T = T @ A
    return axes, origins, T


def jacobians(designs: Designs, q: np.ndarray, length: np.ndarray | float = 1.0,
              ) -> tuple[np.ndarray, np.ndarray]:
    """(N, 6, 7) Jacobians [z x (p - o) / length; z] (eq 2.8) and the tool frames (N, 4, 4).

    `length` (one per row, or a number) divides the linear rows (sec. 2.4.2); 1 keeps
    the units of eq 2.7, where an optimal design is isotropic at its design pose.
    """
    axes, origins, tool = chain(designs, q)
    linear = np.cross(axes, tool[:, None, :3, 3] - origins)
    linear /= np.reshape(length, (-1, 1, 1))
    return np.concatenate([linear, axes], axis=2).transpose(0, 2, 1), tool


def local_measures(J: np.ndarray) -> np.ndarray:
    """(N, 6) local measures of N Jacobians (N, 6, 7), columns as `MEASURES`.

    1/kappa, w, sigma_m of J (eqs 2.9-2.10) and their worst cases after one locked
    joint, min over f of the measures of ^fJ (eqs 2.3, 2.11-2.12), from the eigenvalues
    of J J^T and of ^fJ ^fJ^T = J J^T - j_f j_f^T (rounding below 0 is clipped).
    """
    gram = J @ J.transpose(0, 2, 1)
    values = np.sqrt(np.clip(np.linalg.eigvalsh(gram), 0.0, None))[:, ::-1]
    reduced = gram[:, None] - np.einsum("nif,njf->nfij", J, J)
    post = np.sqrt(np.clip(np.linalg.eigvalsh(reduced), 0.0, None))[..., ::-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = np.nan_to_num(values[:, -1] / values[:, 0])
        post_inverse = np.nan_to_num(post[..., -1] / post[..., 0])
    return np.stack([inverse, values.prod(axis=1), values[:, -1], post_inverse.min(axis=1),
                     post.prod(axis=2).min(axis=1), post[..., -1].min(axis=1)], axis=1)


def reach(designs: Designs, seed: int) -> np.ndarray:
    """R (D,): the largest distance of the tool point from the base origin (sec. 2.4.2).

    In the units of eq 2.7's linear rows (the radius of the sphere every joint axis
    touches at the design pose).

    The `REACH_STARTS` farthest of `REACH_SAMPLES` joint samples climb |p|^2 along its
    gradient 2 J_v^T p with normalised steps `REACH_STEPS`; R is the best end point.
    """
    q = joint_samples(REACH_SAMPLES, seed, stream=2)
    rows = designs.rows(REACH_SAMPLES)
    distance = np.linalg.norm(chain(rows, np.tile(q, (len(designs), 1)))[2][:, :3, 3], axis=1)
    far = np.argsort(distance.reshape(len(designs), REACH_SAMPLES), axis=1)[:, -REACH_STARTS:]
    starts = q[far.ravel()]
    climbers = designs.rows(REACH_STARTS)
    for step in REACH_STEPS:
        axes, origins, tool = chain(climbers, starts)
        p = tool[:, :3, 3]
        gradient = np.einsum("nik,nk->ni", np.cross(axes, p[:, None] - origins), p)
        starts = starts + step * gradient / np.maximum(
            np.linalg.norm(gradient, axis=1, keepdims=True), 1e-300)
    end = np.linalg.norm(chain(climbers, starts)[2][:, :3, 3], axis=1)
    return np.maximum(end.reshape(len(designs), REACH_STARTS).max(axis=1),
                      distance.reshape(len(designs), REACH_SAMPLES).max(axis=1))


def sampled_measures(designs: Designs, q: np.ndarray, reaches: np.ndarray) -> np.ndarray:
    """(D, S, 6) local `MEASURES` of every design at every sample q (S, 7, rad).

    Design d's linear rows are divided by reaches[d] (`reach`); computed in `BLOCK`s.
    """
    count = len(designs) * len(q)
    out = np.empty((count, len(MEASURES)))
    rows = designs.rows(len(q))
    lengths = np.repeat(reaches, len(q))
    for start in range(0, count, BLOCK):
        block = slice(start, min(start + BLOCK, count))
        samples = q[np.arange(block.start, block.stop) % len(q)]
        out[block] = local_measures(jacobians(rows.take(block), samples, lengths[block])[0])
    return out.reshape(len(designs), len(q), len(MEASURES))


def _null_directions(J: np.ndarray) -> np.ndarray:
    """Unit null vectors (N, 7) of N 6 x 7 Jacobians: n_f = (-1)^f det(^fJ), normalised.

    The cofactor vector: J n expands the determinant of J with one of its rows
    repeated, so J n = 0; |n|^2 = det(J J^T) (Cauchy-Binet). Zero at a singular J.
    """
    cofactors = np.linalg.det(J[:, :, _OTHERS].transpose(0, 2, 1, 3)) * _COFACTOR_SIGN
    norm = np.linalg.norm(cofactors, axis=1, keepdims=True)
    return np.divide(cofactors, norm, out=np.zeros_like(cofactors), where=norm > 0)


def _pose_error(target: np.ndarray, tool: np.ndarray) -> np.ndarray:
    """(N, 6) [position error; rotation error] of tool frames from targets (small angles).

    The rotation part is the axis times sin(angle) of target R^T, which is what the
    angular rows of the Jacobian map to for a small correction.
    """
    E = target[:, :3, :3] @ tool[:, :3, :3].transpose(0, 2, 1)
    rotation = 0.5 * np.stack([E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0],
                               E[:, 1, 0] - E[:, 0, 1]], axis=1)
    return np.concatenate([target[:, :3, 3] - tool[:, :3, 3], rotation], axis=1)


@dataclass(frozen=True)
class SelfMotion:
    """Result of `self_motion_maxima` for M poses.

    Attributes:
        maxima: (M, 2) largest sigma_m and sigma_m^* along each traced manifold.
        closed: (M,) the curve returned to its start within `MAX_STEPS`.
        steps: (M,) steps taken.
        pose_error: largest |position error| (eq 2.7 units) or |rotation error| (rad)
            at any corrected point.
    """

    maxima: np.ndarray
    closed: np.ndarray
    steps: np.ndarray
    pose_error: float


def self_motion_maxima(designs: Designs, q0: np.ndarray, lengths: np.ndarray) -> SelfMotion:
    """Largest sigma_m and sigma_m^* on the self-motion manifold through each q0 (sec. 2.4.3).

    Row k traces design row k from q0[k] (M, 7) at the pose q0[k] gives: a step of `STEP`
    rad along the null vector (its sign kept continuous), two Newton corrections
    q += J^T (J J^T)^-1 e back to the pose, then the measures with the linear rows
    divided by lengths[k]. A row stops when it is back within `STEP` of q0 (after three
    steps) or after `MAX_STEPS`; finished rows leave the batch.
    """
    count = len(q0)
    lengths = np.broadcast_to(np.asarray(lengths, dtype=float), (count,))
    J, target = jacobians(designs, q0, lengths)
    maxima = local_measures(J)[:, [2, 5]]
    closed, steps = np.zeros(count, dtype=bool), np.zeros(count, dtype=int)
    active = np.arange(count)
    q, previous, pose_error = q0.copy(), _null_directions(J), 0.0
    for step in range(MAX_STEPS):
        rows, goal = designs.take(active), target[active]
        direction = _null_directions(J)
        flip = np.sum(direction * previous, axis=1) < 0
        direction[flip] *= -1.0
        direction = np.where(np.any(direction != 0, axis=1, keepdims=True), direction, previous)
        q = q + STEP * direction
        for _ in range(2):
            J_raw, tool = jacobians(rows, q)
            error = _pose_error(goal, tool)
            q = q + np.einsum("nji,nj->ni", J_raw, np.linalg.solve(
                J_raw @ J_raw.transpose(0, 2, 1), error[..., None])[..., 0])
        J, tool = jacobians(rows, q, lengths[active])
        pose_error = max(pose_error, float(np.abs(_pose_error(goal, tool)).max(initial=0.0)))
        maxima[active] = np.maximum(maxima[active], local_measures(J)[:, [2, 5]])
        steps[active] += 1
        back = np.linalg.norm(np.angle(np.exp(1j * (q - q0[active]))), axis=1) < STEP
        done = back if step >= 2 else np.zeros_like(back)
        closed[active[done]] = True
        active, q, previous, J = active[~done], q[~done], direction[~done], J[~done]
        if not active.size:
            break
    return SelfMotion(maxima, closed, steps, pose_error)
