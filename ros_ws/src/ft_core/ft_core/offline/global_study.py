"""The study of sec. 2.4 (Xie 2019) on the 7! designs of eq 2.7: `study` and `GlobalStudy`.

Every design's global sigma_m and sigma_m^* over joint samples (eqs 2.13-2.14,
`joint_space_job`), the candidates among them (sec. 2.4.4, `candidates`, a
non-dominated sorting by `pareto_layers`), and the workspace measures of the
candidates and of random designs (sec. 2.4.3, `workspace_job`), on worker processes or
a Dask cluster (`ft_core.offline.batch`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ft_core.offline import batch, dh
from ft_core.offline.design_measures import (
    Designs,
    design_index,
    joint_samples,
    reach,
    sampled_measures,
    self_motion_maxima,
)

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
    the columns divided by their largest values (`ft_core.offline.global_dexterity`).
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
