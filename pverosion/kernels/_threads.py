"""Parallel loops without numba's parfors: serial ``nogil`` kernels run on index ranges in a thread pool.

A ``parallel=True`` kernel costs several seconds of compilation per loop
(numba builds, types and lowers a separate gufunc for every ``prange``) on
the first run after an install. A serial kernel over an index range
``[start, stop)``, compiled with ``nogil=True``, compiles in a fraction of
that; these helpers run it on several ranges at once from a pool of Python
threads, which run in parallel because the kernel releases the GIL.

The pieces of a loop are claimed one at a time, by the calling thread and by
the pool threads it wakes: a thread that starts late (on a machine busy with
other processes) takes fewer pieces, and the caller waits only for the
pieces already started, never for a thread still asleep.

The number of threads is ``numba.get_num_threads()``, so
``NUMBA_NUM_THREADS``, :func:`numba.set_num_threads` and the per-stage caps
of :func:`pverosion._runtime.stage_run` apply as they do to parfors. While
the count is numba's default, threads are added when other programs are
running (:func:`other_running`), so that a busy machine slows a loop in
proportion to the share of the cores it loses.
Results never depend on it, nor on which thread runs which piece:
:func:`for_ranges` splits items whose results are written independently, and
:func:`for_chunks` runs the fixed :data:`~pverosion.kernels._scatter.CHUNKS`
chunks of a deterministic scatter-add, each into its own accumulator.
"""

from __future__ import annotations

import itertools
import os
import threading
import time
from collections.abc import Callable
from queue import SimpleQueue

from pverosion.kernels._scatter import CHUNKS

__all__ = ["BUSY_PIECES_PER_THREAD", "HEAVY_ITEMS_PER_RANGE", "LOAD_CHECK_S", "MIN_ITEMS_PER_RANGE",
           "PIECES_PER_THREAD", "adapt_to_load", "for_chunks", "for_ranges", "other_running", "range_count"]

MIN_ITEMS_PER_RANGE = 2048
"""Smallest range handed to a thread by default: below it, one call in the calling thread is cheaper."""

HEAVY_ITEMS_PER_RANGE = 64
"""Smallest range for kernels with much work per item (pair tests, polygon cuts, ray casts)."""

PIECES_PER_THREAD = 4
"""Ranges per thread :func:`for_ranges` splits a loop into (when they keep ``min_items``), so that the threads
that start first take over the pieces of one that starts late."""


BUSY_PIECES_PER_THREAD = 16
"""Ranges per thread when other programs are running (:func:`other_running`): a thread that the system suspends
in the middle of a piece then holds back a smaller part of the loop."""

LOAD_CHECK_S = 0.05
"""Seconds for which one reading of the system's running-thread count (:func:`other_running`) is reused."""

_load_seen = [-1.0, 0, 0]  # time of the last reading, threads of other programs running then and the time before
_adapt = [True]


class _Loop:
    """The pieces ``(kernel, args)`` of one parallel loop, claimed one at a time by the threads that run them."""

    __slots__ = ("calls", "claims", "done", "error", "finished", "n")

    def __init__(self, calls: list[tuple]) -> None:
        self.calls = calls
        self.n = len(calls)
        self.claims = itertools.count()  # next() is atomic: each piece goes to one thread
        self.done = itertools.count(1)
        self.finished = threading.Lock()  # released when the last piece is done
        self.finished.acquire()
        self.error: BaseException | None = None

    def work(self) -> None:
        """Run unclaimed pieces until none is left; after an error (or Ctrl-C) the rest are only counted."""
        n = self.n
        while True:
            i = n
            try:
                i = next(self.claims)
                if i < n and self.error is None:
                    kernel, args = self.calls[i]
                    kernel(*args)
            except BaseException as exc:  # noqa: BLE001 - re-raised in the caller once the pieces in flight end
                if self.error is None:
                    self.error = exc
            finally:
                if i < n and next(self.done) == n:
                    self.finished.release()
            if i >= n:
                return


class _Pool:
    """Daemon threads waiting on one queue for loops to work on, started as the loops need them."""

    def __init__(self) -> None:
        self.queue: SimpleQueue[_Loop] = SimpleQueue()
        self.size = 0
        self.lock = threading.Lock()

    def wake(self, count: int, loop: _Loop) -> None:
        """Hand ``loop`` to ``count`` threads (each claims pieces until none is left)."""
        if self.size < count:
            with self.lock:
                while self.size < count:
                    threading.Thread(target=self._serve, name=f"pverosion-{self.size}", daemon=True).start()
                    self.size += 1
        for _ in range(count):
            self.queue.put(loop)

    def _serve(self) -> None:
        while True:
            self.queue.get().work()


