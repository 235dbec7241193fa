"""Deterministic parallel scatter-add from faces to vertices.

Face loops that add into per-vertex sums are split into a fixed number of
contiguous face chunks, each with its own accumulator; the chunk sums are
then added in chunk order. The result is bit-identical whatever the number
of threads, and no atomics are needed. Sorting faces by their smallest vertex
(:func:`pverosion.kernels.mesh.topology.locality_order`) keeps each chunk's
writes local in memory.
"""

from __future__ import annotations

from numba import njit

CHUNKS = 4
"""Number of face chunks (and accumulators) of every scatter-add."""


@njit(cache=True, inline="always")
def chunk_range(n_items, chunk):
    """Half-open index range ``[start, stop)`` of ``chunk`` out of :data:`CHUNKS`."""
    return chunk * n_items // CHUNKS, (chunk + 1) * n_items // CHUNKS


@njit(cache=True, inline="always")
def chunk_total(acc, i, k):
    """Sum over the chunks, in chunk order, of component ``k`` of item ``i`` in ``acc`` (CHUNKS, N, K)."""
    total = acc[0, i, k]
    for c in range(1, CHUNKS):
        total += acc[c, i, k]
    return total
