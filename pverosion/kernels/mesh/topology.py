"""Connectivity of triangle meshes: edges, one-rings, boundaries, incidence.

All functions take ``faces`` of shape (F, 3) (validated, int64) and return
plain arrays. Build these once per connectivity and reuse them while only the
point coordinates change.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pverosion.kernels._jit import njit, unsigned
from pverosion.kernels._threads import for_ranges, range_count

__all__ = [
    "EdgeTopology",
    "boundary_edges",
    "boundary_vertices",
    "edge_topology",
    "find_root",
    "halfedge_twins",
    "join_sets",
    "locality_order",
    "locality_sorted",
    "one_ring",
    "sorted_twins",
    "vertex_face_incidence",
    "vertex_fan_counts",
]


@dataclass(frozen=True)
class EdgeTopology:
    """Undirected edges of a triangle mesh and how faces use them.

    Attributes
    ----------
    edges : numpy.ndarray, shape (E, 2), int64
        Unique undirected edges, ``edges[:, 0] < edges[:, 1]``.
    halfedge_edge : numpy.ndarray, shape (F, 3), int64
        Edge id of half-edge ``faces[f, k] -> faces[f, (k + 1) % 3]``; ``-1`` for
        the zero-length half-edges of faces that repeat a vertex.
    face_count : numpy.ndarray, shape (E,), int64
        Number of faces using each edge: 1 on the boundary, 2 on a manifold
        interior edge, more at non-manifold edges.
    """

    edges: np.ndarray
    halfedge_edge: np.ndarray
    face_count: np.ndarray

    @property
    def n_boundary_edges(self) -> int:
        """Number of edges used by exactly one face."""
        return int(np.count_nonzero(self.face_count == 1))

    @property
    def n_nonmanifold_edges(self) -> int:
        """Number of edges used by more than two faces."""
        return int(np.count_nonzero(self.face_count > 2))

    def irregular_vertices(self, n_vertices: int) -> np.ndarray:
        """Mask (V,) of vertices on a boundary or non-manifold edge (not used by exactly two faces)."""
        mask = np.zeros(n_vertices, bool)
        mask[self.edges[self.face_count != 2].ravel()] = True
        return mask


@njit(cache=True, error_model="numpy")
def _group_halfedges(faces, start, fill, bucket_hi, bucket_half, edge_of_slot, edges, count, halfedge_edge):
    """Group the half-edges that are not zero-length into undirected edges; returns the number of edges E.

    The half-edges are bucketed by their smaller vertex (a counting sort, in face order: bucket ``v`` is
    ``start[v]:start[v + 1]`` of ``bucket_hi``, the larger vertex, and ``bucket_half``, ``3 f + k``); those
    of one bucket with the same larger vertex form one edge, numbered in order of first appearance, into
    ``edges`` (E, 2), with its number of half-edges in ``count`` (E,); the edge of each half-edge goes to
    ``halfedge_edge`` (3F,). ``start`` (V + 1,) must be zero, ``edge_of_slot`` and ``halfedge_edge`` ``-1``;
    ``fill`` (V,) is scratch.
    """
    n_faces = faces.shape[0]
    n_vertices = fill.shape[0]
    for f in range(n_faces):
        for k in range(3):
            a = faces[f, k]
            b = faces[f, (k + 1) % 3]
            if a < b:
                start[a + 1] += 1
            elif b < a:
                start[b + 1] += 1
    for v in range(n_vertices):
        fill[v] = start[v]
        start[v + 1] += start[v]
    for f in range(n_faces):
        for k in range(3):
            a = faces[f, k]
            b = faces[f, (k + 1) % 3]
            if a == b:
                continue
            lo, hi = (a, b) if a < b else (b, a)
            i = fill[lo]
            bucket_hi[i] = hi
            bucket_half[i] = 3 * f + k
            fill[lo] = i + 1
    n_edges = 0
    for v in range(n_vertices):
        for i in range(start[v], start[v + 1]):
            if edge_of_slot[i] >= 0:
                continue
            edge_of_slot[i] = n_edges
            c = 1
            for j in range(i + 1, start[v + 1]):
                if bucket_hi[j] == bucket_hi[i]:
                    edge_of_slot[j] = n_edges
                    c += 1
            count[n_edges] = c
            edges[n_edges, 0] = v
            edges[n_edges, 1] = bucket_hi[i]
            n_edges += 1
    for i in range(start[n_vertices]):
        halfedge_edge[bucket_half[i]] = edge_of_slot[i]
    return n_edges


def edge_topology(faces: np.ndarray, n_vertices: int) -> EdgeTopology:
    """Group the half-edges of a triangle mesh into undirected edges.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
        Triangles.
    n_vertices : int
        Number of mesh vertices V.

    Returns
    -------
    EdgeTopology
    """
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    n_vertices = int(n_vertices)
    n_faces = faces.shape[0]
    n_half = 3 * n_faces  # at most
    edges = np.empty((n_half, 2), np.int64)
    count = np.empty(n_half, np.int64)
    halfedge_edge = np.full(n_half, -1, np.int64)
    n_edges = _group_halfedges(faces, np.zeros(n_vertices + 1, np.int64), np.empty(n_vertices, np.int64),
                               np.empty(n_half, np.int64), np.empty(n_half, np.int64), np.full(n_half, -1, np.int64),
                               edges, count, halfedge_edge)
    return EdgeTopology(edges=edges[:n_edges].copy(), halfedge_edge=halfedge_edge.reshape(n_faces, 3),
                        face_count=count[:n_edges].copy())


@njit(cache=True, error_model="numpy")
def _corner_offsets(faces, n_vertices):
    """Where each vertex's corners start when the corners are grouped per vertex: ``indptr`` (V + 1,)."""
    indptr = np.zeros(n_vertices + 1, np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            indptr[faces[f, k] + 1] += 1
    for v in range(n_vertices):
        indptr[v + 1] += indptr[v]
    return indptr


@njit(cache=True, error_model="numpy")
def _incidence(faces, n_vertices):
    n_faces = faces.shape[0]
    indptr = _corner_offsets(faces, n_vertices)
    fill = indptr[:-1].copy()
    face_ids = np.empty(3 * n_faces, np.int64)
    corners = np.empty(3 * n_faces, np.int64)
    for f in range(n_faces):
        for k in range(3):
            v = faces[f, k]
            face_ids[fill[v]] = f
            corners[fill[v]] = k
            fill[v] += 1
    return indptr, face_ids, corners


def vertex_face_incidence(
    faces: np.ndarray, n_vertices: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Faces around each vertex, in compressed sparse row form.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int

    Returns
    -------
    indptr : numpy.ndarray, shape (V + 1,)
        The faces of vertex ``v`` are ``face_ids[indptr[v]:indptr[v + 1]]``.
    face_ids : numpy.ndarray, shape (3F,)
    corners : numpy.ndarray, shape (3F,)
        Corner (0, 1 or 2) at which ``v`` appears in each listed face.
    """
    return _incidence(faces, int(n_vertices))


@njit(cache=True, error_model="numpy")
def _sort_by_min_vertex(faces, start, order, rows):
    """Stable counting sort of the faces by their smallest vertex into ``order`` (F,) and ``rows`` (F, 3);
    ``start`` (V + 1,) must be zero."""
    n_vertices = start.shape[0] - 1
    for f in range(faces.shape[0]):
        a0, a1, a2 = faces[f, 0], faces[f, 1], faces[f, 2]
        lo = a0 if a0 < a1 else a1
        start[(lo if lo < a2 else a2) + 1] += 1
    for v in range(n_vertices):
        start[v + 1] += start[v]
    for f in range(faces.shape[0]):
        a0, a1, a2 = faces[f, 0], faces[f, 1], faces[f, 2]
        lo = a0 if a0 < a1 else a1
        lo = lo if lo < a2 else a2
        i = start[lo]
        order[i] = f
        rows[i, 0], rows[i, 1], rows[i, 2] = a0, a1, a2
        start[lo] = i + 1


def locality_sorted(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`locality_order` and the sorted faces ``faces[order]``, from one pass.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int

    Returns
    -------
    order : numpy.ndarray, shape (F,), int64
    sorted_faces : numpy.ndarray, shape (F, 3)
    """
    faces = np.ascontiguousarray(faces)
    order = np.empty(faces.shape[0], np.int64)
    rows = np.empty_like(faces)
    _sort_by_min_vertex(faces, np.zeros(int(n_vertices) + 1, np.int64), order, rows)
    return order, rows


def locality_order(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Face permutation that sorts faces by their smallest vertex index (stable).

    Scanned and exported meshes often list faces in an order unrelated to
    their vertices; kernels that walk the vertex-face incidence run several
    times faster on faces sorted this way, because the faces around
    neighbouring vertices then sit next to each other in memory.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int

    Returns
    -------
    numpy.ndarray, shape (F,), int64
        ``faces[order]`` is the sorted face array.
    """
    return locality_sorted(faces, n_vertices)[0]


@njit(cache=True, error_model="numpy")
def _corner_slots(faces, n_vertices):
    """The corners of every vertex, grouped per vertex in face order (a counting sort).

    Returns ``indptr`` (V + 1,) and, per slot, the vertices after and before
    the corner in its face and the half-edge ``3 f + k`` that starts there.
    """
    n_faces = faces.shape[0]
    indptr = _corner_offsets(faces, n_vertices)
    fill = indptr[:-1].copy()
    after = np.empty(3 * n_faces, np.int32)
    before = np.empty(3 * n_faces, np.int32)
    half = np.empty(3 * n_faces, np.int32)
    for f in range(n_faces):
        _put_corners(faces, f, 3 * f, fill, after, before, half)
    return indptr, after, before, half


@njit(cache=True, error_model="numpy", inline="always")
def _put_corners(faces, f, h, fill, after, before, half):
    """Store the three corners of face ``f`` (half-edges ``h``, ``h + 1``, ``h + 2``) in their vertices' slots."""
    a0, a1, a2 = faces[f, 0], faces[f, 1], faces[f, 2]
    s = fill[a0]
    after[s], before[s], half[s] = a1, a2, h
    fill[a0] += 1
    s = fill[a1]
    after[s], before[s], half[s] = a2, a0, h + 1
    fill[a1] += 1
    s = fill[a2]
    after[s], before[s], half[s] = a0, a1, h + 2
    fill[a2] += 1


@njit(cache=True, error_model="numpy", inline="always")
def _lowest_corner(a0, a1, a2):
    """Corner (0, 1 or 2) of the smallest of three distinct vertices."""
    if a0 < a1:
        return 0 if a0 < a2 else 2
    return 1 if a1 < a2 else 2


@njit(cache=True, error_model="numpy", nogil=True)
def _count_parts(faces, bounds, lows, mids, repeated, start, stop):
    """For parts ``start`` to ``stop`` of the faces (part ``p`` is ``bounds[p]`` to ``bounds[p + 1]``): the faces
    per smallest vertex into ``lows[p]``, per middle vertex into ``mids[p]``, and the faces that repeat a corner
    into ``repeated[p]``."""
    for p in range(start, stop):
        for f in range(bounds[p], bounds[p + 1]):
            u = unsigned(f)
            a0, a1, a2 = faces[u, 0], faces[u, 1], faces[u, 2]
            if a0 == a1 or a1 == a2 or a2 == a0:
                repeated[p] += 1
                continue
            j = _lowest_corner(a0, a1, a2)
            lows[p, unsigned(faces[u, j])] += 1
            b, c = faces[u, (j + 1) % 3], faces[u, (j + 2) % 3]
            mids[p, unsigned(b if b < c else c)] += 1


@njit(cache=True, error_model="numpy")
def _part_offsets(lows, mids, starts):
    """Turn the per-part counts (P, V) of :func:`_count_parts` into the first sorted position of each part's faces
    per smallest vertex and of its far edges per middle vertex (exclusive running sums in vertex-major,
    part-minor order), in place; ``starts`` (2, V + 1) gets where the faces and the far edges of each vertex
    start."""
    n_parts, n_vertices = lows.shape
    faces_before = 0
    edges_before = 0
    for v in range(n_vertices):
        starts[0, v] = faces_before
        starts[1, v] = edges_before
        for p in range(n_parts):
            n_low = lows[p, v]
            lows[p, v] = faces_before
            faces_before += n_low
            n_mid = mids[p, v]
            mids[p, v] = edges_before
            edges_before += n_mid
    starts[0, n_vertices] = faces_before
    starts[1, n_vertices] = edges_before


@njit(cache=True, error_model="numpy", nogil=True)
def _fill_parts(faces, bounds, lows, mids, order, rows, far_end, far_half, start, stop):
    """Place the faces of parts ``start`` to ``stop`` at their sorted positions, and the far edge of each (the
    one away from its smallest vertex) in the slots of its smaller vertex: its larger vertex into ``far_end``
    and its half-edge of the sorted faces into ``far_half``."""
    for p in range(start, stop):
        for f in range(bounds[p], bounds[p + 1]):
            u = unsigned(f)
            a0, a1, a2 = faces[u, 0], faces[u, 1], faces[u, 2]
            j = _lowest_corner(a0, a1, a2)
            low = unsigned(faces[u, j])
            i = lows[p, low]
            lows[p, low] = i + 1
            order[unsigned(i)] = f
            rows[unsigned(i), 0], rows[unsigned(i), 1], rows[unsigned(i), 2] = a0, a1, a2
            b, c = faces[u, (j + 1) % 3], faces[u, (j + 2) % 3]
            lo, hi = (b, c) if b < c else (c, b)
            s = mids[p, unsigned(lo)]
            mids[p, unsigned(lo)] = s + 1
            far_end[unsigned(s)] = hi
            far_half[unsigned(s)] = 3 * i + (j + 1) % 3


_TALLY = 32
"""Bit of a tally of :func:`_match_sorted_range` where the count of an edge's half-edges starts; below it, the
exclusive or of their positions in a vertex's list (under ``3 F``, so under ``2**31`` where the tally is used):
neither part can carry into the other."""

_NEAR = 4096
"""Span of vertex indices past a vertex that the tally of :func:`_match_sorted_range` covers (32 KB, in a core's
cache); the few edges to vertices farther on are matched by comparing them with each other."""


@njit(cache=True, error_model="numpy", nogil=True)
def _match_sorted_range(rows, starts, far_end, far_half, partner, others, start, stop):
    """Twins and edge multiplicities of the half-edges of the edges whose smaller vertex is ``start`` to ``stop``.

    The edges of vertex ``v`` to larger vertices are the two at ``v`` of its faces (those with smallest vertex
    ``v``, sorted rows ``starts[0, v]`` to ``starts[0, v + 1]``) and its far-edge slots. Each end less than
    :data:`_NEAR` past ``v`` tallies its half-edges' count and the exclusive or of their positions, so the twin
    of a half-edge of a manifold edge is that or with its own position taken out: short passes without
    data-dependent branches. The ends farther on (a few percent, in an order of spatial locality) are
    compared with each other."""
    ends = np.empty(16, np.int64)
    halves = np.empty(16, np.int64)
    far = np.empty(16, np.int64)
    tally = np.empty(_NEAR, np.int64)  # per end, offset by ``v``; zero between vertices
    for e in range(_NEAR):  # a loop: np.zeros would compile one more allocation
        tally[e] = 0
    low = (1 << _TALLY) - 1
    for v in range(start, stop):
        first, last = starts[0, v], starts[0, v + 1]
        size = 2 * (last - first) + starts[1, v + 1] - starts[1, v]
        if size > ends.shape[0]:
            ends = np.empty(2 * size, np.int64)
            halves = np.empty(2 * size, np.int64)
            far = np.empty(2 * size, np.int64)
        n = 0
        for i in range(first, last):
            u = unsigned(i)
            j = _lowest_corner(rows[u, 0], rows[u, 1], rows[u, 2])
            ends[n], halves[n] = rows[u, (j + 1) % 3] - v, 3 * i + j
            ends[n + 1], halves[n + 1] = rows[u, (j + 2) % 3] - v, 3 * i + (j + 2) % 3
            n += 2
        for s in range(starts[1, v], starts[1, v + 1]):
            ends[n], halves[n] = far_end[unsigned(s)] - v, far_half[unsigned(s)]
            n += 1
        n_far = 0
        for s in range(n):
            if ends[s] < _NEAR:
                e = unsigned(ends[s])
                tally[e] = (tally[e] + (1 << _TALLY)) ^ s
            else:
                far[n_far] = s
                n_far += 1
        for s in range(n):
            if ends[s] < _NEAR:
                x = tally[unsigned(ends[s])]
                count = (x >> _TALLY) - 1
                mate = (x & low) ^ s
            else:
                count = 0
                mate = s
                for k in range(n_far):
                    t = far[k]
                    if t != s and ends[t] == ends[s]:
                        count += 1
                        mate = t
            h = unsigned(halves[s])
            others[h] = count  # 0 on a boundary edge
            partner[h] = halves[unsigned(mate)] if count == 1 else -1  # -1 on a boundary or non-manifold edge
        for s in range(n):
            if ends[s] < _NEAR:
                tally[unsigned(ends[s])] = 0


def _sorted_twins_of_triangles(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, ...] | None:
    """:func:`sorted_twins` by one counting sort split over the threads, or None when a face repeats a corner.

    Each part of the faces counts and then places its own faces, from offsets
    that put the parts in order, so the result is that of one pass over the
    faces whatever the number of threads. Besides the sorted faces, only the
    far edge of each face is sorted (into the slots of its smaller vertex):
    the two other edges start at the face's smallest vertex, so the sorted
    faces list them per vertex already.
    """
    n_faces = faces.shape[0]
    parts = range_count(n_faces)
    bounds = np.array([p * n_faces // parts for p in range(parts + 1)], np.int64)
    lows = np.zeros((parts, n_vertices), np.int32)  # positions below 3 F: 32 bits halve the cache these walk
    mids = np.zeros((parts, n_vertices), np.int32)
    repeated = np.zeros(parts, np.int64)
    for_ranges(_count_parts, parts, faces, bounds, lows, mids, repeated, min_items=1)
    if repeated.any():
        return None
    starts = np.empty((2, n_vertices + 1), np.int64)
    _part_offsets(lows, mids, starts)
    order = np.empty(n_faces, np.int64)
    rows = np.empty_like(faces)
    far_end, far_half = np.empty(n_faces, np.int32), np.empty(n_faces, np.int32)
    for_ranges(_fill_parts, parts, faces, bounds, lows, mids, order, rows, far_end, far_half, min_items=1)
    partner = np.empty(3 * n_faces, np.int32)  # every half-edge is in the group of one edge: all are written
    others = np.empty(3 * n_faces, np.int32)
    for_ranges(_match_sorted_range, n_vertices, rows, starts, far_end, far_half, partner, others)
    return order, rows, partner, others


@njit(cache=True, error_model="numpy", nogil=True)
def _match_range(indptr, after, before, half, partner, others, start, stop):
    """Twins and edge multiplicities of the half-edges leaving vertices ``start`` to ``stop``."""
    for a in range(start, stop):
        for s in range(indptr[a], indptr[a + 1]):
            b = after[s]
            if b == a:
                continue
            found = -1
            count = 0
            for t in range(indptr[a], indptr[a + 1]):
                if t == s:
                    continue
                if after[t] == b:
                    found = half[t]  # runs a -> b too
                    count += 1
                elif before[t] == b:
                    corner = half[t] % 3
                    found = half[t] - corner + (corner + 2) % 3  # runs b -> a
                    count += 1
            others[half[s]] = count
            if count == 1:
                partner[half[s]] = found


def _match_slots(indptr: np.ndarray, after: np.ndarray, before: np.ndarray,
                 half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Twin and edge multiplicity of every half-edge from the corner slots of :func:`_corner_slots`."""
    partner = np.full(half.shape[0], -1, np.int64)
    others = np.zeros(half.shape[0], np.int64)
    for_ranges(_match_range, indptr.shape[0] - 1, indptr, after, before, half, partner, others)
    return partner, others


@njit(cache=True, error_model="numpy", nogil=True)
def _incidence_range(faces, face_ids, corner_ids, after, before, half, start, stop):
    for s in range(start, stop):
        g = face_ids[s]
        c = corner_ids[s]
        after[s] = faces[g, (c + 1) % 3]
        before[s] = faces[g, (c + 2) % 3]
        half[s] = 3 * g + c


def _incidence_slots(faces: np.ndarray, indptr: np.ndarray, face_ids: np.ndarray,
                     corner_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n_slots = face_ids.shape[0]
    after = np.empty(n_slots, np.int64)
    before = np.empty(n_slots, np.int64)
    half = np.empty(n_slots, np.int64)
    for_ranges(_incidence_range, n_slots, faces, face_ids, corner_ids, after, before, half)
    return after, before, half


def halfedge_twins(
    faces: np.ndarray, n_vertices: int, incidence: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The other half-edge of every edge, from the corners around each vertex.

    Half-edge ``h = 3 f + k`` runs from ``faces[f, k]`` to ``faces[f, (k + 1) % 3]``.
    The corners are grouped per vertex by one counting sort that stores, per
    corner, its two neighbours in the face; each half-edge then looks for its
    edge's other uses among the corners of its start vertex only.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int
    incidence : tuple, optional
        Reuse the result of :func:`vertex_face_incidence` instead of sorting the corners again.

    Returns
    -------
    partner : numpy.ndarray, shape (3F,), int64
        The twin half-edge where exactly two faces share the edge, else ``-1``.
    others : numpy.ndarray, shape (3F,), int64
        How many other faces use the edge: 0 on the boundary, 1 inside a
        manifold, 2 or more at non-manifold edges.
    """
    if incidence is None and not _slots_fit_int32(len(faces), n_vertices):
        incidence = vertex_face_incidence(faces, n_vertices)
    if incidence is not None:
        indptr, face_ids, corner_ids = incidence
        after, before, half = _incidence_slots(faces, indptr, face_ids, corner_ids)
    else:
        indptr, after, before, half = _corner_slots(faces, int(n_vertices))
    return _match_slots(indptr, after, before, half)


def _slots_fit_int32(n_faces: int, n_vertices: int) -> bool:
    """Whether half-edge and vertex indices fit the 32-bit corner slots."""
    return 3 * n_faces < 2**31 and n_vertices < 2**31


def sorted_twins(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`locality_sorted` and the :func:`halfedge_twins` of the sorted faces, from two passes over ``faces``.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int

    Returns
    -------
    order : numpy.ndarray, shape (F,), int64
    sorted_faces : numpy.ndarray, shape (F, 3)
        ``faces[order]``.
    partner, others : numpy.ndarray, shape (3F,), int32
        As :func:`halfedge_twins` of ``sorted_faces`` returns them, in 32 bits (which halves the memory the
        propagation of an orientation walks); int64 when ``3 F`` exceeds the 32-bit range.
    """
    faces = np.ascontiguousarray(faces)
    compact = _slots_fit_int32(len(faces), n_vertices)
    if compact:
        twins = _sorted_twins_of_triangles(faces, int(n_vertices))
        if twins is not None:
            return twins
    order, rows = locality_sorted(faces, n_vertices)
    partner, others = halfedge_twins(rows, n_vertices)
    if compact:
        partner, others = partner.astype(np.int32), others.astype(np.int32)
    return order, rows, partner, others


@njit(cache=True, error_model="numpy")
def _ring_rows(edges, indptr, indices):
    """Fill the one-ring CSR ``indptr`` (V + 1,), zero on entry, and ``indices`` (2E,) from the edges (E, 2),
    each row sorted."""
    n_vertices = indptr.shape[0] - 1
    for e in range(edges.shape[0]):
        indptr[edges[e, 0] + 1] += 1
        indptr[edges[e, 1] + 1] += 1
    for v in range(n_vertices):
        indptr[v + 1] += indptr[v]
    for e in range(edges.shape[0]):  # indptr[v] moves from the start to the end of row v, then back a row
        a, b = edges[e, 0], edges[e, 1]
        indices[indptr[a]] = b
        indptr[a] += 1
        indices[indptr[b]] = a
        indptr[b] += 1
    for v in range(n_vertices, 0, -1):
        indptr[v] = indptr[v - 1]
    indptr[0] = 0
    for v in range(n_vertices):  # insertion sort of each (short) row
        for i in range(indptr[v] + 1, indptr[v + 1]):
            x = indices[i]
            j = i - 1
            while j >= indptr[v] and indices[j] > x:
                indices[j + 1] = indices[j]
                j -= 1
            indices[j + 1] = x


def one_ring(faces: np.ndarray, n_vertices: int, *, edges: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One-ring vertex neighbourhoods N(i), in compressed sparse row form.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int
    edges : numpy.ndarray, shape (E, 2), optional
        Reuse the unique edges of :func:`edge_topology`.

    Returns
    -------
    indptr : numpy.ndarray, shape (V + 1,)
    indices : numpy.ndarray, shape (2E,)
        The neighbours of vertex ``i`` are ``indices[indptr[i]:indptr[i + 1]]``
        (sorted, each once). Isolated vertices have none.
    """
    if edges is None:
        edges = edge_topology(faces, n_vertices).edges
    edges = np.ascontiguousarray(edges, dtype=np.int64)
    indptr = np.zeros(int(n_vertices) + 1, np.int64)
    indices = np.empty(2 * edges.shape[0], np.int64)
    _ring_rows(edges, indptr, indices)
    return indptr, indices


def boundary_edges(faces: np.ndarray, n_vertices: int, topology: EdgeTopology | None = None) -> np.ndarray:
    """Directed boundary edges, oriented as in the single face that uses each.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int
    topology : EdgeTopology, optional
        Reuse an already built :func:`edge_topology`.

    Returns
    -------
    numpy.ndarray, shape (B, 2), int64
        ``(a, b)`` pairs; following them traces the holes of the mesh.
    """
    topo = topology if topology is not None else edge_topology(faces, n_vertices)
    he = topo.halfedge_edge
    on_boundary = np.zeros(he.shape, bool)
    valid = he >= 0
    on_boundary[valid] = topo.face_count[he[valid]] == 1
    f, k = np.nonzero(on_boundary)
    return np.stack([faces[f, k], faces[f, (k + 1) % 3]], axis=1)


def boundary_vertices(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Boolean mask of vertices that lie on a boundary edge.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int

    Returns
    -------
    numpy.ndarray, shape (V,), bool
    """
    mask = np.zeros(n_vertices, bool)
    mask[boundary_edges(faces, n_vertices).ravel()] = True
    return mask


@njit(cache=True, error_model="numpy")
def find_root(parent: np.ndarray, c: int) -> int:
    """Root of ``c`` in the union-find forest ``parent`` (N,) of integers, halving the path on the way."""
    while parent[c] != c:
        parent[c] = parent[parent[c]]
        c = parent[c]
    return c


@njit(cache=True, error_model="numpy")
def join_sets(parent: np.ndarray, a: int, b: int) -> None:
    """Join the sets of ``a`` and ``b`` in the union-find forest ``parent`` (N,) under the lower of their roots."""
    ra, rb = find_root(parent, a), find_root(parent, b)
    if ra < rb:
        parent[rb] = ra
    elif rb < ra:
        parent[ra] = rb


@njit(cache=True, error_model="numpy")
def _count_fans(faces, halfedge_edge, n_edges, fans):
    """Add the number of fans around each vertex to ``fans`` (V,), zero on entry.

    A union-find over the corners ``3 f + k`` joins, for every further
    half-edge of an edge (``halfedge_edge`` (3F,), ``-1`` skipped), its two
    corners with those of the edge's first half-edge at the same vertices;
    each set left is one fan of its vertex.
    """
    n_corners = 3 * faces.shape[0]
    parent = np.arange(n_corners)
    first = np.full(n_edges, -1, np.int64)  # the first half-edge of every edge
    for h in range(n_corners):
        e = halfedge_edge[h]
        if e < 0:
            continue
        g = first[e]
        if g < 0:
            first[e] = h
            continue
        h_end = h - h % 3 + (h % 3 + 1) % 3  # the corner where half-edge h ends
        g_end = g - g % 3 + (g % 3 + 1) % 3
        if faces[h // 3, h % 3] == faces[g // 3, g % 3]:  # both run the same way
            join_sets(parent, h, g)
            join_sets(parent, h_end, g_end)
        else:
            join_sets(parent, h, g_end)
            join_sets(parent, h_end, g)
    for c in range(n_corners):
        if parent[c] == c:
            fans[faces[c // 3, c % 3]] += 1


def vertex_fan_counts(faces: np.ndarray, n_vertices: int, *, topology: EdgeTopology | None = None) -> np.ndarray:
    """Number of fans of faces around every vertex.

    The faces around a vertex form one fan where each can be reached from
    any other through edges at that vertex that they share. On a 2-manifold
    every used vertex has one fan: closed inside the surface, open on its
    boundary. A vertex with more (two closed surfaces touching at a point,
    two sheets of an open mesh meeting in a corner) is non-manifold even
    where every edge is.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
        Triangles as vertex indices, each with three distinct vertices (the
        stages refuse others first, with
        :func:`~pverosion.kernels.validation.check_proper_faces`); any orientation.
    n_vertices : int
        Number of vertices V (unused ones included).
    topology : EdgeTopology, optional
        Reuse an already built :func:`edge_topology` of ``faces``.

    Returns
    -------
    numpy.ndarray, shape (V,), int64
        Fans per vertex: 0 for a vertex no face uses, 1 on a 2-manifold,
        more at a non-manifold vertex.
    """
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    topo = topology if topology is not None else edge_topology(faces, n_vertices)
    fans = np.zeros(int(n_vertices), np.int64)
    _count_fans(faces, np.ascontiguousarray(topo.halfedge_edge, dtype=np.int64).ravel(), len(topo.edges), fans)
    return fans
