"""The ways a joint fails, as the sim's plants inject them (docs/sim.md#faults).

A `Fault` is one failure of one joint: a `FaultKind` and the numbers that kind takes.
Beyond the lock and the free swing of Lewis & Maciejewski and Maciejewski et al., a
joint's drive can degrade: more viscous friction (`severity` in N m s/rad), more dry
(Coulomb) friction (`severity` in N m), a loss of torque authority (`severity` the
fraction 0-1 of its effort limit the drive still gives), a new stop inside its range
(`lower` and/or `upper`, rad) or an intermittent jam (locked for `period` s, free for
`period` s, in turn, starting locked). `FaultState` holds the faults in force on a
plant's joints (besides its locks and free swings) and the kinematic plant's analogue of
each. Units: rad, rad/s, s, N m.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from ft_core.errors import SuiteError

#: N m s/rad, the largest viscous friction a fault may add.
MAX_VISCOUS = 1000.0
#: N m, the largest dry friction a fault may add.
MAX_DRY = 1000.0
#: s, the shortest and longest half-period of an intermittent jam.
MIN_PERIOD, MAX_PERIOD = 0.01, 3600.0
#: N m s/rad, the velocity gain of the nominal drive behind the kinematic plant's analogues:
#: a velocity loop u -> tau = K (u - v) against friction settles where K (u - v) equals it.
DRIVE_DAMPING = 20.0


class FaultError(SuiteError):
    """A fault that cannot be injected; the text says why."""


class FaultKind(enum.StrEnum):
    """What fails in a joint (docs/sim.md#faults)."""

    LOCK = "lock"
    FREE_SWING = "free_swing"
    VISCOUS = "viscous"
    DRY = "dry"
    AUTHORITY = "authority"
    RANGE = "range"
    INTERMITTENT = "intermittent"

    @property
    def fields(self) -> tuple[str, ...]:
        """The numbers this kind takes (`Fault`'s fields): none, severity, stops or period."""
        if self in (FaultKind.VISCOUS, FaultKind.DRY, FaultKind.AUTHORITY):
            return ("severity",)
        if self is FaultKind.RANGE:
            return ("lower", "upper")
        if self is FaultKind.INTERMITTENT:
            return ("period",)
        return ()


#: Each field's value when not given.
DEFAULTS = {"severity": math.nan, "lower": -math.inf, "upper": math.inf, "period": math.nan}


@dataclass(frozen=True)
class Fault:
    """One failure of one joint.

    Attributes:
        kind: see `FaultKind`.
        joint: the joint's name.
        severity: viscous N m s/rad in (0, `MAX_VISCOUS`], dry N m in (0, `MAX_DRY`],
            authority the fraction [0, 1] of the effort limit left; nan for other kinds.
        lower, upper: rad, a range fault's new stops (at least one finite, lower < upper);
            -inf and inf otherwise.
        period: s in [`MIN_PERIOD`, `MAX_PERIOD`], an intermittent jam's half-period; nan
            otherwise.

    Raises:
        FaultError: a number missing, not finite, out of its range or given to a kind
            that does not take it.
    """

    kind: FaultKind
    joint: str
    severity: float = math.nan
    lower: float = -math.inf
    upper: float = math.inf
    period: float = math.nan

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "kind", FaultKind(self.kind))
        except ValueError:
            raise FaultError(f"unknown fault kind {str(self.kind)[:40]!r} (one of "
                             f"{', '.join(FaultKind)})") from None
        for name, default in DEFAULTS.items():
            try:
                value = float(getattr(self, name))
            except (TypeError, ValueError):
                raise FaultError(f"{self.kind} of {self.joint}: {name} "
                                 f"{str(getattr(self, name))[:40]!r} is not a number") from None
            object.__setattr__(self, name, value)
            given = not (value == default or (math.isnan(value) and math.isnan(default)))
            if given and name not in self.kind.fields:
                raise FaultError(f"{self.kind} of {self.joint} takes no {name}")
        self._check()

    def _check(self) -> None:
        kind, s = self.kind, self.severity
        where = f"{kind} of {self.joint}"
        for name in ("severity", "period"):
            if name in kind.fields and math.isnan(getattr(self, name)):
                raise FaultError(f"{where}: needs a {name} (a number)")
        if kind is FaultKind.VISCOUS and not 0 < s <= MAX_VISCOUS:
            raise FaultError(f"{where}: severity {s} N m s/rad must be in (0, {MAX_VISCOUS:g}]")
        if kind is FaultKind.DRY and not 0 < s <= MAX_DRY:
            raise FaultError(f"{where}: severity {s} N m must be in (0, {MAX_DRY:g}]")
        if kind is FaultKind.AUTHORITY and not 0 <= s <= 1:
            raise FaultError(f"{where}: severity {s} (the fraction of the effort limit left) "
                             "must be in [0, 1]")
        if kind is FaultKind.RANGE:
            lo, hi = self.lower, self.upper
            if math.isnan(lo) or math.isnan(hi) or lo == math.inf or hi == -math.inf \
                    or not (math.isfinite(lo) or math.isfinite(hi)):
                raise FaultError(f"{where}: needs a finite lower or upper stop (rad), "
                                 f"not [{lo}, {hi}]")
            if not lo < hi:
                raise FaultError(f"{where}: lower {lo} must be below upper {hi}")
        if kind is FaultKind.INTERMITTENT and not MIN_PERIOD <= self.period <= MAX_PERIOD:
            raise FaultError(f"{where}: period {self.period} s must be in "
                             f"[{MIN_PERIOD:g}, {MAX_PERIOD:g}]")

    def stops(self, lower: float, upper: float, q: float) -> tuple[float, float]:
        """A range fault's stops (rad) on a joint of range [lower, upper] now at q.

        A stop the joint is already past is placed where the joint is: it can only move
        back into the new range.

        Raises:
            FaultError: a stop outside [lower, upper] (the URDF's range).
        """
        inside = ((self.lower == -math.inf or lower <= self.lower < upper)
                  and (self.upper == math.inf or lower < self.upper <= upper))
        if not inside:
            raise FaultError(f"range of {self.joint}: stops [{self.lower}, {self.upper}] "
                             f"must lie within the joint's range [{lower:.4g}, {upper:.4g}]")
        return min(max(self.lower, lower), q), max(min(self.upper, upper), q)

    def describe(self) -> str:
        """One phrase for a log line, e.g. `viscous 50 N m s/rad`."""
        unit = {FaultKind.VISCOUS: " N m s/rad", FaultKind.DRY: " N m",
                FaultKind.AUTHORITY: " of its effort limit"}
        if self.kind.fields == ("severity",):
            return f"{self.kind} {self.severity:g}{unit[self.kind]}"
        if self.kind is FaultKind.RANGE:
            return f"range [{self.lower:.4g}, {self.upper:.4g}] rad"
        if self.kind is FaultKind.INTERMITTENT:
            return f"intermittent, period {self.period:g} s"
        return str(self.kind)


