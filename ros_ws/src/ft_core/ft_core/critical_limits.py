"""Soft limits from critical task points, traced in a worker process, taken in the cycle.

The bounding boxes of the self-motion manifolds of the critical points, intersected
(Lewis & Maciejewski 1997 sec. IV; `selfmotion.soft_limits_for_model`), are computed in
the controller's worker process, never in the control cycle: the cycle goes on with the
limits it has and switches to the new ones once they are ready. Points changed while a
computation runs make its result stale: it is dropped, and the newer computation follows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Future

import numpy as np

from ft_core import selfmotion, workers

#: Runs fn(*args) in the worker process.
Submit = Callable[..., Future]


class CriticalPointLimits:
    """The critical points' soft limits: asked for, computed in the background, in force.

    Attributes:
        limits: the box and the traced configurations in force (None: none).
        note: what is in force, for diagnostics: "none", "<k> critical points",
            "computing ...", "none (critical points failed)".
    """

    def __init__(self, submit: Submit, model_source: tuple, report: Callable[..., None],
                 log: Callable[[str], object]):
        """`model_source`: what `robots.load` rebuilds the robot from in the worker.

        `report(name, problem or None)` and `log(message)` say what happens.
        """
        self._submit, self._model_source = submit, model_source
        self._report, self._log = report, log
        self._points: list[float] = []
        self._dirty = False
        self._job: tuple[int, workers.Job] | None = None
        self._generation = 0
        self.limits: selfmotion.SoftLimits | None = None
        self.note = "none"

    def set_points(self, flat: Sequence[float]) -> None:
        """Task points (`selfmotion.targets_from_flat`), traced from the next `update`'s q."""
        self._points = [float(v) for v in flat]
        self._dirty = True

    @property
    def pending(self) -> bool:
        """Whether limits are still to be computed or taken."""
        return self._dirty or self._job is not None

    @property
    def computing(self) -> bool:
        """Whether a computation runs in the worker (its result not back yet)."""
        return self._job is not None and self._job[1].running

    def update(self, q: np.ndarray) -> bool:
        """Take finished limits, start asked-for ones at q (rad); whether `limits` changed."""
        changed = self._job is not None and self._take(*self._job)
        if self._dirty:
            changed = self._start(q) or changed
        return changed

    def _start(self, q: np.ndarray) -> bool:
        self._dirty = False
        flat = self._points
        if not flat:
            self.note = "none"
            self._report("critical points", None)
            self.limits = None
            return True
        self._generation += 1
        self.note = (f"computing soft limits from {len(flat)} values of critical points (the "
                     "previous limits meanwhile)")
        try:
            self._job = (self._generation, workers.Job(self._submit(
                selfmotion.soft_limits_for_model, *self._model_source, flat, q.copy()), 0.0))
        except (AssertionError, RuntimeError, OSError) as error:  # e.g. inside a daemon
            self.note = "none (critical points failed)"
            self._report("critical points", f"cannot start the process that traces the boxes "
                         f"({error}); running without their soft limits")
        return False

    def _take(self, generation: int, job: workers.Job) -> bool:
        state, result = job.poll(0.0)  # no timeout: the boxes take what they take
        if state == workers.JobState.PENDING:
            return False
        self._job = None
        if generation != self._generation:
            return False  # the points changed meanwhile: a newer computation follows
        if state == workers.JobState.FAILED:
            self.note = "none (critical points failed)"
            self._report("critical points", f"{result}; running without their soft limits")
            self.limits = None
            return True
        box, count = result.box, len(result.targets)
        self.note = f"{count} critical points"
        self._report("critical points", None)
        self._log(f"soft limits from {count} critical points: lower "
                  f"{np.round(box[0], 3).tolist()}, upper {np.round(box[1], 3).tolist()}")
        self.limits = result
        return True
