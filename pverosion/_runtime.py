"""Threads and first-run compilation: what every stage run goes through.

- :func:`configure_environment` runs when :mod:`pverosion` is imported, before
  numba starts its thread pool: OpenMP threads that wait for work sleep instead
  of spinning (``OMP_WAIT_POLICY=PASSIVE``, ``KMP_BLOCKTIME=0``), so a competing
  process on the same cores costs time in proportion, not tenfold. Variables the
  user has set are left alone.
- :func:`configure_allocator` also runs on import (Linux with glibc): arrays of
  up to 32 MB come from the heap and freed memory stays mapped (up to 256 MB,
  more after a stage on a large input: :func:`keep_heap_for`), so the kernels'
  scratch arrays do not fault in fresh pages on every call.
- :func:`stage_run` wraps one stage's execution: it caps numba's threads for
  small inputs (respecting ``NUMBA_NUM_THREADS`` and :func:`numba.set_num_threads`)
  and, when numba has to compile kernels (an empty cache: a fresh install, a new
  numba version), says so once on stderr with the time it took. While it
  compiles, the objects alive before are kept out of Python's cyclic garbage
  collector and it collects less often (:func:`relax_gc_for_compilation`).

This module does not import numba; it only uses it once a stage runs.
"""

from __future__ import annotations

import gc
import os
import platform
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping, MutableMapping
from contextlib import ExitStack, contextmanager
from typing import TextIO

__all__ = [
    "ALLOCATOR_SETTINGS",
    "COMPILE_GC_THRESHOLD",
    "POINTS_PER_THREAD",
    "THREAD_ENVIRONMENT",
    "WORK_NOT_IN_POINTS",
    "HEAP_KEPT_PER_POINT",
    "configure_allocator",
    "configure_environment",
    "keep_heap_for",
    "relax_gc_for_compilation",
    "restore_gc",
    "stage_run",
    "threads_for",
]

THREAD_ENVIRONMENT: dict[str, str] = {"OMP_WAIT_POLICY": "PASSIVE", "KMP_BLOCKTIME": "0"}
"""Defaults set by :func:`configure_environment` (OpenMP threads sleep when idle)."""

ALLOCATOR_SETTINGS: dict[str, tuple[int, int]] = {
    "M_TRIM_THRESHOLD": (-1, 256 << 20),
    "M_MMAP_THRESHOLD": (-3, 32 << 20),
}
"""glibc ``mallopt`` parameters (number, value in bytes) set by :func:`configure_allocator`."""

_ALLOCATOR_VARIABLES = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_", "MALLOC_MMAP_MAX_")

HEAP_KEPT_PER_POINT = 1024
"""Bytes of freed heap that stay mapped per point of the largest input a stage has run on (:func:`keep_heap_for`):
about what a curvature call frees per point of a large mesh (the twin search, the orientation and the
operator's scratch arrays, some 600 bytes per point at 1.6M faces), with room to spare."""

_allocator: dict[str, object] = {}  # "mallopt" and "trim" once configure_allocator has set them
_allocator_lock = threading.Lock()

POINTS_PER_THREAD = 8192
"""Input points per numba thread: smaller inputs run on fewer threads."""

WORK_NOT_IN_POINTS = frozenset({"hydraulic", "shard-graph", "freeze-thaw"})
"""Stages whose work is set by their options (particles, cells) more than by the input's points: all threads."""

_state = threading.local()  # .active: a stage_run is in progress in this thread (stages do not nest)


def configure_environment(environ: MutableMapping[str, str] | None = None) -> dict[str, str]:
    """Set the :data:`THREAD_ENVIRONMENT` defaults that are not set yet.

    They take effect only if numba has not started its threads yet, which is
    the case when :mod:`pverosion` is imported before any parallel kernel runs.

    Parameters
    ----------
    environ : mutable mapping, optional
        The environment to update (default: ``os.environ``).

    Returns
    -------
    dict
        The variables this call set, with their values.
    """
    environ = os.environ if environ is None else environ
    added = {name: value for name, value in THREAD_ENVIRONMENT.items() if name not in environ}
    environ.update(added)
    return added


