"""Array aliases used throughout the package."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]
#: Small nonnegative integers per entry in the narrowest type that holds them (ranks
#: among a state's choices).
RankArray = npt.NDArray[np.integer[Any]]
CsrMatrix = sp.csr_matrix
