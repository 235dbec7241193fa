"""The numba decorator every kernel is compiled with: one place for the options all kernels share.

``numba.njit`` builds two wrappers around every function it compiles, callees
included: one that Python calls, and a C-callable one (the "cfunc wrapper")
used only when a compiled function is passed as a first-class function
value, which no kernel does. Leaving out the second saves LLVM work on every
function without changing what runs: 0.1 to 1.9 of about 22 CPU seconds of a
Boolean union's compilation on a fresh install, in five pairs of
``benchmarks/bench_cold_start.py --per-kernel`` runs. The Python wrapper
stays: a function compiled without it crashes the process when Python calls
it.

Indexing is the other shared concern: numba tests every signed index for a
negative value, to count it from the end as Python does. :func:`unsigned`
marks an index known to be non-negative (a vertex, face or slot number read
from an array), so the hot scatter and gather loops skip that test.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba
import numpy as np

__all__ = ["njit", "unsigned"]


def njit(*args: Any, **options: Any) -> Callable:
    """``numba.njit`` with ``no_cfunc_wrapper=True`` unless given; same arguments, same use with or without
    parentheses."""
    options.setdefault("no_cfunc_wrapper", True)
    return numba.njit(*args, **options)


@njit(cache=True, inline="always")
def unsigned(i):
    """Index ``i``, known to be non-negative, as an unsigned integer: numba then indexes with it without the test
    for a negative index. Use it only as a subscript: arithmetic mixing it with signed integers gives floats."""
    return np.uint64(i)