def configure_allocator(environ: Mapping[str, str] | None = None,
                        mallopt: Callable[[int, int], int] | None = None) -> dict[str, int]:
    """Keep the kernels' large scratch arrays in memory that stays mapped (glibc only).

    By default glibc serves an allocation of more than 128 kB to 32 MB (the
    limit adapts to the program) with a fresh ``mmap`` and returns it to the
    system when it is freed, so the next call's array faults in its pages
    again. The kernels allocate several such arrays per call (the per-chunk
    sums of the curvature are 4 x V x 4 doubles), and after other libraries
    (VTK filters among them) have run, the fault-in can cost more than the
    computation (``benchmarks/bench_curvature.py`` prints the bunny's kernel
    time between vtkCurvatures calls with and without this). This sets
    :data:`ALLOCATOR_SETTINGS` with ``mallopt``: allocations up to 32 MB come
    from the heap, and up to 256 MB of freed memory at its top stays mapped
    (a curvature call on a 400k-face mesh frees more than 64 MB of them at once;
    with a lower limit the heap is trimmed and the next call faults them in again).

    Nothing is changed when the user has set one of glibc's ``MALLOC_*``
    tuning variables or ``PVEROSION_MALLOC_TUNING=0``, or when the C library
    is not glibc.

    Parameters
    ----------
    environ : mapping, optional
        The environment to read (default: ``os.environ``).
    mallopt : callable, optional
        ``mallopt(parameter, value) -> int`` (default: glibc's, through ctypes).

    Returns
    -------
    dict
        The parameters set, by name, with their values.
    """
    environ = os.environ if environ is None else environ
    if environ.get("PVEROSION_MALLOC_TUNING") == "0" or any(name in environ for name in _ALLOCATOR_VARIABLES):
        return {}
    if mallopt is None:
        if not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc":
            return {}
        import ctypes

        try:
            mallopt = ctypes.CDLL("libc.so.6").mallopt
        except (OSError, AttributeError):
            return {}
    applied = {name: value for name, (number, value) in ALLOCATOR_SETTINGS.items() if mallopt(number, value) == 1}
    if "M_TRIM_THRESHOLD" in applied:
        _allocator.update(mallopt=mallopt, trim=applied["M_TRIM_THRESHOLD"])
    return applied


def _physical_memory() -> int:
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 0


