"""Binary search in sorted integer arrays, shared by the kernels.

One small kernel instead of ``np.searchsorted``, whose compilation inside a
numba kernel costs several times more.
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels._jit import njit

__all__ = ["lower_bound"]


@njit(cache=True)
def lower_bound(sorted_values: np.ndarray, lo: int, hi: int, value: int) -> int:
    """First index in ``[lo, hi)`` of the ascending (n,) integer array ``sorted_values`` whose entry is
    >= ``value`` (``hi`` if none), as ``np.searchsorted`` on ``sorted_values[lo:hi]`` plus ``lo``."""
    while lo < hi:
        mid = (lo + hi) // 2
        if sorted_values[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo
