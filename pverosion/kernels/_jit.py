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
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba

__all__ = ["njit"]


def njit(*args: Any, **options: Any) -> Callable:
    """``numba.njit`` with ``no_cfunc_wrapper=True`` unless given; same arguments, same use with or without
    parentheses."""
    options.setdefault("no_cfunc_wrapper", True)
    return numba.njit(*args, **options)