class FaultState:
    """The degradations in force on a plant's n joints (not its locks and free swings).

    Attributes:
        faults: joint index -> {kind: the fault in force}; a kind injected again on the
            same joint replaces the earlier one.
        viscous, dry: (n,) added friction, N m s/rad and N m (0: none).
        authority: (n,) fraction of each effort limit left (1: all).
        lower, upper: (n,) rad, the stops of range faults (-inf, inf: none).
        intermittent: joint index -> (period s, plant time s of the injection).
    """

    def __init__(self, n: int):
        self.n = n
        self.faults: dict[int, dict[FaultKind, Fault]] = {}
        self.clear()

    def clear(self) -> None:
        """No fault in force."""
        self.faults = {}
        self.viscous, self.dry = np.zeros(self.n), np.zeros(self.n)
        self.authority = np.ones(self.n)
        self.lower, self.upper = np.full(self.n, -math.inf), np.full(self.n, math.inf)
        self.intermittent: dict[int, tuple[float, float]] = {}

    def add(self, joint: int, fault: Fault, time: float, stops: tuple[float, float]) -> None:
        """`fault` on joint index `joint` from plant time `time` (s); `stops` of a range fault."""
        self.faults.setdefault(joint, {})[fault.kind] = fault
        kind = fault.kind
        if kind is FaultKind.VISCOUS:
            self.viscous[joint] = fault.severity
        elif kind is FaultKind.DRY:
            self.dry[joint] = fault.severity
        elif kind is FaultKind.AUTHORITY:
            self.authority[joint] = fault.severity
        elif kind is FaultKind.RANGE:
            self.lower[joint], self.upper[joint] = stops
        elif kind is FaultKind.INTERMITTENT:
            self.intermittent[joint] = (fault.period, time)
        else:
            raise FaultError(f"{kind} is not a degradation (the plant's lock or swing)")

    def braked(self, time: float) -> set[int]:
        """The intermittent joints in a locked phase at plant time `time` (s).

        Phase k = floor((time - injected) / period): locked for even k, free for odd k.
        """
        return {j for j, (period, since) in self.intermittent.items()
                if math.floor((time - since) / period + 1e-9) % 2 == 0}

    def kinematic_velocity(self, u: np.ndarray, velocity_limits: np.ndarray) -> np.ndarray:
        """The kinematic plant's analogue: the velocity (rad/s) a degraded drive gives for u.

        A velocity loop of gain K = `DRIVE_DAMPING` settles where K (u - v) balances the
        friction: v = u K / (K + b) under viscous friction b, |v| = max(|u| - d / K, 0)
        (a dead band) under dry friction d; an authority a leaves a of the velocity limit.
        """
        v = u * DRIVE_DAMPING / (DRIVE_DAMPING + self.viscous)
        v = np.sign(v) * np.maximum(np.abs(v) - self.dry / DRIVE_DAMPING, 0.0)
        fastest = self.authority * velocity_limits
        return np.clip(v, -fastest, fastest)


