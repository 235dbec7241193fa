"""Parallel loops without numba's parfors: serial ``nogil`` kernels run on index ranges in a thread pool.

A ``parallel=True`` kernel costs several seconds of compilation per loop
(numba builds, types and lowers a separate gufunc for every ``prange``) on
the first run after an install. A serial kernel over an index range
``[start, stop)``, compiled with ``nogil=True``, compiles in a fraction of
that; these helpers run it on several ranges at once from a pool of Python
threads, which run in parallel because the kernel releases the GIL.

The number of threads is ``numba.get_num_threads()``, so
``NUMBA_NUM_THREADS``, :func:`numba.set_num_threads` and the per-stage caps
of :func:`pverosion._runtime.stage_run` apply as they do to parfors.
Results never depend on it: :func:`for_ranges` splits items whose results
are written independently, and :func:`for_chunks` runs the fixed
:data:`~pverosion.kernels._scatter.CHUNKS` chunks of a deterministic
scatter-add, each into its own accumulator.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

from pverosion.kernels._scatter import CHUNKS

__all__ = ["HEAVY_ITEMS_PER_RANGE", "MIN_ITEMS_PER_RANGE", "for_chunks", "for_ranges", "range_count"]

MIN_ITEMS_PER_RANGE = 2048
"""Smallest range handed to a thread by default: below it, one call in the calling thread is cheaper."""

HEAVY_ITEMS_PER_RANGE = 64
"""Smallest range for kernels with much work per item (pair tests, polygon cuts, ray casts)."""

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def _threads() -> int:
    import numba

    return numba.get_num_threads()


def _executor() -> ThreadPoolExecutor:
    global _pool
    with _pool_lock:
        if _pool is None:
            import numba

            _pool = ThreadPoolExecutor(max_workers=numba.config.NUMBA_NUM_THREADS, thread_name_prefix="pverosion")
        return _pool


def _run(calls: list[tuple]) -> None:
    """Run ``kernel(*args)`` for each ``(kernel, args)``: the first in this thread, the others in the pool."""
    if len(calls) == 1:
        kernel, args = calls[0]
        kernel(*args)
        return
    futures = [_executor().submit(kernel, *args) for kernel, args in calls[1:]]
    kernel, args = calls[0]
    try:
        kernel(*args)
    finally:
        for future in futures:
            future.result()


def for_ranges(kernel: Callable, n_items: int, *args, min_items: int = MIN_ITEMS_PER_RANGE) -> None:
    """Call ``kernel(*args, start, stop)`` on consecutive ranges covering ``[0, n_items)``, in parallel.

    ``kernel`` must release the GIL (``@njit(nogil=True)``) and write only
    the results of the items in its range.

    Parameters
    ----------
    kernel : callable
        Serial kernel over one range.
    n_items : int
        Number of items.
    *args
        Leading arguments of ``kernel``.
    min_items : int, default: MIN_ITEMS_PER_RANGE
        Smallest range worth a thread; lower it for kernels with much work per item.
    """
    parts = range_count(n_items, min_items=min_items)
    bounds = [p * n_items // parts for p in range(parts + 1)]
    _run([(kernel, (*args, bounds[p], bounds[p + 1])) for p in range(parts)])


def range_count(n_items: int, *, min_items: int = MIN_ITEMS_PER_RANGE) -> int:
    """Number of ranges :func:`for_ranges` splits ``n_items`` into: one per thread, none below ``min_items``."""
    return max(1, min(_threads(), n_items // max(1, min_items)))


def _chunk_group(kernel: Callable, chunks: range, args: tuple) -> None:
    for c in chunks:
        kernel(*args, c)


def for_chunks(kernel: Callable, n_items: int, *args) -> None:
    """Call ``kernel(*args, c)`` for every chunk ``c`` of :data:`~pverosion.kernels._scatter.CHUNKS`, in parallel.

    Each call handles the items of
    :func:`~pverosion.kernels._scatter.chunk_range` ``(n_items, c)`` and adds
    into accumulator ``c`` only; ``kernel`` must release the GIL.

    Parameters
    ----------
    kernel : callable
        Serial kernel over one chunk.
    n_items : int
        Number of items (faces) split into chunks; small inputs run in one thread.
    *args
        Leading arguments of ``kernel``.
    """
    threads = max(1, min(_threads(), CHUNKS, n_items // MIN_ITEMS_PER_RANGE))
    _run([(_chunk_group, (kernel, range(t, CHUNKS, threads), args)) for t in range(threads)])
