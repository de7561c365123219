"""`make bench`: lock-detection quality on realistic plants, new detector beside the old.

Data is recorded once per case from each of the sim's plants, `ft_core.plant.Plant`
(kinematic) and `ft_core.physics.PhysicsPlant` (MuJoCo: the Panda's dynamics under
joint servos; its response time is at least 10 ms), driven at 250 Hz with 1e-3 rad
position noise, over the plant grid of issue 13 (latency {0, 10, 30, 50} ms x
response time {0, 20, 50} ms), then replayed through `ft_core.detection` (default
parameters; on the physics plant with the gravity directions the monitor gives it,
`ft_core.swing.falling_directions`) and through the detector of main before issue 13
(`fixed_latency_detector`, its defaults) on exactly the same data.

- False locks and free-swing declarations per hour of healthy motion: each grid cell
  runs `--healthy-seconds` of moving targets (smooth oscillations with command pauses
  of 0.05 to 1 s, the plant's watchdog stopping the arm) at peak speeds 0.1, 0.2 and
  0.5 rad/s. After a false lock the detector is reset (an operator's `~/reset`) and
  counting goes on.
- Detection latency: `--trials` locks per speed and cell; the arm first moves
  (moving targets, 2.5 s) then every joint is commanded at the speed with random
  signs, and a random joint locks 0.5 to 1 s later. Latency = first declaration
  of the right joint - lock time; a wrong joint first, or nothing within 1 s, is
  counted as wrong or missed.

Writes `<out>/detection.md` and `<out>/detection.json`.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fixed_latency_detector
from engine_cycle import machine, report
from ft_core import robots, swing
from ft_core.detection import LockDetector
from ft_core.physics import PhysicsPlant
from ft_core.plant import Plant, PlantConfig

PANDA = robots.load("panda")
#: The same arm with its inertias, for the physics plant.
PANDA_INERTIAL = robots.load("panda_inertial")
PLANTS = ("kinematic", "physics")
START = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
DT = 1 / 250
GRID = list(itertools.product((0.0, 0.01, 0.03, 0.05), (0.0, 0.02, 0.05)))
SPEEDS = (0.1, 0.2, 0.5)


@dataclass
class Recording:
    """What a monitor sees: its commands and the measured positions, in time order."""

    events: list[tuple[str, float, np.ndarray]] = field(default_factory=list)
    lock_time: float | None = None
    locked: tuple[int, ...] = ()
    physics: bool = False  #: recorded on the physics plant (its gravity is known)


def record(commands, seconds: float, plant: PlantConfig | None = None,
           lock: tuple[tuple[int, ...], float] | None = None, noise: float = 1e-3,
           pauses: tuple[tuple[float, float], ...] = (), stop_at: float | None = None,
           seed: int = 0, dt: float = DT, physics: bool = False) -> Recording:
    """Drive the plant with `commands(t)` for `seconds` and record what a monitor sees.

    `lock` = (joints, time); `pauses` = ((start, end), ...) without commands;
    `stop_at`: the whole arm stops then (an emergency stop); `physics`: on the
    physics plant instead of the kinematic one.
    """
    rng = np.random.default_rng(seed)
    arm = (PhysicsPlant(PANDA_INERTIAL, START, plant) if physics else
           Plant(PANDA.lower, PANDA.upper, PANDA.velocity_limits, START, plant or PlantConfig()))
    result = Recording(lock_time=lock[1] if lock else None, locked=lock[0] if lock else (),
                       physics=physics)
    for k in range(round(seconds / dt)):
        t = k * dt
        if not any(a <= t < b for a, b in pauses):
            qd = commands(t)
            result.events.append(("command", t, qd))
            arm.command(t, qd)
        if lock is not None and t >= lock[1]:
            for joint in lock[0]:
                arm.lock(joint)
        if stop_at is not None and t >= stop_at:
            for joint in range(PANDA.n):
                arm.lock(joint)
        arm.step(t + dt)
        result.events.append(("measure", t + dt, arm.q + rng.normal(scale=noise, size=PANDA.n)))
    return result


def replay(recording: Recording, detector, reset_after_lock: bool = False,
           swings: list[int] | None = None) -> list[tuple[float, list[int]]]:
    """Feed a recording to a detector; returns [(time, joints newly declared locked)].

    The new detector is told the way gravity turns each joint when the recording's
    plant has gravity (as the monitor does); its free-swing declarations are appended
    to `swings`.
    """
    declared = []
    for kind, t, values in recording.events:
        if kind == "command":
            detector.command(t, values)
            continue
        if isinstance(detector, LockDetector):
            update = detector.measure(t, values, falling=(lambda q=values: swing.falling_directions(
                PANDA_INERTIAL, q)) if recording.physics else None)
            new = list(update.locked)
            if swings is not None:
                swings += update.swinging
        else:  # the old one: a list
            new = detector.measure(t, values)
        if new:
            declared.append((t, new))
            if reset_after_lock:
                detector.reset()
    return declared


def detectors() -> dict[str, object]:
    """Fresh detectors: the new one and the old fixed-latency one."""
    return {"new": LockDetector(PANDA.lower, PANDA.upper),
            "old (fixed latency)": fixed_latency_detector.LockDetector(PANDA.lower, PANDA.upper)}


def moving_targets(speed: float, phase: float = 0.0):
    """Smooth oscillations about START, peak joint speed `speed` (rad/s)."""
    frequency = 0.3

    def commands(t: float) -> np.ndarray:
        return speed * np.cos(2 * np.pi * frequency * t + phase + np.arange(PANDA.n))

    return commands


def healthy(seconds: float, physics: bool) -> dict:
    """False locks (and free-swing declarations) per hour, per detector and speed.

    Summed over the grid.
    """
    counts = {name: dict.fromkeys(SPEEDS, 0) for name in detectors()}
    swung = dict.fromkeys(SPEEDS, 0)
    pauses = tuple((start, start + length) for start, length in
                   zip(np.arange(5.0, seconds, 10.0), itertools.cycle((0.05, 0.15, 0.3, 1.0)),
                       strict=False))
    for (latency, response), speed in itertools.product(GRID, SPEEDS):
        data = record(moving_targets(speed), seconds, PlantConfig(latency, response),
                      pauses=pauses, seed=int(1000 * (latency + response + speed)),
                      physics=physics)
        for name, detector in detectors().items():
            swings: list[int] = []
            counts[name][speed] += sum(len(j) for _, j in replay(data, detector, True, swings))
            swung[speed] += len(swings)
    hours = len(GRID) * seconds / 3600
    return {name: {f"{speed} rad/s": {"false_locks": n, "hours": hours, "per_hour": n / hours,
                                      **({"swings": swung[speed],
                                          "swings_per_hour": swung[speed] / hours}
                                         if name == "new" else {})}
                   for speed, n in by_speed.items()} for name, by_speed in counts.items()}


def latency(trials: int, physics: bool, seed: int = 0) -> dict:
    """Detection latency per detector and speed over the grid."""
    rng = np.random.default_rng(seed)
    results = {name: {speed: {"latencies": [], "missed": 0, "wrong": 0} for speed in SPEEDS}
               for name in detectors()}
    for (plant_latency, response), speed in itertools.product(GRID, SPEEDS):
        for _ in range(trials):
            joint, lock = int(rng.integers(PANDA.n)), 2.5 + float(rng.uniform(0.5, 1.0))
            signs = rng.choice([-1.0, 1.0], size=PANDA.n)
            moving = moving_targets(speed, float(rng.uniform(0, 2 * np.pi)))

            def commands(t: float, signs=signs, moving=moving, speed=speed) -> np.ndarray:
                return moving(t) if t < 2.5 else speed * signs

            data = record(commands, lock + 1.0, PlantConfig(plant_latency, response),
                          lock=((joint,), lock), seed=int(rng.integers(1 << 30)),
                          physics=physics)
            for name, detector in detectors().items():
                found = [(t, j) for t, j in replay(data, detector)]
                entry = results[name][speed]
                if not found:
                    entry["missed"] += 1
                elif found[0][1] != [joint] or found[0][0] < lock:
                    entry["wrong"] += 1
                else:
                    entry["latencies"].append(found[0][0] - lock)
    summary = {}
    for name, by_speed in results.items():
        summary[name] = {}
        for speed, entry in by_speed.items():
            values = np.array(entry["latencies"]) * 1e3
            summary[name][f"{speed} rad/s"] = {
                "p50_ms": float(np.percentile(values, 50)) if values.size else None,
                "p99_ms": float(np.percentile(values, 99)) if values.size else None,
                "detected": int(values.size), "missed": entry["missed"],
                "wrong": entry["wrong"], "trials": trials * len(GRID)}
    return summary


def main(argv: list[str] | None = None) -> int:
    """Record, replay through both detectors, write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--healthy-seconds", type=float, default=120.0,
                        help="healthy motion per grid cell and speed (s)")
    parser.add_argument("--trials", type=int, default=10, help="locks per grid cell and speed")
    args = parser.parse_args(argv)
    plants = {plant: {"false_locks": healthy(args.healthy_seconds, plant == "physics"),
                      "detection": latency(args.trials, plant == "physics")}
              for plant in PLANTS}
    hours = args.healthy_seconds * len(GRID) / 3600

    def cell(figure: dict) -> str:
        if figure["p50_ms"] is None:
            return f"- ({figure['missed']} missed, {figure['wrong']} wrong)"
        return (f"{figure['p50_ms']:.0f} / {figure['p99_ms']:.0f} ({figure['detected']}/"
                f"{figure['trials']}; {figure['missed']} missed, {figure['wrong']} wrong)")

    lines = [f"| plant | detector | speed | false locks per hour ({hours:.2f} h healthy) | "
             "free-swing declarations per hour | detection p50 / p99 (ms) |",
             "|---|---|---:|---:|---:|---:|"]
    for plant, figures in plants.items():
        for name, by_speed in figures["false_locks"].items():
            for speed, healthy_figures in by_speed.items():
                swings = (f"{healthy_figures['swings_per_hour']:.0f}"
                          if "swings" in healthy_figures else "-")
                lines.append(f"| {plant} | {name} | {speed} | "
                             f"{healthy_figures['per_hour']:.0f} | {swings} | "
                             f"{cell(figures['detection'][name][speed])} |")
    info = machine()
    lines += ["", f"Plant grid: latency {{0, 10, 30, 50}} ms x response time {{0, 20, 50}} ms "
              "(the physics plant's servo: at least 10 ms); "
              f"{info['cpu']}, {info['date']}."]
    report(args.out, "detection", lines, {"machine": info, "plants": plants})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
