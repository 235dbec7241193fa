"""Vertex renumbering for memory locality.

Kernels that scatter from faces to vertices (curvature, normals, the twin
search of the orientation) touch the three corners of every face. When the
corners of a face sit far apart in the vertex arrays (Loop subdivision
numbers every new edge vertex after all the old ones; some exporters shuffle
vertices) each face touches distant cache lines, and the cost per face grows
with the mesh. :func:`locality_renumbering` detects such meshes with one pass
over the faces and numbers their vertices along a Morton (Z-order) curve of
their positions; the kernels run in that numbering and the results are put
back in the caller's vertex order.

The order depends only on the positions (vertices in one grid cell keep their
relative order), so it is the same for any face order, and the decision
depends only on the set of faces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pverosion.kernels._jit import njit, unsigned
from pverosion.kernels._scatter import CHUNKS, chunk_range
from pverosion.kernels._threads import for_chunks, for_ranges

__all__ = ["LOCAL_SPAN", "MORTON_BITS", "CanonicalMesh", "Renumbering", "canonical_mesh", "locality_renumbering",
           "morton_renumbering", "poor_locality"]

LOCAL_SPAN = 8192
"""Vertex-index span of a face's corners above which the face counts as scattered.

Kernels keep about 200 bytes per vertex live (points, normals, frames and the
scatter accumulators), so a span of 8192 vertices is about 1.6 MB, the order
of a core's L2 cache."""

MORTON_BITS = 10
"""Bits per axis of the quantised positions whose Morton codes order the vertices (2^30 cells; the vertices
of one cell keep their relative order)."""

SMALL_SORT = 1 << 17
"""Fewest vertices whose Morton codes are sorted in two passes of 15-bit digits; fewer are sorted in three
passes of 10-bit digits, whose counts (8 KB per chunk instead of 256 KB) stay in a core's caches, and in one
thread: each of their passes takes a few hundred microseconds or less, about what waking a second thread saves.
Both give the same order."""


@njit(cache=True, error_model="numpy")
def _scattered_faces(faces, span):
    """Number of faces whose largest and smallest corner index differ by more than ``span``."""
    count = 0
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        if max(a, b, c) - min(a, b, c) > span:
            count += 1
    return count


def poor_locality(faces: np.ndarray, n_vertices: int) -> bool:
    """Whether the median corner span of the faces exceeds :data:`LOCAL_SPAN` vertex indices.

    One pass over all faces; the answer depends only on the set of faces, not
    on their order or the order of their corners. Meshes with at most
    :data:`LOCAL_SPAN` vertices are always local.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
        Validated triangles.
    n_vertices : int
        Number of vertices V.

    Returns
    -------
    bool
    """
    if n_vertices <= LOCAL_SPAN or len(faces) == 0:
        return False
    return 2 * int(_scattered_faces(np.ascontiguousarray(faces), LOCAL_SPAN)) > len(faces)


@njit(cache=True, error_model="numpy", inline="always")
def _spread(x):
    """The 10 low bits of ``x`` spread to every third bit (so MORTON_BITS is at most 10)."""
    x &= 0x3FF
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    return (x | (x << 2)) & 0x09249249


@njit(cache=True, error_model="numpy", nogil=True)
def _box_chunk(points, box, c):
    """Lowest and highest coordinates of the points of chunk ``c`` into ``box[c]`` (2, 3)."""
    start, stop = chunk_range(points.shape[0], c)
    for d in range(3):
        lo = hi = points[start, d] if stop > start else 0.0
        for v in range(start, stop):
            lo = min(lo, points[v, d])
            hi = max(hi, points[v, d])
        box[c, 0, d] = lo
        box[c, 1, d] = hi


@njit(cache=True, error_model="numpy", nogil=True)
def _code_chunk(points, lo, scale, codes, c):
    """Morton codes of the quantised positions of the vertices of chunk ``c``."""
    cells = (1 << MORTON_BITS) - 1
    start, stop = chunk_range(points.shape[0], c)
    for v in range(start, stop):
        code = 0
        for d in range(3):
            q = int((points[v, d] - lo[d]) * scale[d])
            code |= _spread(min(max(q, 0), cells)) << d
        codes[v] = code


@njit(cache=True, error_model="numpy", nogil=True)
def _count_chunk(codes, sequence, shift, counts, c):
    """Histogram ``counts[c]`` (of as many digits as it has columns, a power of two) of the radix digits at
    ``shift`` of the vertices at positions of chunk ``c``."""
    start, stop = chunk_range(sequence.shape[0], c)
    mask = counts.shape[1] - 1
    for i in range(start, stop):
        counts[c, unsigned((codes[unsigned(sequence[i])] >> shift) & mask)] += 1


