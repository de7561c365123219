"""Global pre- and post-failure dexterity of the 7! designs of eq 2.7 (Xie 2019 sec. 2.4).

Each column order of the Jacobian of Xie 2019 eq 2.7 is a 7R design (sec. 2.3,
`ft_core.offline.dh`); at its design configuration every one has the same Jacobian, so
the same local measures (sec. 2.4.1). Away from it they differ, and sec. 2.4 averages
two local measures over sampled configurations:

- sigma_m, the smallest singular value of the 6 x 7 Jacobian (pre-failure), and
- sigma_m^* = min_f sigma_m(^fJ) over the 6 x 6 Jacobians with column f removed, one
  locked joint (eq 2.3, the worst case as eqs 2.11-2.12 take it for kappa and w).

Table 2.1 also uses 1/kappa = sigma_m / sigma_1 (eq 2.9), w = sigma_1 ... sigma_m
(eq 2.10) and their worst cases 1/kappa^* = min_f 1/^fkappa (eq 2.11, read on the
reciprocal: the worst case of kappa is its largest value) and w^* = min_f ^fw (eq 2.12).
All come from one batched eigendecomposition of J J^T and of J J^T - j_f j_f^T, which is
^fJ ^fJ^T (`local_measures`).

Readings taken where the thesis leaves a choice:

- Units (sec. 2.4.2: "the first three rows of the Jacobian are normalized by the maximal
  distance that this robot can reach"): the linear rows are divided by R, the largest
  distance of the tool point from the base frame's origin (on the first axis, at the
  foot of the common normal x_1, as `dh` places it). R is found by gradient ascent of
  |p|^2 from the farthest of `REACH_SAMPLES` joint samples (`reach`), so it does not
  depend on the number of measure samples. With it, Table 2.1 is met to 0.015; the bound
  sum sqrt(a_i^2 + d_i^2) or the sample maximum alone do about as well (0.02). The
  measures are then dimensionless (velocities per joint rate, lengths in units of R).
- Joint space (eqs 2.13-2.14): every joint uniform on [-pi, pi) (no joint limits are
  given); the same samples for every design (common random numbers, so differences
  between designs carry less sampling noise than the means themselves).
- Workspace (sec. 2.4.3, steps a-d): the "direct sampling" of the 6-D workspace is read
  as the poses of uniformly sampled configurations (so poses are spread as the joint
  space maps them, not uniformly in volume). Of "all the self-motion manifolds" at a
  pose only the one through the sampled configuration is traced (the others need an
  inverse kinematics solver for each pose): null-space steps of `STEP` rad, each with
  two Newton corrections back to the pose, until the curve returns to its start (at
  most `MAX_STEPS`; a curve that has not closed keeps the maxima of the part traced,
  a lower bound). The maxima of sigma_m and of sigma_m^* along it (separately, step c)
  are averaged over the poses (step d). Each pose's maximum is at least the value at
  its sampled configuration, so with the same configurations the workspace means are
  never below the joint-space means of those samples.
- Candidates (sec. 2.4.4): the 20 designs "none of the remaining ... have both better"
  are read as the first layers of a non-dominated sorting on (sigma_m, sigma_m^*) in
  joint space, the last layer cut by the sum of the measures normalised by their
  largest value over the 7! designs; candidate k is k-th by that sum (the thesis's
  order, "somewhat arbitrarily"). That property holds for any such set: a design that
  dominates another sits in an earlier layer. Fig. 2.9's "normalized" measures are
  divided the same way.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ft_core.offline import batch, dh

N_JOINTS = 7
#: Columns of `local_measures`, in the order of Table 2.1.
MEASURES = ("1/kappa", "w", "sigma_m", "1/kappa*", "w*", "sigma_m*")
#: Xie 2019 Table 2.1: correlations of the local measures over 10,000 joint samples of the
#: design of eq 2.7 (columns in their printed order), rows and columns as `MEASURES`.
TABLE_2_1 = np.array([
    [1.000, 0.748, 0.992, 0.401, 0.439, 0.401],
    [0.748, 1.000, 0.773, 0.342, 0.604, 0.357],
    [0.992, 0.773, 1.000, 0.398, 0.454, 0.405],
    [0.401, 0.342, 0.398, 1.000, 0.817, 0.996],
    [0.439, 0.604, 0.454, 0.817, 1.000, 0.825],
    [0.401, 0.357, 0.405, 0.996, 0.825, 1.000],
])
#: Joint samples of Table 2.1 and Fig. 2.5 (sec. 2.4.2).
TABLE_SAMPLES = 10_000
#: Sec. 2.4.3: correlation of the global sigma_m and of sigma_m^* between joint space and
#: workspace over 20 random designs.
JOINT_WORKSPACE_CORRELATION = {"sigma_m": 0.74, "sigma_m*": 0.71}
#: Designs drawn at random for that correlation, and optimal candidates (secs. 2.4.3-2.4.5).
RANDOM_DESIGNS = 20
CANDIDATES = 20
#: Sec. 2.4.5: the column orders (1-based columns of eq 2.7) of Candidate 1 (best global
#: sigma_m^* in the workspace) and Candidate 4 (best global sigma_m there).
CANDIDATE_1 = (6, 7, 3, 5, 2, 1, 4)
CANDIDATE_4 = (7, 4, 5, 1, 2, 6, 3)
#: Tracing step (rad of joint motion) and most steps along one self-motion manifold.
STEP = 0.1
MAX_STEPS = 1500
#: Joint samples and ascent of the reach R (module docstring).
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


def pareto_layers(values: np.ndarray) -> np.ndarray:
    """Non-dominated sorting layer (0 = Pareto front) of each row of (D, k), all maximised.

    Row i dominates row j if it is >= in every column and > in one. The D x D
    dominance matrix is peeled layer by layer, each row's count of dominators left
    falling as its dominators are removed (D = 5040: 25 MB, well under a second).
    """
    values = np.asarray(values, dtype=float)
    above = np.greater_equal(values[:, None, :], values[None, :, :])
    dominates: np.ndarray = above.all(axis=2) & ~above.transpose(1, 0, 2).all(axis=2)
    dominators = dominates.sum(axis=0)
    layer = np.full(len(values), -1)
    level = 0
    while np.any(layer < 0):
        peeled = np.flatnonzero((dominators == 0) & (layer < 0))
        layer[peeled] = level
        dominators -= dominates[peeled].sum(axis=0)
        level += 1
    return layer


def candidates(values: np.ndarray, count: int = CANDIDATES) -> np.ndarray:
    """Indices of the `count` candidates (sec. 2.4.4), best normalised sum first.

    The first non-dominated layers of `values` (D, 2), the last one cut by the sum of
    the columns divided by their largest values (module docstring).
    """
    score = (values / values.max(axis=0)).sum(axis=1)
    layers = pareto_layers(values)
    chosen = np.lexsort((-score, layers))[:count]
    return chosen[np.argsort(-score[chosen], kind="stable")]


def joint_space_job(job: tuple[np.ndarray, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Global sigma_m and sigma_m^* (eqs 2.13-2.14) of some designs: a `batch` job.

    Args:
        job: (column orders (D, 7), samples S, seed).

    Returns:
        (means (D, 2), reaches R (D,)).
    """
    orders, samples, seed = job
    designs = Designs.of(orders)
    reaches = reach(designs, seed)
    measures = sampled_measures(designs, joint_samples(samples, seed), reaches)
    return measures[..., [2, 5]].mean(axis=1), reaches


