"""`ft-design`: optimally fault tolerant designs, from the command line (Xie 2019, ch. 2-3).

Subcommands: `redundant` runs `ft_core.offline.optimal_jacobians` (the isotropic
Jacobians of greatest weighted fault tolerance, eqs 3.12-3.29); `dh`, `global`, `r7`
and `multicase` run the tools of `ft_core.offline.dh` (DH parameters and the 7! designs,
sec. 2.3), `ft_core.offline.global_dexterity` (their global pre- and post-failure
dexterity, sec. 2.4), `ft_core.offline.design7r` (7R-realisable optima, eqs 3.20-3.24)
and `ft_core.offline.multicase` (eq 3.30). Each writes JSON and, with `--figure`, a figure.

The functions of `ft_core.offline.optimal_jacobians` are importable from here too.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ft_core import files
from ft_core.offline import batch, cli
from ft_core.offline.optimal_jacobians import (
    optimal_jacobian,
    optimal_null_space_norms,
    optimal_null_vector,
    projection_with_diagonal,
    redundant_optimal_jacobian,
)

__all__ = ["main", "optimal_jacobian", "optimal_null_space_norms", "optimal_null_vector",
           "projection_with_diagonal", "redundant_optimal_jacobian"]


def _dh_report(J: np.ndarray, verify: bool, where: batch.Where) -> dict[str, Any]:
    from ft_core.offline import dh

    family = dh.organise_permutations(J)
    good = family.match_pairs(dh.GOOD_PAIRS)
    report: dict[str, Any] = {
        "designs": len(family.permutations),
        "reverse_pairs": int(np.sum(family.reverse > np.arange(len(family.reverse)))),
        "tree_choices": family.tree_choices(),
        "pairs": [{"columns": [i + 1, k + 1], "alpha": float(al), "a": float(a)}
                  for (i, k), al, a in zip(family.pairs, family.pair_alpha, family.pair_a,
                                           strict=True)],
        "triples": len(family.triples),
        "d_range": [float(family.triple_d.min()), float(family.triple_d.max())],
        "alpha_gap": [float(family.pair_alpha[family.pair_alpha < 0].max()),
                      float(family.pair_alpha[family.pair_alpha > 0].min())],
        "a_range": [float(family.pair_a.min()), float(family.pair_a.max())],
        "good_pairs": [{"columns": [family.pairs[g][0] + 1, family.pairs[g][1] + 1],
                        "alpha": float(family.pair_alpha[g]), "a": float(family.pair_a[g])}
                       for g in good],
        "good_pair_groups": family.group_sizes(good),
        "identity_design": dh.dh_from_jacobian(J).as_rows(),
    }
    if verify:
        report["verified_designs"] = _verify_all(J, family, where)
    report["_family"] = family
    return report


def _verify_chunk(args: tuple[np.ndarray, list[int]]) -> int:
    from ft_core.offline import dh

    J, designs = args
    return dh.verify_family(J, dh.organise_permutations(J), designs)


def _verify_all(J: np.ndarray, family: Any, where: batch.Where) -> int:
    """Recompute every design's DH table, in chunks (`batch`); return how many were checked."""
    chunks = [c.tolist() for c in np.array_split(np.arange(len(family.permutations)), 40)]
    return sum(batch.results(_verify_chunk, [(J, c) for c in chunks], where, what="chunk"))


