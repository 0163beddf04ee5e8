"""Type stubs of reflectance.linalg."""

from typing import Optional

import numpy as np
import numpy.typing as npt

def gram(
    a: npt.NDArray[np.floating], b: Optional[npt.NDArray[np.floating]] = None
) -> npt.NDArray[np.float64]:
    """``a @ b.T`` as a float64 array of shape (m, n), for ``a`` of shape (m, d) and ``b`` of
    shape (n, d); ``a @ a.T`` when ``b`` is None.

    Computed by the toolkit's Gram kernel (``reduce::gram``: SIMD float32 products over blocks
    of 1024 dimensions, float64 sums) with the GIL released, so threads (a Dask worker) run
    in parallel. C-contiguous float32 input is read in place; float64 (or non-contiguous)
    input is converted to float32 first. Raises ValueError when an input is not a 2-D numpy
    array of dtype float32 or float64, or when the row lengths differ.
    """
