"""Input checks of the per-cycle path, compiled (numba): cheaper than numpy at this size."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def all_finite(values: np.ndarray) -> bool:
    """Whether every entry of a 1-D float array is finite (no nan, no inf)."""
    for value in values:
        if not np.isfinite(value):
            return False
    return True
