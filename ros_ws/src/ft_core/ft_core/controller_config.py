"""What the controller's cycle reads besides the engine's configuration (`controller`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ft_core.command_limits import LimitsConfig
from ft_core.observability import ObservabilityConfig
from ft_core.recovery import RecoveryConfig
from ft_core.targets import PoseTracking


@dataclass(frozen=True)
class ControllerConfig:
    """What the cycle reads besides the engine's configuration.

    Attributes:
        state_timeout: s; an older joint state stops the arm (explicit zeros).
        target_timeout: s; an older twist decays linearly to 0 over one more timeout.
        idle_null_space_motion: with no target (or a pose goal reached), allow the
            null-space terms to move the arm; otherwise hold still.
        tracking: pose-goal tracking gains and caps.
        observability: the excursions' settings; None: no excursions.
        recovery: when and how to go round a stall after a lock (`ft_core.recovery`);
            None: never.
        limits: the acceleration and jerk limits every command is smoothed into
            (`ft_core.smoothing`); None: raw commands (which a real driver refuses).
    """

    state_timeout: float = 0.1
    target_timeout: float = 0.5
    idle_null_space_motion: bool = False
    tracking: PoseTracking = field(default_factory=PoseTracking)
    observability: ObservabilityConfig | None = None
    recovery: RecoveryConfig | None = field(default_factory=RecoveryConfig)
    limits: LimitsConfig | None = field(default_factory=LimitsConfig)
