"""`make demo` / `ft-demo` / `ros2 run ft_sim demo`: the fault-tolerance measures of the built-ins.

For each built-in robot at a typical working configuration it prints the
post-failure smallest singular values s_i, kfm, the failure-probability-weighted
measure and the relative manipulability, and it checks the optimal Jacobian of
seed 002 eq 10 (K = sqrt((n - m) / n) = 0.5). The closed-loop story (sim,
controller, monitor, a locked joint) replaces this once those nodes exist.
Exit status 0 when every number is finite and the eq 10 check holds.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from ft_core import design, measures, robots


def _row(label: str, values: np.ndarray) -> str:
    return f"  {label:<28}" + " ".join(f"{v:7.3f}" for v in values)


def report(name: str) -> list[str]:
    """Lines describing the measures of one built-in robot at its working configuration."""
    robot = robots.load(name)
    q = robot.home()
    J = robot.scale_task(robot.jacobian(q))
    return [
        f"{name}: n={robot.n}, task={robot.task_space} (m={robot.m}), "
        f"L={robot.characteristic_length:.3f} m",
        _row("q (rad)", q),
        _row("s_i post-failure sigma_min", measures.post_failure_sigmas(J)),
        _row("relative manipulability", measures.relative_manipulability(J)),
        f"  kfm = {measures.kfm(J):.4f}   weighted (equal p) = "
        f"{measures.weighted_fault_tolerance(J, None):.4f}   "
        f"sigma_min = {np.linalg.svd(J, compute_uv=False)[-1]:.4f}",
    ]


def main(argv: list[str] | None = None) -> int:
    """Print the report; return non-zero if a number is non-finite or eq 10 fails."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", choices=sorted(robots.BUILTINS), action="append",
                        help="robot(s) to report (default: all built-ins)")
    args = parser.parse_args(argv)
    lines = []
    for name in args.robot or sorted(robots.BUILTINS):
        lines += [*report(name), ""]
    optimal = design.optimal_jacobian([1, 1, 1, 1], 3)
    k = measures.kfm(optimal)
    lines.append(f"seed 002 eq 10 optimal 3x4 Jacobian: K = {k:.4f} (bound sqrt(1/4) = 0.5)")
    print("\n".join(lines))
    text = " ".join(lines)
    ok = "nan" not in text and "inf" not in text and abs(k - 0.5) < 1e-12
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
