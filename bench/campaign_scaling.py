"""`make bench`: campaign runs per hour on 1 and 2 local workers and on a Dask cluster (issue 33).

The same small campaign (`--runs` seeds of blend, with and without soft limits, the
realistic plant of docs/campaign.md) three times, each into a fresh folder: `--workers 1`,
`--workers 2`, and `--cluster` on a Dask cluster started as docs/campaign.md says (a
`dask scheduler` and a `dask worker` process with two worker processes of one thread,
not daemonic), here on this machine. Each is the installed `ft-campaign` as a process
of its own; the wall time is from its start to its end (start-up included), the
throughput runs per hour. The speed-up of 2 workers over 1 is the figure the issue's
target asks for (linear: 2), beside the same ratio for plain compute (`compute_scaling`: the
machine's own ceiling, which 2 virtual CPUs may keep well below 2).

Then what one run costs (`cpu_per_run`): the same runs once more, one after the other in
this process (`ft_sim.campaign.one_run`, as a worker runs them), each timed in CPU
seconds of this process, start-up and the run's own draws included; the total adds the
CPU of the worker process the runs' controllers share (their plans). Writes
`<out>/campaign_scaling.md` and `.json`.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from ft_sim.campaign import design_of, one_run, tasks
from ft_sim.scenario import stop_planner

sys.path.insert(0, str(Path(__file__).resolve().parent))
from engine_cycle import machine, report

BIN = Path(sys.executable).parent
#: The realistic plant of the campaign in docs/campaign.md (`ScenarioConfig` fields).
PLANT = {"plant": "kinematic", "command_latency": 0.02, "response_time": 0.03,
         "hold_last_command": True}
#: The same, as `ft-campaign` options.
PLANT_OPTIONS = ["--latency", str(PLANT["command_latency"]), "--response-time",
                 str(PLANT["response_time"]), "--hold-last-command"]


def campaign(out: Path, runs: int, *where: str) -> tuple[float, float]:
    """One `ft-campaign` into `out`: its wall time (s) and its own throughput (runs per hour).

    The throughput is the campaign's report: from the first run handed out to the last
    result (the workers' start-up included, the design and its boxes, traced once
    before, not). Raises if it fails.
    """
    started = time.monotonic()
    # One BLAS thread in every case, as the pool's workers have (`batch`): the same work.
    subprocess.run([str(BIN / "ft-campaign"), "--runs", str(runs), "--modes", "blend",
                    *PLANT_OPTIONS, "--out", str(out), *where], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    wall = time.monotonic() - started
    reported = re.search(r"([0-9]+) runs per hour", (out / "campaign.md").read_text())
    if reported is None:
        raise RuntimeError(f"no throughput in {out / 'campaign.md'}")
    return wall, float(reported.group(1))


def on_cluster(out: Path, runs: int, scratch: Path) -> tuple[float, float]:
    """`campaign` on a local Dask cluster of two worker processes, as a user starts one."""
    address_file = scratch / "scheduler.json"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False",
           "OPENBLAS_NUM_THREADS": "1"}
    scheduler = subprocess.Popen([str(BIN / "dask"), "scheduler", "--port", "0",
                                  "--no-dashboard", "--scheduler-file", str(address_file)],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    worker = None
    try:
        deadline = time.monotonic() + 60.0
        while not address_file.exists():
            if time.monotonic() > deadline:
                raise TimeoutError("the Dask scheduler did not start within 60 s")
            time.sleep(0.2)
        time.sleep(0.5)  # the file is complete
        address = json.loads(address_file.read_text())["address"]
        worker = subprocess.Popen([str(BIN / "dask"), "worker", address, "--nworkers", "2",
                                   "--nthreads", "1", "--no-dashboard"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
        time.sleep(5.0)  # the workers join
        return campaign(out, runs, "--cluster", address)
    finally:
        for process in (worker, scheduler):
            if process is not None:
                process.terminate()
                process.wait(timeout=30)


def _compute(_: int) -> float:
    """A second or so of small SVDs and Python arithmetic: a campaign run's kind of work."""
    matrix, total = np.random.default_rng(0).normal(size=(7, 7)), 0.0
    for _ in range(30000):
        total += float(np.linalg.svd(matrix, compute_uv=False)[0]) + sum(range(30))
    return total


