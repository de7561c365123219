"""Rotations as unit quaternions (x, y, z, w), the order of ROS messages and parameters.

The one conversion between quaternions and rotation matrices of the suite: pose
messages (`ft_msgs_py.convert`) and pose critical points (`ft_core.selfmotion`)
both go through it.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin


def rotation_from_quaternion(quaternion: np.ndarray) -> np.ndarray:
    """The rotation matrix (3x3) of a quaternion (x, y, z, w) of any non-zero finite norm.

    The quaternion is normalised first, divided by its largest component before its
    norm is taken, so components up to the largest finite float do not overflow.
    The caller refuses quaternions that are zero or not finite.
    """
    largest = np.max(np.abs(quaternion))
    x, y, z, w = quaternion / largest
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return pin.Quaternion(w / norm, x / norm, y / norm, z / norm).toRotationMatrix()


def quaternion_from_rotation(rotation: np.ndarray) -> np.ndarray:
    """The unit quaternion (x, y, z, w) of a rotation matrix (3x3), as Eigen computes it."""
    return np.array(pin.Quaternion(np.asarray(rotation)).coeffs())
