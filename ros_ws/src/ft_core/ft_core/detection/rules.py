"""The detector's decision rules, one function each (docs/detection.md, "How it decides").

Velocities are rad/s (m/s for prismatic joints), positions rad, times s. Per joint: v is
the measured velocity (the least-squares slope of the window's positions), s its
standard error, c the weakest plausible prediction. The scalar rules are compiled and
called by `classify`, one joint at a time; the others run in Python at an update.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np
from numba import njit

from ft_core.detection.window import _largest_step

#: A float or an array of them (per joint).
Values = TypeVar("Values", float, np.ndarray)


@njit(cache=True, error_model="numpy")
def weakest_prediction(low: float, high: float) -> float:
    """The weakest prediction c from the plausible models' extremes `low` <= `high`.

    The smallest in magnitude when all agree in sign; 0 when they disagree (or one
    predicts no motion): what the joint must at least have done.
    """
    if low > 0:
        return low
    if high < 0:
        return high
    return 0.0


@njit(cache=True, error_model="numpy")
def is_observable(c: float, s: float, unlocked: bool, min_command: float,
                  confidence: float, stalling: bool) -> bool:
    """Observable: not locked, |c| >= `min_command` and |c| >= 2 `confidence` s.

    A joint whose lock evidence is under way (`stalling`) stays observable down to
    |c| >= `confidence` s: a hysteresis. Twice the separation lets a stall and a follow
    be told apart from the start; once the joint is seen stalled, `is_stalled`'s own
    separation (|v - c| > `confidence` s) still applies, and a lock whose arm slows to
    its goal is not left unjudged for want of a margin it no longer needs.
    """
    bar = confidence * s if stalling else 2 * confidence * s
    return unlocked and abs(c) >= min_command and abs(c) >= bar


@njit(cache=True, error_model="numpy")
def is_stalled(v: float, c: float, s: float, observable: bool, ratio: float,
               confidence: float) -> bool:
    """Stalled by velocity: observable, v / c < `ratio` and |v - c| > `confidence` s."""
    share = v / c if observable else 0.0
    return observable and share < ratio and abs(v - c) > confidence * s


@njit(cache=True, error_model="numpy")
def is_following(v: float, c: float, observable: bool, following_ratio: float) -> bool:
    """Following the model: observable and v / c >= `following_ratio`."""
    share = v / c if observable else 0.0
    return observable and share >= following_ratio


def vouching(measured: np.ndarray, plausible: np.ndarray, error: np.ndarray,
             unlocked: np.ndarray, min_command: float, confidence: float,
             following_ratio: float) -> np.ndarray:
    """Joints that show the plant executing commands: the witnesses a lock needs.

    Moving as some plausible model commands it, beyond the noise: not locked, and for
    one of the models' predictions p (`plausible`, models x n, rad/s) |p| >=
    `min_command` and v / p >= `following_ratio`, with |v| >= `confidence` s. A looser
    bar than `is_following`'s, on two counts. Not the weakest prediction: right after
    the commands turn, the plausible lags disagree on the sign of every joint that
    turned (weakest 0), while the arm already moves as the shorter ones predict; a stall
    is still judged against the weakest. And not |c| >= 2 `confidence` s, which a
    stall's separation needs: a witness need only be seen moving, and a joint made to
    move at a peak of 0.15 rad/s beside a locked one (an observability excursion's
    witness, under 1e-3 rad of noise) clears this bar and not that one. A stopped plant
    moves no joint, so it has none. Returns (n,) bool.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(plausible != 0.0, measured / plausible, 0.0)
    follows = ((np.abs(plausible) >= min_command) & (share >= following_ratio)).any(axis=0)
    return unlocked & follows & (np.abs(measured) >= confidence * error)


@njit(cache=True, error_model="numpy")
def is_pushing(c: float, position: float, lower: float, upper: float,
               limit_margin: float) -> bool:
    """Pushing into a limit: within `limit_margin` (rad) of it, c pointing into it."""
    return ((c > 0 and position >= upper - limit_margin)
            or (c < 0 and position <= lower + limit_margin))


