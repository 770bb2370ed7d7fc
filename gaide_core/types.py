"""The array aliases every package annotates with (one definition, not one per module)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

#: Float arrays: joint vectors, paths, points, poses (float64 throughout the project).
Array = npt.NDArray[np.float64]
#: The same alias under the name some modules read better with.
FloatArray = npt.NDArray[np.float64]
#: Index arrays: table offsets, voxel indices, pixel coordinates.
IntArray = npt.NDArray[np.int64]
#: Masks.
BoolArray = npt.NDArray[np.bool_]

__all__ = ["Array", "BoolArray", "FloatArray", "IntArray"]
