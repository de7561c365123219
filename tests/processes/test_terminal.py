"""What a user sees in a terminal: start-up logs and Ctrl-C (issue 32).

Waiting for a model is no fault: INFO, not ERROR. Ctrl-C sends SIGINT to the whole
process group, worker processes as well as their parent. Each must end quietly: no
KeyboardInterrupt traceback from a worker, the parent saying what it stopped.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from rosutil import fresh_domain

BIN = Path(sys.executable).parent


def interrupted(argv: list[str], started: str, log: Path, timeout: float = 60.0) -> int:
    """`argv`'s exit code after Ctrl-C, once `started` is in its output.

    It runs in a process group of its own, and the whole group gets SIGINT.
    """
    env = {**os.environ, "ROS_DOMAIN_ID": str(fresh_domain()),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    with open(log, "w") as out:
        # SIGINT as a terminal's foreground job has it (a background shell job ignores it).
        process = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, env=env,
                                   cwd=log.parent, start_new_session=True,
                                   preexec_fn=lambda: signal.signal(signal.SIGINT,
                                                                    signal.SIG_DFL))
    try:
        end = time.monotonic() + timeout
        while started not in log.read_text():
            assert process.poll() is None, f"ended before {started!r}: {log.read_text()}"
            assert time.monotonic() < end, f"no {started!r} within {timeout} s"
            time.sleep(0.1)
        time.sleep(1.0)  # the workers at work
        os.killpg(process.pid, signal.SIGINT)
        return process.wait(timeout=30)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def test_ctrl_c_stops_the_controller_and_its_worker_quietly(tmp_path: Path) -> None:
    log = tmp_path / "controller.log"
    code = interrupted([str(BIN / "ft-controller"), "--ros-args", "-p", "robot_model:=panda",
                        "-p", "critical_points:=[0.5, 0.1, 0.4]"],
                       "model from robot_model", log)
    text = log.read_text()
    assert code == 0, text
    assert "Traceback" not in text and "KeyboardInterrupt" not in text, text


def test_ctrl_c_stops_a_campaign_and_says_what_is_kept(tmp_path: Path) -> None:
    log = tmp_path / "campaign.log"
    code = interrupted([str(BIN / "ft-campaign"), "--runs", "1", "--modes", "blend",
                        "--workers", "2", "--first-domain", str(fresh_domain()),
                        "--out", str(tmp_path / "out")], "[sim]: simulating", log)
    text = log.read_text()
    assert code == 130, text
    assert "ft-campaign: interrupted; " in text and "(the same command resumes)" in text, text
    assert "Traceback" not in text and "KeyboardInterrupt" not in text, text


@pytest.mark.parametrize("executable", ["ft-controller", "ft-monitor", "ft-sim"])
def test_a_node_waiting_for_its_model_says_so_at_info(executable: str, tmp_path: Path) -> None:
    log = tmp_path / "node.log"
    code = interrupted([str(BIN / executable), "--ros-args", "-p",
                        f"state_directory:={tmp_path / 'state'}"],
                       "waiting for the 'robot_description' topic", log)
    text = log.read_text()
    assert code == 0, text
    (line,) = [line for line in text.splitlines() if "robot_description" in line]
    assert line.startswith("[INFO]"), text
    assert "[ERROR]" not in text and "Traceback" not in text, text


def test_the_monitor_says_which_locks_it_cannot_see_on_an_idle_arm(tmp_path: Path) -> None:
    """A lock injected on an arm that stands still is not reported: the log says why."""
    env = {**os.environ, "ROS_DOMAIN_ID": str(fresh_domain()),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    log = tmp_path / "monitor.log"
    common = ["--ros-args", "-p", "robot_model:=panda"]
    with open(log, "w") as out:
        processes = [subprocess.Popen([str(BIN / "ft-sim"), *common], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL),
                     subprocess.Popen([str(BIN / "ft-monitor"), *common, "-p",
                                       f"state_directory:={tmp_path / 'state'}"], env=env,
                                      stdout=out, stderr=subprocess.STDOUT)]
    try:
        end = time.monotonic() + 60.0
        while "cannot be seen now" not in log.read_text():
            assert time.monotonic() < end, f"nothing said within 60 s: {log.read_text()}"
            assert all(p.poll() is None for p in processes), log.read_text()
            time.sleep(0.2)
    finally:
        for process in processes:
            process.send_signal(signal.SIGINT)
            process.wait(timeout=30)
    (line,) = [line for line in log.read_text().splitlines() if "cannot be seen now" in line]
    assert line.startswith("[INFO]"), line
    assert str([f"panda_joint{j}" for j in range(1, 8)]) in line, line
