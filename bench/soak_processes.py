"""The soak's processes: the installed executables of a layout, and the CPU they use.

`deployed` starts them from the colcon install space (ros_ws/install) as `ros2 run`
does; `cpu_counters` and `cpu_use` measure the cores used by them, by this process and
by the rest of the machine (Linux /proc).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
INSTALL = REPO / "ros_ws" / "install"
PACKAGES = ("ft_core", "ft_msgs_py", "ft_controller", "ft_monitor", "ft_sim")
#: Per layout: name -> (package, executable) in the install space, started in this order.
LAYOUTS = {
    "separate": {"sim": ("ft_sim", "sim_node"), "monitor": ("ft_monitor", "monitor_node"),
                 "controller": ("ft_controller", "controller_node")},
    "stack": {"sim": ("ft_sim", "sim_node"), "stack": ("ft_sim", "stack")},
}
#: Per plant: the parameters of all three nodes, and the sim's own.
PLANTS: dict[str, dict[str, dict[str, object]]] = {
    "kinematic": {
        "model": {"robot_model": "panda", "task_space": "position"},
        "sim": {"command_latency": 0.03, "response_time": 0.03, "command_timeout": 0.1,
                "position_noise": 0.001},
    },
    "physics": {
        "model": {"robot_model": "panda_inertial", "tip_link": "panda_link8",
                  "task_space": "position"},
        "sim": {"plant": "physics", "command_latency": 0.05, "response_time": 0.05,
                "hold_last_command": True, "position_noise": 0.001},
    },
}


def _argument(value: object) -> str:
    """A parameter value as `-p name:=value` takes it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return "[" + ",".join(_argument(v) for v in value) + "]"
    return str(value)


def _descendants(pid: int) -> list[int]:
    """`pid` and every process it started, and theirs (Linux /proc)."""
    found = [pid]
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            children = (task / "children").read_text().split()
        except OSError:  # the thread ended meanwhile
            continue
        found += [d for child in children for d in _descendants(int(child))]
    return found


def cpu_counters(pids: list[int]) -> dict[str, float]:
    """CPU seconds so far: the whole machine busy, `pids` and theirs, this process, reaped children.

    The machine's busy time is /proc/stat's user, nice, system, irq, softirq and steal.
    """
    tick = os.sysconf("SC_CLK_TCK")
    fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    user, nice, system, _idle, _iowait, irq, softirq, steal = (int(v) for v in fields[:8])
    nodes = 0
    for pid in {d for p in pids for d in _descendants(p)}:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        nodes += int(stat[11]) + int(stat[12])  # utime, stime
    own = os.times()
    return {"machine": (user + nice + system + irq + softirq + steal) / tick,
            "nodes": nodes / tick, "probe": own.user + own.system,
            "reaped": own.children_user + own.children_system}


def cpu_use(start: dict[str, float], end: dict[str, float], seconds: float,
            ) -> dict[str, float]:
    """Mean cores busy between two `cpu_counters`: all, the nodes, the probe, the rest.

    "reaped" is the busy processes of the loaded half (reaped when it ends); "others" is
    what the rest of the machine used meanwhile (other users' work).
    """
    use = {k: (end[k] - start[k]) / seconds for k in start}
    use["others"] = max(0.0, use["machine"] - use["nodes"] - use["probe"] - use["reaped"])
    return use


@contextmanager
def deployed(plant: str, domain: int, log_dir: Path, layout: str,
             ) -> Iterator[dict[str, subprocess.Popen]]:
    """The installed executables of `layout` for `plant` on `domain`; SIGINT (then kill) after.

    Their stdout and stderr go to `<log_dir>/<name>.log`; the monitor keeps its locked set
    in a fresh temporary directory.
    """
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "PYTHONPATH": os.pathsep.join(str(INSTALL / p / "lib" / version / "site-packages")
                                         for p in PACKAGES)}
    log_dir.mkdir(parents=True, exist_ok=True)
    processes: dict[str, subprocess.Popen] = {}
    with tempfile.TemporaryDirectory(prefix="ft_soak_state_") as state:
        values = {"sim": PLANTS[plant]["sim"], "controller": {},
                  "monitor": {"state_directory": state}, "stack": {"state_directory": state}}
        try:
            for name, (package, executable) in LAYOUTS[layout].items():
                script = INSTALL / package / "lib" / package / executable
                if not script.is_file():
                    raise SystemExit(f"{script} is missing: run `make build`")
                parameters = {**PLANTS[plant]["model"], **values[name]}
                arguments = [a for k, v in parameters.items()
                             for a in ("-p", f"{k}:={_argument(v)}")]
                with open(log_dir / f"{name}.log", "w") as log:
                    processes[name] = subprocess.Popen(
                        [sys.executable, str(script), "--ros-args", *arguments],
                        env=env, stdout=log, stderr=subprocess.STDOUT)
            yield processes
        finally:
            for process in processes.values():
                process.send_signal(signal.SIGINT)
            for process in processes.values():
                try:
                    process.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()

