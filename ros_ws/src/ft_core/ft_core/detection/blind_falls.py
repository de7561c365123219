"""The one decision while the commands predict nothing: a silent drive's fall.

While the detector's own reasons keep it from judging motion against the commands
(`rules.not_observing`: their stream paused, settling after it restarted; or the plant
not yet seen following them), the plant holds a command it was sent lately, answers an
older one, or stops. A joint whose drive is silent (`drives.Drives.silent`) and which
falls faster than every command kept and than rest (`rules.falls_past_every_command`)
swings whatever the plant does with them: it is declared free-swinging after
`persistence`, as any free swing (docs/monitor.md, "While the commands predict
nothing"; Maciejewski et al. sec. 2.3).
"""

from __future__ import annotations

import numpy as np

from ft_core.detection import rules
from ft_core.detection.config import DetectorConfig
from ft_core.detection.evidence import Disturbance, JointEvidence, declare_swings
from ft_core.detection.identification import PlantIdentification
from ft_core.detection.window import Samples, _window_fit


def declare_falls(now: float, joints: list[JointEvidence], kept: list[float | None],
                  samples: Samples, commands: np.ndarray, silent: np.ndarray,
                  falling: np.ndarray, plant: PlantIdentification,
                  config: DetectorConfig, declared_at: float,
                  ) -> tuple[list[int], list[int]]:
    """Joints newly declared free-swinging at `now` (s), and those of them that were locked.

    `joints`' evidence was cleared at this update; `kept[j]` is joint j's free-swing
    evidence start (s) before that, carried on where it still falls. `commands` (k x n,
    rad/s) are those the detector keeps, `silent` (n,) the joints whose drives give no
    torque, `falling` (n,) the signs of gravity's acceleration on each joint;
    `declared_at` (s) when a joint was last declared (the disturbance after it,
    `evidence.Disturbance`). Nothing is declared over too few measurements
    (`rules.too_few_samples`).
    """
    window = samples.window()
    if rules.too_few_samples(window[0], config.window, config.min_samples):
        return [], []
    measured, _, error = _window_fit(*window, samples.predicted_sum, samples.timed_sum,
                                     samples.base, plant.plausible_models, plant.best)
    fastest = rules.fastest_fall(commands, falling)
    free = np.array([e.locked_at is None and e.swinging_at is None for e in joints])
    own = rules.falls_past_every_command(silent, measured, error, fastest, falling, free,
                                         config.min_command, config.confidence)
    for j in np.flatnonzero(own).tolist():
        joints[j].swing_since = kept[j]
        joints[j].measured = float(measured[j])
        joints[j].commanded = float(falling[j] * fastest[j])
    settle = plant.settling_time(plant.best)
    swinging, released, _ = declare_swings(
        joints, own.tolist(), now, Disturbance(joints, now, declared_at + settle),
        config.persistence, settle, lambda j, since: 0.0)
    return swinging, released
