"""Array type aliases, defined once for the planner and the GCS."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["BoolArray", "FloatArray", "IntArray"]

#: An array of float64 (positions, velocities, ... in SI units).
FloatArray = NDArray[np.float64]
#: An array of indices.
IntArray = NDArray[np.intp]
#: An array of flags (masks).
BoolArray = NDArray[np.bool_]
