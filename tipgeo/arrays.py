"""Array type aliases for annotations (issue 30).

Shapes and units are not part of the type: each function's docstring names
them (mm and radians, cannula frame: +z along the axis toward the tip, γ about
+z from the heel).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["FloatArray", "IntArray", "BoolArray", "AnyArray", "ArrayLike"]

#: An array of float64 (coordinates in mm, angles in radians, forces in N …).
FloatArray = npt.NDArray[np.float64]

#: An array of integer indices (triangle corners, labels, counts).
IntArray = npt.NDArray[np.integer[Any]]

#: An array of booleans (masks).
BoolArray = npt.NDArray[np.bool_]

#: An array of any dtype (readers, before the dtype is settled).
AnyArray = npt.NDArray[Any]

#: Anything numpy turns into an array.
ArrayLike = npt.ArrayLike