def compute_scaling(jobs: int = 8) -> float:
    """Throughput of 2 processes over 1 on `jobs` equal compute jobs (one BLAS thread)."""
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    seconds = []
    for workers in (1, 2):
        started = time.monotonic()
        with ProcessPoolExecutor(workers) as pool:
            list(pool.map(_compute, range(jobs)))
        seconds.append(time.monotonic() - started)
    return seconds[0] / seconds[1]


def cpu_per_run(runs: int, first_domain: int) -> tuple[list[dict], float]:
    """Each run of the small campaign, run here in turn: its CPU and wall seconds.

    Also the CPU seconds of all of them, the controllers' shared worker process
    (`ft_sim.scenario.planner`) included.
    """
    design = design_of("panda", "", "", PLANT)
    measured = []
    started, children = time.process_time(), _children_cpu()
    for task in tasks(runs, ("blend",), first_domain, design):
        cpu, wall = time.process_time(), time.monotonic()
        result = one_run(task)
        measured.append({"run": task.name, "success": result["success"],
                         "wall_s": time.monotonic() - wall, "cpu_s": time.process_time() - cpu})
    stop_planner()
    return measured, time.process_time() - started + _children_cpu() - children


def _children_cpu() -> float:
    """User and system CPU seconds of this process's children that ended."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    """Measure the three ways and the CPU of each run; write the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=4, help="seeds (2 runs each)")
    parser.add_argument("--out", type=Path, default=Path("bench_out"))
    args = parser.parse_args()
    runs = 2 * args.runs
    with tempfile.TemporaryDirectory(prefix="ft_campaign_scaling_") as scratch:
        root = Path(scratch)
        measured = {"1 worker": campaign(root / "one", args.runs, "--workers", "1"),
                    "2 workers": campaign(root / "two", args.runs, "--workers", "2"),
                    "Dask cluster, 2 workers": on_cluster(root / "cluster", args.runs, root)}
    seconds = {name: wall for name, (wall, _) in measured.items()}
    per_hour = {name: 3600 * runs / s for name, s in seconds.items()}
    running = {name: rate for name, (_, rate) in measured.items()}
    ceiling = compute_scaling()
    costs, total = cpu_per_run(args.runs, int(os.environ.get("ROS_DOMAIN_ID", "0")) + 1)
    lines = [f"{runs} campaign runs (blend, with and without soft limits, realistic plant), "
             f"{machine()['cores']} cores", "",
             "| where | wall time (s) | runs per hour, whole command / speed-up | runs per "
             "hour while running / speed-up |",
             "|---|---:|---:|---:|"]
    lines += [f"| {name} | {seconds[name]:.1f} | {per_hour[name]:.0f} / "
              f"{per_hour[name] / per_hour['1 worker']:.2f} | {running[name]:.0f} / "
              f"{running[name] / running['1 worker']:.2f} |" for name in seconds]
    lines += ["", "While running: the campaign's own figure, from the first run handed out to "
              "the last result (the design, traced once before, is not in it)."]
    lines += ["", f"Plain compute in 2 processes against 1 on this machine: {ceiling:.2f} x "
              "(the ceiling of the speed-up).", "",
              "| run | succeeded | CPU (s) | wall (s) |", "|---|---|---:|---:|"]
    lines += [f"| {c['run']} | {'yes' if c['success'] else 'no'} | {c['cpu_s']:.2f} | "
              f"{c['wall_s']:.2f} |" for c in costs]
    lines += ["", f"{len(costs)} runs one after the other in one process: {total:.1f} s of "
              f"CPU with the controllers' shared worker process, {total / len(costs):.2f} s "
              "per run."]
    report(args.out, "campaign_scaling", lines,
           {"machine": machine(), "runs": runs, "seconds": seconds, "per_hour": per_hour,
            "running_per_hour": running, "compute_scaling": ceiling, "runs_here": costs,
            "cpu_s_here": total})


if __name__ == "__main__":
    main()