@njit(cache=True, error_model="numpy")
def _offsets(counts):
    """First slot (CHUNKS, R) of every chunk's vertices of every digit in the stable order by digit."""
    slots = np.empty_like(counts)
    total = 0
    for b in range(counts.shape[1]):
        for c in range(counts.shape[0]):
            slots[c, b] = total
            total += counts[c, b]
    return slots


@njit(cache=True, error_model="numpy", nogil=True)
def _place_chunk(codes, sequence, shift, slots, out, c):
    """Put the vertices at positions of chunk ``c`` at their slots of the stable order by digit."""
    start, stop = chunk_range(sequence.shape[0], c)
    mask = slots.shape[1] - 1
    for i in range(start, stop):
        v = sequence[i]
        key = unsigned((codes[unsigned(v)] >> shift) & mask)
        out[unsigned(slots[c, key])] = v
        slots[c, key] += 1


@njit(cache=True, nogil=True)
def _rank_range(order, rank, start, stop):
    for i in range(start, stop):
        rank[unsigned(order[i])] = i


@njit(cache=True, nogil=True)
def _map_faces(faces, rank, out, start, stop):
    for f in range(start, stop):
        u = unsigned(f)
        for k in range(3):
            out[u, k] = rank[unsigned(faces[u, k])]


@njit(cache=True, error_model="numpy")
def _renumbered_sorted(faces, rank):
    """``rank[faces]`` sorted by smallest vertex (a stable counting sort), without the unsorted copy."""
    n_vertices = rank.shape[0]
    start = np.zeros(n_vertices + 1, np.int64)
    for f in range(faces.shape[0]):
        start[min(rank[faces[f, 0]], rank[faces[f, 1]], rank[faces[f, 2]]) + 1] += 1
    for v in range(n_vertices):
        start[v + 1] += start[v]
    out = np.empty_like(faces)
    for f in range(faces.shape[0]):
        a, b, c = rank[faces[f, 0]], rank[faces[f, 1]], rank[faces[f, 2]]
        lo = min(a, b, c)
        row = start[lo]
        out[row, 0], out[row, 1], out[row, 2] = a, b, c
        start[lo] += 1
    return out


@njit(cache=True, nogil=True)
def _take_rows(src, index, out, start, stop):
    for i in range(start, stop):
        u, j = unsigned(i), unsigned(index[i])
        for d in range(src.shape[1]):
            out[u, d] = src[j, d]


def _take(values: np.ndarray, index: np.ndarray, out: np.ndarray | None) -> np.ndarray:
    """``values[index]`` for float64 arrays (N,) or (N, K), gathered in parallel into ``out`` (or a new array)."""
    src = np.ascontiguousarray(values, dtype=np.float64)
    rows = src.reshape(len(src), -1)
    shape = (len(index),) + src.shape[1:]
    if out is None:
        out = np.empty(shape)
    elif out.shape != shape or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise ValueError(f"out must be a C-contiguous float64 array of shape {shape}; got {out.dtype} {out.shape}")
    for_ranges(_take_rows, len(index), rows, index, out.reshape(len(index), rows.shape[1]))
    return out


@dataclass(frozen=True)
class Renumbering:
    """A vertex permutation and the maps between the caller's numbering and the local one.

    Attributes
    ----------
    order : numpy.ndarray, shape (V,), int64
        Local vertex ``i`` is the caller's vertex ``order[i]``.
    rank : numpy.ndarray, shape (V,), int64
        The caller's vertex ``v`` is local vertex ``rank[v]`` (the inverse of ``order``).
    """

    order: np.ndarray
    rank: np.ndarray

    def to_local(self, values: np.ndarray, *, out: np.ndarray | None = None) -> np.ndarray:
        """Per-vertex float64 ``values`` (V,) or (V, K) in the local order, written to ``out`` when given
        (a C-contiguous float64 array of the same shape, reused by repeated calls) and returned."""
        return _take(values, self.order, out)

    def to_caller(self, values: np.ndarray, *, out: np.ndarray | None = None) -> np.ndarray:
        """Per-vertex float64 ``values`` (V,) or (V, K) of the local numbering in the caller's order, written
        to ``out`` when given, as :meth:`to_local`."""
        return _take(values, self.rank, out)

    def faces(self, faces: np.ndarray) -> np.ndarray:
        """The caller's ``faces`` (F, 3) int64 in local vertex indices, in the same face order."""
        fcs = np.ascontiguousarray(faces, dtype=np.int64)
        out = np.empty_like(fcs)
        for_ranges(_map_faces, len(fcs), fcs, self.rank, out)
        return out

    def sorted_faces(self, faces: np.ndarray) -> np.ndarray:
        """:meth:`faces` sorted by their smallest (local) vertex, stable: equal to
        ``locality_sorted(self.faces(faces), V)[1]``, in one counting sort.

        Parameters
        ----------
        faces : numpy.ndarray, shape (F, 3), int64
            Validated triangles in the caller's numbering.

        Returns
        -------
        numpy.ndarray, shape (F, 3), int64
        """
        return _renumbered_sorted(np.ascontiguousarray(faces, dtype=np.int64), self.rank)