@njit(cache=True, error_model="numpy")
def moves_on_its_own(v: float, s: float, low: float, high: float, fastest: float,
                     unlocked: bool, undeclared: bool, falling: float, gravity_known: bool,
                     min_command: float, confidence: float) -> bool:
    """Moving on its own: the motion of a joint that lost its torque.

    A joint not yet declared free-swinging with |v| >= `min_command`, and v further than
    max(`confidence` s, `min_command`) outside the velocities a healthy joint could show,
    [min(0, low), max(0, high)] over the plausible predictions, with no command or one
    against it (for a locked joint, whose commands are 0 since its lock, the predictions
    are its coast after them; it must not move faster). Faster than commanded in the commanded
    direction (a servo's tracking error or overshoot, a joint pushed by the others)
    counts only beyond twice `fastest`, the largest plausible prediction of any joint,
    and the noise, which no servo transient reaches: a joint falling the way it was
    commanded. Maciejewski et al.
    (sec. 2.3) name a joint that lost its torque by motion under gravity the command does
    not explain: with the arm's gravity known (`gravity_known`), v must also have the sign
    of `falling`, the direction gravity accelerates the joint (0 where it hardly can).
    """
    # A locked joint may only coast as the commands before its lock make it (a lock
    # declared on ft/declare_failure while the joint moves): those are the predictions.
    healthy_low, healthy_high = min(low, 0.0), max(high, 0.0)
    outside = max(healthy_low - v, v - healthy_high)
    noise = max(confidence * s, min_command)
    ahead = unlocked and ((v > healthy_high and high >= min_command)
                          or (v < healthy_low and low <= -min_command))
    beyond = ahead and abs(v) <= 2 * fastest + noise
    downhill = not gravity_known or falling * v > 0
    return (undeclared and abs(v) >= min_command and outside > noise
            and not beyond and downhill)


def silent_and_on_its_own(silent: np.ndarray, quiet: np.ndarray, measured: np.ndarray,
                          plausible: np.ndarray, error: np.ndarray, unlocked: np.ndarray,
                          undeclared: np.ndarray, falling: np.ndarray,
                          stops: tuple[np.ndarray, np.ndarray, np.ndarray],
                          min_command: float, confidence: float,
                          limit_margin: float) -> np.ndarray:
    """`moves_on_its_own` for the joints whose drives give no torque against gravity.

    Without the allowance for a servo's transient (`fastest` 0): a `silent` joint (its
    drive without torque while it falls) faster than its plausible predictions the way
    gravity turns it is not overshooting, it is falling. A silent joint within
    `limit_margin` of the limit gravity turns it into (`stops`: the latest positions, the
    lower and upper limits, rad) rests on that stop without torque: it counts too, moving
    or not. A joint falls onto a stop close by before its fall can count as motion (a
    Panda shoulder 20 mrad from its limit reaches it in 0.1 s), and a healthy drive
    holding a joint there gives its gravity torque.

    A `quiet` joint (its drive without torque, fallen or not) commanded uphill, every
    plausible prediction at least `min_command` against gravity, counts once its velocity
    lies beyond them the way gravity turns it by max(`confidence` `error`, `min_command`):
    it slows as gravity alone slows it (Maciejewski et al. sec. 2.3), where a healthy
    servo behind an uphill command pushes beyond the gravity torque and a brake holding
    it takes its drive's push. It has not fallen yet (it coasts to a stop first), and
    otherwise reads as a stall. Arguments as `classify`'s; returns (n,) bool.
    """
    latest, lower, upper = stops
    own = np.zeros(measured.size, dtype=np.bool_)
    for j in np.flatnonzero(silent | quiet):
        column = plausible[:, j]
        low, high = column.min(), column.max()
        if silent[j]:
            own[j] = (unlocked[j] and undeclared[j] and is_pushing(
                falling[j], latest[j], lower[j], upper[j], limit_margin)) or moves_on_its_own(
                measured[j], error[j], low, high, 0.0, unlocked[j], undeclared[j], falling[j],
                True, min_command, confidence)
        if own[j] or not (unlocked[j] and undeclared[j]):
            continue
        noise = max(confidence * error[j], min_command)
        uphill = min(-falling[j] * low, -falling[j] * high) >= min_command
        own[j] = bool(uphill and falling[j] * measured[j] - max(falling[j] * low,
                                                              falling[j] * high) > noise)
    return own


