"""Zhao & Li sec. V offline: the path error after a joint-3 lock grows with the velocity jump.

Planar 3R arm, links 0.29/0.32/0.23 m (sec. V, Power-Cube test bed), tool velocity
xd = (pi/30) [-sin(pi t/3), cos(pi t/3)] m/s: a circle of radius 0.1 m and period
6 s, run counter-clockwise from the start point forward(Q0) (centre 0.1 m in -x of
it). Only joint 3 may fail (sec. V). Before the lock the arm resolves xd by least
norm (the paper's choice in sec. V) or by minimum jump (eq 5, every joint equally
likely to fail); joint 3 locks at the moment of the period where its jump (eq 1) is
largest or smallest. From then on joint 3 stands still and joints 1-2 chase the
reduced solution (eq 2) under an acceleration limit of 5 rad/s^2 and a jerk limit
of 1000 rad/s^3 (ruckig, velocity interface, Synchronization.No, one update per
1 ms period: the paper's calculation time, sec. IV-A). The largest path error and
the integrated path error in the 0.5 s after the lock are the figures; a sweep of 23
lock moments and a control without limits check that the error follows the jump.

Readings (the paper gives neither the start configuration nor the centre of the
circle): Q0 was found by a random search (not in this file) among start
configurations whose least-norm path puts the largest and smallest joint-3 jumps at
the paper's 3.1 s and 4.5 s and keeps every reduced condition number (eq 15) under 7
on both modes' paths (sec. III-C/D: eq 5 needs non-singular reduced robots). This is
a calibration to the two times sec. V reports, not a prediction of them. The smallest
jump is a zero crossing of joint 3's velocity; the crossing near 1.57 s is almost as
small. Minimum jump weights every joint equally (eq 5 with 1/n): with only joint 3
allowed to fail, eq 5 becomes eq 8, which holds joint 3 still, so every jump and error
here would be 0. Path error is the distance from the prescribed circle (the paper fits a circle
by least squares to the measured path; we know the circle). A closed-loop term
`GAIN (x* - x)` is added to xd before resolution in both phases, so Euler drift does
not accumulate and the arm returns to the circle, as the paper's arm does (Fig. 9).

    python bench/zhao_li_circle.py --out bench_out
"""

from __future__ import annotations

import argparse
import json
from functools import cache
from pathlib import Path

import numpy as np
from ft_core.velocity_jump import joint_velocity_jumps, jump_index, min_jump_velocity
from ruckig import ControlInterface as Interface
from ruckig import InputParameter, OutputParameter, Result, Ruckig, Synchronization

LINKS = np.array([0.29, 0.32, 0.23])  #: link lengths (m), Zhao & Li sec. V
OMEGA = np.pi / 3  #: angular rate of the circle (rad/s): period 6 s
RADIUS = (np.pi / 30) / OMEGA  #: 0.1 m
PERIOD = 2 * np.pi / OMEGA  #: 6 s
Q0 = np.array([2.2, -0.48, -1.98])  #: start configuration (rad), see the module text
DT = 0.001  #: control period (s), Zhao & Li sec. IV-A
LOCKED = 2  #: joint 3 (0-based)
GAIN = 10.0  #: closed-loop task gain (1/s)
ACCELERATION = 5.0  #: rad/s^2, healthy joints after the lock
JERK = 1000.0  #: rad/s^3
WINDOW = 0.5  #: s after the lock in which the error is measured
MODES = ("least_norm", "min_jump")


def forward(q: np.ndarray) -> np.ndarray:
    """Tool position (m) of the planar 3R arm at joint angles q (rad)."""
    a = np.cumsum(q)
    return np.array([LINKS @ np.cos(a), LINKS @ np.sin(a)])


def jacobian(q: np.ndarray) -> np.ndarray:
    """2 x 3 position Jacobian (m/rad): column j sums the links from joint j on."""
    a = np.cumsum(q)
    c, s = np.cumsum((LINKS * np.cos(a))[::-1])[::-1], np.cumsum((LINKS * np.sin(a))[::-1])[::-1]
    return np.array([-s, c])


CENTRE = forward(Q0) - np.array([RADIUS, 0.0])  #: centre of the circle (m)


def desired(t: float) -> tuple[np.ndarray, np.ndarray]:
    """Tool position (m) and velocity (m/s) on the circle at time t (s) (Zhao & Li sec. V)."""
    c, s = np.cos(OMEGA * t), np.sin(OMEGA * t)
    return CENTRE + RADIUS * np.array([c, s]), RADIUS * OMEGA * np.array([-s, c])


def command(q: np.ndarray, t: float) -> np.ndarray:
    """Task velocity to resolve (m/s): xd plus GAIN times the position error."""
    x, xd = desired(t)
    return xd + GAIN * (x - forward(q))


