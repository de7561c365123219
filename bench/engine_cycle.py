"""`make bench`: one control cycle of the engine in each mode, beside its peers, in one run.

Robot: the built-in Panda (our URDF, for every candidate), pose task (m = 6) at
`panda_hand_tcp`. Every candidate sees the same seeded configurations inside the
joint limits and the same task velocities xd (|xd| ~ 0.1), and is used as its
authors recommend for a control loop:

* ft engine, each mode: `ResolutionEngine.step(robot.kinematics(q), xd)` (the
  snapshot's Pinocchio pass, dJ/dq where the mode needs it, computed inside), position
  limits over dt = 0.004 s and the URDF velocity limits.
* pink (pin-pink, DAQP): one `pink.Configuration` made once and updated each cycle
  (`configuration.update(q)`: forward kinematics and Jacobians); a frame task whose
  target is the current tool pose moved by xd over dt (so the task asks for the
  velocity xd, as the engine is asked) plus a posture task (cost 1e-3, target q);
  its default limits, the URDF's position and velocity limits.
* mink (MuJoCo, DAQP): our URDF loaded by MuJoCo; one `mink.Configuration` updated
  each cycle; the same frame task (body `panda_hand_tcp`) and posture task; a
  `ConfigurationLimit` (position, default gain) and a `VelocityLimit` with the URDF
  velocity limits.
* numpy baseline: what a user would otherwise write with numpy.linalg: Pinocchio's
  Jacobian, the least-norm solution `pinv(J) xd`, and a kfm-style post-failure
  analysis (the smallest singular value of J without each column in turn: n SVDs
  in one batched call). No limits.
* Pinocchio floor: Pinocchio's own frame Jacobian call alone, the irreducible part
  every candidate pays in some form (the engine's dJ/dq comes from J's columns).

Each figure is the median and 99th percentile over repeated passes after a warm-up
pass, the candidates' passes interleaved.

Writes `<out>/engine_cycle.md` (a Markdown table) and `<out>/engine_cycle.json`
(every figure with the machine's description).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections.abc import Callable
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

import numpy as np
import pink
import pinocchio as pin
from ft_core import robots
from ft_core.engine import RESOLUTIONS, EngineConfig, ResolutionEngine
from pink.tasks import FrameTask, PostureTask

TIP = "panda_hand_tcp"
DT = 0.004  # the control period every candidate is given (s)
PINK = "pink (reused configuration, DAQP)"
MINK = "mink (MuJoCo, DAQP)"
NUMPY = "numpy baseline (pinv + n SVDs)"
FLOOR = "Pinocchio floor (frame Jacobian)"


def workload(robot: robots.Robot, count: int,
             seed: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Seeded configurations (0.2 rad inside the limits) and task velocities (|v| ~ 0.1)."""
    rng = np.random.default_rng(seed)
    qs = [robot.random_configuration(rng, margin=0.2) for _ in range(count)]
    xds = [rng.normal(scale=0.05, size=robot.m) for _ in range(count)]
    return qs, xds


def time_calls(calls: dict[str, Callable[[int], object]], count: int,
               repeats: int) -> dict[str, np.ndarray]:
    """Seconds per call of each candidate, over `repeats` passes after a warm-up pass.

    The passes are interleaved (every candidate once per pass, in turn), so a slow
    spell of a noisy machine falls on all of them alike.
    """
    samples: dict[str, list[float]] = {name: [] for name in calls}
    for repeat in range(repeats + 1):
        for name, call in calls.items():
            for i in range(count):
                start = time.perf_counter()
                call(i)
                if repeat:
                    samples[name].append(time.perf_counter() - start)
    return {name: np.array(values) for name, values in samples.items()}


def advanced_pose(pose: np.ndarray, xd: np.ndarray, dt: float) -> np.ndarray:
    """The 4x4 pose `pose` moved over dt by xd (linear at the frame's origin, angular; world axes).

    A frame task with gain 1 towards it asks for the velocity xd, which is what the
    engine's `step` is asked for (its Jacobian is the tool point's, world-aligned).
    """
    target = np.eye(4)
    target[:3, :3] = pin.exp3(xd[3:] * dt) @ pose[:3, :3]
    target[:3, 3] = pose[:3, 3] + xd[:3] * dt
    return target


