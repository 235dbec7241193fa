"""Allocation-free 3-vector arithmetic on tuples, for use inside numba kernels.

Small NumPy arrays created inside a ``prange`` loop are heap allocations;
tuples stay in registers, which makes the per-face and per-vertex loops
several times faster.

The functions are ordinary numba functions, not ``inline="always"``: LLVM
inlines them into the kernels all the same (the machine code of a kernel has
no call left), while numba's own inlining types and lowers their bodies again
at every call site; on the weathering stage that cost 1.6 CPU s of the 15.7 s
its kernels take to compile after an install.
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels._jit import njit


@njit(cache=True)
def row(a, i):
    """Row ``i`` of an (N, 3) array as a tuple."""
    return (a[i, 0], a[i, 1], a[i, 2])


@njit(cache=True)
def sub(a, b):
    """a - b."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True)
def add(a, b):
    """a + b."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True)
def scale(a, s):
    """s * a."""
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(cache=True)
def dot(a, b):
    """a . b."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def cross(a, b):
    """a x b."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True)
def norm(a):
    """|a|."""
    return np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit(cache=True)
def store(out, i, a):
    """out[i] = a for an (N, 3) array."""
    out[i, 0] = a[0]
    out[i, 1] = a[1]
    out[i, 2] = a[2]
