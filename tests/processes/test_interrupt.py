"""Ctrl-C as a terminal sends it: SIGINT to the whole process group (issue 32).

Worker processes get it as well as their parent. Each must end quietly: no
KeyboardInterrupt traceback from a worker, the parent saying what it stopped.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

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