def fastest_fall(commands: np.ndarray, falling: np.ndarray) -> np.ndarray:
    """The fastest the commands move each joint the way gravity turns it (n,) (rad/s, >= 0).

    Over `commands` (k x n rad/s, any k, none included) and rest, along `falling` (the
    signs of gravity's acceleration, `ft_core.swing.falling_directions`).
    """
    return np.maximum((falling * commands).max(axis=0, initial=0.0), 0.0)


def falls_past_every_command(silent: np.ndarray, measured: np.ndarray, error: np.ndarray,
                             fastest: np.ndarray, falling: np.ndarray, free: np.ndarray,
                             min_command: float, confidence: float) -> np.ndarray:
    """Silent joints falling faster than any command moves them, predictions or none.

    Used while the commands predict nothing (their stream paused, settling after it
    restarted, the plant not yet seen following): the plant holds a command it was sent
    lately, answers one before it, or stops. A healthy joint that moves the way gravity
    turns it faster than every such command and than rest (`fastest`, `fastest_fall`) is
    held back by its servo with more than its gravity torque; a `silent` drive
    (`drives.Drives.silent`) gives none, so its joint falls (Maciejewski et al. sec. 2.3).
    Counts where the velocity `measured` lies beyond `fastest` the way gravity turns it
    (`falling`, the signs) by max(`confidence` `error`, `min_command`), for the `free`
    joints. Returns (n,) bool.
    """
    noise = np.maximum(confidence * error, min_command)
    return silent & free & (falling != 0) & (falling * measured - fastest > noise)


def departure(measured: np.ndarray, plausible: np.ndarray, error: np.ndarray,
              free: np.ndarray, floor: float, confidence: float,
              kept: np.ndarray | None = None, keep: float = 1.0) -> np.ndarray:
    """How far each joint's velocity lies beyond every plausible prediction (n,) (rad/s).

    Outside [low, high] over the plausible predictions (`plausible`, models x n, rad/s),
    ahead of them or behind, by more than max(`confidence` `error`, `floor`), for the
    joints `free` to be judged; 0 elsewhere (`drives.Drives.unanswered` asks whether a
    drive answers it). The joints `kept` (left unanswered at the last update) need only `keep`
    of that margin, so that a departure near it does not come and go with the slope's
    noise. Behind its predictions is also how a stall looks: a joint a brake holds, its
    drive pushing, is answered; a stopped plant moves no witness.
    """
    if plausible.size == 0:
        return np.zeros(measured.size)
    low, high = plausible.min(axis=0), plausible.max(axis=0)
    outside = np.maximum(low - measured, measured - high)
    noise = np.maximum(confidence * error, floor)
    if kept is not None:
        noise = np.where(kept, keep * noise, noise)
    return np.where(free & (outside > noise), outside, 0.0)


def held_still(pushing: np.ndarray, positions: np.ndarray, plausible: np.ndarray,
               min_command: float, span: float) -> np.ndarray:
    """Joints held against their drives' push: a brake or a jam, seen by the efforts.

    A `pushing` joint (its drive's external torque far beyond what moving it needs,
    `drives.DriveWatch`) whose measured `positions` (window, n) spread by at most `span`
    (rad) while some plausible model (`plausible`, models x n, rad/s) commands it at least
    `min_command`. The velocity test misses such a joint when its commands change sign
    within the plausible lags, and takes two joints stalled together, the others hardly
    commanded, for a stopped plant; a drive's push shows neither is the case (a stopped
    driver pushes nothing). Returns (n,) bool.
    """
    if positions.shape[0] < 2 or plausible.size == 0:
        return np.zeros(pushing.size, dtype=bool)
    still = positions.max(axis=0) - positions.min(axis=0) <= span
    return pushing & still & (np.abs(plausible).max(axis=0) >= min_command)


