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

The kinematics and local measures are `ft_core.offline.design_measures`, the study
`ft_core.offline.global_study`; this module compares a study with the thesis
(`comparison`, `markdown`, `figure`) and re-exports both modules' public names.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ft_core.offline.design_measures import (
    BLOCK,
    MAX_STEPS,
    MEASURES,
    N_JOINTS,
    REACH_SAMPLES,
    REACH_STARTS,
    REACH_STEPS,
    STEP,
    Designs,
    SelfMotion,
    chain,
    column_orders,
    design_index,
    jacobians,
    joint_samples,
    local_measures,
    reach,
    sampled_measures,
    self_motion_maxima,
)
from ft_core.offline.global_study import (
    CANDIDATE_1,
    CANDIDATE_4,
    CANDIDATES,
    JOINT_WORKSPACE_CORRELATION,
    RANDOM_DESIGNS,
    TABLE_2_1,
    TABLE_SAMPLES,
    GlobalStudy,
    candidates,
    joint_space_job,
    pareto_layers,
    study,
    thesis_designs,
    workspace_job,
)

__all__ = ["BLOCK", "CANDIDATES", "CANDIDATE_1", "CANDIDATE_4", "JOINT_WORKSPACE_CORRELATION",
           "MAX_STEPS", "MEASURES", "N_JOINTS", "RANDOM_DESIGNS", "REACH_SAMPLES", "REACH_STARTS",
           "REACH_STEPS", "STEP", "TABLE_2_1", "TABLE_SAMPLES", "Designs", "GlobalStudy",
           "SelfMotion", "candidates", "chain", "column_orders", "comparison", "design_index",
           "figure", "jacobians", "joint_samples", "joint_space_job", "local_measures", "markdown",
           "pareto_layers", "reach", "sampled_measures", "self_motion_maxima", "study",
           "thesis_designs", "workspace_job"]


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