def morton_renumbering(points: np.ndarray) -> Renumbering:
    """Vertices numbered along the Morton curve of their positions.

    The positions are quantised to :data:`MORTON_BITS` bits per axis of their
    bounding box; vertices in one cell keep their relative order.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64

    Returns
    -------
    Renumbering
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    n = len(pts)
    short = SMALL_SORT // 2  # fewest vertices per thread of the bounding box and sort passes: one below SMALL_SORT
    box = np.empty((CHUNKS, 2, 3))
    for_chunks(_box_chunk, n, pts, box, min_items=short)
    filled = [c for c in range(CHUNKS) if chunk_range(n, c)[1] > chunk_range(n, c)[0]]
    lo, hi = box[filled, 0].min(axis=0), box[filled, 1].max(axis=0)
    extent = hi - lo
    scale = np.where(extent > 0.0, ((1 << MORTON_BITS) - 1) / np.where(extent > 0.0, extent, 1.0), 0.0)
    codes = np.empty(n, np.int64)
    for_chunks(_code_chunk, n, pts, lo, scale, codes)
    order, spare = np.arange(n), np.empty(n, np.int64)
    digit = 15 if n >= SMALL_SORT else 10
    for shift in range(0, 3 * MORTON_BITS, digit):  # least significant digit first: stable
        counts = np.zeros((CHUNKS, 1 << digit), np.int64)
        for_chunks(_count_chunk, n, codes, order, shift, counts, min_items=short)
        for_chunks(_place_chunk, n, codes, order, shift, _offsets(counts), spare, min_items=short)
        order, spare = spare, order
    rank = np.empty(n, np.int64)
    for_ranges(_rank_range, n, order, rank, min_items=short)
    return Renumbering(order, rank)


@dataclass(frozen=True)
class CanonicalMesh:
    """A mesh numbered by its geometry alone (:func:`canonical_mesh`), and the way back to the caller's numbering.

    Attributes
    ----------
    renumbering : Renumbering
        Local vertex ``i`` is the caller's vertex ``renumbering.order[i]``.
    faces : numpy.ndarray, shape (F, 3), int64
        The faces in local vertex indices, each starting at its smallest
        corner (the cyclic order, so the orientation, is kept), sorted by
        their corners.
    face_order : numpy.ndarray, shape (F,), int64
        Local face ``k`` is the caller's face ``face_order[k]``.
    """

    renumbering: Renumbering
    faces: np.ndarray
    face_order: np.ndarray

    def caller_faces(self, faces: np.ndarray) -> np.ndarray:
        """Local ``faces`` (F, 3), one per local face, as the caller's faces in the caller's face order."""
        out = np.empty_like(faces)
        out[self.face_order] = self.renumbering.order[faces]
        return out


def canonical_mesh(points: np.ndarray, faces: np.ndarray) -> CanonicalMesh:
    """Number the vertices and order the faces of a mesh by its geometry, whatever the caller's numbering.

    The vertices follow the Morton curve of their positions
    (:func:`morton_renumbering`), and vertices in one Morton cell follow their
    coordinates (x, then y, then z); the faces start at their smallest local
    corner and are sorted by their corners. Two numberings of one mesh give
    the same local arrays, except for coincident vertices, which keep the
    caller's relative order. A stage that runs on these arrays gives results
    that do not depend on the order of the caller's vertices and faces, nor
    on the corner each face starts at.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64
    faces : numpy.ndarray, shape (F, 3), int64
        Validated triangles.

    Returns
    -------
    CanonicalMesh
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    by_coordinates = np.lexsort((pts[:, 2], pts[:, 1], pts[:, 0]))
    morton = morton_renumbering(pts[by_coordinates])  # stable: a cell's vertices stay in coordinate order
    order = by_coordinates[morton.order]
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    renumbering = Renumbering(order, rank)
    local = renumbering.faces(faces)
    first = np.argmin(local, axis=1)
    rows = np.arange(len(local))[:, None]
    rotated = local[rows, (first[:, None] + np.arange(3)) % 3]
    face_order = np.lexsort((rotated[:, 2], rotated[:, 1], rotated[:, 0]))
    return CanonicalMesh(renumbering, np.ascontiguousarray(rotated[face_order]), face_order)


def locality_renumbering(points: np.ndarray, faces: np.ndarray) -> Renumbering | None:
    """:func:`morton_renumbering` of a mesh of :func:`poor_locality`, else None.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64
    faces : numpy.ndarray, shape (F, 3), int64
        Validated triangles.

    Returns
    -------
    Renumbering or None
    """
    return morton_renumbering(points) if poor_locality(faces, len(points)) else None
