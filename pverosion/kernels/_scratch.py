"""Large scratch arrays in memory backed by transparent huge pages.

Kernels over meshes of hundreds of thousands of vertices need scratch arrays
of tens of megabytes (per-chunk accumulators, renumbered coordinates). Served
by the C heap they come back, call after call, as freshly mapped 4 kB pages
once the heap has been trimmed, and faulting those in can cost as much as the
computation (a 400k-face curvature spent more time in page faults than in
arithmetic). :func:`scratch_arrays` carves several arrays out of one
anonymous memory map aligned to 2 MB and advised for transparent huge pages
(``MADV_HUGEPAGE``), which faults in 512 times fewer pages; owners that call a
kernel repeatedly keep the arrays and reuse them.

Requests below :data:`MIN_MAPPED_BYTES`, and systems without
``MADV_HUGEPAGE``, get ordinary zeroed NumPy arrays.
"""

from __future__ import annotations

import mmap

import numpy as np

__all__ = ["HUGE_PAGE", "MIN_MAPPED_BYTES", "scratch_arrays"]

HUGE_PAGE = 2 << 20
"""Alignment of the map and size of a transparent huge page on x86_64 and arm64 (bytes)."""

MIN_MAPPED_BYTES = 32 << 20
"""Smallest total size served by a memory map. Smaller requests come from the heap, which under the
allocator settings of :mod:`pverosion._runtime` (arrays up to 32 MB from the heap, up to 64 MB of freed
memory kept at its top) is not trimmed for them, so their pages stay mapped between calls."""

_ALIGN = 64
"""Alignment of every array inside the map (a cache line)."""


def _mapped(nbytes: int) -> np.ndarray | None:
    """A zeroed uint8 buffer of ``nbytes`` starting on a :data:`HUGE_PAGE` boundary, or None."""
    advice = getattr(mmap, "MADV_HUGEPAGE", None)
    if advice is None:
        return None
    try:
        area = mmap.mmap(-1, nbytes + HUGE_PAGE, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
        area.madvise(advice)
    except (OSError, ValueError, AttributeError):
        return None
    raw = np.frombuffer(area, dtype=np.uint8)
    skip = -raw.ctypes.data % HUGE_PAGE
    return raw[skip:skip + nbytes]


def scratch_arrays(*specs: tuple[tuple[int, ...], type]) -> list[np.ndarray]:
    """Zeroed C-contiguous arrays of the given shapes and dtypes, sharing one huge-page-backed map.

    Parameters
    ----------
    *specs : (shape, dtype)
        One pair per array.

    Returns
    -------
    list of numpy.ndarray
        Writeable and zero-filled. Those sharing a map (a total of at least
        :data:`MIN_MAPPED_BYTES`) start on 64-byte boundaries and keep the map
        alive; it is released when the last of them is freed.
    """
    sizes = [int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize for shape, dtype in specs]
    offsets = np.concatenate(([0], np.cumsum([-(-size // _ALIGN) * _ALIGN for size in sizes])))
    buffer = _mapped(int(offsets[-1])) if offsets[-1] >= MIN_MAPPED_BYTES else None
    if buffer is None:
        return [np.zeros(shape, dtype) for shape, dtype in specs]
    return [buffer[start:start + size].view(dtype).reshape(shape)
            for (shape, dtype), start, size in zip(specs, offsets[:-1], sizes)]
