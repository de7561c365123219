"""Locked-joint detection against an identified model of the plant (docs/detection.md).

One concept per module:
    plant_model: the commands sent and the positions a candidate model predicts from them.
    buffers: the growing arrays the streams of commands, measurements and offsets use.
    window: the sliding window of measurements, its least-squares fits and offsets.
    identification: the bank of candidate models, their scores and the plausible set.
    rules: the decision rules (observable, stalled, following, at a limit, on its own,
        lost position, plant fault, no decision without evidence), one function each.
    evidence: each joint's evidence, when it becomes a declaration (persistence, the
        settling time of a disturbed arm), and the detector's answers (`Update`,
        `Confirmation`).
    follow: the share of its command each joint follows, and degraded joints.
    config: `DetectorConfig`, the detector's parameters.
    detector: `LockDetector`, which applies them to streams of commands and measurements.
"""

from ft_core.detection.config import DetectorConfig
from ft_core.detection.detector import (
    DECISION_PERIOD,
    SUSPECT_SPAN,
    LockDetector,
    compile_ahead,
)
from ft_core.detection.evidence import Confirmation, Decision, JointEvidence, Update
from ft_core.detection.identification import (
    IDENTIFY_PERIOD,
    LATENCY_GRID,
    LATENCY_MARGIN,
    RESPONSE_STEPS,
    RESPONSE_TIME_GRID,
    PlantEstimate,
)
from ft_core.detection.plant_model import CommandHistory, _add_command
from ft_core.detection.rules import classify as _classify
from ft_core.detection.spans import SLOW_SPAN
from ft_core.detection.window import (
    Offsets,
    Samples,
    _accumulate,
    _ingest,
    _largest_step,
    _window_fit,
)

__all__ = [
    "DECISION_PERIOD",
    "IDENTIFY_PERIOD",
    "LATENCY_GRID",
    "LATENCY_MARGIN",
    "RESPONSE_STEPS",
    "RESPONSE_TIME_GRID",
    "SLOW_SPAN",
    "SUSPECT_SPAN",
    "CommandHistory",
    "Confirmation",
    "Decision",
    "DetectorConfig",
    "JointEvidence",
    "LockDetector",
    "Offsets",
    "PlantEstimate",
    "Samples",
    "Update",
    "_accumulate",
    "_add_command",
    "_classify",
    "_ingest",
    "_largest_step",
    "_window_fit",
    "compile_ahead",
]
