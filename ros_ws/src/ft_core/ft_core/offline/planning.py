"""The trajectory with minimum probability of task failure (Xie 2019, sec. 4.3), and `ft-plan`.

    ft-plan --robot planar3r --points "1.2,0.6;0.3,1.4" --start 0.2,0.9,0.9 --rates 0.002

Like the chapter's planner it assumes a single failure (scenarios A and B only,
sec. 4.3.1), joints of equal top speed v and legs timed by eq 4.2 (max_i
|Delta q_i| / v): the arm never waits. Under those assumptions the cost separates
by joint. In a leg of duration T from q to q', with I_i the intersection of the
remaining points' boxes for joint i, joint i is exposed (a lock there fails the
task) only while it is outside I_i; the least exposure is to enter I_i as soon as
possible and leave it as late as possible, both at full speed: exposed for
min(T, (a_i + b_i) / v), with a_i and b_i the distances of q_i and q'_i from I_i.
This is the chapter's sub-case analysis generalised to n joints: equal rotations
into the nearer boundary first (figs 4.8-4.9, eqs 4.13-4.15), and the detours into
adjacent regions with fewer failure scenarios of figs 4.11-4.14, which fit within
the leg exactly when a_i + b_i < v T (condition 4 of sec. 4.3.3).
Case 1 and Case 2 of sec. 4.3.1 are then one search: the configuration at which each
task point is reached is chosen among the samples of its traced self-motion
manifold by dynamic programming (Case 2 checks "all the configurations along the
self-motion manifold"; in Case 1 the optimum lies in the intersection of the boxes).
Each stage keeps, for each configuration, the cheapest way to reach it; the start
time of the next leg only rescales its exp(-lambda t) factors, so this is exact to
first order in lambda t.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ft_core import robots, selfmotion
from ft_core.offline import batch, cli, reliability
from ft_core.offline.reliability import TaskPoint, Trajectory

#: Most manifold samples kept per task point for the search (every k-th sample).
CANDIDATES = 400
#: Most simulated failures of `--monte-carlo` (its draws take samples x joints x 8 bytes).
MAX_SAMPLES = 10**6
#: Tie-break (probability per second): of trajectories whose single-failure
#: probabilities differ by less than this times their durations, the faster wins.
#: Inside the intersection every lock is survived, so without it any detour there
#: would do; a longer one only exposes the arm to more double failures.
TIME_WEIGHT = 1e-9


def _distance_to(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Per-joint distance (rad) of q from [lower, upper]; inf where the interval is empty."""
    gap = np.maximum(lower - q, 0.0) + np.maximum(q - upper, 0.0)
    return np.where(lower > upper, np.inf, gap)


