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

from dataclasses import dataclass

import numpy as np
from numba import njit

from pverosion.kernels import _vec3 as v3
from pverosion.kernels.mesh.topology import _incidence

__all__ = ["CollapseResult", "collapse_short_edges", "short_edge_candidates"]


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
    """

    points: np.ndarray
    faces: np.ndarray
    kept: np.ndarray
    n_collapsed: int


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
    if indptr[a + 1] - indptr[a] > 128 or indptr[b + 1] - indptr[b] > 128:
        return -1, -1
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
        return -1, -1
    if indptr[opp0 + 1] - indptr[opp0] > 128 or indptr[opp1 + 1] - indptr[opp1] > 128:
        return -1, -1
    # link condition: common neighbours are exactly the two opposite vertices
    na = star_vertices(faces, indptr, face_ids, a, ring_a)
    nb = star_vertices(faces, indptr, face_ids, b, ring_b)
    common = 0
    for i in range(na):
        for j in range(nb):
            if ring_a[i] == ring_b[j]:
                common += 1
    if common != 2:
        return -1, -1
    if (
        star_vertices(faces, indptr, face_ids, opp0, ring_c) <= 3
        or star_vertices(faces, indptr, face_ids, opp1, ring_c) <= 3
    ):
        return -1, -1
    return na, nb


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
def _collapse_pass(points, faces, cand_a, cand_b, locked):
    n_vertices = points.shape[0]
    indptr, face_ids, _ = _incidence(faces, n_vertices)
    alive = np.ones(faces.shape[0], np.bool_)
    removed = np.zeros(n_vertices, np.bool_)
    frozen = locked.copy()
    ring_a = np.empty(256, np.int64)
    ring_b = np.empty(256, np.int64)
    ring_c = np.empty(256, np.int64)
    n_done = 0
    for c in range(cand_a.shape[0]):
        a, b = cand_a[c], cand_b[c]
        if frozen[a] or frozen[b]:
            continue
        na, nb = collapsible(faces, indptr, face_ids, a, b, ring_a, ring_b, ring_c)
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
        merge_vertices(points, faces, indptr, face_ids, alive, a, b, best_pos)
        removed[b] = True
        frozen[a] = frozen[b] = True
        for i in range(na):
            frozen[ring_a[i]] = True
        for j in range(nb):
            frozen[ring_b[j]] = True
        n_done += 1
    return alive, removed, n_done


@njit(cache=True, error_model="numpy")
def _short_edges(points, edges, usable, min_length):
    n = 0
    out = np.empty(edges.shape[0], np.int64)
    length = np.empty(edges.shape[0])
    for e in range(edges.shape[0]):
        if not usable[e]:
            continue
        d = v3.norm(v3.sub(v3.row(points, edges[e, 0]), v3.row(points, edges[e, 1])))
        if d < min_length:
            out[n] = e
            length[n] = d
            n += 1
    return out[:n], length[:n]


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
    ids, length = _short_edges(points, edges, usable, float(min_length))
    return edges[ids[np.argsort(length, kind="stable")]]


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
    if len(candidates) == 0:
        return CollapseResult(pts, fcs, np.arange(len(pts)), 0)
    cand = np.ascontiguousarray(candidates, dtype=np.int64)
    alive, removed, n_done = _collapse_pass(pts, fcs, cand[:, 0].copy(), cand[:, 1].copy(), locked)
    if n_done == 0:
        return CollapseResult(pts, fcs, np.arange(len(pts)), 0)
    kept = np.flatnonzero(~removed)
    new_index = np.full(len(pts), -1, np.int64)
    new_index[kept] = np.arange(len(kept))
    return CollapseResult(pts[kept], new_index[fcs[alive]], kept, int(n_done))
