"""Locked-joint detection against an identified model of the plant (docs/detection.md).

**Plant model.** A velocity command u(t) takes effect after a latency L and is
followed through a first-order lag of time constant T (the driver's velocity loop):
T v' = u(t - L) - v, from rest before the first command. Integrating,
the predicted position is P(t) = U(t - L) - T y_T(t - L), with U the integral of the
command and y_T the command filtered by the lag. Chosen over an acceleration limit
because it is linear in the command: one pass over the commands serves every
candidate model exactly, and a lag with the right T also bounds the transient of an
acceleration-limited driver on the small command changes of closed-loop control.

**Identification.** A bank of candidate models on a grid (L in 0..150 ms by 10 ms,
T in {0, 10, 20, 35, 50, 75, 100, 150} ms; a `latency` or `response_time` given in
the config replaces its grid by that one value). At updates (at most every
`IDENTIFY_PERIOD`) in which no joint stalls and the candidates disagree (a changing command), each
model's squared error between the measured and predicted slopes of every moving
joint is added to its score, with exponential forgetting (`memory` s): least
squares over recent windows, shared by all joints. Until `min_excitation` s of
such data have been seen (the prior), every model on the grid is plausible;
afterwards the plausible set is every model whose score is at most twice the
best's, widened by 10 ms of latency below and 20 ms above (transport jitter) and by
one grid step of response time.

**Decision** (per joint, over a sliding `window` of measured positions): the
measured velocity v is the least-squares slope of the positions; each plausible
model's predicted velocity is the slope of its predicted positions at the same
instants. The weakest prediction c (smallest magnitude; 0 when plausible models
disagree in sign) is what the joint must at least have done. The slope's standard
error s comes from the fit's residuals, so noise is measured, not assumed: the
smaller of two estimates that each include the noise, the residuals of a straight
line through the measured positions (inflated by changes of speed) and those of the
measured minus the best model's positions (inflated by model error; before
identification the best model is only a guess). A joint is
- observable when |c| >= `min_command` and |c| >= 2 `confidence` s;
- stalled when observable, v / c < `ratio` and |v - c| > `confidence` s, and (for a
  joint never declared free-swinging) it also lost position: the window's mean offset
  of measured from predicted positions (best model) lies further behind, along c, than
  that of every earlier window of the last window + 2 x (the plausible set's slowest
  settling time), by more than `confidence` standard errors of a difference of two
  window means (sqrt(2 / samples) times the positions' residual scatter). A servo that
  integrates its command into a position reference (as the physics plant's does, and
  most drives' velocity interfaces) pauses after it ran ahead, pushed by the other links'
  reaction torques, until the reference catches up: a stall by velocity, with no
  position lost. A lock loses position from its first instant. Reading taken: the papers
  define a lock as a joint held in place (Lewis & Maciejewski 1997, sec. I; Maciejewski
  et al., sec. 2.2) and say nothing of how to see one; this rule asks that the joint's
  stillness cost the position its command asked for. A joint
  locked while it ran ahead is declared once the loss exceeds the lead (at 0.1 rad/s,
  10 ms per mrad of lead);
- following when observable and v / c >= `following_ratio`;
- stalled at a physical limit, with the command pushing into it: reported, never a lock;
- moving on its own when |v| >= `min_command` and v lies further than
  max(`confidence` s, `min_command`) outside the velocities a healthy joint could show,
  [min(0, p_min), max(0, p_max)] over the plausible predictions p, with no command or
  against it: moving while commanded to stay, or opposite to every plausible
  prediction. Faster than commanded in the commanded direction (a servo's tracking
  error or overshoot) never counts: Maciejewski et al. name a joint that lost its
  torque by motion under gravity that the command does not explain, and a healthy
  servo also runs ahead of its command. When the caller knows the arm's gravity
  (`measure(..., falling=...)`: a function giving the direction gravity accelerates
  each joint, 0 where it hardly can, called only at an update where a joint moves on
  its own by the other tests, since this test can only clear joints), the motion must
  also go that way: a joint gravity cannot move, or
  one moving uphill, is a servo's transient or the links' coupling, not a lost
  torque (without it, the sign test alone stands in for "follows gravity"). Held for
  `persistence` s plus the best plant model's settling time (its latency and 3 response
  times: a servo's overshoot or spring back after a stop dies within it; `persistence`
  alone once |v| exceeds twice the largest plausible prediction of any joint plus that
  noise, faster than any transient of a servo or of the links' coupling, so that a
  joint falling under gravity is named before it reaches its stop) with
  no plant fault, the joint is declared free-swinging, reported
  in `swinging`, never as a lock. A free-swinging joint moving against its command
  passes through a stall, so it may first be declared locked: a locked joint
  (declared, restored or detected) that then moves by itself is taken out of the
  locked set and declared free-swinging. A joint declared locked after that (the brake
  applied) is not reclassified again. Whatever it was declared before, a joint that
  stops (|v| within that noise) while commanded is a lock candidate again: a joint
  once seen swinging can still lock (also one that lost its torque and came to rest,
  which then acts as locked), and should it move on its own again it is taken out of
  the locked set and declared free-swinging again.

**No decision without evidence.** Nothing is decided (and the reason is kept in
`not_observing`) while the command stream has a gap longer than half a window,
for a settling time after it resumes (window + the plausible set's largest latency
+ 3 x its largest response time), while measured positions are too few or have a
gap longer than half a window, until the plant has been seen following commands
for `follow_time` s (at start-up, after a command gap and after a plant fault), or
while the caller says so (`measure(..., blind=reason)`).

**Decision rate.** Every measurement enters the window; the fits and the rules above run
at most every `DECISION_PERIOD` (2.5 ms): at every measurement up to 250 Hz, at every
second one at 500 Hz, at every third at 1 kHz. A lock in a 1 kHz stream is then
declared at most that period later than at every measurement, within the `persistence`
it waits anyway.

**A lock, not a plant fault.** A stalled joint's evidence counts only while at
least one other commanded joint follows the model. When two or more joints stall
and they outnumber those following, the plant as a whole is not following (a
stopped driver, an emergency stop, a lost command path): `plant_fault` says so with
the evidence and no lock is declared; likewise two or more joints moving on their
own that outnumber those following. Two genuine simultaneous locks on a 7-joint
arm are both declared (two stalled, the others following); locks of more joints at
once than keep following are reported as a plant fault, never as locks. A joint
whose lock evidence holds for `persistence` s is declared locked and stays so
until `reset`; a locked joint is no longer examined. Times are seconds on one clock
shared by commands and measurements.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit

#: Candidate latencies (s) and response times (s) of the identified plant model.
LATENCY_GRID = np.round(np.arange(0.0, 0.1501, 0.01), 3)
RESPONSE_TIME_GRID = np.array([0.0, 0.01, 0.02, 0.035, 0.05, 0.075, 0.1, 0.15])
#: Shortest time (s) between two identification updates (each scores every model).
IDENTIFY_PERIOD = 0.01
#: Shortest time (s) between two decisions (`LockDetector.measure`). Every measurement
#: goes into the window, but a 1 kHz stream is judged at every third one and a 500 Hz
#: stream at every second: the window (80 ms by default) moves by 1 ms per measurement
#: at 1 kHz, which changes its fit little, and deciding at each cost a 1 kHz monitor
#: about a third of its CPU. Well short of 250 Hz's 4 ms, so that streams up to that
#: rate, with up to 1.5 ms of jitter, are still judged at every measurement, and not an
#: exact multiple of a common period, so that rounding in the stamps' differences
#: (3 ms coming out as 2.9999 ms) cannot skip one more.
DECISION_PERIOD = 0.0025
#: Widening of the plausible set: latency below and above (s), response-time grid steps.
LATENCY_MARGIN = (0.01, 0.02)
RESPONSE_STEPS = 1
#: s over which a suspect from elsewhere, commanded too slowly for the window's test, is
#: judged (`LockDetector.confirm`): the task-space channel's window, over which it
#: suspected the joint.
SLOW_SPAN = 0.5


@dataclass(frozen=True)
class DetectorConfig:
    """Detector parameters (see the module docstring).

    Attributes:
        window: sliding window (s), > 0.
        min_command: smallest observable predicted velocity (rad/s or m/s), >= 0.
        latency: plant latency (s) if known (fixes the model); None: identified.
        response_time: plant response time (s) if known; None: identified.
        persistence: how long lock evidence must hold before a lock is declared (s).
        ratio: measured over predicted velocity below which a joint looks stalled, in (0, 1).
        following_ratio: measured over predicted velocity from which a joint follows.
        confidence: separation in standard errors (z), > 0.
        min_samples: fewest positions in the window for a decision, >= 3.
        limit_margin: distance to a physical limit counting as "at the limit" (rad).
        follow_time: s the plant must be seen following before decisions.
        memory: s, forgetting time of the identification.
        min_excitation: s of informative data before the identified set replaces the prior.
    """

    window: float = 0.08
    min_command: float = 0.05
    latency: float | None = None
    response_time: float | None = None
    persistence: float = 0.03
    ratio: float = 0.3
    following_ratio: float = 0.7
    confidence: float = 5.0
    min_samples: int = 5
    limit_margin: float = 0.01
    follow_time: float = 0.2
    memory: float = 10.0
    min_excitation: float = 0.5

    def __post_init__(self) -> None:
        checks = {"window": self.window > 0, "min_command": self.min_command >= 0,
                  "persistence": self.persistence >= 0, "ratio": 0 < self.ratio < 1,
                  "following_ratio": self.ratio <= self.following_ratio <= 1,
                  "confidence": self.confidence > 0, "min_samples": self.min_samples >= 3,
                  "limit_margin": self.limit_margin >= 0, "follow_time": self.follow_time >= 0,
                  "memory": self.memory > 0, "min_excitation": self.min_excitation >= 0}
        for name in ("latency", "response_time"):
            value = getattr(self, name)
            checks[name] = value is None or 0 <= value <= 1.0
        for name, ok in checks.items():
            value = getattr(self, name)
            if not ok or (value is not None and not math.isfinite(value)):
                raise ValueError(f"detection {name} = {value} is out of range")

    def grids(self) -> tuple[np.ndarray, np.ndarray]:
        """(latencies, response times) of the candidate models (s)."""
        return (LATENCY_GRID if self.latency is None else np.array([self.latency]),
                RESPONSE_TIME_GRID if self.response_time is None
                else np.array([self.response_time]))


@dataclass
class JointEvidence:
    """What the detector saw of one joint at its last update."""

    observable: bool = False
    following: bool = False
    measured: float = 0.0  #: slope of the measured positions (rad/s)
    commanded: float = 0.0  #: weakest plausible predicted velocity (rad/s)
    standard_error: float = 0.0  #: of the slope (rad/s)
    #: position lost against the best plant model during the window (rad, along the
    #: command; computed only when a never-swinging joint stalls, else 0)
    deficit: float = 0.0
    evidence_since: float | None = None  #: when the current lock evidence started (s)
    at_limit: bool = False  #: stalled at a physical limit
    #: a lock candidate at the last update: stalled beyond the noise, not at a limit, not
    #: moving on its own, no plant fault (whether or not a following joint vouches for the
    #: plant, which the detector's own decision also needs)
    candidate: bool = False
    swing_since: float | None = None  #: when the current free-swing evidence started (s)
    swinging_at: float | None = None  #: time free-swinging was declared (s)
    locked_at: float | None = None  #: time the lock was declared (s)
    position: float = 0.0  #: position when locked (rad)


@dataclass(frozen=True)
class Update:
    """What one measurement decided: joints newly declared locked and free-swinging.

    `released`: those of `swinging` that were declared locked (a swing takes the lock back).
    """

    locked: tuple[int, ...] = ()
    swinging: tuple[int, ...] = ()
    released: tuple[int, ...] = ()


@dataclass(frozen=True)
class Confirmation:
    """The detector's answer to a suspect from elsewhere (the controller's task channel).

    Attributes:
        decision: "locked" (declared now), "known" (already locked) or "refused" (not a
            lock candidate at the last update: following, within the noise, moving on
            its own, or at a limit). A joint declared free-swinging is decided like any
            other: locked if it has stopped while commanded.
        evidence: the joint's evidence at the decision (a copy).
    """

    decision: str
    evidence: JointEvidence


@dataclass(frozen=True)
class PlantEstimate:
    """The identified plant model: best values and the plausible ranges (s)."""

    latency: float
    response_time: float
    latency_range: tuple[float, float]
    response_time_range: tuple[float, float]
    identified: bool  #: False: still the prior (every model on the grid)
    excitation: float  #: s of informative data behind the estimate (with forgetting)


@njit(cache=True, error_model="numpy")
def _slope_error(values: np.ndarray, centred: np.ndarray, slope: np.ndarray,
                 spread: float) -> np.ndarray:
    """Standard error of least-squares slopes from the fit's residuals (per column)."""
    count, n = values.shape
    error = np.empty(n)
    for j in range(n):
        mean = values[:, j].mean()
        total = 0.0
        for s in range(count):
            residual = values[s, j] - mean - centred[s] * slope[j]
            total += residual * residual
        error[j] = np.sqrt(total / (count - 2) / spread)
    return error


