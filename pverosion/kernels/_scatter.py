"""Deterministic parallel scatter-add from faces to vertices.

Face loops that add into per-vertex sums are split into a fixed number of
contiguous face chunks, each with its own accumulator; the chunk sums are
then added in chunk order. The result is bit-identical whatever the number
of threads, and no atomics are needed. Sorting faces by their smallest vertex
(:func:`pverosion.kernels.mesh.topology.locality_order`) keeps each chunk's
writes local in memory.

Kernels whose faces are sorted that way can instead share one accumulator
(:class:`OwnedRows`): each chunk owns the rows from its first face's smallest
vertex to the next chunk's, adds there directly, and sets aside in its own
slots the few corners that fall past them, which are then added in chunk
order. That needs a quarter of the memory, to fill and to read, and is as
independent of the number of threads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pverosion.kernels._jit import njit, unsigned

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


@njit(cache=True, error_model="numpy", inline="always")
def outside_corners(faces, f, lo, hi):
    """How many corners of face ``f`` lie outside rows ``lo`` to ``hi``."""
    n = 0
    for k in range(3):
        if faces[f, k] < lo or faces[f, k] >= hi:
            n += 1
    return n


@njit(cache=True, error_model="numpy", nogil=True)
def _count_outside_chunk(faces, owners, counts, c):
    """Count into ``counts[c]`` the corners of chunk ``c`` of the faces outside the rows it owns."""
    lo, hi = owners[c], owners[c + 1]
    n = 0
    start, stop = chunk_range(faces.shape[0], c)
    for f in range(start, stop):
        n += outside_corners(faces, f, lo, hi)
    counts[c] = n


@dataclass(frozen=True)
class OwnedRows:
    """The rows of one shared accumulator that each face chunk owns, and the slots of the corners outside them.

    Attributes
    ----------
    owners : numpy.ndarray, shape (CHUNKS + 1,), int64
        Chunk ``c`` owns rows ``owners[c]`` to ``owners[c + 1]``; together they cover every row once.
    outside : numpy.ndarray, shape (CHUNKS + 1,), int64
        The corners of chunk ``c`` outside its rows take slots ``outside[c]`` to ``outside[c + 1]``, in face
        and corner order.
    """

    owners: np.ndarray
    outside: np.ndarray

    @property
    def n_outside(self) -> int:
        """Number of slots, all chunks together."""
        return int(self.outside[-1])

    @classmethod
    def from_counts(cls, owners: np.ndarray, counts: np.ndarray) -> OwnedRows:
        """The split of :func:`owner_rows` ``owners`` whose chunk ``c`` has ``counts[c]`` corners outside its rows
        (counted by a pass over the faces that a caller makes anyway, with :func:`outside_corners`)."""
        outside = np.zeros(CHUNKS + 1, np.int64)
        np.cumsum(counts, out=outside[1:])
        return cls(owners, outside)


def owner_rows(faces: np.ndarray, n_rows: int) -> np.ndarray:
    """The ``owners`` (CHUNKS + 1,) of :class:`OwnedRows`: chunk ``c`` owns the rows from the smallest vertex of its
    first face on (monotone whatever the face order).

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_rows : int

    Returns
    -------
    numpy.ndarray, shape (CHUNKS + 1,), int64
    """
    n_faces = faces.shape[0]
    owners = np.full(CHUNKS + 1, n_rows, np.int64)
    owners[0] = 0
    for c in range(1, CHUNKS):
        start = c * n_faces // CHUNKS
        if start < n_faces:
            owners[c] = min(int(faces[start].min()), n_rows)
    return np.maximum.accumulate(owners)


def owned_rows(faces: np.ndarray, n_rows: int) -> OwnedRows:
    """Split the rows of a scatter-add from ``faces`` among the face chunks.

    Chunk ``c`` owns the rows from the smallest vertex of its first face on;
    with the faces sorted by their smallest vertex almost every corner of a
    chunk falls in its own rows. Any face order is handled, only more
    corners take slots.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
        Validated triangles.
    n_rows : int
        Number of accumulator rows (vertices).

    Returns
    -------
    OwnedRows
    """
    from pverosion.kernels._threads import for_chunks  # _threads imports this module

    owners = owner_rows(faces, n_rows)
    counts = np.zeros(CHUNKS, np.int64)
    for_chunks(_count_outside_chunk, faces.shape[0], np.ascontiguousarray(faces), owners, counts)
    return OwnedRows.from_counts(owners, counts)


@njit(cache=True, error_model="numpy", inline="always")
def owned_start(acc, owners, outside, c):
    """Zero the rows of ``acc`` that chunk ``c`` owns; returns them ``(lo, hi)`` and its first slot."""
    lo, hi = owners[c], owners[c + 1]
    acc[lo:hi] = 0.0
    return lo, hi, outside[c]


@njit(cache=True, error_model="numpy", inline="always")
def owned_add(acc, spill, spill_rows, slot, lo, hi, i, a, b, c, d):
    """Add ``(a, b, c, d)`` to row ``i`` of ``acc`` (V, 4) when it lies in ``lo`` to ``hi``, else store them and
    ``i`` in ``slot`` of ``spill`` (S, 4) and ``spill_rows`` (S,); returns the chunk's next slot."""
    if i >= lo and i < hi:  # not lo <= i < hi, which numba compiles into a far slower loop
        row = unsigned(i)
        acc[row, 0] += a
        acc[row, 1] += b
        acc[row, 2] += c
        acc[row, 3] += d
        return slot
    spill[slot, 0] = a
    spill[slot, 1] = b
    spill[slot, 2] = c
    spill[slot, 3] = d
    spill_rows[slot] = i
    return slot + 1


@njit(cache=True, error_model="numpy", nogil=True)
def add_outside(acc, spill, spill_rows):
    """Add every slot of ``spill`` (S, 4) to its row of ``acc`` (V, 4), in slot order."""
    for s in range(spill_rows.shape[0]):
        i = spill_rows[s]
        acc[i, 0] += spill[s, 0]
        acc[i, 1] += spill[s, 1]
        acc[i, 2] += spill[s, 2]
        acc[i, 3] += spill[s, 3]