def _plot_dh(report: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    family = report["_family"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    left.scatter(family.pair_alpha, family.pair_a, c="tab:blue")
    for (i, k), al, a in zip(family.pairs, family.pair_alpha, family.pair_a, strict=True):
        left.annotate(f"{i + 1}{k + 1}", (al, a), fontsize=7, xytext=(3, 3),
                      textcoords="offset points")
    for pair in report["good_pairs"]:
        left.scatter(pair["alpha"], pair["a"], s=120, facecolors="none", edgecolors="tab:red")
    left.set(xlabel="alpha (rad)", ylabel="a", title=f"{len(family.pairs)} {{alpha, a}} pairs"
             " (Fig. 2.2a, c); red: good pairs")
    right.scatter(family.triple_theta, family.triple_d, s=8, c="tab:green")
    right.set(xlabel="theta (rad)", ylabel="d",
              title=f"{len(family.triples)} {{d, theta}} pairs (Fig. 2.2b)")
    for axis in (left, right):
        axis.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _global_report(args: argparse.Namespace) -> dict[str, Any]:
    from ft_core.offline import global_dexterity as gd

    study = gd.study(args.samples, args.poses, args.seed, batch.Where.from_arguments(args))
    rows = gd.comparison(study)
    orders = gd.column_orders()

    def design(index: int) -> dict[str, Any]:
        entry = {"design": index, "columns": (orders[index] + 1).tolist(),
                 "joint_space": study.joint_space[index].tolist(),
                 "good_pairs": int(study.good_pairs[index]), "reach": float(study.reaches[index])}
        if index in study.workspace:
            entry.update(workspace=study.workspace[index].tolist(),
                         workspace_error=study.workspace_error[index].tolist(),
                         closed=study.closed[index])
        return entry

    return {
        "sampling": {"joint_samples": study.samples, "workspace_poses": study.poses,
                     "seed": study.seed, "table_samples": gd.TABLE_SAMPLES,
                     "step": gd.STEP, "max_steps": gd.MAX_STEPS},
        "measures": list(gd.MEASURES),
        "table_2_1": study.table.tolist(),
        "joint_space": study.joint_space.tolist(),
        "reaches": study.reaches.tolist(),
        "candidates": [design(int(d)) for d in study.candidates],
        "random_designs": [design(int(d)) for d in study.random_designs],
        "thesis_candidates": {"1": design(int(gd.thesis_designs()[0])),
                              "4": design(int(gd.thesis_designs()[1]))},
        "workspace_front": study.workspace_front().tolist(),
        "pose_error": study.pose_error,
        "comparison": [dict(zip(("what", "thesis", "here", "rule", "verdict"), row, strict=True))
                       for row in rows],
        "_study": study,
        "_markdown": gd.markdown(rows),
    }


def _plot_global(report: dict[str, Any], path: Path) -> None:
    from ft_core.offline import global_dexterity

    global_dexterity.figure(report["_study"], path)


def _r7_report(args: argparse.Namespace) -> dict[str, Any]:
    from ft_core import measures
    from ft_core.offline import design7r, dh

    start = design7r.J_324 if args.start == "3.24" else None
    design = design7r.realisable_design(args.probabilities, free_weights=not args.fixed_weights,
                                        start=start, restarts=args.restarts, seed=args.seed)
    J = design.jacobian
    return {
        "realisable": design.realisable,
        "residual": design.residual,
        "target_weights": design.target.tolist(),
        "weights": design.weights.tolist(),
        "jacobian": J.tolist(),
        "singular_values": np.linalg.svd(J, compute_uv=False).tolist(),
        "post_failure_sigmas": measures.post_failure_sigmas(J).tolist(),
        "weighted_fault_tolerance": measures.weighted_fault_tolerance(J, design.weights),
        "dh": dh.dh_from_jacobian(J).as_rows(),
        "max_distance_from_start": (None if start is None
                                    else float(np.abs(J - start).max())),
    }


def _plot_r7(report: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axis = plt.subplots(figsize=(6, 4))
    joints = np.arange(1, 8)
    axis.bar(joints - 0.2, report["target_weights"], 0.4, label="requested w")
    axis.bar(joints + 0.2, report["weights"], 0.4, label="realisable w")
    axis.set(xlabel="joint", ylabel="failure weight",
             title=f"7R design (eqs 3.20-3.24), residual {report['residual']:.1e}")
    axis.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _redundant_report(args: argparse.Namespace) -> dict[str, Any]:
    from ft_core import measures

    J, N = redundant_optimal_jacobian(args.probabilities, args.m, args.sigma)
    return {
        "jacobian": J.tolist(),
        "null_space": N.tolist(),
        "null_space_norms": optimal_null_space_norms(args.probabilities, args.m).tolist(),
        "post_failure_sigmas": measures.post_failure_sigmas(J).tolist(),
        "weighted_fault_tolerance": measures.weighted_fault_tolerance(J, args.probabilities),
    }


def _plot_redundant(report: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axis = plt.subplots(figsize=(6, 4))
    joints = np.arange(1, len(report["null_space_norms"]) + 1)
    axis.bar(joints - 0.2, report["null_space_norms"], 0.4, label="|n_i| (eq 3.29)")
    axis.bar(joints + 0.2, report["post_failure_sigmas"], 0.4, label="i_sigma_m (eq 3.27)")
    axis.set(xlabel="joint", title="several degrees of redundancy")
    axis.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _multicase_report(args: argparse.Namespace) -> dict[str, Any]:
    from ft_core.offline import multicase

    grid = multicase.link_grid(args.step)
    scores = multicase.score_grid(grid, args.radii, args.samples,
                                  batch.Where.from_arguments(args))
    family = multicase.optimal_family(scores, args.family_tolerance)
    balanced = multicase.balanced_design(family)
    best = max(scores, key=lambda s: s.objective)

    def entry(s: Any) -> dict[str, Any]:
        return {"lengths": list(s.lengths), "objective": s.objective,
                "unconstrained": s.unconstrained, "radius": s.radius,
                "components": dict(zip(multicase.COMPONENTS, s.maxima.tolist(), strict=True)),
                "configurations_deg": dict(zip(multicase.COMPONENTS,
                                               np.degrees(s.configurations).tolist(),
                                               strict=True))}

    return {"designs": len(scores), "best": entry(best), "balanced": entry(balanced),
            "family": [entry(s) for s in family],
            "family_l3": sorted({round(s.lengths[2], 6) for s in family}),
            "_scores": scores}


def _plot_multicase(report: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scores = report["_scores"]
    l1 = [s.lengths[0] for s in scores]
    l2 = [s.lengths[1] for s in scores]
    fig, axis = plt.subplots(figsize=(6, 5))
    points = axis.scatter(l1, l2, c=[s.objective for s in scores], s=14, cmap="viridis")
    fig.colorbar(points, label="F (eq 3.30)")
    best = report["balanced"]["lengths"]
    axis.plot([0, 0.6], [0.6, 0], "r--", lw=1, label="l3 = 0.4")
    axis.scatter([best[0]], [best[1]], marker="*", s=150, c="red", label="balanced design")
    axis.set(xlabel="l1", ylabel="l2", title="planar 3R, total length 1 (Fig. 3.4)")
    axis.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _load_jacobian(path: Path | None) -> np.ndarray:
    from ft_core.offline import dh

    if path is None:
        return dh.J_STAR
    data = files.load_json(path, cli.MAX_FILE_BYTES)
    J = np.asarray(data["jacobian"] if isinstance(data, dict) else data, dtype=float)
    if J.ndim != 2 or J.shape[0] != 6 or not 1 <= J.shape[1] <= MAX_JOINTS:
        raise ValueError(f"{path}: need a 6 x n Jacobian (n 1 to {MAX_JOINTS}), got shape "
                         f"{J.shape}")
    if not np.all(np.isfinite(J)):
        raise ValueError(f"{path}: the Jacobian has non-finite entries")
    return J


#: Most joints a design may have (`--probabilities`): the redundant design applies up to
#: n rotations as dense n x n products (`projection_with_diagonal`), O(n^4) time.
MAX_JOINTS = 64


def _probabilities(text: str) -> list[float]:
    try:
        values = cli.numbers(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from error
    if not 1 <= len(values) <= MAX_JOINTS:
        raise argparse.ArgumentTypeError(f"{len(values)} probabilities: 1 to {MAX_JOINTS}")
    return values


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ft-design", description="Design tools of Xie 2019 ch. 2-3: DH parameters and the"
        " 7! designs and their global dexterity, 7R-realisable optima, several degrees of"
        " redundancy, eq 3.30.")
    commands = parser.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--output", "-o", type=Path, required=True, help="JSON file to write")
    common.add_argument("--figure", type=Path, help="PNG figure to write (optional)")
    workers = argparse.ArgumentParser(add_help=False)
    batch.add_arguments(workers)

    dh_cmd = commands.add_parser("dh", parents=[common, workers],
                                 help="DH parameters of the 7! column orders (sec. 2.3)")
    dh_cmd.add_argument("--jacobian", type=Path, help="JSON 6 x n matrix (default: eq 2.7)")
    dh_cmd.add_argument("--verify", action="store_true",
                        help="recompute every design's DH table from its own axes")

    glob = commands.add_parser("global", parents=[common, workers],
                               help="global dexterity of the 7! designs (sec. 2.4)")
    glob.add_argument("--samples", type=cli.bounded(int, 10, 100000), default=2000,
                      help="joint samples per design (10 to 100000, default 2000; the thesis"
                      " used 10000)")
    glob.add_argument("--poses", type=cli.bounded(int, 1, 5000), default=200,
                      help="workspace poses per traced design (1 to 5000, default 200; the"
                      " thesis used 5000)")
    glob.add_argument("--seed", type=cli.bounded(int, 0, cli.MAX_SEED), default=0,
                      help="random seed (default 0)")

    r7 = commands.add_parser("r7", parents=[common],
                             help="7R-realisable optimal Jacobian (eqs 3.20-3.24)")
    r7.add_argument("--probabilities", type=_probabilities, default=None,
                    help="7 failure probabilities (default: equal)")
    r7.add_argument("--start", choices=["3.24", "random"], default="random",
                    help="polish eq 3.24 (with its weights) or start at random")
    r7.add_argument("--fixed-weights", action="store_true",
                    help="keep the weights fixed (usually not realisable)")
    r7.add_argument("--restarts", type=cli.bounded(int, 0, 1000), default=8,
                    help="random starts (0 to 1000, default 8)")
    r7.add_argument("--seed", type=cli.bounded(int, 0, cli.MAX_SEED), default=0,
                    help="random seed (default 0)")

    red = commands.add_parser("redundant", parents=[common],
                              help="Jacobian with several degrees of redundancy (3.26-3.29)")
    red.add_argument("--probabilities", type=_probabilities, required=True,
                     help="n failure probabilities")
    red.add_argument("--m", type=cli.bounded(int, 1, MAX_JOINTS - 1), required=True,
                     help="task dimension m < n")
    red.add_argument("--sigma", type=cli.bounded(float, 1e-6, 1e6), default=1.0,
                     help="singular value (1e-6 to 1e6, default 1)")

    multi = commands.add_parser("multicase", parents=[common, workers],
                                help="planar 3R design for several cases (eq 3.30)")
    multi.add_argument("--step", type=cli.bounded(float, 1e-3, 0.5), default=0.02,
                       help="link-length step (0.001 to 0.5, default 0.02; the designs scored "
                       "grow as 1/step^2)")
    multi.add_argument("--radii", type=cli.bounded(int, 1, 10000), default=100,
                       help="task-point distances (1 to 10000, default 100)")
    multi.add_argument("--samples", type=cli.bounded(int, 4, 100000), default=360,
                       help="points per manifold (4 to 100000, default 360)")
    multi.add_argument("--family-tolerance", type=cli.bounded(float, 0.0, 1.0), default=2e-3,
                       help="relative tolerance of the optimal family (default 2e-3)")
    return parser


@cli.clear_file_errors("ft-design")
def main(argv: list[str] | None = None) -> int:
    """Run `ft-design`; return the exit status (0 ok, 1 bad input, 2 bad arguments)."""
    args = _parser().parse_args(argv)
    cli.check_folder(args.output.parent)  # a file in the way fails now, not after the work
    try:
        if args.command == "dh":
            report, plot = _dh_report(_load_jacobian(args.jacobian), args.verify,
                                      batch.Where.from_arguments(args)), _plot_dh
        elif args.command == "global":
            report, plot = _global_report(args), _plot_global
        elif args.command == "r7":
            if args.start == "3.24" and args.probabilities is None:
                from ft_core.offline.design7r import W_324

                args.probabilities = W_324.tolist()
            report, plot = _r7_report(args), _plot_r7
        elif args.command == "redundant":
            report, plot = _redundant_report(args), _plot_redundant
        else:
            report, plot = _multicase_report(args), _plot_multicase
    except (ValueError, OSError, KeyError) as error:
        print(f"ft-design: {error}", file=sys.stderr)
        return 1
    public = {key: value for key, value in report.items() if not key.startswith("_")}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"command": args.command, **public}, indent=1) + "\n")
    if args.figure is not None:
        args.figure.parent.mkdir(parents=True, exist_ok=True)
        plot(report, args.figure)
    if "_markdown" in report:
        print(report["_markdown"])
    print(f"ft-design {args.command}: wrote {args.output}"
          + (f" and {args.figure}" if args.figure else ""))
    return 0