#: The numbers `from_spec` takes when a spec gives none: the severities of the measurements
#: that motivated the library (viscous 50, dry 5, authority 0.3), a 1 s jam, a 0.1 rad stop.
SPEC_DEFAULTS = {FaultKind.VISCOUS: 50.0, FaultKind.DRY: 5.0, FaultKind.AUTHORITY: 0.3,
                 FaultKind.INTERMITTENT: 1.0, FaultKind.RANGE: 0.1}


def parse_spec(spec: str) -> tuple[FaultKind, float]:
    """`KIND[:VALUE]` (a command line's fault) as (kind, value; `SPEC_DEFAULTS` if none).

    VALUE is the severity (viscous, dry, authority), the period (intermittent) or how far
    (rad) the new stops lie on either side of the joint (range); lock and free_swing take
    none.

    Raises:
        FaultError: an unknown kind, a value that is not a number, or one a kind takes not.
    """
    name, _, value = spec.partition(":")
    try:
        kind = FaultKind(name)
    except ValueError:
        raise FaultError(f"unknown fault kind {name[:40]!r} (one of "
                         f"{', '.join(FaultKind)})") from None
    if not value:
        return kind, SPEC_DEFAULTS.get(kind, math.nan)
    if kind not in SPEC_DEFAULTS:
        raise FaultError(f"{kind} takes no value")
    try:
        number = float(value)
    except ValueError:
        raise FaultError(f"{kind}: {value[:40]!r} is not a number") from None
    if not (math.isfinite(number) and number > 0):
        raise FaultError(f"{kind}: {number} must be finite and > 0")
    return kind, number


def from_spec(spec: str, joint: str, q: float, lower: float, upper: float) -> Fault:
    """The fault a `KIND[:VALUE]` spec (`parse_spec`) names on `joint`, now at q (rad).

    A range fault's stops lie VALUE rad either side of q, within [lower, upper].

    Raises:
        FaultError: a spec `parse_spec` refuses, or a value out of the kind's range.
    """
    kind, value = parse_spec(spec)
    if kind is FaultKind.RANGE:
        return Fault(kind, joint, lower=max(q - value, lower), upper=min(q + value, upper))
    if kind is FaultKind.INTERMITTENT:
        return Fault(kind, joint, period=value)
    if kind.fields == ("severity",):
        return Fault(kind, joint, severity=value)
    return Fault(kind, joint)
