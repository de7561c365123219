"""Self-motion manifolds of critical task points and their bounding boxes.

Lewis & Maciejewski 1997, secs. II-IV.

The configurations that put the tool at a task point x* form the self-motion
manifold of x*, of dimension r = n - m; the null space of J is its tangent space.
If a joint locks anywhere inside the manifold's bounding box (per joint, min and
max over the manifold), some configuration of the manifold still has that joint
at that value, so the reduced robot can still reach x* (Lewis & Maciejewski 1997 sec. II-III).

Modules:
    manifold: the traced `Manifold`, Newton projection onto it (`project`), its
        tangent space (`null_basis`), a first configuration on it (`find_seed`).
    tracing: `trace`, the walks that follow a manifold (curve, spiral, extremal).
    boxes: bounding boxes, their intersection, soft limits from critical points.
    lock_recovery: configurations of a manifold with a locked joint (`recover`).
    critical_points: the flat-list form of critical points, points near a configuration.
"""

from ft_core.selfmotion.boxes import (
    MAX_SEEDS,
    CriticalBoxes,
    SoftLimits,
    bounding_box,
    box_volume,
    critical_boxes,
    empty_joints,
    intersect,
    reachability,
    soft_limits,
    soft_limits_for_model,
)
from ft_core.selfmotion.critical_points import (
    bent_configuration,
    flat_from_targets,
    point_size,
    points_around,
    targets_from_flat,
)
from ft_core.selfmotion.lock_recovery import recover, recovery_configuration
from ft_core.selfmotion.manifold import (
    NEWTON_DAMPING,
    STEP,
    TOLERANCE,
    Manifold,
    UnreachableError,
    check_target,
    find_seed,
    near,
    null_basis,
    project,
)
from ft_core.selfmotion.tracing import (
    BRANCH_DIRECTIONS,
    BRANCH_OFFSET,
    BRANCH_SIGMA,
    EXPLORE_LENGTH,
    EXTREMAL_ROUNDS,
    MAX_BRANCHES,
    SPIRAL_SPACING,
    SPIRAL_STEP_FACTOR,
    trace,
)

__all__ = [
    "BRANCH_DIRECTIONS", "BRANCH_OFFSET", "BRANCH_SIGMA", "EXPLORE_LENGTH", "EXTREMAL_ROUNDS",
    "MAX_BRANCHES", "MAX_SEEDS", "NEWTON_DAMPING", "SPIRAL_SPACING", "SPIRAL_STEP_FACTOR",
    "STEP", "TOLERANCE", "CriticalBoxes", "Manifold", "SoftLimits", "UnreachableError",
    "bent_configuration", "bounding_box", "box_volume", "check_target", "critical_boxes",
    "empty_joints", "find_seed", "flat_from_targets", "intersect", "near", "null_basis",
    "point_size", "points_around", "project", "reachability", "recover",
    "recovery_configuration", "soft_limits", "soft_limits_for_model", "targets_from_flat",
    "trace",
]