def engine_call(robot: robots.Robot, mode: str, qs: list,
                xds: list) -> Callable[[int], object]:
    """One engine cycle per workload entry."""
    engine = ResolutionEngine(robot, EngineConfig(resolution=mode, dt=DT))
    return lambda i: engine.step(robot.kinematics(qs[i]), xds[i])


def pink_call(xml: str, tip: str, qs: list, xds: list) -> Callable[[int], np.ndarray]:
    """Pink with one reused configuration, a frame task asking for xd and a posture task.

    Its default limits: the model's position and velocity limits (from the URDF).
    Returns the joint velocities (rad/s).
    """
    model = pin.buildModelFromXML(xml)
    configuration = pink.Configuration(model, model.createData(), qs[0])
    frame = FrameTask(tip, position_cost=1.0, orientation_cost=1.0)
    posture = PostureTask(cost=1e-3)
    targets = []
    for q, xd in zip(qs, xds, strict=True):
        configuration.update(q)
        pose = configuration.get_transform_frame_to_world(tip).homogeneous
        targets.append(pin.SE3(advanced_pose(pose, xd, DT)))

    def call(i: int) -> np.ndarray:
        configuration.update(qs[i])
        frame.set_target(targets[i])
        posture.set_target(qs[i])
        return pink.solve_ik(configuration, [frame, posture], DT, solver="daqp")

    return call


def mujoco_model(xml: str) -> object:
    """MuJoCo's `MjModel` of a URDF, keeping every link as a body (so the tool frame exists).

    The URDFs have no inertias: bodies get a tiny mass, which kinematics ignores.
    (mujoco is imported here: only when mink is measured.)
    """
    import mujoco

    extension = ('<mujoco><compiler fusestatic="false" boundmass="1e-3" '
                 'boundinertia="1e-6" angle="radian" discardvisual="true"/></mujoco>')
    start = xml.index(">", xml.index("<robot")) + 1
    return mujoco.MjModel.from_xml_string(xml[:start] + extension + xml[start:])


def mink_call(robot: robots.Robot, xml: str, tip: str, qs: list,
              xds: list) -> Callable[[int], np.ndarray]:
    """Mink on MuJoCo: the same frame and posture tasks, position and velocity limits.

    Returns the joint velocities (rad/s).
    """
    import mink

    model = mujoco_model(xml)
    names = [model.joint(j).name for j in range(model.njnt)]
    if names != list(robot.joint_names):
        raise RuntimeError(f"MuJoCo's joints {names} are not the chain's {robot.joint_names}")
    configuration = mink.Configuration(model, qs[0])
    frame = mink.FrameTask(tip, "body", position_cost=1.0, orientation_cost=1.0)
    posture = mink.PostureTask(model, cost=1e-3)
    limits = [mink.ConfigurationLimit(model),
              mink.VelocityLimit(model, dict(zip(robot.joint_names,
                                                 robot.velocity_limits.tolist(),
                                                 strict=True)))]
    targets = []
    for q, xd in zip(qs, xds, strict=True):
        configuration.update(q)
        pose = configuration.get_transform_frame_to_world(tip, "body").as_matrix()
        targets.append(mink.SE3.from_matrix(advanced_pose(pose, xd, DT)))

    def call(i: int) -> np.ndarray:
        configuration.update(qs[i])
        frame.set_target(targets[i])
        posture.set_target(qs[i])
        return mink.solve_ik(configuration, [frame, posture], DT, solver="daqp",
                             limits=limits)

    return call