def _leg_timing(q: np.ndarray, q_next: np.ndarray, box: tuple[np.ndarray, np.ndarray],
                speed: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(T, a, b, through) of legs q -> q_next (broadcast; last axis: joints).

    T: the leg's duration (eq 4.2), s; a, b: per joint, the time to the interval from q
    and from it to q_next at full speed, s; through: whether the joint can pass by the
    interval within the leg (a + b < T).
    """
    T = np.abs(q_next - q).max(axis=-1) / speed
    a = _distance_to(q, *box) / speed
    b = _distance_to(q_next, *box) / speed
    return T, a, b, a + b < T[..., None]


def leg_cost(q: np.ndarray, q_next: np.ndarray, t0: float | np.ndarray,
             box: tuple[np.ndarray, np.ndarray], rates: np.ndarray, speed: float,
             ) -> tuple[np.ndarray, np.ndarray]:
    """Least single-failure probability of the legs q -> q_next started at t0, and their times.

    Broadcasts over leading axes (last axis: joints). Joint i is exposed during
    [t0, t0 + a_i / v] and [t0 + T - b_i / v, t0 + T] when a_i + b_i < v T, else during
    the whole leg (eqs 4.3-4.4 over those stretches; eq 4.13 is the two-joint case).
    """
    T, a, b, through = _leg_timing(q, q_next, box, speed)
    t0 = np.asarray(t0, dtype=float)[..., None]
    end = t0 + T[..., None]
    with np.errstate(invalid="ignore"):
        split = (np.exp(-rates * t0) - np.exp(-rates * (t0 + a))
                 + np.exp(-rates * (end - b)) - np.exp(-rates * end))
    whole = np.exp(-rates * t0) - np.exp(-rates * end)
    return np.where(through, split, whole).sum(axis=-1), T


def leg_waypoints(q: np.ndarray, q_next: np.ndarray, box: tuple[np.ndarray, np.ndarray],
                  speed: float) -> tuple[np.ndarray, np.ndarray]:
    """The leg of `leg_cost` as waypoints: (times from the leg's start (s), configurations).

    Each joint moves at full speed to the nearer edge of its interval, through it,
    and leaves at full speed to arrive at q_next at the leg's end; a joint that cannot
    gain time inside moves straight (timed so it arrives at the end).
    """
    duration, a, b, through = _leg_timing(q, q_next, box, speed)
    T = float(duration)
    enter, leave = np.clip(q, *box), np.clip(q_next, *box)
    knots = [(np.array([0.0, a[i], T - b[i], T]), np.array([q[i], enter[i], leave[i], q_next[i]]))
             if through[i] else (np.array([0.0, T]), np.array([q[i], q_next[i]]))
             for i in range(q.size)]
    times = np.unique(np.concatenate([kt for kt, _ in knots]))
    return times, np.stack([np.interp(times, kt, kq) for kt, kq in knots], axis=1)


@dataclass(frozen=True)
class Plan:
    """A planned trajectory and its probability of task failure.

    Attributes:
        trajectory: the timed joint trajectory through the task points.
        reached: the configuration (rad) at which each task point is reached.
        probability: its single-failure probability of task failure (sec. 4.3).
    """

    trajectory: Trajectory
    reached: np.ndarray
    probability: float


def _candidates(point: TaskPoint) -> np.ndarray:
    samples = point.samples
    return samples[:: max(1, int(np.ceil(samples.shape[0] / CANDIDATES)))]


def plan(points: Sequence[TaskPoint], start: np.ndarray, rates: reliability.Rates,
         speed: float) -> Plan:
    """The trajectory through the points, in order, of least single-lock task failure.

    Sec. 4.3: from `start`, the probability that one lock makes the task fail is least.

    Dynamic programming over the candidate configurations of each point (its traced
    manifold's samples); each leg is `leg_waypoints` (the per-joint optimum).
    """
    start = np.asarray(start, dtype=float)
    lam = reliability.check_rates(rates, start.size)
    if not speed > 0:
        raise ValueError(f"speed must be positive, got {speed}")
    options = [_candidates(p) for p in points]
    cost, time = leg_cost(start[None], options[0], 0.0,
                          reliability.remaining_box(points, 0), lam, speed)
    parents = []
    for k in range(1, len(points)):
        box = reliability.remaining_box(points, k)
        legs, durations = leg_cost(options[k - 1][:, None, :], options[k][None, :, :],
                                   time[:, None], box, lam, speed)
        total = cost[:, None] + legs
        best = np.argmin(total + TIME_WEIGHT * (time[:, None] + durations), axis=0)
        columns = np.arange(options[k].shape[0])
        parents.append(best)
        cost, time = total[best, columns], time[best] + durations[best, columns]
    chosen = [int(np.argmin(cost + TIME_WEIGHT * time))]
    for best in reversed(parents):
        chosen.append(int(best[chosen[-1]]))
    reached = np.array([options[k][c] for k, c in enumerate(reversed(chosen))])
    return Plan(_join(points, start, reached, speed), reached, float(cost.min()))


def _join(points: Sequence[TaskPoint], start: np.ndarray, reached: np.ndarray,
          speed: float) -> Trajectory:
    """The legs' waypoints in one trajectory."""
    times, configurations, arrivals = [np.zeros(1)], [start[None]], []
    here, clock = start, 0.0
    for k, target in enumerate(reached):
        t, q = leg_waypoints(here, target, reliability.remaining_box(points, k), speed)
        times.append(clock + t[1:])
        configurations.append(q[1:])
        clock += float(t[-1])
        here = target
        arrivals.append(sum(c.shape[0] for c in configurations) - 1)
    return Trajectory(np.concatenate(times), np.vstack(configurations), tuple(arrivals))


def straight(points: Sequence[TaskPoint], start: np.ndarray, speed: float) -> Trajectory:
    """The baseline: straight legs to each point's nearest configuration (max-norm)."""
    here, reached = np.asarray(start, dtype=float), []
    for point in points:
        samples = point.samples
        here = samples[np.argmin(np.abs(samples - here).max(axis=1))]
        reached.append(here)
    return Trajectory.at_speed(np.vstack([start, *reached]),
                               list(range(1, len(points) + 1)), speed)


def _trace(job: tuple[str, tuple[str | None, str | None], str | None, list[float],
                      list[float]]) -> tuple[list[np.ndarray], list, list]:
    """Trace one point's manifold from the configuration nearest the start (a worker's job).

    `job` = (model spec, chain, task space, the point flat, the start configuration).
    """
    spec, chain, task, target, start = job
    robot = robots.load(spec, *chain, task_space=task)
    goal = selfmotion.targets_from_flat(robot, target)[0]
    manifold = selfmotion.trace(robot, goal, selfmotion.find_seed(robot, goal, np.array(start)))
    lower, upper = manifold.box
    return list(manifold.paths), lower.tolist(), upper.tolist()


def trace_points(args: argparse.Namespace, flat: list[float], size: int, start: np.ndarray,
                 where: batch.Where) -> list[TaskPoint]:
    """Each point's traced manifold, where `where` says (`batch`), with a progress bar."""
    chain = (args.base_link or None, args.tip_link or None)
    jobs = [(args.robot, chain, args.task, flat[i:i + size], start.tolist())
            for i in range(0, len(flat), size)]
    return [TaskPoint(tuple(paths), np.array(lo), np.array(hi))
            for paths, lo, hi in batch.results(_trace, jobs, where, what="point")]


def draw(points: Sequence[TaskPoint], plans: dict[str, Trajectory], path: Path,
         names: Sequence[str]) -> None:
    """Each joint against time, with the remaining points' intersection shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(names)
    fig, axes = plt.subplots(n, 1, figsize=(7, 1.6 * n + 0.6), sharex=True, squeeze=False)
    planned = plans["planned"]
    ends = np.concatenate([[0.0], planned.times[list(planned.arrivals)]])
    for j, ax in enumerate(axes[:, 0]):
        for k in range(len(points)):
            lower, upper = reliability.remaining_box(points, k)
            if lower[j] <= upper[j]:
                ax.fill_between([ends[k], ends[k + 1]], lower[j], upper[j], color="tab:green",
                                alpha=0.15, lw=0, label="survivable lock" if j == k == 0 else None)
        for (label, trajectory), style in zip(plans.items(), ("-", "--"), strict=False):
            ax.plot(trajectory.times, trajectory.configurations[:, j], style, label=label)
        ax.set_ylabel(f"{names[j]} (rad)", fontsize=8)
    axes[0, 0].legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("joint trajectories; shaded: along the planned one, a lock there is survived",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def parser() -> argparse.ArgumentParser:
    """`ft-plan`'s command line (every number bounded: `cli.bounded`)."""
    parser = argparse.ArgumentParser(prog="ft-plan", description=__doc__.splitlines()[0])
    cli.add_model_arguments(parser, robot="planar3r")
    parser.add_argument("--points", required=True, type=cli.nonempty,
                        help="task points in visiting order: 'x,y;x,y' (planar), 'x,y,z;...'")
    parser.add_argument("--start", required=True, type=cli.nonempty,
                        help="start configuration 'q1,...,qn' (rad)")
    parser.add_argument("--rates", required=True, type=cli.nonempty,
                        help="failure rate per joint (1/s): one value for all, or n values")
    parser.add_argument("--speed", type=cli.bounded(float, 1e-3, 100.0), default=0.5,
                        help="joint speed v (rad/s, 0.001 to 100), default %(default)s")
    parser.add_argument("--monte-carlo", type=cli.bounded(int, 0, MAX_SAMPLES), default=100000,
                        help=f"simulated failures for the check (0: none; at most "
                        f"{MAX_SAMPLES:g}), default %(default)s")
    batch.add_arguments(parser)
    parser.add_argument("--out", type=Path, default=Path("plan_out"), help="output folder")
    return parser


@cli.clear_file_errors("ft-plan")
def main(argv: list[str] | None = None) -> int:
    """Run `ft-plan`; return the exit status (0 success, 1 bad input, 3 unreachable)."""
    args = parser().parse_args(argv)
    try:
        robot = cli.load_robot(args)
        start = cli.configuration(args.start, robot, "--start")
        rates = reliability.check_rates(cli.numbers(args.rates), robot.n)
        flat = cli.parse_points(args.points)
        size = selfmotion.point_size(robot)
        selfmotion.targets_from_flat(robot, flat)
    except ValueError as error:
        print(f"ft-plan: {error}", file=sys.stderr)
        return 1
    cli.check_folder(args.out)  # a file in the way fails now, not at the end
    try:
        points = trace_points(args, flat, size, start, batch.Where.from_arguments(args))
    except selfmotion.UnreachableError as error:
        print(f"ft-plan: {error}", file=sys.stderr)
        return 3
    best = plan(points, start, rates, args.speed)
    trajectories = {"planned": best.trajectory, "straight": straight(points, start, args.speed)}
    summary: dict = {"robot": robot.name, "joints": list(robot.joint_names),
                     "rates": rates.tolist(), "speed": args.speed, "points": flat}
    rng = np.random.default_rng(0)
    for name, trajectory in trajectories.items():
        entry = {
            "duration": trajectory.duration,
            "single_failure": reliability.task_failure_probability(
                points, trajectory, rates, args.speed, second_failures=False),
            "with_second_failures": reliability.task_failure_probability(
                points, trajectory, rates, args.speed),
            "exact": reliability.task_failure_probability(
                points, trajectory, rates, args.speed, exact=True),
            "times": trajectory.times.tolist(),
            "configurations": trajectory.configurations.tolist(),
            "arrivals": list(trajectory.arrivals),
        }
        if args.monte_carlo > 0:
            failures, runs = reliability.monte_carlo(points, trajectory, rates, args.speed,
                                                     args.monte_carlo, rng)
            entry["monte_carlo"] = {"failures": failures, "runs": runs}
        summary[name] = entry
        mc = entry.get("monte_carlo")
        check = f", Monte-Carlo {mc['failures'] / mc['runs']:.5f}" if mc else ""
        print(f"{name}: {trajectory.duration:.2f} s, P(task failure) single "
              f"{entry['single_failure']:.5f}, with second failures "
              f"{entry['with_second_failures']:.5f} (first order; exact "
              f"{entry['exact']:.5f}){check}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "plan.json").write_text(json.dumps(summary, indent=1))
    draw(points, trajectories, args.out / "plan.png", robot.joint_names)
    print(f"wrote {args.out / 'plan.json'} and {args.out / 'plan.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