@njit(cache=True, error_model="numpy")
def is_candidate(v: float, s: float, stalled: bool, pushing: bool, on_its_own: bool,
                 undeclared: bool, min_command: float, confidence: float) -> bool:
    """A lock candidate by velocity: stalled, not pushing into a limit, not on its own.

    A joint once declared free-swinging is a candidate again only once it stops:
    |v| <= max(`confidence` s, `min_command`). Whether a never-swinging candidate also
    lost position is `lost_position`'s test.
    """
    noise = max(confidence * s, min_command)
    return stalled and not pushing and not on_its_own and (undeclared or abs(v) <= noise)


@njit(cache=True, error_model="numpy")
def classify(measured: np.ndarray, plausible: np.ndarray, error: np.ndarray,
             latest: np.ndarray, lower: np.ndarray, upper: np.ndarray, unlocked: np.ndarray,
             undeclared: np.ndarray, stalling: np.ndarray, falling: np.ndarray,
             gravity_known: bool,
             min_command: float, confidence: float,
             ratio: float, following_ratio: float, limit_margin: float,
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                        np.ndarray, np.ndarray]:
    """Every joint's evidence at one update, by the scalar rules above.

    Args:
        measured: v per joint (n,).
        plausible: the plausible models' predicted velocities (models, n).
        error: s per joint (n,).
        latest: the newest measured positions (n,) (rad).
        lower: lower position limits (n,) (rad).
        upper: upper position limits (n,) (rad).
        unlocked: joints not declared locked (n,).
        undeclared: joints not declared free-swinging (n,).
        stalling: joints whose lock evidence is under way (n,), see `is_observable`.
        falling: the direction gravity accelerates each joint (n,), read only when
            `gravity_known`.
        gravity_known: whether `falling` is known.
        min_command: see `is_observable`.
        confidence: see `is_observable`.
        ratio: see `is_stalled`.
        following_ratio: see `is_following`.
        limit_margin: see `is_pushing`.

    Returns:
        (weakest prediction, observable, following, stalled, pushing into a limit, lock
        candidate, moving on its own), per joint.
    """
    n = measured.size
    weakest = np.zeros(n)
    flags = np.zeros((6, n), dtype=np.bool_)
    observable, following, stalled, pushing, candidate, on_its_own = flags
    fastest = np.abs(plausible).max() if plausible.size else 0.0
    for j in range(n):
        low, high = plausible[:, j].min(), plausible[:, j].max()
        weakest[j] = weakest_prediction(low, high)
        c, v, s = weakest[j], measured[j], error[j]
        observable[j] = is_observable(c, s, unlocked[j], min_command, confidence,
                                      stalling[j])
        stalled[j] = is_stalled(v, c, s, observable[j], ratio, confidence)
        pushing[j] = is_pushing(c, latest[j], lower[j], upper[j], limit_margin)
        following[j] = is_following(v, c, observable[j], following_ratio)
        on_its_own[j] = moves_on_its_own(v, s, low, high, fastest, unlocked[j], undeclared[j],
                                         falling[j], gravity_known, min_command, confidence)
        candidate[j] = is_candidate(v, s, stalled[j], pushing[j], on_its_own[j],
                                    undeclared[j], min_command, confidence)
    return weakest, observable, following, stalled, pushing, candidate, on_its_own