def numpy_call(robot: robots.Robot, xml: str, tip: str, qs: list,
               xds: list) -> Callable[[int], tuple[np.ndarray, float]]:
    """The textbook cycle: Pinocchio's J, pinv(J) xd, and kfm from n SVDs (numpy.linalg).

    Returns (joint velocities, kfm): kfm is the smallest singular value over the n
    Jacobians with one column removed (angular rows scaled as the engine's).
    """
    model = pin.buildModelFromXML(xml)
    data, frame = model.createData(), model.getFrameId(tip)
    n, scale = robot.n, robot.task_scale
    keep = np.array([[j for j in range(n) if j != i] for i in range(n)])

    def call(i: int) -> tuple[np.ndarray, float]:
        J = pin.computeFrameJacobian(model, data, qs[i], frame, pin.LOCAL_WORLD_ALIGNED)
        Js = scale[:, None] * J
        qd = np.linalg.pinv(Js) @ (scale * xds[i])
        reduced = np.swapaxes(Js[:, keep], 0, 1)  # (n, m, n - 1): joint i locked
        kfm = float(np.linalg.svd(reduced, compute_uv=False)[:, -1].min())
        return qd, kfm

    return call


def floor_call(xml: str, tip: str, qs: list) -> Callable[[int], np.ndarray]:
    """Pinocchio's frame Jacobian alone (forward kinematics included)."""
    model = pin.buildModelFromXML(xml)
    data, frame = model.createData(), model.getFrameId(tip)
    return lambda i: pin.computeFrameJacobian(model, data, qs[i], frame,
                                              pin.LOCAL_WORLD_ALIGNED)


def summary(seconds: np.ndarray) -> dict[str, float | int]:
    """Median and 99th percentile (us) and the sample count."""
    return {"median_us": float(np.median(seconds) * 1e6),
            "p99_us": float(np.percentile(seconds, 99) * 1e6), "samples": int(seconds.size)}


def report(out: Path, name: str, lines: list[str], figures: dict) -> None:
    """Write `<out>/<name>.md` (the table lines) and `<out>/<name>.json`, and print the table."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    (out / f"{name}.json").write_text(json.dumps(figures, indent=2) + "\n")
    print("\n".join(lines))


def machine() -> dict[str, str]:
    """What the figures were measured on."""
    cpu = platform.processor()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    info = {"cpu": cpu, "cores": str(os.cpu_count()), "python": platform.python_version(),
            "numpy": np.__version__, "pinocchio": pin.__version__,
            "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")}
    for package, distribution in (("pink", "pin-pink"), ("mink", "mink"), ("mujoco", "mujoco")):
        try:
            info[package] = metadata.version(distribution)
        except metadata.PackageNotFoundError:
            pass
    return info


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and write the table and JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    parser.add_argument("--configurations", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    xml = robots.builtin_urdf("panda")
    robot = robots.load("panda")
    qs, xds = workload(robot, args.configurations, args.seed)
    calls = {f"ft engine {mode}": engine_call(robot, mode, qs, xds) for mode in RESOLUTIONS}
    calls[PINK] = pink_call(xml, TIP, qs, xds)
    notes = []
    try:
        calls[MINK] = mink_call(robot, xml, TIP, qs, xds)
    except ImportError as exc:
        notes.append(f"mink not measured: {exc}")
    calls[NUMPY] = numpy_call(robot, xml, TIP, qs, xds)
    calls[FLOOR] = floor_call(xml, TIP, qs)
    results = {name: summary(seconds) for name, seconds
               in time_calls(calls, args.configurations, args.repeats).items()}
    pink_median = results[PINK]["median_us"]
    numpy_median = results[NUMPY]["median_us"]
    lines = ["| cycle (Panda, pose task) | median (us) | p99 (us) | median / pink | "
             "median / numpy baseline |", "|---|---:|---:|---:|---:|"]
    for name, figures in results.items():
        lines.append(f"| {name} | {figures['median_us']:.1f} | {figures['p99_us']:.0f} | "
                     f"{figures['median_us'] / pink_median:.2f} | "
                     f"{figures['median_us'] / numpy_median:.2f} |")
    info = machine()
    lines.append("")
    lines.append(f"{args.configurations} configurations x {args.repeats} passes; "
                 f"{info['cpu']}, {info['cores']} cores, Python {info['python']}, "
                 f"{info['date']}.")
    lines.extend(notes)
    report(args.out, "engine_cycle", lines, {
        "machine": info, "configurations": args.configurations, "repeats": args.repeats,
        "seed": args.seed, "dt": DT, "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