def resolve(mode: str, J: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Healthy joint velocity (rad/s): least norm J+ v, or minimum jump (Zhao & Li eq 5)."""
    if mode == "least_norm":
        return np.linalg.pinv(J) @ v
    if mode == "min_jump":
        return min_jump_velocity(J, v)
    raise ValueError(f"unknown mode {mode!r}")


def lock_jump(J: np.ndarray, qd: np.ndarray, v: np.ndarray) -> float:
    """Jump (rad/s) a lock of joint 3 causes: the 2-norm over j of 3lambda_j (Zhao & Li eq 1)."""
    return float(np.linalg.norm(joint_velocity_jumps(J, qd, v)[LOCKED]))


@cache
def healthy(mode: str) -> dict[str, np.ndarray]:
    """One period of the healthy arm, Euler-integrated at DT from Q0.

    Arrays over time: t (s), q (rad), qd (rad/s), the joint-3 jump (rad/s, Zhao & Li
    eq 1) and the all-joint jump index (rad^2/s^2, Zhao & Li eqs 9-10).
    """
    steps = round(PERIOD / DT)
    t, q = np.arange(steps + 1) * DT, np.empty((steps + 1, 3))
    qd, jump, index = np.empty_like(q), np.empty(steps + 1), np.empty(steps + 1)
    q[0] = Q0
    for k in range(steps + 1):
        J, v = jacobian(q[k]), command(q[k], t[k])
        qd[k] = resolve(mode, J, v)
        jump[k], index[k] = lock_jump(J, qd[k], v), jump_index(J, qd[k], v)
        if k < steps:
            q[k + 1] = q[k] + DT * qd[k]
    return {"t": t, "q": q, "qd": qd, "jump": jump, "index": index}


def extreme_moments(mode: str) -> tuple[float, float]:
    """Times (s) in the period with the largest and the smallest joint-3 jump (eq 1)."""
    h = healthy(mode)
    return float(h["t"][np.argmax(h["jump"])]), float(h["t"][np.argmin(h["jump"])])


def path_error(x: np.ndarray) -> float:
    """Distance (m) of the tool position x (m) from the prescribed circle."""
    return abs(float(np.linalg.norm(x - CENTRE)) - RADIUS)


def run(mode: str, lock_time: float, acceleration: float = ACCELERATION,
        jerk: float = JERK, window: float = WINDOW) -> dict[str, float]:
    """Lock joint 3 at lock_time (s) on the circle resolved by `mode`; simulate `window` s.

    At the lock joint 3 stops; joints 1-2 keep their velocity and acceleration and
    ruckig moves their velocity towards the reduced least-norm solution
    (J_3)^-1 v (Zhao & Li eq 2) within `acceleration` (rad/s^2) and `jerk` (rad/s^3),
    one update per DT, the target recomputed each period at the current position.
    Returns the jump at the lock (rad/s, eq 1; jump_index, rad^2/s^2, eqs 9-10), the
    largest and integrated path error (mm, mm*s), the largest distance from the
    desired point x*(t) (mm), and the path error just before the lock (mm).
    """
    if not 0.0 < lock_time <= PERIOD:
        raise ValueError(f"lock_time must be in (0, {PERIOD:g}] s, got {lock_time}")
    h = healthy(mode)
    k = round(lock_time / DT)
    q, qd = h["q"][k].copy(), h["qd"][k]
    accel = (qd - h["qd"][k - 1]) / DT if k > 0 else np.zeros(3)
    healthy_joints = [j for j in range(3) if j != LOCKED]
    otg, inp, out = Ruckig(2, DT), InputParameter(2), OutputParameter(2)
    inp.control_interface, inp.synchronization = Interface.Velocity, Synchronization.No
    inp.current_position = list(q[healthy_joints])
    inp.current_velocity = list(qd[healthy_joints])
    inp.current_acceleration = list(np.clip(accel[healthy_joints], -acceleration, acceleration))
    inp.max_acceleration, inp.max_jerk = [acceleration] * 2, [jerk] * 2
    inp.target_acceleration = [0.0, 0.0]
    errors, tracking = [], []
    t = h["t"][k]
    for _ in range(round(window / DT)):
        v = command(q, t)
        inp.target_velocity = list(np.linalg.solve(jacobian(q)[:, healthy_joints], v))
        if otg.update(inp, out) not in (Result.Working, Result.Finished):
            raise RuntimeError("ruckig failed")
        out.pass_to_input(inp)
        q[healthy_joints], t = out.new_position, t + DT
        errors.append(path_error(forward(q)))
        tracking.append(float(np.linalg.norm(forward(q) - desired(t)[0])))
    return {"lock_time_s": float(h["t"][k]), "jump_rad_s": float(h["jump"][k]),
            "jump_index_rad2_s2": float(h["index"][k]),
            "max_path_error_mm": 1e3 * max(errors),
            "integrated_path_error_mm_s": 1e3 * DT * float(np.sum(errors)),
            "max_tracking_error_mm": 1e3 * max(tracking),
            "path_error_before_lock_mm": 1e3 * path_error(forward(h["q"][k]))}


def study(acceleration: float = ACCELERATION, jerk: float = JERK) -> dict:
    """All figures: a run per mode and per extreme moment of that mode, a sweep, a control.

    `same_moment` compares both modes' jumps at those moments, on their own paths and
    (min jump) at least norm's configuration, where Zhao & Li eq 14 must hold.
    """
    runs, compare = [], []
    for mode in MODES:
        for moment, lock_time in zip(("largest jump", "smallest jump"), extreme_moments(mode),
                                     strict=True):
            figures = run(mode, lock_time, acceleration, jerk)
            runs.append({"mode": mode, "moment": moment, **figures})
            k = round(lock_time / DT)
            q, t = healthy("least_norm")["q"][k], healthy("least_norm")["t"][k]
            J, v = jacobian(q), command(q, t)  # min jump at least norm's configuration
            qd = resolve("min_jump", J, v)
            compare.append({"moment": f"{mode} {moment}", "time_s": lock_time,
                            **{f"{m}_jump_rad_s": float(healthy(m)["jump"][k]) for m in MODES},
                            **{f"{m}_index_rad2_s2": float(healthy(m)["index"][k]) for m in MODES},
                            "min_jump_at_ln_q_jump_rad_s": lock_jump(J, qd, v),
                            "min_jump_at_ln_q_index_rad2_s2": jump_index(J, qd, v)})
    sweep = {}
    for mode in MODES:  # every 0.25 s of the period: does the error follow the jump?
        rs = [run(mode, t, acceleration, jerk) for t in np.arange(0.25, PERIOD, 0.25)]
        jumps = [r["jump_rad_s"] for r in rs]
        sweep[mode] = {"runs": rs, "pearson_jump_path_error": float(np.corrcoef(
            jumps, [r["max_path_error_mm"] for r in rs])[0, 1]),
            "pearson_jump_tracking_error": float(np.corrcoef(
                jumps, [r["max_tracking_error_mm"] for r in rs])[0, 1])}
    # Control: velocities that may change at once (1e4 rad/s^2, 1e8 rad/s^3) leave no error.
    control = run("least_norm", extreme_moments("least_norm")[0], 1e4, 1e8)
    return {"links_m": LINKS.tolist(), "q0_rad": Q0.tolist(), "centre_m": CENTRE.tolist(),
            "radius_m": RADIUS, "period_s": PERIOD, "dt_s": DT, "gain_1_s": GAIN,
            "acceleration_rad_s2": acceleration, "jerk_rad_s3": jerk, "window_s": WINDOW,
            "runs": runs, "same_moment": compare, "sweep": sweep, "control_unlimited": control}


def main(argv: list[str] | None = None) -> int:
    """Run the study and write <out>/zhao_li_circle.md and .json."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--acceleration", type=float, default=ACCELERATION)
    parser.add_argument("--jerk", type=float, default=JERK)
    args = parser.parse_args(argv)
    figures = study(args.acceleration, args.jerk)
    lines = [f"Zhao & Li sec. V, joint 3 locks; healthy joints limited to {args.acceleration:g} "
             f"rad/s^2 and {args.jerk:g} rad/s^3 (ruckig, {DT * 1e3:g} ms); errors over "
             f"{WINDOW:g} s after the lock; Q0 = {Q0.tolist()} rad.", "",
             "| mode | lock moment | time on circle (s) | joint-3 jump, eq 1 (rad/s) | "
             "largest path error (mm) | integrated path error (mm*s) | "
             "largest tracking error (mm) |", "|---|---|---:|---:|---:|---:|---:|"]
    for r in figures["runs"]:
        lines.append(f"| {r['mode']} | {r['moment']} | {r['lock_time_s']:.3f} | "
                     f"{r['jump_rad_s']:.4f} | {r['max_path_error_mm']:.3f} | "
                     f"{r['integrated_path_error_mm_s']:.4f} | {r['max_tracking_error_mm']:.3f} |")
    lines += ["", "Same moment, least norm (LN) against minimum jump (MJ) on its own path and "
              "at LN's configuration: joint-3 jump (eq 1, rad/s) and all-joint index "
              "(eqs 9-10, rad^2/s^2).", "",
              "| moment | time (s) | jump LN | jump MJ | jump MJ at LN's q | index LN | "
              "index MJ | index MJ at LN's q |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for c in figures["same_moment"]:
        lines.append(f"| {c['moment']} | {c['time_s']:.3f} | {c['least_norm_jump_rad_s']:.4f} | "
                     f"{c['min_jump_jump_rad_s']:.4f} | {c['min_jump_at_ln_q_jump_rad_s']:.4f} | "
                     f"{c['least_norm_index_rad2_s2']:.4f} | {c['min_jump_index_rad2_s2']:.4f} | "
                     f"{c['min_jump_at_ln_q_index_rad2_s2']:.4f} |")
    for mode, sw in figures["sweep"].items():
        lines.append(f"\n{mode}, 23 lock moments every 0.25 s: Pearson r(jump, largest path "
                     f"error) = {sw['pearson_jump_path_error']:.2f}, r(jump, largest tracking "
                     f"error) = {sw['pearson_jump_tracking_error']:.2f}.")
    lines.append(f"\nControl, least norm at its largest jump with unlimited acceleration: "
                 f"{figures['control_unlimited']['max_path_error_mm']:.3f} mm.")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "zhao_li_circle.md").write_text("\n".join(lines) + "\n")
    (args.out / "zhao_li_circle.json").write_text(json.dumps(figures, indent=2) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
