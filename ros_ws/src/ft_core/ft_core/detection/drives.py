"""A drive that gives no torque: a free swing told by the efforts as well as by the motion.

A joint whose drive lost its torque falls under gravity (Maciejewski et al. sec. 2.3:
the swing angle is the damage). By its motion alone the lock detector names it only
beyond what a healthy servo's transients could do (`rules.moves_on_its_own`: faster than
twice any joint's plausible command when it falls the way it was commanded, and for the
plant's settling time when slow). Those transients need torque; a drive without torque
gives none, while one that holds or moves a joint against gravity gives about the gravity
torque g(q) (the URDF's inertias).

`DriveWatch` names a joint *silent* when, for `SILENT_TIME` s, its reported effort stays
below `SILENT_SHARE` of its gravity torque, that torque is at least `GRAVITY_SHARE` of
the joint's effort limit, and the joint has fallen `FALL` rad, the way gravity turns it
(`ft_core.swing.falling_directions`), from the highest point since. Silence alone is no
fault: a healthy drive is silent while its command accelerates the joint downhill as
fast as gravity does (a Panda's shoulder: its 7.5 rad/s^2 limit is about g / inertia),
for 60 ms in 12 minutes of goals and for 200 ms in a remap after a brake, on the physics
plant. So a silent joint still has to move outside its plausible predictions, but with
no allowance for a servo's transient and no wait (`LockDetector.measure`), and the
contact veto does not hold it back. A joint moving uphill when its drive goes quiet
(under `SILENT_SHARE` of its gravity torque for `SILENT_TIME`, `Drives.quiet`) coasts to
a stop before it can fall: it counts once it lags its uphill predictions the way
gravity turns it (`rules.silent_and_on_its_own`), where a healthy servo behind an uphill
command pushes beyond its gravity torque and a brake takes its push. Nor is a drive
silent while the tool is or was
lately pushed by an obstacle (`ContactWatch.lately`) before its joint has fallen
`CARRIED_FALL`: the obstacle's force carries part of the arm's weight, and a healthy
drive whose joint it props up gives none (a Panda's shoulder and elbow against a wall,
on the physics plant), but it holds that joint up. A joint gravity hardly turns
(a vertical axis) is never silent: its free swing is told by its motion alone. Without
efforts, inertias or effort limits nothing is silent.

The other way round, a drive that *pushes* a joint that does not move: a brake or a jam
takes its drive's torque, so the external torque tau - g(q) of its joint grows with the
command it cannot follow, while a healthy joint pushed that hard accelerates away (a
Panda shoulder at 26 N m moves 24 mrad in 80 ms). `DriveWatch` names a joint *pushing*
while |tau - g(q)| reached `PUSH_SHARE` of its effort limit (and `PUSH_TORQUE`) within
the last `PUSH_MEMORY` s: in free motion on the physics plant the servos' transients and
the 10 % gravity-model error reach at most 0.26 of a Panda's limits. The lock detector
takes a pushing joint that stays still while commanded, another joint moving, as a lock
candidate even where the commands change too fast for its velocity test
(`LockDetector.measure`); the contact test still holds back a push a force on the tool
explains (a wall loads every joint, a brake its own).

A healthy joint can also stall, or stand still against its drive's push, because the
other links accelerate: decelerating hard, they load it through the joint-space inertia's
off-diagonal terms, c_j = sum_{k != j} M_jk(q) qdd_k, and its servo, a slow driver
behind it, gives that torque late. A brake is an external torque on its own joint; a
stall by the coupling is none: the drive's torque is what the measured motion needs,
tau = M(q) qdd + C(q, qd) qd + g(q) (inverse dynamics: the residual is the external joint
torque that actuator-fault observers estimate, De Luca & Mattone 2003).
`Drives.moved_by_others` names a joint *moved by the others* where that residual
tau - M qdd - C qd - g is under `COUPLED_SHARE` of c_j, c_j is at least `COUPLING_SHARE`
of its effort limit, c_j drives the joint the way it lags behind its command (by at
least `detection.min_command`), and its drive gives most of c_j (a drive without torque,
which the others swing, gives none). Scaled by c_j, the test needs no threshold per
drive (a shoulder's brake and a wrist's differ tenfold). The accelerations are the
window slopes' change over `ACCELERATION_SPAN`. A joint that lost its torque has no
residual either (its fall is what the dynamics say), so the test only holds back locks.

The same residual, the other way: a joint commanded too slowly for the lock detector's
window is judged over a longer span (`rules.slow_stall`), where a few mrad of lag tell
nothing alone. `Drives.braking` asks that its drive push along the command beyond what
the motion needs, by `BRAKE_SHARE` of the effort limit (and `BRAKE_TORQUE`): a brake
takes its servo's push. So does every lock candidate while the tool is or was lately
pushed (`carried`): the arm lurches as the obstacle goes, its servos wound up at it, and
a healthy joint moved back against its command for 0.2 s, nothing external on it
(a wall removed on the physics plant), lags as a locked one does.

A joint gravity hardly turns (a vertical axis, `GRAVITY_SHARE`) is never silent: without
torque it coasts as commanded, as a healthy joint at constant speed does, and its drive's
torque there is as small as a healthy one's. It shows once the others' reactions or a
change of command take its velocity beyond every plausible prediction, by more than the
noise and `DEPARTURE_SHARE` of `detection.min_command`: a servo answers that departure,
about M_jj(q) |dv| / T for a departure dv (rad/s) and a response time T (the plausible
set's slowest), and a drive without torque gives none. `Drives.unanswered` names such a
joint where that answer is at least `ANSWER_TORQUE` and its drive gave under
`ANSWER_SHARE` of it, beyond gravity or at all (a drive without torque gives none,
whatever gravity's small torque would ask of it), throughout the last `ANSWER_SPANS`
response times, the tool not pushed lately (`Drives.carried`); the lock detector takes
it as moving on its own once the departure has held `UNANSWERED_TIME` s (kept meanwhile
by `DEPARTURE_KEEP` of its margin), counted from when it began as far back as those
`ANSWER_SPANS` response times reach.
A healthy servo's torque crosses zero too: as a hard acceleration ends, its velocity
overshoots the command while its reference term still pushes the joint on, and the two
cancel for a few tens of ms; but just before, it pushed the joint there. A drive without
torque gave nothing throughout.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ft_core import swing
from ft_core.robots import Robot

#: A drive giving less than this share of its joint's gravity torque gives none.
SILENT_SHARE = 0.1
#: Least gravity torque, as a share of the joint's effort limit, for a silent drive to say
#: anything (below it a healthy drive's torque is mostly its servo's).
GRAVITY_SHARE = 0.03
#: s a drive must stay silent, its joint falling, to be named.
SILENT_TIME = 0.05
#: rad the joint must have fallen meanwhile (five times the sim's position noise).
FALL = 0.005
#: rad, as `FALL` while the tool is or was lately pushed (`Drives.carried`): an obstacle
#: that carries a joint's weight holds it up, and a joint falling this far is not held.
CARRIED_FALL = 0.03
#: Least external torque, as a share of the joint's effort limit, of a pushing drive.
PUSH_SHARE = 0.3
#: N m, and at least this (a wrist's model errors are a large share of its small limit).
PUSH_TORQUE = 5.0
#: s a push counts after it was last seen (the commands it follows may change sign).
PUSH_MEMORY = 0.1
#: rad, the most a joint's measured positions may spread over the detector's window for
#: it to stand still (`rules.held_still`): beyond the range of the window's samples under
#: the sim's 1 mrad noise, short of what a healthy joint pushed that hard moves.
STILL_SPAN = 0.008
#: s a joint must stay held before it is a lock candidate: longer than a healthy joint
#: reversing at its acceleration limit stands still, pushed as hard.
HELD_TIME = 0.03
#: rad: nor within this of a position limit, whose stop may be what holds it.
HELD_LIMIT_MARGIN = 0.05
#: A joint moved by the others leaves a residual under this share of their coupling torque.
COUPLED_SHARE = 0.5
#: Least coupling torque, as a share of the joint's effort limit, that says anything
#: (below it, the accelerations' noise).
COUPLING_SHARE = 0.02
#: Least residual torque, as a share of the joint's effort limit, of a brake holding a
#: slowly commanded joint (`Drives.braking`): twice the largest a healthy joint held a
#: few mrad back left in the deployed series, a fifth of what a brake took there.
BRAKE_SHARE = 0.02
#: N m, and at least this (a wrist's model errors are a large share of its small limit).
BRAKE_TORQUE = 1.0
#: Share of a servo's answer to its joint's departure from every plausible prediction
#: under which a drive leaves it unanswered (`Drives.unanswered`).
ANSWER_SHARE = 0.1
#: N m, the least answer a departure must call for to say anything (below it, a drive's
#: torque is mostly its model's error): a Panda wrist (M_55 about 0.056 kg m^2) departing
#: 0.13 rad/s behind a 75 ms response asks this much.
ANSWER_TORQUE = 0.1
#: Share of `detection.min_command` (rad/s) a joint's velocity must lie beyond every
#: plausible prediction, and beyond the noise, for its drive's answer to be asked
#: (`rules.departure`): `ANSWER_TORQUE` bounds it from below as well (a Panda shoulder's
#: 0.025 rad/s over a 50 ms response asks about 0.5 N m).
DEPARTURE_SHARE = 0.5
#: Share of that margin a departure left unanswered at the last update must keep: one
#: near the margin otherwise comes and goes with the window slope's noise.
DEPARTURE_KEEP = 0.5
#: s a departure must stay unanswered for its joint to move on its own (from when it
#: began, at most `ANSWER_SPANS` response times before its drive was found silent).
UNANSWERED_TIME = 0.05
#: Response times over which a drive must have given under `ANSWER_SHARE` of the answer.
ANSWER_SPANS = 2
#: s of the drives' torques kept for `Drives.unanswered` (beyond the longest span it asks).
ANSWER_HORIZON = 0.5
#: Most drives' torques kept (a bound on the loop over them, whatever the state rate).
ANSWER_KEPT = 1000
#: s over which the window slopes' change gives the accelerations.
ACCELERATION_SPAN = 0.02
#: Share of a joint's gravity torque its drive's torque may err by, the gravity model's
#: error: a joint moving on its own is free only with its drive short of holding it by
#: more (`Drives.let_go`).
DRAG_SHARE = 0.1


@dataclass(frozen=True)
class Drives:
    """What the efforts said of every joint at one update ((n,) each)."""

    silent: np.ndarray  #: bool, no torque against gravity while the joint falls
    pushing: np.ndarray  #: bool, a push far beyond what moving the joint needs, lately
    #: N m, each drive's torque beyond its gravity torque, tau - g(q); None: unknown
    external: np.ndarray | None = None
    gravity: np.ndarray | None = None  #: N m, |g(q)|; None: unknown
    robot: Robot | None = None  #: its inertias; None: unknown
    q: np.ndarray | None = None  #: rad, where the efforts were
    effort: np.ndarray | None = None  #: N m, the drives' torques tau
    #: the largest min(|tau - g(q)|, |tau|) (N m, (n,)) each drive gave over the last
    #: given s, up to this update; None: only this update's is known
    given: Callable[[float], np.ndarray] | None = None
    #: a force on the tool lately, which can carry any joint's weight: no drive unanswered
    carried: bool = False
    #: the tool came off an obstacle lately (`ContactWatch.left`): servos wound up
    #: against it are turning round
    left: bool = False
    #: bool, no torque against gravity for `SILENT_TIME`, fallen or not, the tool not
    #: pushed lately (`silent` is this and a fall); None: as `silent`
    quiet: np.ndarray | None = None

    @property
    def weighed(self) -> bool:
        """Whether the efforts can be weighed against the arm's dynamics (`braking`)."""
        return self.robot is not None and self.q is not None and self.effort is not None

    def moved_by_others(self, velocity: np.ndarray, acceleration: np.ndarray,
                        commanded: np.ndarray, least_lag: float) -> np.ndarray:
        """Whether each joint is held back by the other links' accelerations (n,) bool.

        `velocity` (rad/s) and `acceleration` (rad/s^2) as measured, `commanded` the
        velocity it was to follow (rad/s). The coupling torque c = M qdd - diag(M) qdd
        is at least `COUPLING_SHARE` of the effort limit; the joint lags behind its
        command by `least_lag` rad/s or more, the way c drives it; its drive gives at
        least 1 - `COUPLED_SHARE` of c beyond gravity (a healthy servo resisting the
        coupling; a drive without torque gives none); and the residual
        tau - M qdd - C qd - g is under `COUPLED_SHARE` of c (the module). A joint whose
        lag is within `least_lag`, as when its commands reverse, has nothing for the
        coupling to explain. False everywhere without efforts.
        """
        if self.robot is None or self.q is None or self.effort is None or self.external is None:
            return np.zeros(velocity.size, bool)
        inertia, residual = self._residual(self.robot, self.q, self.effort, velocity,
                                           acceleration)
        coupling = inertia @ acceleration - np.diag(inertia) * acceleration
        lag = commanded - velocity
        least = COUPLING_SHARE * np.asarray(self.robot.effort_limits, float)
        return ((np.abs(coupling) >= least) & (np.abs(lag) >= least_lag) & (coupling * lag > 0)
                & (self.external * coupling >= (1 - COUPLED_SHARE) * coupling ** 2)
                & (np.abs(residual) < COUPLED_SHARE * np.abs(coupling)))

    def braking(self, velocity: np.ndarray, acceleration: np.ndarray,
                along: np.ndarray) -> np.ndarray:
        """Whether each drive pushes its joint along `along` beyond its motion's needs (n,) bool.

        The residual tau - M qdd - C qd - g (De Luca & Mattone 2003: minus the external
        joint torque) at `velocity` (rad/s) and `acceleration` (rad/s^2) as measured,
        taken along the direction of `along` (the commanded velocity, rad/s), is at least
        `BRAKE_SHARE` of the effort limit and `BRAKE_TORQUE`: a brake or a jam takes the
        push of a servo whose reference runs on, which grows while the joint stays, where
        a healthy joint a few mrad behind a slow command is held by torques the dynamics
        explain. False everywhere without efforts.
        """
        return self._spent_along(velocity, acceleration, along, BRAKE_SHARE, BRAKE_TORQUE)

    def resisted(self, velocity: np.ndarray, acceleration: np.ndarray,
                 along: np.ndarray) -> np.ndarray:
        """Whether something resists each joint's motion along `along` hard (n,) bool.

        As `braking`, with the bar of a push (`PUSH_SHARE` of the effort limit and
        `PUSH_TORQUE`): the residual tau - M qdd - C qd - g along the commanded velocity
        (rad/s) is a drive's torque spent on an external resistance, friction in the
        joint or a force on the tool (De Luca & Mattone 2003). A healthy joint in free
        motion leaves less (the module). False everywhere without efforts.
        """
        return self._spent_along(velocity, acceleration, along, PUSH_SHARE, PUSH_TORQUE)

    def _spent_along(self, velocity: np.ndarray, acceleration: np.ndarray,
                     along: np.ndarray, share: float, torque: float) -> np.ndarray:
        """Whether the residual along `along` is at least `share` of the limit and `torque`."""
        if self.robot is None or self.q is None or self.effort is None:
            return np.zeros(velocity.size, bool)
        _, residual = self._residual(self.robot, self.q, self.effort, velocity, acceleration)
        least = np.maximum(share * np.asarray(self.robot.effort_limits, float), torque)
        return np.sign(along) * residual >= least

    def unanswered(self, departure: np.ndarray, response: float) -> np.ndarray:
        """Whether each drive leaves its joint's departure unanswered (n,) bool.

        `departure` (rad/s, >= 0): how far each joint's velocity lies beyond every
        plausible prediction (0: within, or not to be judged); `response` (s): the
        slowest plausible response time. A servo answers with about M_jj(q) departure /
        `response` (N m); where that is at least `ANSWER_TORQUE`, the joint's gravity
        torque under `GRAVITY_SHARE` of its effort limit (`silent` judges the others) and
        its drive's torque, beyond gravity or at all, under `ANSWER_SHARE` of the answer
        throughout the last `ANSWER_SPANS` `response` (`given`), the drive gives none
        (the module).
        False everywhere without efforts or inertias, and while `carried`.
        """
        robot = self.robot
        if (robot is None or self.q is None or self.external is None or self.gravity is None
                or self.carried):
            return np.zeros(departure.size, bool)
        _, inertia = robot.gravity_dynamics(self.q)
        answer = inertia * departure / response
        limits = np.asarray(robot.effort_limits, float)
        given = (self.given(ANSWER_SPANS * response) if self.given is not None
                 else np.abs(self.external) if self.effort is None
                 else np.minimum(np.abs(self.external), np.abs(self.effort)))
        return ((answer >= ANSWER_TORQUE) & (self.gravity < GRAVITY_SHARE * limits)
                & (given < ANSWER_SHARE * answer))

    @staticmethod
    def _residual(robot: Robot, q: np.ndarray, effort: np.ndarray, velocity: np.ndarray,
                  acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M(q) (kg m^2) and the residual tau - M qdd - C qd - g (N m) at q (rad)."""
        inertia, nonlinear = robot.dynamics(q, velocity)
        return inertia, effort - nonlinear - inertia @ acceleration

    def let_go(self, velocity: np.ndarray) -> np.ndarray:
        """Whether each joint's drive lets it move at `velocity` (rad/s) (n,) bool.

        A healthy servo moved by something else (the other links' reaction when one of
        them stops or falls, a push on the tool) drives against the motion, back to its
        reference: sign(v) (tau - g(q)) < 0. A drive without torque leaves tau - g = -g,
        which a joint falling under gravity has the sign of: sign(v) (tau - g) = |g|. A
        joint moving on its own is free only where sign(v) (tau - g) exceeds `DRAG_SHARE`
        |g|, beyond the gravity model's error. True everywhere without efforts.
        """
        if self.external is None or self.gravity is None:
            return np.ones(velocity.size, bool)
        return np.sign(velocity) * self.external > DRAG_SHARE * self.gravity


class Accelerations:
    """The joints' accelerations from their velocities' change over `ACCELERATION_SPAN`."""

    def __init__(self) -> None:
        self._history: deque[tuple[float, np.ndarray]] = deque()

    def update(self, now: float, velocity: np.ndarray) -> np.ndarray | None:
        """Add `velocity` (rad/s) at `now` (s); the acceleration (rad/s^2) since then.

        From the newest velocity at least `ACCELERATION_SPAN` older; None without one.
        """
        history, old = self._history, now - ACCELERATION_SPAN
        while len(history) > 1 and history[1][0] <= old:
            history.popleft()
        then, before = history[0] if history else (math.inf, velocity)
        history.append((now, velocity.copy()))
        if then > old:
            return None
        return (velocity - before) / (now - then)


class DriveWatch:
    """Which joints' drives give no torque while gravity turns them, or push (the module)."""

    def __init__(self, robot: Robot) -> None:
        self._robot = robot
        limits = np.asarray(robot.effort_limits, float)
        #: N m, the least gravity torque per joint (inf: never judged)
        self._least = np.where(np.isfinite(limits) & (limits > 0), GRAVITY_SHARE * limits,
                               math.inf)
        self._since = np.full(robot.n, math.nan)  # s, when each drive fell silent
        self._from = np.zeros(robot.n)  # rad, where its joint was then
        #: N m, the least external torque of a push per joint
        self._push = np.where(np.isfinite(limits) & (limits > 0),
                              np.maximum(PUSH_SHARE * limits, PUSH_TORQUE), math.inf)
        self._pushed_at = np.full(robot.n, -math.inf)  # s, when each last pushed
        self.silent = np.zeros(robot.n, bool)  #: the joints named silent at the last update
        #: (s, |tau - g| (N m, (n,))) of the last `ANSWER_HORIZON` s, oldest first
        self._given: deque[tuple[float, np.ndarray]] = deque(maxlen=ANSWER_KEPT)

    def reset(self) -> None:
        """Forget every silence, push and torque given."""
        self._since[:] = math.nan
        self._pushed_at[:] = -math.inf
        self.silent[:] = False
        self._given.clear()

    def given(self, span: float) -> np.ndarray:
        """The largest min(|tau - g(q)|, |tau|) (N m, (n,)) each drive gave over `span` s.

        A servo's answer shows beyond its gravity torque; a drive without torque gives
        none at all, whatever gravity would ask of it.
        """
        peak = np.zeros(self._robot.n)
        if not self._given:
            return peak
        latest = self._given[-1][0]
        for at, torque in reversed(self._given):
            if at < latest - span:
                break
            np.maximum(peak, torque, out=peak)
        return peak

    def update(self, now: float, q: np.ndarray, effort: np.ndarray,
               carried: bool = False, left: bool = False) -> Drives:
        """What the `effort` (N m) says of each joint at `now` (s) and q (rad).

        `carried`: the tool is or was lately pushed by an obstacle (`detection.contact`),
        whose force can carry any joint's weight: no drive is unanswered, nor silent
        before its joint has fallen `CARRIED_FALL`.
        `left`: the tool came off it lately (`ContactWatch.left`), passed on as is.
        """
        robot = self._robot
        if not robot.has_inertias or not np.isfinite(self._least).any():
            return Drives(self.silent, np.zeros(robot.n, bool))
        signed = robot.gravity(q)
        external = np.abs(effort - signed)
        given = self._given
        if given and given[-1][0] > now:  # time went back (a reset clock): start anew
            given.clear()
        while given and given[0][0] < now - ANSWER_HORIZON:
            given.popleft()
        given.append((now, np.minimum(external, np.abs(effort))))
        self._pushed_at[external >= self._push] = now
        pushing = now - self._pushed_at <= PUSH_MEMORY
        gravity = np.abs(signed)
        # Quiet since the drive gave under SILENT_SHARE of its gravity torque, or of the
        # least that says anything (gravity grows as a joint without torque moves on).
        quiet = np.abs(effort) < SILENT_SHARE * np.maximum(gravity, self._least)
        started = quiet & np.isnan(self._since)
        self._since[started], self._from[started] = now, q[started]
        self._since[~quiet] = math.nan
        quiet &= gravity >= self._least
        self.silent[:] = False
        held = quiet & (now - self._since >= SILENT_TIME)
        lasting = held & (not carried)
        if quiet.any():
            falling = swing.falling_directions(robot, q)
            if falling is not None:
                # The fall counts from the highest point since the drive fell silent (a
                # joint moving uphill then coasts to a stop first).
                fallen = (q - self._from) * falling
                self._from = np.where(quiet & (fallen < 0), q, self._from)
                self.silent[:] = held & (fallen >= (CARRIED_FALL if carried else FALL))
        return Drives(self.silent.copy(), pushing, effort - signed, gravity, robot, q, effort,
                      self.given, carried, left, lasting)