_pool = _Pool()


def _reset_pool() -> None:
    global _pool
    _pool = _Pool()  # the threads of the parent do not exist in a forked child


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_pool)


def adapt_to_load(enabled: bool) -> None:
    """Let the default thread count grow while other programs run (the default), or keep it fixed.

    A batch job on a Dask worker turns it off for the worker: the other
    programs running there are mostly the batch's other workers.
    """
    _adapt[0] = bool(enabled)


def other_running() -> int:
    """Threads of other programs running or waiting for a core now (Linux), besides the calling one; 0 elsewhere.

    The smaller count of the last two readings of the running-entity count of
    ``/proc/loadavg``, taken at most every :data:`LOAD_CHECK_S` seconds, so
    that a program running for a moment (or a thread of this one, finishing)
    does not count.
    """
    now = time.monotonic()
    if now - _load_seen[0] >= LOAD_CHECK_S:
        try:
            with open("/proc/loadavg", "rb") as f:
                running = int(f.read().split()[3].split(b"/")[0])
        except (OSError, ValueError, IndexError):
            running = 1
        _load_seen[0], _load_seen[1], _load_seen[2] = now, max(0, running - 1), _load_seen[1]
    return min(_load_seen[1], _load_seen[2])


def _threads() -> int:
    """Threads for a loop: ``numba.get_num_threads()``, plus two per running thread of another program (at most
    the count again) when the count is numba's default and ``NUMBA_NUM_THREADS`` is not set.

    With ``k`` threads of other programs running on ``c`` cores, a loop on
    ``c`` threads gets at most ``c / (c + k)`` of the cores, less when the
    system suspends one of its threads in the middle of a piece and the loop
    end waits for it; on ``c + 2k`` threads it gets ``(c + 2k) / (c + 3k)``
    of them, and a suspended thread holds back a smaller part of the loop.
    """
    import numba

    n = numba.get_num_threads()
    if _adapt[0] and n == numba.config.NUMBA_DEFAULT_NUM_THREADS and "NUMBA_NUM_THREADS" not in os.environ:
        n += min(n, 2 * other_running())
    return n


def _run(calls: list[tuple], threads: int) -> None:
    """Run ``kernel(*args)`` for each ``(kernel, args)`` on up to ``threads`` threads, this one included.

    The first error of a piece is raised here once the pieces already started
    are done; the pieces not yet started are then skipped.
    """
    if threads <= 1 or len(calls) == 1:
        for kernel, args in calls:
            kernel(*args)
        return
    loop = _Loop(calls)
    _pool.wake(min(threads, len(calls)) - 1, loop)
    try:
        loop.work()
        loop.finished.acquire()
    except BaseException as exc:  # interrupted outside a piece: the pieces not yet started are skipped
        if loop.error is None:
            loop.error = exc
        raise
    if loop.error is not None:
        raise loop.error


def for_ranges(kernel: Callable, n_items: int, *args, min_items: int = MIN_ITEMS_PER_RANGE) -> None:
    """Call ``kernel(*args, start, stop)`` on consecutive ranges covering ``[0, n_items)``, in parallel.

    ``kernel`` must release the GIL (``@njit(nogil=True)``) and write only
    the results of the items in its range. With several threads the items
    are split into up to :data:`PIECES_PER_THREAD` ranges per thread, none
    shorter than ``min_items``.

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
    threads = range_count(n_items, min_items=min_items)
    if threads == 1:
        kernel(*args, 0, n_items)
        return
    import numba

    per_thread = BUSY_PIECES_PER_THREAD if threads > numba.get_num_threads() else PIECES_PER_THREAD
    parts = min(threads * per_thread, n_items // max(1, min_items))
    bounds = [p * n_items // parts for p in range(parts + 1)]
    _run([(kernel, (*args, bounds[p], bounds[p + 1])) for p in range(parts)], threads)


def range_count(n_items: int, *, min_items: int = MIN_ITEMS_PER_RANGE) -> int:
    """Threads :func:`for_ranges` runs ``n_items`` on: one per thread, none for fewer than ``min_items`` items."""
    return max(1, min(_threads(), n_items // max(1, min_items)))


def for_chunks(kernel: Callable, n_items: int, *args, min_items: int = MIN_ITEMS_PER_RANGE) -> None:
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
    min_items : int, default: MIN_ITEMS_PER_RANGE
        Fewest items per thread; raise it for passes so short that waking a thread costs more than it saves.
    """
    threads = max(1, min(_threads(), CHUNKS, n_items // max(1, min_items)))
    _run([(kernel, (*args, c)) for c in range(CHUNKS)], threads)