def workspace_job(job: tuple[np.ndarray, np.ndarray, int, int]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Global sigma_m and sigma_m^* in the workspace of some designs: a `batch` job.

    Args:
        job: (column orders (D, 7), reaches R (D,), poses P, seed).

    Returns:
        (means of the per-pose maxima (D, 2), their standard errors relative to the
        means (D, 2), fraction of closed curves (D,), largest pose error while tracing).
    """
    orders, reaches, poses, seed = job
    designs = Designs.of(orders)
    q0 = joint_samples(poses, seed, stream=1)
    motion = self_motion_maxima(designs.rows(poses), np.tile(q0, (len(designs), 1)),
                                np.repeat(reaches, poses))
    maxima = motion.maxima.reshape(len(designs), poses, 2)
    means = maxima.mean(axis=1)
    return (means, maxima.std(axis=1) / np.sqrt(poses) / means,
            motion.closed.reshape(len(designs), poses).mean(axis=1), motion.pose_error)


@dataclass(frozen=True)
class GlobalStudy:
    """Everything `study` computes; designs are indices into `column_orders`.

    Attributes:
        samples, poses, seed: the sampling used.
        joint_space: (5040, 2) global sigma_m and sigma_m^* in joint space (eqs 2.13-2.14).
        reaches: (5040,) R of each design (eq 2.7 units).
        table_measures: (`TABLE_SAMPLES`, 6) local `MEASURES` of design 0 (eq 2.7 as printed).
        good_pairs: (5040,) how many of the three good {alpha, a} pairs each has (sec. 2.4.4).
        reverse: (5040,) each design's reverse version (sec. 2.3.3).
        random_designs, candidates: the designs of secs. 2.4.3 and 2.4.4 (candidates in
            their order: candidate k is candidates[k - 1]).
        workspace: {design: (2,)} global measures in the workspace (sec. 2.4.3), for the
            random designs, the candidates and the thesis's Candidates 1 and 4.
        workspace_error: {design: (2,)} their standard errors relative to the means.
        closed: {design: fraction of its self-motion curves that closed}.
        pose_error: largest pose error while tracing (eq 2.7 units or rad).
    """

    samples: int
    poses: int
    seed: int
    joint_space: np.ndarray
    reaches: np.ndarray
    table_measures: np.ndarray
    good_pairs: np.ndarray
    reverse: np.ndarray
    random_designs: np.ndarray
    candidates: np.ndarray
    workspace: dict[int, np.ndarray]
    workspace_error: dict[int, np.ndarray]
    closed: dict[int, float]
    pose_error: float

    @property
    def table(self) -> np.ndarray:
        """(6, 6) correlations of the local measures over the samples of design 0 (Table 2.1)."""
        return np.corrcoef(self.table_measures.T)

    def normalised(self) -> np.ndarray:
        """Joint-space measures divided by their largest values over the designs."""
        return self.joint_space / self.joint_space.max(axis=0)

    def reverse_differences(self) -> np.ndarray:
        """(2520,) distances of normalised measures, design to reverse version (Fig. 2.9)."""
        first = np.flatnonzero(self.reverse > np.arange(len(self.reverse)))
        values = self.normalised()
        return np.linalg.norm(values[first] - values[self.reverse[first]], axis=1)

    def workspace_of(self, designs: np.ndarray) -> np.ndarray:
        """(len(designs), 2) workspace measures of traced designs."""
        return np.array([self.workspace[int(k)] for k in designs])

    def correlation(self, designs: np.ndarray, column: int) -> float:
        """Pearson correlation of the joint-space and workspace measure `column` (0 or 1)."""
        return float(np.corrcoef(self.joint_space[designs, column],
                                 self.workspace_of(designs)[:, column])[0, 1])

    def workspace_front(self) -> np.ndarray:
        """The candidates on the Pareto front of their workspace measures (Fig. 2.11)."""
        return self.candidates[pareto_layers(self.workspace_of(self.candidates)) == 0]


def thesis_designs() -> np.ndarray:
    """Design indices of the thesis's Candidates 1 and 4 (sec. 2.4.5)."""
    return np.array([design_index(CANDIDATE_1), design_index(CANDIDATE_4)])


def study(samples: int, poses: int, seed: int, where: batch.Where) -> GlobalStudy:
    """Sec. 2.4 on the 7! designs of eq 2.7: all in joint space, some in the workspace.

    Args:
        samples: joint samples per design (eqs 2.13-2.14; the thesis used 10,000).
        poses: workspace poses per traced design (sec. 2.4.3; the thesis used 5000).
        seed: random seed (the same samples for every design).
        where: worker processes or a Dask cluster (`batch`).
    """
    family = dh.organise_permutations(dh.J_STAR)
    orders = family.permutations
    chunks = np.array_split(np.arange(len(orders)), len(orders) // 60)
    results = batch.results(joint_space_job, [(orders[c], samples, seed) for c in chunks],
                            where, what="chunk")
    joint_space = np.concatenate([r[0] for r in results])
    reaches = np.concatenate([r[1] for r in results])
    table_measures = sampled_measures(Designs.of(orders[:1]), joint_samples(TABLE_SAMPLES, seed),
                                      reaches[:1])[0]
    random_designs = np.sort(np.random.default_rng((seed, 3)).choice(
        len(orders), RANDOM_DESIGNS, replace=False))
    chosen = candidates(joint_space)
    traced = np.unique(np.concatenate([random_designs, chosen, thesis_designs()]))
    groups = np.array_split(traced, max(1, len(traced) // 5))
    found = batch.results(workspace_job, [(orders[g], reaches[g], poses, seed) for g in groups],
                          where, what="design group")
    workspace, errors, closed = {}, {}, {}
    for g, (means, error, fraction, _) in zip(groups, found, strict=True):
        for k, design in enumerate(g.tolist()):
            workspace[design], errors[design] = means[k], error[k]
            closed[design] = float(fraction[k])
    return GlobalStudy(samples, poses, seed, joint_space, reaches, table_measures,
                       np.isin(family.pair_index, family.match_pairs(dh.GOOD_PAIRS)).sum(axis=1),
                       family.reverse, random_designs, chosen, workspace, errors, closed,
                       max(r[3] for r in found))


def _columns(design: int) -> str:
    """'[7 4 5 1 2 6 3]': the 1-based columns of eq 2.7 of a design, as the thesis writes."""
    return "[" + " ".join(str(c + 1) for c in column_orders()[design]) + "]"


def comparison(s: GlobalStudy) -> list[tuple[str, str, str, str, str]]:
    """Rows (what, Xie 2019 sec. 2.4, here, rule, verdict) comparing a study with the thesis.

    Printed numbers are met to a tolerance; figures are compared by the sign or order
    of what they show. The verdict is "agrees", "differs" or "n/a" (no rule applies).
    """
    table, tm = s.table, s.table_measures
    pre, post = np.linalg.norm(table[:3, :3], axis=0), np.linalg.norm(table[3:, 3:], axis=0)
    high = tm[:, 2] >= np.median(tm[:, 2])
    relative = tm[:, [2, 5]].std(axis=0) / tm[:, [2, 5]].mean(axis=0) / np.sqrt(s.samples)
    r = [s.correlation(s.random_designs, k) for k in (0, 1)]
    means = np.array([s.joint_space[s.good_pairs == n].mean(axis=0) for n in range(4)])
    rising = bool(np.all(np.diff(means, axis=0) > 0))
    worst = s.joint_space[s.good_pairs == 3].min(axis=0)
    percentile = [100 * float(np.mean(s.joint_space[:, k] < worst[k])) for k in (0, 1)]
    differences = s.reverse_differences()
    layers = pareto_layers(s.joint_space)
    score = s.normalised().sum(axis=1)
    rank = np.argsort(np.argsort(-score)) + 1
    c1, c4 = thesis_designs()
    ours = {int(d): k + 1 for k, d in enumerate(s.candidates)}
    ratio = s.workspace_of(s.candidates) / s.joint_space[s.candidates]
    front = s.workspace_front()
    space = s.workspace_of(s.candidates)
    best = [int(s.candidates[np.argmax(space[:, k])]) for k in (0, 1)]
    thesis_space = s.workspace_of(np.array([c1, c4]))
    space_error = np.median([s.workspace_error[int(d)] for d in s.workspace], axis=0)

    def where(design: int) -> str:
        label = f"our candidate {ours[design]}" if design in ours else "not a candidate"
        return f"{label} (rank {rank[design]} by the sum, layer {layers[design] + 1})"

    def row(what: str, thesis: str, here: str, rule: str, holds: bool | None
            ) -> tuple[str, str, str, str, str]:
        return what, thesis, here, rule, "n/a" if holds is None else (
            "agrees" if holds else "differs")

    largest = float(np.abs(table - TABLE_2_1).max())
    return [
        row("Table 2.1: correlations of the six local measures (design of eq 2.7, 10,000"
            " joint samples)", "printed to 0.001", f"largest difference {largest:.3f}",
            "within 0.03", largest <= 0.03),
        row("sigma_m, sigma_m^* the most representative (largest column norm in their block)",
            "yes", f"pre {pre.round(3).tolist()}, post {post.round(3).tolist()}",
            "the same column", bool(np.argmax(pre) == 2 and np.argmax(post) == 2)),
        row("Fig. 2.5: sigma_m^* <= sigma_m, and near 0 even where sigma_m is large", "figure",
            f"sigma_m^*/sigma_m <= {(tm[:, 5] / tm[:, 2]).max():.3f}; least sigma_m^* where"
            f" sigma_m is above its median {tm[high, 5].min():.1e}",
            "bounded; < 1 % of its largest value",
            bool(np.all(tm[:, 5] <= tm[:, 2]) and tm[high, 5].min() < 0.01 * tm[:, 5].max())),
        row("error of the joint-space means", "~3 % (sigma_m), ~5 % (sigma_m^*), N = 10,000",
            f"{100 * relative[0]:.1f} %, {100 * relative[1]:.1f} % (one standard error, design"
            f" of eq 2.7, N = {s.samples})", "the thesis does not define its error", None),
        row("sec. 2.4.3: joint space vs workspace, 20 random designs",
            "r = {sigma_m} (sigma_m), {sigma_m*} (sigma_m^*)".format(
                **JOINT_WORKSPACE_CORRELATION), f"r = {r[0]:.2f}, {r[1]:.2f}",
            "both r > 0.5", min(r) > 0.5),
        row("Fig. 2.8: means rise with the number of good pairs (1968, 2016, 864, 192 designs)",
            "figure", "sigma_m " + ", ".join(f"{m:.4f}" for m in means[:, 0]) + "; sigma_m^* "
            + ", ".join(f"{m:.5f}" for m in means[:, 1]), "both rise", rising),
        row("Fig. 2.8: the worst design with three good pairs is still relatively good",
            "figure", f"beats {percentile[0]:.0f} % (sigma_m), {percentile[1]:.0f} % (sigma_m^*)"
            " of the designs", "beats >= 40 % in both", min(percentile) >= 40),
        row("Fig. 2.9: a design and its reverse can differ a lot, though usually not", "figure",
            f"normalised distance: median {np.median(differences):.3f}, largest"
            f" {differences.max():.3f}", "largest > 5 x median",
            bool(differences.max() > 5 * np.median(differences))),
        row(f"sec. 2.4.5: Candidate 4 {_columns(c4)} among the 20", "yes", where(c4),
            "in our 20", c4 in ours),
        row(f"sec. 2.4.5: Candidate 1 {_columns(c1)} among the 20", "yes", where(c1),
            "in our 20", c1 in ours),
        row("Fig. 2.10: workspace measures much better than joint space (20 candidates)",
            "yes", f"{ratio[:, 0].min():.1f}-{ratio[:, 0].max():.1f} x (sigma_m),"
            f" {ratio[:, 1].min():.1f}-{ratio[:, 1].max():.1f} x (sigma_m^*)", "> 1.2 x",
            bool(np.all(ratio > 1.2))),
        row("Fig. 2.11: workspace Pareto front of the candidates",
            "Candidate 4 (best sigma_m), Candidate 1 (best sigma_m^*)",
            ", ".join(_columns(int(d)) for d in front) + f"; best sigma_m {_columns(best[0])}"
            f" {space[:, 0].max():.3f}, best sigma_m^* {_columns(best[1])}"
            f" {space[:, 1].max():.4f}; the thesis's Candidate 4 {thesis_space[1, 0]:.3f},"
            f" {thesis_space[1, 1]:.4f}, Candidate 1 {thesis_space[0, 0]:.3f},"
            f" {thesis_space[0, 1]:.4f}", "the same two designs",
            set(front.tolist()) == {int(c1), int(c4)}),
        row("error of the workspace means", "~2 %, N = 5000", f"{100 * space_error[0]:.1f} %,"
            f" {100 * space_error[1]:.1f} % (median standard error, N = {s.poses})",
            "the thesis does not define its error", None),
    ]


def markdown(rows: list[tuple[str, str, str, str, str]]) -> str:
    """The comparison as a markdown table."""
    lines = ["| Xie 2019 sec. 2.4 | thesis | here | rule | verdict |", "|---|---|---|---|---|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def figure(s: GlobalStudy, path: Path) -> None:
    """Figs. 2.5-2.11 in one PNG (matplotlib Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 4, figsize=(17, 8))
    tm, js = s.table_measures, s.joint_space
    ax[0, 0].scatter(tm[:, 2], tm[:, 5], s=1, alpha=0.3, rasterized=True)
    ax[0, 0].set(xlabel="sigma_m", ylabel="sigma_m*",
                 title=f"Fig. 2.5: {len(tm)} joint samples, eq 2.7")
    for k, name in enumerate(("sigma_m", "sigma_m*")):
        joint, space = js[s.random_designs, k], s.workspace_of(s.random_designs)[:, k]
        r = s.correlation(s.random_designs, k)
        ax[0, 1 + k].scatter(joint, space)
        ax[0, 1 + k].set(xlabel=f"global {name}, joint space", ylabel="workspace",
                         title=f"Fig. 2.6: 20 random designs, r = {r:.2f}")
    colours = plt.get_cmap("viridis")(np.linspace(0, 0.9, 4))
    for n in range(4):
        group = s.good_pairs == n
        ax[0, 3].scatter(js[group, 0], js[group, 1], s=3, color=colours[n],
                         label=f"{n} good pairs ({group.sum()})", rasterized=True)
    ax[0, 3].scatter(*js[s.candidates].T, s=25, facecolors="none", edgecolors="red",
                     label="our 20 candidates")
    for label, design in zip(("C1", "C4"), thesis_designs(), strict=True):
        ax[0, 3].annotate(f"thesis {label}", js[design], color="black", fontsize=8,
                          arrowprops={"arrowstyle": "->"}, xytext=(-60, 15),
                          textcoords="offset points")
    ax[0, 3].set(xlabel="global sigma_m", ylabel="global sigma_m*",
                 title="Figs. 2.7-2.8: the 7! designs, joint space")
    ax[0, 3].legend(fontsize=7, markerscale=3)
    normal = s.normalised()
    ax[1, 0].boxplot([normal[s.good_pairs == n, k] for k in (0, 1) for n in range(4)],
                     positions=[n + 5 * k for k in (0, 1) for n in range(4)], widths=0.7)
    ax[1, 0].set_xticks([1.5, 6.5], ["sigma_m by 0-3 good pairs", "sigma_m* by 0-3"])
    ax[1, 0].set(ylabel="normalised global measure", title="Fig. 2.8: groups")
    ax[1, 1].hist(s.reverse_differences(), bins=50)
    ax[1, 1].set(xlabel="distance of normalised (sigma_m, sigma_m*)", ylabel="reverse pairs",
                 title="Fig. 2.9: design vs reverse version")
    space = s.workspace_of(s.candidates)
    number = np.arange(1, len(s.candidates) + 1)
    ax[1, 2].plot(number, js[s.candidates, 0] / space[:, 0].max(), "o-", label="sigma_m joint")
    ax[1, 2].plot(number, space[:, 0] / space[:, 0].max(), "s-", label="sigma_m workspace")
    ax[1, 2].plot(number, js[s.candidates, 1] / space[:, 1].max(), "o--", label="sigma_m* joint")
    ax[1, 2].plot(number, space[:, 1] / space[:, 1].max(), "s--", label="sigma_m* workspace")
    ax[1, 2].set(xlabel="candidate", ylabel="/ best in the workspace",
                 title="Fig. 2.10: our 20 candidates")
    ax[1, 2].legend(fontsize=7)
    ax[1, 3].scatter(space[:, 0], space[:, 1], c="tab:red", label="our candidates")
    for k, point in enumerate(space):
        ax[1, 3].annotate(str(k + 1), point, fontsize=7, xytext=(3, 3), textcoords="offset points")
    thesis = s.workspace_of(thesis_designs())
    ax[1, 3].scatter(*thesis.T, marker="x", c="black", label="thesis's candidates")
    for label, point in zip(("C1", "C4"), thesis, strict=True):
        ax[1, 3].annotate(f"thesis {label}", point, fontsize=8, xytext=(4, -10),
                          textcoords="offset points")
    ax[1, 3].set(xlabel="global sigma_m, workspace", ylabel="global sigma_m*, workspace",
                 title="Fig. 2.11: workspace")
    ax[1, 3].legend(fontsize=7)
    for axis in ax.flat:
        axis.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=72, pil_kwargs={"optimize": True})
    plt.close(fig)