def mean_difference_error(slope_error: Values, times: np.ndarray) -> Values:
    """Standard error (rad) of a difference of two window means of positions.

    From the window's slope standard errors (rad/s, a float or per joint) and its
    sample `times` (s): one position's scatter is the slope's error times the root of
    the times' spread, and a mean of the window's samples has sqrt(1 / samples) of it,
    twice over.
    """
    centred = times - times.mean()
    return slope_error * math.sqrt(centred @ centred) * math.sqrt(2.0 / times.size)


def lost_position(current: np.ndarray, past: np.ndarray, weakest: np.ndarray,
                  sigma: np.ndarray, confidence: float,
                  shift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far (rad) each joint fell behind the model, and whether that is a lost position.

    A lock loses position from its first instant; a servo that integrates its command
    into a position reference and pauses after it ran ahead, until the reference catches
    up, stalls by velocity without losing any. The deficit is the window's mean offset
    (measured minus predicted position, one model) `current` (n,) against the
    most-behind of the earlier windows' offsets `past` (k, n), counted along the
    weakest prediction `weakest` (n,), less `shift` (k, n; rad), how far the model's
    offset may have moved since each earlier window with no position lost: a model
    whose latency is off by dL leaves an offset of dL times the velocity, which a
    change of command dv moves by dL dv (a Panda wrist decelerating from 1.3 to 0.08
    rad/s under a model 10 ms late: 12 mrad). +inf with no earlier window. Lost: deficit
    > `confidence` `sigma`, the standard error of a difference of two window means (n,).
    The papers define a lock as a joint held in place (Lewis & Maciejewski 1997, sec. I;
    Maciejewski et al., sec. 2.2); this rule asks that its stillness cost the position
    its command asked for.
    """
    if not len(past):
        deficit = np.full(current.size, math.inf)
    else:
        direction = -np.sign(weakest)  # behind: measured short of predicted, along c
        deficit = (direction * current - direction * past - shift).min(axis=0)
    return deficit, deficit > confidence * sigma


def swing_wait(measured: float, error: float, plausible: np.ndarray, settling: float,
               confidence: float, min_command: float) -> float:
    """How long (s) motion on its own must last beyond `persistence` to be a swing.

    A servo's transient (overshoot, the spring back after a stop, a joint dragged by
    the others) dies within the plant's settling time `settling` (s) and is no faster
    than twice the largest plausible prediction of any joint (`plausible`, rad/s). A
    joint faster than that by more than max(`confidence` `error`, `min_command`) need
    not wait: 0; otherwise `settling`.
    """
    transient = 2 * float(np.abs(plausible).max(initial=0.0))
    noise = max(confidence * error, min_command)
    if abs(measured) > transient + noise:
        return 0.0
    return settling


def slow_stall(moved: np.ndarray, predicted: np.ndarray, reached: np.ndarray,
               latest: np.ndarray, lower: np.ndarray, upper: np.ndarray, sigma: np.ndarray,
               shift: np.ndarray, least: float, ratio: float, confidence: float,
               limit_margin: float) -> np.ndarray:
    """Which slowly commanded joints lost their motion over a span of two halves.

    Per joint: `moved` (2, n) is how far its window-mean position moved over each half
    (rad), `predicted` (2, n) what the model predicted there, `reached` (k, n) the window
    means over the span and `latest` (n,) the newest positions (rad), `sigma` (n,) the
    standard error of a difference of two window means (rad), `shift` (2, n) how far the
    model's latency error can move its prediction over each half with no motion lost
    (rad; `lost_position`'s allowance). Stalled when, in each half, |predicted| >=
    `confidence` `sigma` + `shift` and the joint moved less than `ratio` of it either
    way, and the joint came within 2 `limit_margin` of no limit a half's prediction
    points into, and the halves' |predicted| add up to at least `least` (rad: the
    motion the window's own test needs, `min_command` times the window, so that a joint
    whose measurements hardly scatter is not judged on a command too small to move a
    sticky drive). Either way: a lock holds its joint in place (Maciejewski et al., sec.
    2.2), while a joint the others' motion pushes back against its slow command (behind
    a slow servo, after a lock elsewhere or as a wall lets the tool go) moves. The
    halves may point either way: a locked joint the controller commands to and fro,
    slowly, moves in neither. Both halves: a servo that ran ahead and then waits
    for its reference lost nothing over the half that holds its lead; a lock loses
    steadily. At the equilibrium of Maciejewski et al. Theorem 1 an undetected lock
    leaves the arm short of its goal with the null space commanding the locked joint at a
    few hundredths of a rad/s, below what the window can judge through the noise; a
    joint locked as the arm slows into its goal is commanded as slowly. Returns (n,) bool.
    """
    # A limit that stopped the commanded part of a to-and-fro motion takes it out of the
    # measured motion: pushing at any time of the span counts. Window means come within
    # `limit_margin` of where the joint touched the limit at most 2 x `limit_margin` away.
    top = np.maximum(latest, reached.max(axis=0, initial=-np.inf))
    bottom = np.minimum(latest, reached.min(axis=0, initial=np.inf))
    pushing = (((predicted > 0).any(axis=0) & (top >= upper - 2 * limit_margin))
               | ((predicted < 0).any(axis=0) & (bottom <= lower + 2 * limit_margin)))
    size = np.abs(predicted)
    lost = (size >= confidence * sigma + shift) & (np.abs(moved) < ratio * size)
    return lost.all(axis=0) & (size.sum(axis=0) >= least) & ~pushing


def too_few_samples(times: np.ndarray, window: float, min_samples: int) -> bool:
    """Fewer than `min_samples` measurements (`times`, s), or over less than half `window`."""
    return bool(times.size < min_samples or times[-1] - times[0] < window / 2)


def not_observing(now: float, last_command: float, resumed_at: float, settling: float,
                  times: np.ndarray, window: float, min_samples: int) -> str | None:
    """Why nothing can be decided at `now` (s), or None: no decision without evidence.

    Args:
        now: the update's time (s).
        last_command: start of the newest command (s); -inf: none yet.
        resumed_at: when the command stream last (re)started (s).
        settling: window + the plausible set's slowest settling time (s).
        times: the window's measurement times (s).
        window: the detector's window (s).
        min_samples: fewest measurements in the window.

    Returns:
        The reason: no command yet, a command gap longer than a window, the
        settling time after commands (re)started, too few measurements over less than
        half a window, or a gap between measurements longer than half a window.
    """
    if last_command == -math.inf:
        return "no command yet"
    gap = now - last_command
    if gap > window:
        return f"command stream paused for {gap:.3f} s"
    if now < resumed_at + settling:
        return "settling after the command stream (re)started"
    if too_few_samples(times, window, min_samples):
        return "too few joint states in the window"
    if _largest_step(times) > window / 2:
        return "joint states arrive with gaps"
    return None


def plant_fault(candidate: list[bool], following: list[bool], on_its_own: list[bool],
                torqueless: list[bool] | None = None) -> list[bool] | None:
    """The joints that show the plant as a whole not following, or None.

    A plant fault (a stopped driver, an emergency stop, a lost command path) when two
    or more joints are lock candidates and they outnumber the joints following (those
    are named), or else when two or more move on their own and outnumber them. A joint
    moving on its own whose drive gives no torque (`torqueless[j]`, from the efforts:
    `detection.drives`) shows its own drive's fault, not the plant's, and is not counted
    (a Panda shoulder falling onto its stop during a pause, a neighbour pushed by its
    fall: two joints on their own, none following).
    """
    if torqueless is not None:
        on_its_own = [o and not t for o, t in zip(on_its_own, torqueless, strict=True)]
    n_stalled, n_following, n_own = sum(candidate), sum(following), sum(on_its_own)
    if n_stalled >= 2 and n_stalled > n_following:
        return candidate
    if n_own >= 2 and n_own > n_following:
        return on_its_own
    return None