def keep_heap_for(n_points: int, *, memory: int | None = None) -> int:
    """Keep the freed heap of a stage on ``n_points`` points mapped for the next call.

    On a large mesh a stage frees more scratch memory at once than the
    256 MB that :func:`configure_allocator` keeps mapped: at 1.6M faces a
    curvature call then faulted 4,900 pages in again on every call (40 to 90 ms
    of system time, a quarter of the call) once another library had used the
    heap in between. This raises glibc's trim threshold to
    :data:`HEAP_KEPT_PER_POINT` bytes per point, up to an eighth of the
    physical memory, and never lowers it: the process may keep that much
    more resident after the stage. It does nothing unless
    :func:`configure_allocator` has set the threshold (so not with
    ``PVEROSION_MALLOC_TUNING=0`` or glibc's own ``MALLOC_*`` variables).

    Parameters
    ----------
    n_points : int
        Points of the stage's input.
    memory : int, optional
        Physical memory in bytes (default: the machine's).

    Returns
    -------
    int
        The trim threshold now in force, 0 when the allocator is not tuned.
    """
    with _allocator_lock:
        if "mallopt" not in _allocator:
            return 0
        memory = _physical_memory() if memory is None else memory
        wanted = min(HEAP_KEPT_PER_POINT * max(0, int(n_points)), memory // 8)
        number = ALLOCATOR_SETTINGS["M_TRIM_THRESHOLD"][0]
        if wanted > _allocator["trim"] and _allocator["mallopt"](number, wanted) == 1:
            _allocator["trim"] = wanted
        return int(_allocator["trim"])


def threads_for(n_points: int, available: int) -> int:
    """Numba threads for an input of ``n_points`` points: ``n_points / POINTS_PER_THREAD``, in ``[1, available]``.

    Parameters
    ----------
    n_points : int
        Size of the input (points of a surface or of a volume); 0 when unknown.
    available : int
        The threads numba would use otherwise (``numba.get_num_threads()``).
    """
    if n_points <= 0:
        return max(1, available)
    return max(1, min(available, -(-int(n_points) // POINTS_PER_THREAD)))


COMPILE_GC_THRESHOLD = (20_000, 20, 20)
"""Python's cyclic GC thresholds while numba compiles (default ``(700, 10, 10)``): numba's typing and lowering
make millions of short-lived objects, and each collection of the older generations walks every object alive."""


def relax_gc_for_compilation() -> tuple[int, int, int] | None:
    """Keep the objects alive now out of the cyclic GC (:func:`gc.freeze`) and collect less often.

    numba's compilation spends a tenth of its time in the collector otherwise
    (``bench_cold_start.py``, Boolean union, see the performance notes).
    Nothing is changed if some objects are frozen already (by the
    application).

    Returns
    -------
    tuple of int or None
        The previous thresholds, for :func:`restore_gc`; None if nothing was changed.
    """
    if gc.get_freeze_count() > 0:
        return None
    previous = gc.get_threshold()
    gc.freeze()
    gc.set_threshold(*COMPILE_GC_THRESHOLD)
    return previous


def restore_gc(previous: tuple[int, int, int] | None) -> None:
    """Undo :func:`relax_gc_for_compilation` (given what it returned)."""
    if previous is not None:
        gc.unfreeze()
        gc.set_threshold(*previous)


def _cache_location() -> str:
    from numba.core import config

    return config.CACHE_DIR or "the package's __pycache__ folders"


def _compile_notice(stage: str, stream: TextIO):
    """A numba event listener that announces the first compilation, starts the compile helper
    (:mod:`pverosion._precompile`) and sums the compile time; its ``helper`` is the helper process or None."""
    from numba.core import event

    class CompileNotice(event.Listener):
        def __init__(self):
            self.depth = 0
            self.started = 0.0
            self.seconds = 0.0
            self.count = 0  # functions compiled, the ones compiled for a caller included
            self.helper = None
            self.gc_before = None  # the GC thresholds before the first compilation (restore_gc)

        def on_start(self, ev):
            self.count += 1
            if self.depth == 0:
                if self.seconds == 0.0 and self.count == 1:
                    print(f"pverosion {stage}: compiling kernels, once per install (cached in {_cache_location()}) ...",
                          file=stream, flush=True)
                    from pverosion._precompile import start_helper

                    self.helper = start_helper(stage)
                    self.gc_before = relax_gc_for_compilation()
                self.started = time.perf_counter()
            self.depth += 1

        def on_end(self, ev):
            self.depth -= 1
            if self.depth == 0:
                self.seconds += time.perf_counter() - self.started

    return CompileNotice()


@contextmanager
def stage_run(stage: str, n_points: int = 0, *, stream: TextIO | None = None) -> Iterator[None]:
    """Run one stage: fewer numba threads for small inputs, a notice when kernels compile.

    Parameters
    ----------
    stage : str
        Name shown in the notice (the stage's command name).
    n_points : int, default: 0
        Size of the input, for :func:`threads_for`; 0 keeps the thread count,
        as do the stages in :data:`WORK_NOT_IN_POINTS`.
    stream : text stream, optional
        Where the notice goes (default: ``sys.stderr`` at the time of the call).
    """
    if getattr(_state, "active", False):  # a stage inside a stage: the outer one reports
        yield
        return
    import numba
    from numba.core import event

    stream = sys.stderr if stream is None else stream
    keep_heap_for(n_points)
    notice = _compile_notice(stage, stream)
    previous = numba.get_num_threads()
    _state.active = True
    try:
        with ExitStack() as stack:
            stack.enter_context(event.install_listener("numba:compile", notice))
            numba.set_num_threads(threads_for(0 if stage in WORK_NOT_IN_POINTS else n_points, previous))
            stack.callback(numba.set_num_threads, previous)
            yield
    finally:
        _state.active = False
        restore_gc(notice.gc_before)
        if notice.helper is not None:
            from pverosion._precompile import stop_helper

            stop_helper(notice.helper)
        if notice.seconds > 0.0:
            print(f"pverosion {stage}: compiled {notice.count} functions in {notice.seconds:.1f} s", file=stream,
                  flush=True)