@njit(cache=True, error_model="numpy")
def _window_fit(times: np.ndarray, positions: np.ndarray, predicted: np.ndarray,
                predicted_sum: np.ndarray, timed_sum: np.ndarray, base: float,
                models: np.ndarray, best: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares slopes over the window (compiled: one call per joint state).

    Returns the measured slopes (n,), the slopes of the models at indices `models`
    (len(models), n) and the slopes' standard error (n,): the smaller of the residual
    estimates of the measured positions and of the measured minus the best model's.
    A model's slope comes from the window's running sums (`Samples`): the sum over
    samples of (t - mean t) p = sum (t - base) p - (mean t - base) sum p, so it costs
    the models times the joints, not that times the samples.
    """
    count, n = positions.shape
    mean = times.mean()
    centred = times - mean
    spread = centred @ centred
    measured = np.zeros(n)
    best_slope = np.zeros(n)
    for s in range(count):
        c = centred[s] / spread
        for j in range(n):
            measured[j] += c * positions[s, j]
            best_slope[j] += c * predicted[s, best, j]
    shift = mean - base
    slopes = np.empty((models.size, n))
    for i in range(models.size):
        m = models[i]
        for j in range(n):
            slopes[i, j] = (timed_sum[m, j] - shift * predicted_sum[m, j]) / spread
    error = np.minimum(_slope_error(positions, centred, measured, spread),
                       _slope_error(positions - predicted[:, best, :], centred,
                                    measured - best_slope, spread))
    return measured, slopes, error


@njit(cache=True, error_model="numpy")
def _window_offsets(positions: np.ndarray, predicted_sum: np.ndarray,
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Mean over the window of measured minus predicted positions, (models, n) (rad).

    From the window's running sum of predicted positions (`Samples`); also returns the
    window's mean measured positions (n,).
    """
    count, n = positions.shape
    means = np.zeros(n)
    for s in range(count):
        for j in range(n):
            means[j] += positions[s, j]
    means /= count
    out = np.empty(predicted_sum.shape)
    for i in range(predicted_sum.shape[0]):
        for j in range(n):
            out[i, j] = means[j] - predicted_sum[i, j] / count
    return out, means


@njit(cache=True, error_model="numpy")
def _accumulate(predicted_sum: np.ndarray, timed_sum: np.ndarray, times: np.ndarray,
                predicted: np.ndarray, first: int, last: int, base: float,
                sign: float) -> None:
    """Add (sign 1) or take away (-1) entries [first, last) to the running sums.

    `predicted_sum` += p and `timed_sum` += (t - base) p, per model and joint.
    """
    models, n = predicted_sum.shape
    for s in range(first, last):
        weight = times[s] - base
        for i in range(models):
            for j in range(n):
                p = sign * predicted[s, i, j]
                predicted_sum[i, j] += p
                timed_sum[i, j] += weight * p


class _Buffers:
    """Arrays that grow along their first axis: entries [start, end) are in use.

    Old entries are dropped by moving `start`; when `end` reaches the capacity, the
    entries in use move to the front, into arrays twice as large if more than half
    of the capacity is in use. Subclasses name their arrays in `NAMES`.
    """

    NAMES: tuple[str, ...] = ()
    times: np.ndarray
    start: int = 0
    end: int = 0

    def __len__(self) -> int:
        return self.end - self.start

    def make_room_for_one(self) -> None:
        """Room for one more entry at index `end`."""
        if self.end == self.times.size:
            self._make_room()

    def _make_room(self) -> None:
        size = len(self)
        for name in self.NAMES:
            old = getattr(self, name)
            new = (np.zeros((2 * old.shape[0], *old.shape[1:])) if size > old.shape[0] // 2
                   else old)
            # One copy, no temporary: numpy copies overlapping ranges (a move within
            # `old`) correctly, and fresh pages cost time to touch (a growth of the
            # Panda's offsets at 250 Hz: 2-7 ms with a temporary, 1.1 ms without).
            new[:size] = old[self.start:self.end]
            setattr(self, name, new)
        self.start, self.end = 0, size


@njit(cache=True, error_model="numpy")
def _classify(measured: np.ndarray, plausible: np.ndarray, error: np.ndarray,
              latest: np.ndarray, lower: np.ndarray, upper: np.ndarray, unlocked: np.ndarray,
              undeclared: np.ndarray, falling: np.ndarray, gravity_known: bool,
              min_command: float, confidence: float,
              ratio: float, following_ratio: float, limit_margin: float,
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                         np.ndarray, np.ndarray]:
    """Each joint's evidence at one update (the module's Decision rules), compiled.

    Returns (weakest prediction, observable, following, stalled, pushing into a limit,
    lock candidate, moving on its own), per joint.
    """
    n = measured.size
    weakest = np.zeros(n)
    flags = np.zeros((6, n), dtype=np.bool_)
    observable, following, stalled, pushing, candidate, on_its_own = flags
    for j in range(n):
        low, high = plausible[:, j].min(), plausible[:, j].max()
        if low > 0:
            weakest[j] = low
        elif high < 0:
            weakest[j] = high
        c, v, s = weakest[j], measured[j], error[j]
        observable[j] = (unlocked[j] and abs(c) >= min_command
                         and abs(c) >= 2 * confidence * s)
        share = v / c if observable[j] else 0.0
        stalled[j] = observable[j] and share < ratio and abs(v - c) > confidence * s
        pushing[j] = ((c > 0 and latest[j] >= upper[j] - limit_margin)
                      or (c < 0 and latest[j] <= lower[j] + limit_margin))
        following[j] = observable[j] and share >= following_ratio
        # A locked joint should not move at all: its healthy range is [0, 0].
        healthy_low = min(low, 0.0) if unlocked[j] else 0.0
        healthy_high = max(high, 0.0) if unlocked[j] else 0.0
        outside = max(healthy_low - v, v - healthy_high)
        # Faster than commanded in the commanded direction is tracking error or a servo's
        # overshoot, never a joint moving on its own: that needs no command or one against.
        beyond = unlocked[j] and ((v > healthy_high and high >= min_command)
                                  or (v < healthy_low and low <= -min_command))
        noise = max(confidence * s, min_command)
        downhill = not gravity_known or falling[j] * v > 0
        on_its_own[j] = (undeclared[j] and abs(v) >= min_command and outside > noise
                         and not beyond and downhill)
        # A free-swinging joint is not a lock; one declared so before is again a candidate
        # once it stops while commanded.
        candidate[j] = stalled[j] and not pushing[j] and not on_its_own[j] and (
            undeclared[j] or abs(v) <= noise)
    return weakest, observable, following, stalled, pushing, candidate, on_its_own


@njit(cache=True, error_model="numpy")
def _add_command(times: np.ndarray, values: np.ndarray, integrals: np.ndarray,
                 lagged: np.ndarray, rate: np.ndarray, span: tuple[int, int], time: float,
                 velocity: np.ndarray, forget_before: float) -> int:
    """`CommandHistory.append`, compiled: entry `span[1]` from the one before it.

    Its integral and lag states follow entry k - 1's command over the interval
    (none before the first: zeros); then the entries no longer needed for times >=
    `forget_before` are dropped (the one in force then stays). Returns the new start.
    """
    start, k = span
    n = values.shape[1]
    if k > start:
        h = time - times[k - 1]
        for j in range(n):
            integrals[k, j] = integrals[k - 1, j] + h * values[k - 1, j]
        for t in range(rate.size):
            decay = np.exp(-h * rate[t])
            for j in range(n):
                u = values[k - 1, j]
                lagged[k, t, j] = u + (lagged[k - 1, t, j] - u) * decay
    else:
        integrals[k] = 0.0
        lagged[k] = 0.0
    times[k] = time
    values[k] = velocity
    keep = int(np.searchsorted(times[start:k + 1], forget_before, side="right")) - 1
    return start + max(keep, 0)


@njit(cache=True, error_model="numpy")
def _largest_step(times: np.ndarray) -> float:
    """The longest interval between consecutive times (s)."""
    largest = 0.0
    for i in range(1, times.size):
        largest = max(largest, times[i] - times[i - 1])
    return largest


@njit(cache=True, error_model="numpy")
def _predicted_positions(starts: np.ndarray, values: np.ndarray, integrals: np.ndarray,
                         lagged: np.ndarray, start: int, end: int, rate: np.ndarray,
                         response_times: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Predicted displacement since the first command at `times`, (len(times), nT, n) (rad).

    Row i is U(t_i) - T y_T(t_i) for each response time T (`CommandHistory`'s entries
    [start, end)): the plant at rest before the first command. Each t_i is already
    shifted by its latency.
    """
    n, models = values.shape[1], response_times.size
    out = np.empty((times.size, models, n))
    for i in range(times.size):
        k = max(int(np.searchsorted(starts[start:end], times[i], side="right")) - 1, 0) + start
        h = max(times[i] - starts[k], 0.0)
        for t in range(models):
            decay = np.exp(-h * rate[t])
            for j in range(n):
                u = values[k, j]
                following = u + (lagged[k, t, j] - u) * decay
                out[i, t, j] = integrals[k, j] + h * u - response_times[t] * following
    return out


@njit(cache=True, error_model="numpy")
def _ingest(time: float, position: np.ndarray, latencies: np.ndarray,
            history: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                           np.ndarray],
            history_span: tuple[int, int],
            times: np.ndarray, positions: np.ndarray, predicted: np.ndarray,
            predicted_sum: np.ndarray, timed_sum: np.ndarray, span: tuple[int, int],
            base: float, window_start: float,
            offset_times: np.ndarray, offset_values: np.ndarray, offset_means: np.ndarray,
            offset_span: tuple[int, int], keep_from: float) -> tuple[int, int]:
    """One measurement into the window and the window's offsets, compiled (`measure`).

    Stores the measurement at index `span[1]` of the samples with every model's
    prediction (`_predicted_positions`; `history` is the command history's times,
    values, integrals, lags, rates and response times), adds it to the running sums
    (`_accumulate`), drops the samples before `window_start` from the window and the
    sums, stores the window's offsets (`_window_offsets`) at index `offset_span[1]` and
    drops the offsets before `keep_from`. The caller made room at both ends. Returns
    the new starts of the samples and of the offsets.
    """
    starts, values, integrals, lagged, rate, response_times = history
    start, end = span
    prediction = _predicted_positions(starts, values, integrals, lagged, history_span[0],
                                      history_span[1], rate, response_times, time - latencies)
    times[end] = time
    positions[end] = position
    for i in range(latencies.size):
        for t in range(response_times.size):
            predicted[end, i * response_times.size + t] = prediction[i, t]
    _accumulate(predicted_sum, timed_sum, times, predicted, end, end + 1, base, 1.0)
    end += 1
    first = start + int(np.searchsorted(times[start:end], window_start, side="left"))
    _accumulate(predicted_sum, timed_sum, times, predicted, start, first, base, -1.0)
    offsets, means = _window_offsets(positions[first:end], predicted_sum)
    k = offset_span[1]
    offset_times[k] = time
    offset_values[k] = offsets
    offset_means[k] = means
    kept = offset_span[0] + int(np.searchsorted(offset_times[offset_span[0]:k + 1], keep_from,
                                                side="left"))
    return first, kept


class CommandHistory(_Buffers):
    """Piecewise-constant commands, their running integral and their lagged versions.

    Entry k holds the command u_k in force from time s_k, the integral U(s_k) (rad)
    and, for each response time T, the lag's state y_T(s_k) (rad/s).
    """

    NAMES = ("times", "values", "integrals", "lagged")

    def __init__(self, n: int, response_times: np.ndarray, capacity: int = 256):
        self.n, self.response_times = n, np.asarray(response_times, float)
        self.rate = np.where(self.response_times > 0,
                             1.0 / np.maximum(self.response_times, 1e-12), 1e12)
        self.times = np.zeros(capacity)
        self.values = np.zeros((capacity, n))
        self.integrals = np.zeros((capacity, n))
        self.lagged = np.zeros((capacity, self.response_times.size, n))
        self.start = self.end = 0

    @property
    def last_time(self) -> float:
        """Start time (s) of the newest command; -inf before any."""
        return float(self.times[self.end - 1]) if len(self) else -math.inf

    def append(self, time: float, velocity: np.ndarray, forget_before: float) -> None:
        """The command in force from `time` on; earlier than the newest: ignored.

        Then drops the entries no longer needed for times >= `forget_before` (the one in
        force then stays).
        """
        if len(self) and time < self.last_time:
            return
        self.make_room_for_one()
        self.start = _add_command(self.times, self.values, self.integrals, self.lagged,
                                  self.rate, (self.start, self.end), time, velocity,
                                  forget_before)
        self.end += 1


class Samples(_Buffers):
    """The window's measurements: times, positions and every model's predicted positions.

    Contiguous arrays: the per-update fits read views, no copies. Also the running sums
    over the window of each model's predicted positions p and of (t - `base`) p, which
    the fits use (`_window_fit`, `_window_offsets`): kept as entries come and go, and
    summed afresh whenever the entries move to the front of the arrays (every few
    windows), so rounding never accumulates. `base` is the first entry's time then.
    """

    NAMES = ("times", "positions", "predicted")

    def __init__(self, n: int, models: int, capacity: int = 128):
        self.times = np.zeros(capacity)
        self.positions = np.zeros((capacity, n))
        self.predicted = np.zeros((capacity, models, n))
        self.start = self.end = 0
        self.base = 0.0
        self.predicted_sum = np.zeros((models, n))
        self.timed_sum = np.zeros((models, n))

    def make_room_for(self, time: float) -> None:
        """Room for one more entry, at `time`.

        The sums are made afresh when the entries move, and start at `time` (`base`)
        when the window is empty.
        """
        if self.end == self.times.size:
            self._make_room()
            self._sum_afresh()
        if not len(self):
            self.base = time
            self.predicted_sum[:] = self.timed_sum[:] = 0.0

    def _sum_afresh(self) -> None:
        self.base = float(self.times[self.start]) if len(self) else 0.0
        self.predicted_sum[:] = self.timed_sum[:] = 0.0
        _accumulate(self.predicted_sum, self.timed_sum, self.times, self.predicted,
                    self.start, self.end, self.base, 1.0)

    def window(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times, positions, predicted) of the window, as views."""
        return (self.times[self.start:self.end], self.positions[self.start:self.end],
                self.predicted[self.start:self.end])


class Offsets(_Buffers):
    """Per update: every model's window-mean offset, and the window-mean position.

    The offset is measured minus predicted position. Kept for `horizon` s, so that a
    stalled joint's position can be compared with where it stood against the same model
    before the stall (the position-deficit rule), and a slowly commanded suspect's motion
    over that span (`LockDetector.confirm`).
    """

    NAMES = ("times", "values", "means")

    def __init__(self, n: int, models: int, capacity: int = 256):
        self.times = np.zeros(capacity)
        self.values = np.zeros((capacity, models, n))
        self.means = np.zeros((capacity, n))
        self.start = self.end = 0

    def between(self, start: float, end: float) -> np.ndarray:
        """The kept offsets of windows ending in [start, end], (k, models, n)."""
        times = self.times[self.start:self.end]
        first = int(np.searchsorted(times, start, side="left"))
        last = int(np.searchsorted(times, end, side="right"))
        return self.values[self.start + first:self.start + last]


@dataclass
class LockDetector:
    """Streams of commands and measurements in, declared locks out."""

    lower: np.ndarray
    upper: np.ndarray
    config: DetectorConfig = field(default_factory=DetectorConfig)

    def __post_init__(self) -> None:
        self.lower = np.asarray(self.lower, dtype=float)
        self.upper = np.asarray(self.upper, dtype=float)
        self.n = self.lower.size
        self.reset()

    def reset(self) -> None:
        """Forget every lock and all history (after a repair or a new configuration)."""
        self._latencies, self._response_times = self.config.grids()
        self._longest_latency = float(self._latencies.max())
        models = np.array([(lat, rt) for lat in self._latencies for rt in self._response_times])
        self._model_latency, self._model_response = models[:, 0], models[:, 1]
        self.history = CommandHistory(self.n, self._response_times)
        self._samples = Samples(self.n, len(models))
        self._offsets = Offsets(self.n, len(models))
        self._last_identification_try = -math.inf
        self._scores = np.zeros(len(models))
        self._weight = 0.0  # forgetting count of identification updates
        self._excitation = 0.0  # s of informative data, with forgetting
        self._last_identification = -math.inf
        self._resumed_at = -math.inf  # when commands last resumed after a gap (or began)
        self._seen_following = 0.0
        self._last_update = -math.inf
        self._set_plausible(np.ones(len(models), dtype=bool))
        self._all_models = np.arange(len(models))
        self.not_observing: str | None = "no command yet"
        self.plant_fault: str | None = None
        self.joints = [JointEvidence() for _ in range(self.n)]

    def configure(self, config: DetectorConfig) -> None:
        """New parameters; a change of the model grid restarts identification (locks kept)."""
        old = self.config
        self.config = config
        if config.grids()[0].tolist() != old.grids()[0].tolist() or (
                config.grids()[1].tolist() != old.grids()[1].tolist()):
            locked = [(j, e.position, e.locked_at) for j, e in enumerate(self.joints)
                      if e.locked_at is not None]
            self.reset()
            for j, position, time in locked:
                self.lock(j, position, time)

    # ----------------------------------------------------------------- state
    @property
    def latest_time(self) -> float:
        """Time (s) of the newest measurement; -inf before any."""
        samples = self._samples
        return float(samples.times[samples.end - 1]) if len(samples) else -math.inf

    @property
    def locked(self) -> dict[int, float]:
        """{joint index: position at lock} of every locked joint."""
        return {i: e.position for i, e in enumerate(self.joints) if e.locked_at is not None}

    @property
    def swinging(self) -> dict[int, float]:
        """{joint index: time declared} of the joints declared free-swinging (not locked)."""
        return {i: e.swinging_at for i, e in enumerate(self.joints)
                if e.swinging_at is not None and e.locked_at is None}

    def lock(self, joint: int, position: float, time: float) -> None:
        """Mark a joint locked (a failure declared on purpose, or restored from storage)."""
        evidence = self.joints[joint]
        if evidence.locked_at is None:
            evidence.locked_at, evidence.position = time, position

    def fill_unknown_positions(self, position: np.ndarray) -> bool:
        """Give locked joints of unknown position (nan) this measured one; True if any."""
        filled = False
        for j, evidence in enumerate(self.joints):
            if evidence.locked_at is not None and not math.isfinite(evidence.position):
                evidence.position, filled = float(position[j]), True
        return filled

    def estimate(self) -> PlantEstimate:
        """The identified plant model (the prior's ranges until identified)."""
        best = int(np.argmin(self._scores)) if self._weight > 0 else 0
        lat, rt = self._model_latency[self._plausible], self._model_response[self._plausible]
        identified = self._excitation >= self.config.min_excitation and self._weight > 0
        return PlantEstimate(
            latency=float(self._model_latency[best]) if identified else math.nan,
            response_time=float(self._model_response[best]) if identified else math.nan,
            latency_range=(float(lat.min()), float(lat.max())),
            response_time_range=(float(rt.min()), float(rt.max())),
            identified=identified, excitation=self._excitation)

    # ---------------------------------------------------------------- inputs
    def command(self, time: float, velocity: np.ndarray) -> None:
        """The velocity sent to the plant from `time` on (rad/s)."""
        last = self.history.last_time  # -inf before any command
        if time < last:
            return  # out of order: ignored
        if time - last > self.config.window / 2:
            self._resumed_at = time  # the first command, or the first after a gap
            self._seen_following = 0.0
        # Floats and contiguous arrays: the types `compile_ahead` compiled for.
        self.history.append(float(time), np.ascontiguousarray(velocity, dtype=float),
                            time - 2 * self.config.window - self._longest_latency)

    def measure(self, time: float, position: np.ndarray, blind: str | None = None,
                falling: Callable[[], np.ndarray | None] | None = None) -> Update:
        """A measured configuration; the joints it newly declares locked or free-swinging.

        `blind` (a reason) forbids decisions and identification at this update.
        `falling` returns (n,) the sign of the acceleration gravity gives each joint at
        `position` were its torque lost, 0 where it is too weak to move it
        (`ft_core.swing.falling_directions`), or None where the arm's gravity is unknown;
        it is called only when a joint moves on its own by the other tests (gravity's
        test can only clear a joint), so a healthy cycle pays nothing for it.
        """
        if time <= self.latest_time:
            return Update()  # out of order or repeated: ignored
        self._into_window(float(time), np.ascontiguousarray(position, dtype=float))
        if blind is None and time - self._last_update < DECISION_PERIOD:
            return Update()  # in the window; judged at the next decision
        dt = time - self._last_update if math.isfinite(self._last_update) else 0.0
        self._last_update = time
        reason = blind or self._gap_reason(time)
        self.not_observing = reason
        if reason is not None:
            self.plant_fault = None  # no evidence either way
            self._clear_evidence()
            return Update()
        return self._update(time, dt, falling)

    def _into_window(self, time: float, position: np.ndarray) -> None:
        """The measurement into the window, its offsets kept (`_ingest`, compiled)."""
        samples, offsets, history = self._samples, self._offsets, self.history
        samples.make_room_for(time)
        offsets.make_room_for_one()
        samples.start, offsets.start = _ingest(
            time, position, self._latencies,
            (history.times, history.values, history.integrals, history.lagged, history.rate,
             history.response_times), (history.start, history.end),
            samples.times, samples.positions, samples.predicted, samples.predicted_sum,
            samples.timed_sum, (samples.start, samples.end), samples.base,
            time - self.config.window, offsets.times, offsets.values, offsets.means,
            (offsets.start, offsets.end), time - max(self._horizon(), SLOW_SPAN))
        samples.end += 1
        offsets.end += 1

    def confirm(self, joint: int, position: float, time: float) -> Confirmation:
        """Decide on a suspected lock of `joint` (at `position` rad, `time` s) from elsewhere.

        Locked when the joint is a candidate of the detector's own stall test at the
        last update, without the witness of another joint seen following (a suspect
        comes exactly where no such witness exists: the task-space channel of issue 16);
        the noise tests, the joint-limit rule and the plant-fault rule all apply. Or,
        for a joint commanded too slowly for the window's test, when it lost its motion
        over the longer span of the kept window offsets (`_slow_stall`): at the
        equilibrium of Maciejewski et al. Theorem 1 an undetected lock leaves the arm
        short of its goal with the null space commanding the locked joint at a few
        hundredths of a rad/s, below what the window can judge through the noise.
        """
        evidence = self.joints[joint]
        if evidence.locked_at is not None:
            return Confirmation("known", replace(evidence))
        if not evidence.candidate:
            slow = self._slow_stall(joint)
            if slow is None:
                return Confirmation("refused", replace(evidence))
            evidence = slow
        self.lock(joint, position, time)
        return Confirmation("locked", replace(evidence, locked_at=time, position=position))

    def _mean_difference_error(self, slope_error: float | np.ndarray) -> float | np.ndarray:
        """Standard error (rad) of a difference of two window means of positions.

        From the window's slope standard errors (rad/s, a float or per joint): one
        position's scatter is the slope's error times the root of the times' spread,
        and a mean of the window's samples has sqrt(1 / samples) of it, twice over.
        """
        times = self._samples.window()[0]
        centred = times - times.mean()
        return slope_error * math.sqrt(centred @ centred) * math.sqrt(2.0 / times.size)

    def _slow_stall(self, j: int) -> JointEvidence | None:
        """Joint j's evidence over the last `SLOW_SPAN` s if it lost its motion there.

        For a suspect commanded too slowly for the window's test (`confirm`). Over each
        half of the span (window means `SLOW_SPAN` / 2 apart) the best model predicts a
        displacement d = (change of the window-mean position) - (change of its offset).
        Stalled when, in both halves, |d| is at least `confidence` standard errors of a
        difference of two window means and the joint moved less than `ratio` of d
        (along the span's d), and the whole span's |d| at least twice that; not pushing
        into a limit at any time of the span, with decisions allowed and commands flowing
        for the whole span.
        Both halves: a servo that ran ahead and then waits for its reference (a pause
        of 0.1 to 0.2 s on the physics plant) lost nothing over the half that holds its
        lead; a lock loses steadily. The evidence's velocities are the span's (rad/s),
        its deficit the position lost (rad). None: not stalled.
        """
        cfg, offsets = self.config, self._offsets
        now = self.latest_time
        if (self.not_observing is not None or self.plant_fault is not None
                or self._resumed_at + self._settling_time() > now - SLOW_SPAN
                or offsets.times[offsets.start] > now - SLOW_SPAN + self.config.window):
            return None
        times = offsets.times[offsets.start:offsets.end]
        marks = offsets.start + np.searchsorted(
            times, [now - SLOW_SPAN, now - SLOW_SPAN / 2, now], side="left")
        marks[-1] = offsets.end - 1
        best = int(np.argmin(self._scores))
        moved = np.diff(offsets.means[marks, j])
        predicted = moved - np.diff(offsets.values[marks, best, j])
        evidence = self.joints[j]
        sigma = self._mean_difference_error(evidence.standard_error)
        total, along = float(predicted.sum()), math.copysign(1.0, float(predicted.sum()))
        # Pushing into a limit at any time of the span, not only now: a limit that stopped
        # the commanded part of a to-and-fro motion takes it out of the measured motion
        # (the campaign's one false lock). Window means come within `limit_margin` of where
        # the joint touched the limit at most 2 x `limit_margin` away.
        reached = offsets.means[marks[0]:marks[-1] + 1, j]
        latest = float(self._samples.positions[self._samples.end - 1, j])
        pushing = ((total > 0 and max(latest, float(reached.max()))
                    >= self.upper[j] - 2 * cfg.limit_margin)
                   or (total < 0 and min(latest, float(reached.min()))
                       <= self.lower[j] + 2 * cfg.limit_margin))
        lost = (along * predicted >= cfg.confidence * sigma) & (
            along * moved < cfg.ratio * along * predicted)
        if pushing or not lost.all() or abs(total) < 2 * cfg.confidence * sigma:
            return None
        span = float(offsets.times[marks[-1]] - offsets.times[marks[0]])
        return replace(evidence, measured=float(moved.sum()) / span, commanded=total / span,
                       deficit=abs(total) - along * float(moved.sum()), candidate=True)

    # -------------------------------------------------------------- decisions
    def _set_plausible(self, plausible: np.ndarray) -> None:
        """The plausible models (mask and indices), and their longest settling time."""
        self._plausible = plausible
        self._plausible_models = np.flatnonzero(plausible)
        self._slowest = (float(self._model_latency[plausible].max())
                         + 3 * float(self._model_response[plausible].max()))

    def _settling_time(self) -> float:
        return self.config.window + self._slowest

    def _horizon(self) -> float:
        """How long (s) window offsets are kept: the window and twice the slowest settling."""
        return self.config.window + 2 * self._slowest

    def _deficit(self, now: float, weakest: np.ndarray, best: int) -> np.ndarray:
        """How far (rad) each joint fell behind the best model during the window.

        The window's mean offset (measured minus predicted position) against the
        most-behind offset of the windows that ended before this one began, within the
        horizon, counted in the direction of the weakest prediction; +inf with no earlier
        window to compare with. The best model alone: the plausible models' offsets
        differ by their lags times the change of command, which is no loss of position.
        """
        past = self._offsets.between(now - self._horizon(), now - self.config.window)
        if not len(past):
            return np.full(self.n, math.inf)
        direction = -np.sign(weakest)  # behind: measured short of predicted, along c
        current = direction * self._offsets.values[self._offsets.end - 1, best]
        return current - (direction * past[:, best]).max(axis=0)

    def _gap_reason(self, now: float) -> str | None:
        cfg = self.config
        if not len(self.history):
            return "no command yet"
        gap = now - self.history.last_time
        if gap > cfg.window / 2:
            return f"command stream paused for {gap:.3f} s"
        if now < self._resumed_at + self._settling_time():
            return "settling after the command stream (re)started"
        times = self._samples.window()[0]
        if times.size < cfg.min_samples or times[-1] - times[0] < cfg.window / 2:
            return "too few joint states in the window"
        if _largest_step(times) > cfg.window / 2:
            return "joint states arrive with gaps"
        return None

    def _clear_evidence(self) -> None:
        for evidence in self.joints:
            evidence.evidence_since = evidence.swing_since = None

    def _update(self, now: float, dt: float,
                falling: Callable[[], np.ndarray | None] | None) -> Update:
        cfg = self.config
        samples = self._samples
        _times, positions, _predicted = window = samples.window()
        fit = (*window, samples.predicted_sum, samples.timed_sum, samples.base)
        best = int(np.argmin(self._scores))  # always plausible
        # Identification (every model) at most every IDENTIFY_PERIOD; decisions need only
        # the plausible models, far fewer once identified.
        identify = now - self._last_identification_try >= IDENTIFY_PERIOD
        if identify:
            self._last_identification_try = now
            measured, slopes, error = _window_fit(*fit, self._all_models, best)  # (models, n)
            plausible = slopes[self._plausible]
        else:
            measured, plausible, error = _window_fit(*fit, self._plausible_models, best)
        joints = self.joints
        unlocked = np.array([e.locked_at is None for e in joints])
        undeclared = np.array([e.swinging_at is None for e in joints])
        latest = positions[-1]
        evidence_of = (measured, plausible, error, latest, self.lower, self.upper, unlocked,
                       undeclared)
        rules = (cfg.min_command, cfg.confidence, cfg.ratio, cfg.following_ratio,
                 cfg.limit_margin)
        flags = _classify(*evidence_of, np.zeros(self.n), False, *rules)
        directions = falling() if falling is not None and flags[-1].any() else None
        if directions is not None:  # gravity's test only clears joints: now it matters
            flags = _classify(*evidence_of, np.asarray(directions, dtype=float), True, *rules)
        weakest, observable, following, stalled, pushing, candidates, on_its_own = flags
        deficit = np.zeros(self.n)
        if (candidates & undeclared).any():
            # A lock loses position; a servo pausing to catch up after it ran ahead does
            # not. (A joint once seen swinging moved on its own: stopping is its test.)
            deficit = self._deficit(now, weakest, best)
            lost = deficit > cfg.confidence * self._mean_difference_error(error)
            candidates = candidates & (lost | ~undeclared)
        # Python lists from here on: per-joint bookkeeping on numpy scalars costs more
        # than the fits.
        measured_of, weakest_of, error_of = measured.tolist(), weakest.tolist(), error.tolist()
        candidate_of, following_of = candidates.tolist(), following.tolist()
        own_of = on_its_own.tolist()
        for evidence, observes, follows, v, c, s, at_limit, candidate, lost_position in zip(
                joints, observable.tolist(), following_of, measured_of, weakest_of, error_of,
                (stalled & pushing).tolist(), candidate_of, deficit.tolist(), strict=True):
            evidence.observable, evidence.following = observes, follows
            evidence.measured, evidence.commanded, evidence.standard_error = v, c, s
            evidence.at_limit, evidence.candidate = at_limit, candidate
            evidence.deficit = lost_position
        n_stalled, n_following, n_own = sum(candidate_of), sum(following_of), sum(own_of)
        if n_stalled == 0 and n_own == 0 and identify:
            self._identify(now, measured, slopes, error, unlocked & ~pushing)
        odd = candidate_of if n_stalled >= 2 and n_stalled > n_following else (
            own_of if n_own >= 2 and n_own > n_following else None)
        if odd is not None:
            self.plant_fault = "plant not following commands: " + ", ".join(
                f"joint {j} measured {measured_of[j]:.3f} rad/s, expected {weakest_of[j]:.3f}"
                for j, is_odd in enumerate(odd) if is_odd)
            self._seen_following = 0.0
            self._clear_evidence()
            for evidence in joints:
                evidence.candidate = False
            return Update()
        self.plant_fault = None
        if self._seen_following < cfg.follow_time:
            if n_following and not n_stalled:
                self._seen_following += dt
            self.not_observing = "plant not yet seen following commands"
            self._clear_evidence()
            return Update()
        swinging, released = [], []
        for j, evidence in enumerate(joints):
            if not own_of[j]:
                evidence.swing_since = None
            elif evidence.swinging_at is None:
                if evidence.swing_since is None:
                    evidence.swing_since = now
                if now - evidence.swing_since >= cfg.persistence + self._swing_wait(
                        measured_of[j], error_of[j], plausible, best):
                    # A joint declared locked that moves was never locked: it swings.
                    if evidence.locked_at is not None:
                        released.append(j)
                    evidence.swinging_at, evidence.locked_at = now, None
                    swinging.append(j)
        newly = []
        for j, evidence in enumerate(joints):
            supported = candidate_of[j] and n_following - following_of[j] >= 1
            if not supported:
                evidence.evidence_since = None
                continue
            if evidence.evidence_since is None:
                evidence.evidence_since = now
            if now - evidence.evidence_since >= cfg.persistence:
                evidence.locked_at, evidence.position = now, float(latest[j])
                # Seen swinging before: should it move on its own again, it swings again.
                evidence.swinging_at = None
                newly.append(j)
        return Update(tuple(newly), tuple(swinging), tuple(released))

    def _swing_wait(self, measured: float, error: float, plausible: np.ndarray,
                    best: int) -> float:
        """How long (s) motion on its own must last beyond `persistence` to be a swing.

        A transient dies within the plant's (best model's) settling time; motion on its
        own that outlasts it, or outruns it, does not. A servo's transient (overshoot,
        the spring back after a stop, a joint dragged by the others) is no faster than
        twice the largest velocity commanded lately (`plausible`, rad/s): a joint faster
        than that beyond the noise need not wait.
        """
        cfg = self.config
        transient = 2 * float(np.abs(plausible).max(initial=0.0))
        noise = max(cfg.confidence * error, cfg.min_command)
        if abs(measured) > transient + noise:
            return 0.0
        return float(self._model_latency[best] + 3 * self._model_response[best])

    def _identify(self, now: float, measured: np.ndarray, slopes: np.ndarray,
                  error: np.ndarray, usable: np.ndarray) -> None:
        """Least-squares scores of the candidate models from one informative window."""
        cfg = self.config
        moving = usable & (np.max(np.abs(slopes), axis=0) >= cfg.min_command)
        disagreement = np.ptp(slopes, axis=0)
        if not np.any(moving & (disagreement >= np.maximum(0.02, 3 * error))):
            return
        elapsed = now - self._last_identification
        self._last_identification = now
        forget = math.exp(-min(elapsed, 1e3) / cfg.memory)
        step = min(elapsed, cfg.window)
        squared = (measured[moving] - slopes[:, moving]) ** 2
        self._scores = forget * self._scores + squared.sum(axis=1)
        self._weight = forget * self._weight + 1.0
        self._excitation = forget * self._excitation + step
        if self._excitation < cfg.min_excitation:
            return
        best = self._scores.min()
        floor = self._weight * 1e-6 * moving.sum()  # (1 mrad/s)^2 per joint and update
        chosen = self._scores <= 2 * best + floor
        lat, rt = self._model_latency[chosen], self._model_response[chosen]
        grid = self._response_times
        low = grid[max(int(np.searchsorted(grid, rt.min())) - RESPONSE_STEPS, 0)]
        high = grid[min(int(np.searchsorted(grid, rt.max())) + RESPONSE_STEPS, grid.size - 1)]
        self._set_plausible((self._model_latency >= lat.min() - LATENCY_MARGIN[0] - 1e-9)
                            & (self._model_latency <= lat.max() + LATENCY_MARGIN[1] + 1e-9)
                            & (self._model_response >= low) & (self._model_response <= high))


@functools.cache
def compile_ahead() -> None:
    """Run the detector's compiled functions once, so numba compiles (or loads) them now.

    Once per process. `make build` calls it, so that they are compiled and cached on
    disk: otherwise the first monitor to take a joint state compiles them inside that
    callback (about 5 s on 2 cores), with its commands held meanwhile. Every
    `ft_core.monitor.Monitor` calls it on construction, so that they are loaded from
    that cache before its first callback: loaded lazily, one by one as the detector
    first needs each (0.4 s in all), they stalled the monitor's callbacks for 5-20 ms
    of CPU each during its first seconds, and for up to 0.7 s of wall time on a busy
    machine, long enough for the controller's guard of a dead monitor to fire.
    """
    detector = LockDetector(np.full(2, -1.0), np.full(2, 1.0))
    for k in range(300):  # 1.2 s: past the settling time, so that decisions run
        t = 0.004 * k
        detector.command(t, np.full(2, 0.1))
        detector.measure(t + 0.004, np.full(2, 0.0004 * k))
