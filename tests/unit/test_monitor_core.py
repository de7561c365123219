"""ft_core.monitor: the monitor's logic without ROS, in closed loop with ft_core.plant."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from ft_core import locked_set, remap, robots
from ft_core.detection import DetectorConfig
from ft_core.monitor import Monitor, MonitorConfig
from ft_core.plant import Plant, PlantConfig

PANDA = robots.load("panda")
START = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
DT = 0.004


class Loop:
    """A Monitor between a commander and the sim's plant, stepped at 250 Hz.

    Its commands are the filter's own, unsmoothed unless `config` says otherwise
    (the smoother: test_smoothing.py).
    """

    def __init__(self, store: Path | None, config: MonitorConfig | None = None):
        self.problems: dict[str, str | None] = {}
        self.monitor = Monitor(PANDA, DetectorConfig(), config or MonitorConfig(limits=None), store,
                               self.report)
        self.plant = Plant(PANDA.lower, PANDA.upper, PANDA.velocity_limits, START,
                           PlantConfig(latency=0.01, response_time=0.02))
        self.t = 0.0

    def report(self, name: str, problem: str | None, warning: bool = False) -> None:
        self.problems[name] = problem

    def step(self, qd: np.ndarray):
        """Command `qd`, let the plant run one period, show the monitor the result."""
        sent = self.monitor.command(qd, self.t)
        self.plant.command(self.t, sent)
        self.t += DT
        self.plant.step(self.t)
        q = self.plant.q + np.random.default_rng(round(self.t / DT)).normal(0, 1e-4, 7)
        return sent, self.monitor.observe(q, self.t)


def test_a_lock_is_announced_once_it_is_on_disk(tmp_path: Path) -> None:
    store = tmp_path / "monitor--panda.json"
    lp = Loop(store)
    for _ in range(500):  # 2 s of healthy motion: identification, nothing decided
        _, change = lp.step(np.full(7, 0.2))
        assert not change.changed
    lp.plant.lock(3)
    for _ in range(100):
        lp.step(np.full(7, 0.2))
        if lp.monitor.locked:
            break
    assert list(lp.monitor.locked) == ["panda_joint4"], "the lock was not found within 0.4 s"
    change = lp.monitor.flush(5.0)
    assert change.changed, "the lock was never handed over"
    assert change.events and change.events[0].startswith("joint panda_joint4 locked at")
    assert lp.monitor.announced == lp.monitor.locked
    assert locked_set.load(store, "panda", list(PANDA.joint_names)) == pytest.approx(
        lp.monitor.locked)
    assert lp.problems["state_directory"] is None
    # From now on the locked joint gets exactly 0, the rest are remapped (test_remap.py).
    qd = np.full(7, 0.1)
    sent = lp.monitor.command(qd, lp.t)
    assert sent[3] == 0.0
    np.testing.assert_array_equal(
        sent, remap.remap(PANDA, lp.monitor.q, qd, [3], PANDA.velocity_limits))



@pytest.mark.parametrize("bounded", [True, False], ids=["bounded", "without bounds"])
def test_the_remap_brings_a_healthy_joint_to_rest_at_its_position_limit(
        bounded: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Behind a commander that knows nothing of a lock, a healthy joint reaches its limit.

    panda_joint3 locked and commanded 0.8 rad/s on its own: the healthy joints make up
    for it and panda_joint1 turns to its upper limit. The remap's commands keep it within
    the speeds from which it stops there (`Monitor._position_bounds`): it arrives at
    rest and is commanded (nearly) 0 there. Without those bounds (the remap as it was) it
    runs into the limit at full speed and is still commanded into it.
    """
    if not bounded:
        unbounded = remap.remap
        monkeypatch.setattr(remap, "remap", lambda *args, bounds=None, **kwargs: unbounded(
            *args, **kwargs))
    lp = Loop(None, MonitorConfig())
    lp.step(np.zeros(7))
    lp.monitor.declare([2], lp.t)
    qd, arrival = np.array([0.0, 0.0, 0.8, 0.0, 0.0, 0.0, 0.0]), None
    before = lp.plant.q.copy()
    for _ in range(round(5.0 / DT)):
        sent, _ = lp.step(qd)
        if arrival is None and PANDA.upper[0] - lp.plant.q[0] < 1e-3:
            arrival = (lp.plant.q[0] - before[0]) / DT
        before = lp.plant.q.copy()
    assert arrival is not None, "panda_joint1 never reached its limit"
    assert list(lp.monitor.locked) == ["panda_joint3"]
    if bounded:
        assert arrival < 0.1, f"arrived at {arrival:.3f} rad/s"
        assert sent[0] < 0.01  # the measurement's noise: 1e-4 rad
    else:
        assert arrival > 0.3 and sent[0] > 0.5


