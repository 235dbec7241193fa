"""Mesh improvement: removal of small triangles by edge collapse (Skorkovská 2019, §4.1).

An edge shorter than the threshold is collapsed when that keeps the surface
a valid closed 2-manifold:

- the edge is interior and manifold (two faces), and neither end vertex lies
  on a boundary or on a non-manifold edge (so no hole grows or closes);
- the link condition holds: the two end vertices share exactly the two
  vertices opposite the edge, and both of those keep at least three
  neighbours;
- no remaining face around the edge flips or degenerates.

The merged vertex goes to the midpoint or to one of the two ends, whichever
changes the enclosed volume least without increasing it, so erosion followed
by improvement never adds volume. Collapses are applied shortest edge first;
a vertex takes part in at most one collapse per pass (its neighbourhood is
frozen for the rest of the pass).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels._scatter import CHUNKS, chunk_range
from pverosion.kernels._threads import for_chunks, for_ranges
from pverosion.kernels.mesh.topology import _incidence, edge_topology, one_ring

__all__ = [
    "CollapseResult",
    "CollapseTopology",
    "apply_collapses",
    "collapse_short_edges",
    "plan_collapses",
    "short_edge_candidates",
    "short_edges_and_mean_length",
]


@dataclass(frozen=True)
class CollapseResult:
    """Outcome of :func:`collapse_short_edges`.

    Attributes
    ----------
    points : numpy.ndarray, shape (V', 3)
    faces : numpy.ndarray, shape (F', 3), int64
    kept : numpy.ndarray, shape (V',), int64
        Index, in the input, of every output vertex: carry per-vertex arrays
        over with ``values[kept]``.
    n_collapsed : int
        Number of edges collapsed.
    pairs : numpy.ndarray, shape (n_collapsed, 2), int64
        ``(a, b)`` per collapse, input indices: vertex b merged into vertex a.
    """

    points: np.ndarray
    faces: np.ndarray
    kept: np.ndarray
    n_collapsed: int
    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))


@njit(cache=True, error_model="numpy")
def star_vertices(faces, indptr, face_ids, v, out):
    """Distinct neighbours of ``v`` (from its faces) into ``out``; returns how many."""
    n = 0
    for s in range(indptr[v], indptr[v + 1]):
        f = face_ids[s]
        for k in range(3):
            w = faces[f, k]
            if w == v:
                continue
            seen = False
            for j in range(n):
                if out[j] == w:
                    seen = True
                    break
            if not seen:
                out[n] = w
                n += 1
    return n


@njit(cache=True, error_model="numpy")
def _det(a, b, c):
    return v3.dot(a, v3.cross(b, c))


@njit(cache=True, error_model="numpy")
def collapse_cost(points, faces, indptr, face_ids, a, b, pos, tol):
    """Volume change (times 6) of merging b into a at ``pos``, or +inf if a face flips or degenerates (a face
    whose height is at most ``tol`` has no orientation to keep)."""
    change = 0.0
    for end in range(2):
        v = a if end == 0 else b
        for s in range(indptr[v], indptr[v + 1]):
            f = face_ids[s]
            i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
            p0, p1, p2 = v3.row(points, i0), v3.row(points, i1), v3.row(points, i2)
            shared = (i0 == a or i1 == a or i2 == a) and (i0 == b or i1 == b or i2 == b)
            if shared:
                if end == 0:
                    change -= _det(p0, p1, p2)  # removed with the edge
                continue
            if end == 1 and (i0 == a or i1 == a or i2 == a):
                continue  # already counted from a
            q0 = pos if (i0 == a or i0 == b) else p0
            q1 = pos if (i1 == a or i1 == b) else p1
            q2 = pos if (i2 == a or i2 == b) else p2
            n_old = v3.cross(v3.sub(p1, p0), v3.sub(p2, p0))
            n_new = v3.cross(v3.sub(q1, q0), v3.sub(q2, q0))
            span = tol * max(v3.norm(v3.sub(p1, p0)), v3.norm(v3.sub(p2, p1)), v3.norm(v3.sub(p0, p2)))
            if v3.norm(n_new) <= span or (
                v3.norm(n_old) > span and v3.dot(n_old, n_new) <= 1e-3 * v3.norm(n_old) * v3.norm(n_new)
            ):
                return np.inf
            change += _det(q0, q1, q2) - _det(p0, p1, p2)
    return change


@njit(cache=True, error_model="numpy")
def collapsible(faces, indptr, face_ids, a, b, ring_a, ring_b, ring_c):
    """Whether edge (a, b) can collapse without breaking the 2-manifold: the edge has two faces, the link
    condition holds and both opposite vertices keep three neighbours. Returns the neighbour counts of a and b
    (their distinct neighbours in ``ring_a`` / ``ring_b``), or (-1, -1)."""
    na, nb, _, _ = _collapsible_opposite(faces, indptr, face_ids, a, b, ring_a, ring_b, ring_c,
                                         np.zeros(0, np.int64))
    return na, nb


@njit(cache=True, error_model="numpy")
def _collapsible_opposite(faces, indptr, face_ids, a, b, ring_a, ring_b, ring_c, lost):
    """:func:`collapsible`, with ``lost`` (V,) the neighbours each vertex has lost to collapses not yet made in
    ``faces`` (or shape (0,): none); also returns the two vertices opposite the edge, or (-1, -1, -1, -1)."""
    if indptr[a + 1] - indptr[a] > 128 or indptr[b + 1] - indptr[b] > 128:
        return -1, -1, -1, -1
    n_shared = 0
    opp0 = opp1 = -1
    for s in range(indptr[a], indptr[a + 1]):
        f = face_ids[s]
        if faces[f, 0] == b or faces[f, 1] == b or faces[f, 2] == b:
            o = faces[f, 0] + faces[f, 1] + faces[f, 2] - a - b
            if n_shared == 0:
                opp0 = o
            else:
                opp1 = o
            n_shared += 1
    if n_shared != 2 or opp0 == opp1:
        return -1, -1, -1, -1
    if indptr[opp0 + 1] - indptr[opp0] > 128 or indptr[opp1 + 1] - indptr[opp1] > 128:
        return -1, -1, -1, -1
    # link condition: common neighbours are exactly the two opposite vertices
    na = star_vertices(faces, indptr, face_ids, a, ring_a)
    nb = star_vertices(faces, indptr, face_ids, b, ring_b)
    common = 0
    for i in range(na):
        for j in range(nb):
            if ring_a[i] == ring_b[j]:
                common += 1
    if common != 2:
        return -1, -1, -1, -1
    lost0 = lost[opp0] if lost.shape[0] else 0
    lost1 = lost[opp1] if lost.shape[0] else 0
    if (
        star_vertices(faces, indptr, face_ids, opp0, ring_c) - lost0 <= 3
        or star_vertices(faces, indptr, face_ids, opp1, ring_c) - lost1 <= 3
    ):
        return -1, -1, -1, -1
    return na, nb, opp0, opp1


@njit(cache=True, error_model="numpy")
def merge_vertices(points, faces, indptr, face_ids, alive, a, b, pos):
    """Collapse edge (a, b): b merges into a, which moves to ``pos``; the two faces on the edge die."""
    v3.store(points, a, pos)
    for s in range(indptr[b], indptr[b + 1]):
        f = face_ids[s]
        if faces[f, 0] == a or faces[f, 1] == a or faces[f, 2] == a:
            alive[f] = False
        for k in range(3):
            if faces[f, k] == b:
                faces[f, k] = a


@njit(cache=True, error_model="numpy")
def _collapse_plan(points, faces, indptr, face_ids, cand_a, cand_b, locked):
    """The collapses of one pass, decided on the unchanged mesh: pairs (a, b) (b merges into a) and positions.

    A collapse freezes both ends and all their neighbours, so no later candidate reads a face it changes; only
    the two vertices opposite the edge lose a neighbour (b), which ``lost`` counts for the link condition.
    """
    frozen = locked.copy()
    lost = np.zeros(points.shape[0], np.int64)
    ring_a = np.empty(256, np.int64)
    ring_b = np.empty(256, np.int64)
    ring_c = np.empty(256, np.int64)
    pairs = np.empty((cand_a.shape[0], 2), np.int64)
    where = np.empty((cand_a.shape[0], 3))
    n_done = 0
    for c in range(cand_a.shape[0]):
        a, b = cand_a[c], cand_b[c]
        if frozen[a] or frozen[b]:
            continue
        na, nb, opp0, opp1 = _collapsible_opposite(faces, indptr, face_ids, a, b, ring_a, ring_b, ring_c, lost)
        if na < 0:
            continue
        pa, pb = v3.row(points, a), v3.row(points, b)
        best = np.inf
        best_pos = pa
        for k in range(3):
            pos = v3.scale(v3.add(pa, pb), 0.5) if k == 0 else (pa if k == 1 else pb)
            cost = collapse_cost(points, faces, indptr, face_ids, a, b, pos, 0.0)
            if cost <= 0.0 and (best == np.inf or cost > best):
                best = cost
                best_pos = pos
        if best == np.inf:
            continue
        pairs[n_done, 0], pairs[n_done, 1] = a, b
        v3.store(where, n_done, best_pos)
        lost[opp0] += 1
        lost[opp1] += 1
        for i in range(na):
            frozen[ring_a[i]] = True
        for j in range(nb):
            frozen[ring_b[j]] = True
        n_done += 1
    return pairs[:n_done].copy(), where[:n_done].copy()


@njit(cache=True, error_model="numpy", nogil=True)
def _short_range(points, edges, usable, min_length, length, start, stop):
    """Length of edges ``start`` to ``stop`` when usable and shorter than ``min_length``, else inf."""
    for e in range(start, stop):
        length[e] = np.inf
        if usable[e]:
            d = v3.norm(v3.sub(v3.row(points, edges[e, 0]), v3.row(points, edges[e, 1])))
            if d < min_length:
                length[e] = d


def short_edge_candidates(points: np.ndarray, edges: np.ndarray, usable: np.ndarray, min_length: float) -> np.ndarray:
    """Edges shorter than ``min_length``, shortest first.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    edges : numpy.ndarray, shape (E, 2), int64
    usable : numpy.ndarray, shape (E,), bool
        Edges that may be collapsed at all (interior manifold edges).
    min_length : float

    Returns
    -------
    numpy.ndarray, shape (K, 2), int64
    """
    length = np.empty(len(edges))
    for_ranges(_short_range, len(edges), np.ascontiguousarray(points, dtype=np.float64), edges, usable,
               float(min_length), length)
    ids = np.flatnonzero(length < np.inf)
    return edges[ids[np.argsort(length[ids], kind="stable")]]


@njit(cache=True, error_model="numpy", nogil=True)
def _edge_chunk(points, edges, usable, min_length, total, short, c):
    """Chunk ``c`` of the edges: their summed length, in edge order, in ``total[c]`` (as
    :func:`~pverosion.kernels.mesh.geometry.average_edge_length` sums it) and how many of them are usable and
    shorter than ``min_length`` in ``short[c]``."""
    lo, hi = chunk_range(edges.shape[0], c)
    length = 0.0
    n = 0
    for e in range(lo, hi):
        d = v3.norm(v3.sub(v3.row(points, edges[e, 0]), v3.row(points, edges[e, 1])))
        length += d
        n += usable[e] and d < min_length
    total[c] = length
    short[c] = n


def short_edges_and_mean_length(points: np.ndarray, edges: np.ndarray, usable: np.ndarray,
                                min_length: float) -> tuple[np.ndarray, float]:
    """:func:`short_edge_candidates` and the mean edge length, from one pass over the edges.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64
    edges : numpy.ndarray, shape (E, 2), int64
    usable : numpy.ndarray, shape (E,), bool
    min_length : float

    Returns
    -------
    candidates : numpy.ndarray, shape (K, 2), int64
        As :func:`short_edge_candidates` returns them.
    mean_length : float
        Bit for bit :func:`~pverosion.kernels.mesh.geometry.average_edge_length` of ``points`` and ``edges``
        (lengths summed in the same fixed chunks, so for any thread count).
    """
    total = np.empty(CHUNKS)
    short = np.empty(CHUNKS, np.int64)
    for_chunks(_edge_chunk, edges.shape[0], points, edges, usable, float(min_length), total, short)
    length = 0.0
    for c in range(CHUNKS):
        length += float(total[c])
    mean = length / max(edges.shape[0], 1)
    if not short.any():  # most steps: no edge became short, and the pass is all there is
        return np.zeros((0, 2), np.int64), mean
    return short_edge_candidates(points, edges, usable, min_length), mean


def plan_collapses(points: np.ndarray, faces: np.ndarray, candidates: np.ndarray, locked: np.ndarray, *,
                   incidence: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The collapses :func:`collapse_short_edges` makes, without making them.

    Parameters
    ----------
    points, faces, candidates, locked
        As for :func:`collapse_short_edges`; read only.
    incidence : tuple of numpy.ndarray, optional
        ``(indptr, face_ids)`` of :func:`~pverosion.kernels.mesh.topology.vertex_face_incidence` of ``faces``,
        when already built.

    Returns
    -------
    pairs : numpy.ndarray, shape (K, 2), int64
        ``(a, b)`` per collapse: vertex b merges into vertex a.
    positions : numpy.ndarray, shape (K, 3)
        Where each merged vertex a goes.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    fcs = np.ascontiguousarray(faces, dtype=np.int64)
    cand = np.ascontiguousarray(candidates, dtype=np.int64).reshape(-1, 2)
    if len(cand) == 0:
        return np.zeros((0, 2), np.int64), np.zeros((0, 3))
    indptr, face_ids = incidence if incidence is not None else _incidence(fcs, len(pts))[:2]
    return _collapse_plan(pts, fcs, indptr, face_ids, cand[:, 0].copy(), cand[:, 1].copy(),
                          np.ascontiguousarray(locked, dtype=np.bool_))


@njit(cache=True, error_model="numpy")
def _dies(faces, target, f):
    """Whether face f comes to repeat a vertex when every vertex v merges into ``target[v]``."""
    a, b, c = target[faces[f, 0]], target[faces[f, 1]], target[faces[f, 2]]
    repeats = faces[f, 0] == faces[f, 1] or faces[f, 1] == faces[f, 2] or faces[f, 0] == faces[f, 2]
    return (a == b or b == c or a == c) and not repeats


@njit(cache=True, error_model="numpy")
def _merged_faces(faces, target, new_index):
    """Faces after merging every vertex v into ``target[v]``, renumbered by ``new_index``; the faces that a merge
    makes repeat a vertex (the two on each collapsed edge) die. Returns the new faces and the new index of every
    face (-1 for those that die)."""
    n = faces.shape[0]
    new_face = np.empty(n, np.int64)
    m = 0
    for f in range(n):
        if _dies(faces, target, f):
            new_face[f] = -1
        else:
            new_face[f] = m
            m += 1
    out = np.empty((m, 3), np.int64)
    for f in range(n):
        if new_face[f] >= 0:
            for k in range(3):
                out[new_face[f], k] = new_index[target[faces[f, k]]]
    return out, new_face


def apply_collapses(points: np.ndarray, faces: np.ndarray, pairs: np.ndarray,
                    positions: np.ndarray) -> tuple[CollapseResult, np.ndarray]:
    """Make the collapses of :func:`plan_collapses`.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64
    faces : numpy.ndarray, shape (F, 3), int64
    pairs : numpy.ndarray, shape (K, 2), int64
    positions : numpy.ndarray, shape (K, 3)

    Returns
    -------
    result : CollapseResult
        New arrays; the inputs are not modified.
    new_face : numpy.ndarray, shape (F,), int64
        Index of every input face among the output faces, -1 for the faces that died.
    """
    target = np.arange(len(points))
    target[pairs[:, 1]] = pairs[:, 0]
    kept = np.flatnonzero(target == np.arange(len(points)))
    new_index = np.full(len(points), -1, np.int64)
    new_index[kept] = np.arange(len(kept))
    out_faces, new_face = _merged_faces(np.ascontiguousarray(faces, dtype=np.int64), target, new_index)
    out_points = points[kept]
    out_points[new_index[pairs[:, 0]]] = positions
    return CollapseResult(out_points, out_faces, kept, len(pairs), pairs), new_face


def collapse_short_edges(
    points: np.ndarray, faces: np.ndarray, candidates: np.ndarray, locked: np.ndarray
) -> CollapseResult:
    """Collapse the candidate edges that can go without damaging the surface.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64
    faces : numpy.ndarray, shape (F, 3), int64
        Consistently oriented triangles.
    candidates : numpy.ndarray, shape (K, 2), int64
        Edges to try, in order (see :func:`short_edge_candidates`).
    locked : numpy.ndarray, shape (V,), bool
        Vertices that must not move or disappear (boundary and non-manifold
        vertices).

    Returns
    -------
    CollapseResult
        New arrays; the inputs are not modified.
    """
    pts = np.array(points, dtype=np.float64)
    fcs = np.array(faces, dtype=np.int64)
    pairs, positions = plan_collapses(pts, fcs, candidates, locked)
    return apply_collapses(pts, fcs, pairs, positions)[0]


@njit(cache=True, error_model="numpy")
def _merged_row(indptr, indices, first, second, value_map, drop, buffer):
    """Values of old rows ``first`` and ``second`` (-1: none) mapped by ``value_map``, without negatives and
    ``drop``, sorted and each once, into ``buffer``; returns how many."""
    m = 0
    for r in (first, second):
        if r < 0:
            continue
        for s in range(indptr[r], indptr[r + 1]):
            x = value_map[indices[s]]
            if x < 0 or x == drop:
                continue
            j = m  # insertion into the sorted buffer, skipping repeats
            while j > 0 and buffer[j - 1] > x:
                j -= 1
            if j > 0 and buffer[j - 1] == x:
                continue
            for k in range(m, j, -1):
                buffer[k] = buffer[k - 1]
            buffer[j] = x
            m += 1
    return m


@njit(cache=True, error_model="numpy")
def _near_collapses(ring_ptr, ring_idx, pairs, kept):
    """Which kept vertices (by new index) are an end of a collapse or a neighbour of one: the only rows of the
    one-rings and the vertex-face incidence that a collapse changes other than by renumbering."""
    near = np.zeros(ring_ptr.shape[0] - 1, np.bool_)
    for c in range(pairs.shape[0]):
        for v in (pairs[c, 0], pairs[c, 1]):
            near[v] = True
            for s in range(ring_ptr[v], ring_ptr[v + 1]):
                near[ring_idx[s]] = True
    out = np.empty(kept.shape[0], np.bool_)
    for i in range(kept.shape[0]):
        out[i] = near[kept[i]]
    return out


@njit(cache=True, error_model="numpy")
def _merged_rows(indptr, indices, rows, extra, near, value_map, drop_self):
    """Rows of a CSR table after collapses: new row i holds the old rows ``rows[i]`` and ``extra[i]`` (the row
    merged into it, or -1), each value x replaced by ``value_map[x]``, without negatives (and ``i`` itself when
    ``drop_self``), sorted and each once. Rows not ``near`` a collapse keep their values' order and count."""
    n = rows.shape[0]
    longest = 0
    for v in range(indptr.shape[0] - 1):
        longest = max(longest, indptr[v + 1] - indptr[v])
    buffer = np.empty(2 * longest, np.int64)
    count = np.zeros(n + 1, np.int64)
    for i in range(n):
        if near[i]:
            m = _merged_row(indptr, indices, rows[i], extra[i], value_map, i if drop_self else -1, buffer)
        else:
            m = indptr[rows[i] + 1] - indptr[rows[i]]
        count[i + 1] = count[i] + m
    out = np.empty(count[n], np.int64)
    for i in range(n):
        if near[i]:
            m = _merged_row(indptr, indices, rows[i], extra[i], value_map, i if drop_self else -1, buffer)
            out[count[i]:count[i] + m] = buffer[:m]
        else:
            start = indptr[rows[i]]
            for s in range(count[i + 1] - count[i]):
                out[count[i] + s] = value_map[indices[start + s]]
    return count, out


@njit(cache=True, error_model="numpy")
def _ring_edges(ring_ptr, ring_idx, fixed, faces, inc_ptr, inc_faces):
    """Edges (v, w), v < w, in lexicographic order from the sorted one-rings, and whether two faces use each (an
    edge at a vertex that is not fixed always has two)."""
    n_edges = 0
    for v in range(ring_ptr.shape[0] - 1):
        for s in range(ring_ptr[v], ring_ptr[v + 1]):
            if ring_idx[s] > v:
                n_edges += 1
    edges = np.empty((n_edges, 2), np.int64)
    usable = np.empty(n_edges, np.bool_)
    e = 0
    for v in range(ring_ptr.shape[0] - 1):
        for s in range(ring_ptr[v], ring_ptr[v + 1]):
            w = ring_idx[s]
            if w <= v:
                continue
            edges[e, 0], edges[e, 1] = v, w
            uses = 2
            if fixed[v] and fixed[w]:  # count the half-edges between v and w in the faces of v
                uses = 0
                for t in range(inc_ptr[v], inc_ptr[v + 1]):
                    f = inc_faces[t]
                    for k in range(3):
                        a, b = faces[f, k], faces[f, (k + 1) % 3]
                        uses += (a == v and b == w) or (a == w and b == v)
            usable[e] = uses == 2
            e += 1
    return edges, usable


@dataclass(frozen=True)
class CollapseTopology:
    """Connectivity the mesh improvement reads, updated through collapses without a rebuild.

    Attributes
    ----------
    ring : tuple of numpy.ndarray
        One-rings ``(indptr (V + 1,), indices (2E,))``, each sorted, as
        :func:`~pverosion.kernels.mesh.topology.one_ring`.
    incidence : tuple of numpy.ndarray
        Faces of every vertex ``(indptr (V + 1,), face_ids (3F,))``, each in
        increasing order, as :func:`~pverosion.kernels.mesh.topology.vertex_face_incidence`.
    edges : numpy.ndarray, shape (E, 2), int64
        Undirected edges ``(v, w)``, ``v < w``, in lexicographic order.
    usable : numpy.ndarray, shape (E,), bool
        Edges used by exactly two faces.
    fixed : numpy.ndarray, shape (V,), bool
        Vertices on a boundary or non-manifold edge.
    """

    ring: tuple[np.ndarray, np.ndarray]
    incidence: tuple[np.ndarray, np.ndarray]
    edges: np.ndarray
    usable: np.ndarray
    fixed: np.ndarray

    @classmethod
    def build(cls, faces: np.ndarray, n_vertices: int) -> CollapseTopology:
        """The connectivity of ``faces`` (F, 3) int64 on ``n_vertices`` vertices."""
        fcs = np.ascontiguousarray(faces, dtype=np.int64)
        topo = edge_topology(fcs, n_vertices)
        ring = one_ring(fcs, n_vertices, edges=topo.edges)
        return cls._make(fcs, ring, _incidence(fcs, int(n_vertices))[:2], topo.irregular_vertices(n_vertices))

    @classmethod
    def _make(cls, faces, ring, incidence, fixed) -> CollapseTopology:
        edges, usable = _ring_edges(ring[0], ring[1], fixed, faces, incidence[0], incidence[1])
        return cls(ring, incidence, edges, usable, fixed)

    def collapsed(self, result: CollapseResult, new_face: np.ndarray) -> CollapseTopology:
        """The connectivity after the collapses of :func:`apply_collapses` (``result``, ``new_face``); equal to
        :meth:`build` on ``result.faces``."""
        n = len(self.fixed)
        kept = result.kept
        new_index = np.full(n, -1, np.int64)
        new_index[kept] = np.arange(len(kept))
        target = np.arange(n)
        target[result.pairs[:, 1]] = result.pairs[:, 0]
        extra = np.full(len(kept), -1, np.int64)
        extra[new_index[result.pairs[:, 0]]] = result.pairs[:, 1]
        near = _near_collapses(*self.ring, result.pairs, kept)
        ring = _merged_rows(*self.ring, kept, extra, near, new_index[target], True)
        incidence = _merged_rows(*self.incidence, kept, extra, near, new_face, False)
        return self._make(result.faces, ring, incidence, self.fixed[kept])