def test_without_remapping_locked_joints_are_only_zeroed_and_all_is_scaled(tmp_path) -> None:
    lp = Loop(None, MonitorConfig(remap_commands=False, velocity_scale=0.5, limits=None))
    lp.monitor.declare([0], 0.0)
    qd = PANDA.velocity_limits.copy()  # twice what the scale allows
    sent = lp.monitor.command(qd, 0.0)
    assert sent[0] == 0.0
    np.testing.assert_allclose(sent[1:], 0.5 * qd[1:])
    assert not np.any(lp.monitor.command(np.full(7, np.nan), 0.0))


@pytest.mark.parametrize("scale", [0.0, -0.5, 1.5, math.nan])
def test_a_velocity_scale_outside_0_1_is_refused(scale: float) -> None:
    """Commands are scaled into the scale times the URDF limits: 0 would divide by zero."""
    with pytest.raises(ValueError, match="velocity_scale"):
        MonitorConfig(velocity_scale=scale)
    assert MonitorConfig(velocity_scale=0.01).velocity_scale == 0.01


def test_declare_restore_and_reset_go_through_the_file(tmp_path: Path) -> None:
    store = tmp_path / "monitor--panda.json"
    first = Loop(store)
    first.monitor.declare([1, 4], 1.0)
    change = first.monitor.flush(5.0)
    assert change.changed and change.events == ["joint panda_joint2 declared locked",
                                                "joint panda_joint5 declared locked"]
    assert not first.monitor.declare([1], 2.0).changed  # already locked
    assert set(locked_set.load(store, "panda", list(PANDA.joint_names))) == {
        "panda_joint2", "panda_joint5"}
    # Declared before any joint state: the position is unknown until one arrives.
    assert all(math.isnan(p) for p in first.monitor.locked.values())
    second = Loop(store)
    restored = second.monitor.restore(0.0)
    assert restored.changed and "panda_joint2" in restored.events[0]
    second.monitor.observe(START, 0.1)  # the unknown positions, filled in
    assert second.monitor.flush(5.0).changed
    assert second.monitor.announced == {"panda_joint2": START[1], "panda_joint5": START[4]}
    assert second.monitor.reset(0.2) == ["panda_joint2", "panda_joint5"]
    assert second.monitor.flush(5.0).changed and second.monitor.announced == {}
    assert locked_set.load(store, "panda", list(PANDA.joint_names)) == {}


def test_the_command_path_never_waits_for_the_disk(tmp_path: Path, monkeypatch) -> None:
    """Issue 29: the soak saw an fsync under load hold the commands for 4.4 s.

    With the write held up, a declared lock zeroes its joint at once and is not
    announced; once written, it is.
    """
    written = threading.Event()
    monkeypatch.setattr(locked_set, "save", lambda *args: written.wait(10.0) and None)
    lp = Loop(tmp_path / "monitor--panda.json")
    lp.monitor.observe(START, 0.0)
    assert not lp.monitor.declare([2], 0.1).changed  # returns at once, nothing written
    assert lp.monitor.command(np.full(7, 0.1), 0.1)[2] == 0.0
    assert lp.monitor.announced == {} and not lp.monitor.settled().changed
    assert lp.monitor.writing  # what a lock-step clock waits for (ft_sim.scenario)
    written.set()
    change = lp.monitor.flush(5.0)
    assert not lp.monitor.writing
    assert change.changed and change.events == ["joint panda_joint3 declared locked"]
    assert list(lp.monitor.announced) == ["panda_joint3"]
    assert not lp.monitor.close().changed  # nothing left to write


def test_a_suspect_is_decided_by_the_detectors_evidence() -> None:
    lp = Loop(None)
    answer, change = lp.monitor.suspect(2, 0.0)
    assert answer.decision == "refused" and not change.changed  # no joint state yet
    for _ in range(500):
        lp.step(np.full(7, 0.2))
    answer, change = lp.monitor.suspect(2, lp.t)  # joint 3 follows its command
    assert answer.decision == "refused" and not change.changed
    assert answer.evidence.following
    report = lp.monitor.joint_report(2)
    assert report.state == "ok" and report.evidence.following


def test_an_unwritable_state_directory_is_reported_and_the_lock_still_holds(tmp_path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    lp = Loop(blocker / "monitor--panda.json")  # a directory that cannot be made
    lp.monitor.declare([6], 0.0)
    change = lp.monitor.flush(5.0)
    assert change.changed and list(lp.monitor.locked) == ["panda_joint7"]
    assert lp.problems["state_directory"].startswith("cannot keep the locked set")
    assert lp.monitor.joint_report(6).state == "locked"


def test_the_state_file_is_keyed_by_namespace_robot_and_domain(tmp_path: Path) -> None:
    paths = {locked_set.path_for(tmp_path, node, robot, domain)
             for node in ("/monitor", "/arm1/monitor") for robot in ("panda", "iiwa")
             for domain in (0, 7)}
    assert len(paths) == 8 and all(p.parent == tmp_path for p in paths)
    assert locked_set.path_for(tmp_path, "/arm1/monitor", "panda", 7).name == (
        "arm1__monitor--panda--domain7.state")
    assert locked_set.path_for("", "/monitor", "panda", 0).parent == (
        locked_set.default_directory())


JOINTS = list(PANDA.joint_names)


def test_a_change_is_one_write_in_place_and_a_torn_one_leaves_the_set_before(
        tmp_path: Path, monkeypatch) -> None:
    """Two slots with a generation and a CRC each: the newest intact copy is read.

    Once the file exists, a change costs one pwrite and one fdatasync: no fsync, no
    rename, no new file. A crash in the middle of a write (the slot half written) leaves
    the previous set.
    """
    store = tmp_path / "monitor--panda--domain0.state"
    locked_set.save(store, "panda", {"panda_joint2": 0.5})  # created whole
    assert store.stat().st_size == 2 * locked_set.SLOT_BYTES
    calls: list[str] = []
    real_pwrite, real_fdatasync = os.pwrite, os.fdatasync
    monkeypatch.setattr(os, "fsync", lambda _fd: calls.append("fsync"))
    monkeypatch.setattr(os, "replace", lambda *_: calls.append("replace"))
    monkeypatch.setattr(os, "pwrite", lambda *a: calls.append("pwrite") or real_pwrite(*a))
    monkeypatch.setattr(os, "fdatasync", lambda fd: calls.append("fdatasync")
                        or real_fdatasync(fd))
    inode = store.stat().st_ino
    for k, name in enumerate(["panda_joint3", "panda_joint5"]):
        before = locked_set.load(store, "panda", JOINTS)
        locked_set.save(store, "panda", {**before, name: 0.1 * k})
        assert calls == ["pwrite", "fdatasync"] and store.stat().st_ino == inode
        calls.clear()
    assert locked_set.load(store, "panda", JOINTS) == {
        "panda_joint2": 0.5, "panda_joint3": 0.0, "panda_joint5": pytest.approx(0.1)}
    # Generations 1, 2, 3 went to slots B, A, B: generation 3, torn mid-payload, is
    # skipped for generation 2 in slot A.
    data = bytearray(store.read_bytes())
    data[locked_set.SLOT_BYTES + 40:] = bytes(len(data) - locked_set.SLOT_BYTES - 40)
    store.write_bytes(bytes(data))
    assert locked_set.load(store, "panda", JOINTS) == {"panda_joint2": 0.5,
                                                       "panda_joint3": 0.0}
    locked_set.save(store, "panda", {})  # the torn slot is the older: written over
    assert locked_set.load(store, "panda", JOINTS) == {}
    store.write_bytes(locked_set.MAGIC.ljust(2 * locked_set.SLOT_BYTES, b"\0"))
    with pytest.raises(locked_set.LockedSetError, match="no intact copy"):
        locked_set.load(store, "panda", JOINTS)


def gated_save(monkeypatch) -> threading.Event:
    """`locked_set.save` waits for the event, then writes: a disk as slow as a test needs."""
    gate, save = threading.Event(), locked_set.save
    monkeypatch.setattr(locked_set, "save", lambda *args: gate.wait(10.0) and save(*args))
    return gate


def test_a_lock_on_disk_but_not_yet_announced_is_restored_after_a_crash(
        tmp_path: Path, monkeypatch) -> None:
    """Persist, then announce: a crash in between loses nothing, a restart restores it."""
    store = tmp_path / "monitor--panda--domain0.state"
    first = Loop(store)
    gate = gated_save(monkeypatch)
    assert not first.monitor.restore(0.0).changed  # the empty file, made at the start
    first.monitor.observe(START, 0.0)
    assert not first.monitor.declare([3], 0.1).changed
    gate.set()
    deadline = time.monotonic() + 5.0
    while first.monitor.writing and time.monotonic() < deadline:
        time.sleep(0.001)
    assert not first.monitor.writing and first.monitor.announced == {}  # the crash: now
    second = Loop(store)
    restored = second.monitor.restore(0.0)
    assert restored.changed and second.monitor.announced == {"panda_joint4": START[3]}


def test_the_writer_says_when_a_set_is_on_disk_so_it_is_announced_then(
        tmp_path: Path, monkeypatch) -> None:
    """`written` is called in the writer's thread as each write ends: what wakes the node.

    The caller serialises the hand-overs (as the node does): a write may end before
    `declare` has returned.
    """
    handed: list[list[str]] = []
    ready, turns = threading.Event(), threading.Lock()
    monitor: list[Monitor] = []

    def written() -> None:
        with turns:
            change = monitor[0].settled()
        if change.changed:
            handed.append(list(monitor[0].announced))
            ready.set()

    monitor.append(Monitor(PANDA, DetectorConfig(), MonitorConfig(),
                           tmp_path / "monitor--panda--domain0.state", written=written))
    gate = gated_save(monkeypatch)
    with turns:
        assert not monitor[0].declare([5], 0.0).changed
    gate.set()
    assert ready.wait(5.0) and handed == [["panda_joint6"]]
    assert not monitor[0].writing and not monitor[0].close().changed


def test_an_older_versions_json_file_is_restored_and_migrated(tmp_path: Path) -> None:
    store = locked_set.path_for(tmp_path, "/monitor", "panda", 0)
    legacy = locked_set.legacy_path(store)
    assert legacy.name == "monitor--panda--domain0.json"
    legacy.write_text(json.dumps({"robot": "panda", "locked": {"panda_joint6": 1.25}},
                                 indent=1))
    lp = Loop(store)
    restored = lp.monitor.restore(0.0)
    assert restored.changed and lp.monitor.announced == {"panda_joint6": 1.25}
    lp.monitor.flush(5.0)
    assert not legacy.exists() and store.read_bytes().startswith(locked_set.MAGIC)
    assert locked_set.load(store, "panda", JOINTS) == {"panda_joint6": 1.25}
    assert Loop(store).monitor.restore(0.0).events == restored.events


def test_a_hostile_state_file_is_refused_at_start_without_a_crash_or_a_hang(
        tmp_path: Path) -> None:
    """Issue 31 item 10: deeply nested JSON crashed the monitor at start, a FIFO hung it."""
    import os

    deep = tmp_path / "deep.json"
    deep.write_text("[" * 30_000 + "]" * 30_000)  # within the size bound
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    outcomes: list[str | None] = []

    def start() -> None:
        for store in (deep, fifo):
            lp = Loop(store)
            change = lp.monitor.restore(0.0)
            assert not change.changed and lp.monitor.locked == {}
            outcomes.append(lp.problems.get("state_directory"))

    worker = threading.Thread(target=start, daemon=True)
    worker.start()
    worker.join(timeout=30)
    if worker.is_alive():  # unblock the reader of the FIFO, then fail
        with open(fifo, "w"):
            pass
    assert not worker.is_alive(), f"restoring hung: {outcomes}"
    assert outcomes[0] is not None and "nested too deep" in outcomes[0]
    assert outcomes[1] is not None and "not a regular file" in outcomes[1]


def test_joints_not_commanded_for_a_while_are_named_unseen() -> None:
    """Issue 32: a lock injected on an idle joint is never reported; the monitor says why.

    Joints 1-6 move, joint 7 is never commanded: after 5 s it is unseen, the others are
    not; once it is commanded it is seen again; a locked joint is never listed.
    """
    lp = Loop(None)
    command = np.r_[np.full(6, 0.2), 0.0]
    for k in range(round(6.0 / DT)):
        lp.step(command * (1 if (k // 250) % 2 else -1))  # to and fro, 1 s each way
        if k == round(4.0 / DT):
            assert lp.monitor.unseen(lp.t) == []  # 4 s: not yet
    assert lp.monitor.unseen(lp.t) == ["panda_joint7"]
    assert lp.monitor.unseen(lp.t, after=10.0) == []
    for _ in range(round(0.5 / DT)):
        lp.step(np.full(7, 0.2))
    assert lp.monitor.unseen(lp.t) == []
    lp.monitor.declare([0], lp.t)
    assert lp.monitor.unseen(lp.t + 10.0) == [f"panda_joint{j}" for j in range(2, 8)]


def test_a_new_monitor_has_loaded_the_detectors_compiled_code() -> None:
    """The detector's compiled functions are loaded when the core is built, not in a callback.

    In a fresh interpreter, so that nothing else loaded them: loaded lazily, one by one as
    the detector first needed each, they held the monitor's joint-state and command
    callbacks for 5-20 ms of CPU each during its first seconds (0.4 s in all), and on a
    busy machine the controller's guard of a dead monitor fired on a live one.
    """
    kernels = ("_ingest", "_add_command", "_accumulate", "_window_fit", "_classify",
               "_largest_step")
    code = ("from ft_core import detection, robots\n"
            "from ft_core.monitor import Monitor, MonitorConfig\n"
            "Monitor(robots.load('panda'), detection.DetectorConfig(), MonitorConfig(), None)\n"
            f"print(*[len(getattr(detection, k).signatures) for k in {kernels!r}])\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert len(out.split()) == len(kernels), out
    assert all(int(count) >= 1 for count in out.split()), dict(zip(kernels, out.split(),
                                                                  strict=True))
