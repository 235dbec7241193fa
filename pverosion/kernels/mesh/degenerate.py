"""Removal of nearly degenerate triangles: needles by edge collapse, caps by edge flip or split.

A *needle* has a short edge; a *cap* has a corner that nearly lies on the
opposite (longest) edge, or a very obtuse angle there (Botsch and Kobbelt's
classification, which Skorkovská's thesis uses before and after the
intersection repair, §10.1 and §10.3):

- a needle's shortest edge collapses (the link condition and the face
  orientations checked as in :mod:`pverosion.kernels.mesh.remesh`); the merged
  vertex goes to the end or midpoint that changes the enclosed volume least;
- a cap's longest edge flips when that is a valid flip (the edge between the
  two opposite corners is new, both new faces keep the orientation of the
  pair, and the two faces are nearly coplanar unless the cap has no area to
  speak of);
- a cap whose longest edge lies on a *curve* (the intersection curves after a
  repair: creases that must stay) is split at the foot of its corner instead,
  and the two needles this makes collapse onto the curve in a later pass.

Curve vertices never move: an edge with one curve end collapses onto that
end, and an edge between two curve vertices collapses only when it is a
curve edge and one end is an ordinary curve point (two curve edges), which
then merges into the other. Operations are applied worst face first; a
vertex takes part in at most one operation per pass (its neighbourhood is
frozen for the rest of the pass), and passes repeat until nothing changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels.mesh.remesh import collapse_cost, collapsible, merge_vertices, star_vertices
from pverosion.kernels.mesh.topology import _incidence

__all__ = ["DegenerateCleanup", "remove_degenerate_faces"]


@dataclass(frozen=True)
class DegenerateCleanup:
    """Outcome of :func:`remove_degenerate_faces`.

    Attributes
    ----------
    points : numpy.ndarray, shape (V', 3)
    faces : numpy.ndarray, shape (F', 3), int64
    vertex_source : numpy.ndarray, shape (V',), int64
        Input index of every output vertex, -1 for a vertex a split made.
    face_source : numpy.ndarray, shape (F',), int64
        Input face every output face comes from.
    on_curve : numpy.ndarray, shape (V',), bool
    polylines : list of numpy.ndarray
        The curves in output vertex indices.
    collapsed, flipped, split : int
        Numbers of edges collapsed, flipped and split.
    """

    points: np.ndarray
    faces: np.ndarray
    vertex_source: np.ndarray
    face_source: np.ndarray
    on_curve: np.ndarray
    polylines: list
    collapsed: int
    flipped: int
    split: int


_NEEDLE, _CAP = 0, 1


@njit(cache=True, error_model="numpy")
def _face_candidate(points, faces, f, needle, cap_height, cap_cos, length):
    """Whether face f is a needle or a cap, with its sort key, kind and corner (see :func:`_candidates`);
    ``length`` (3,) is scratch space."""
    p0, p1, p2 = v3.row(points, faces[f, 0]), v3.row(points, faces[f, 1]), v3.row(points, faces[f, 2])
    length[0] = v3.norm(v3.sub(p1, p0))
    length[1] = v3.norm(v3.sub(p2, p1))
    length[2] = v3.norm(v3.sub(p0, p2))
    short = np.argmin(length)
    if length[short] < needle:
        return True, length[short] / needle, _NEEDLE, short
    long = np.argmax(length)
    apex = p2 if long == 0 else (p0 if long == 1 else p1)
    e0 = v3.sub(p0 if long == 0 else (p1 if long == 1 else p2), apex)
    e1 = v3.sub(p1 if long == 0 else (p2 if long == 1 else p0), apex)
    height = v3.norm(v3.cross(e0, e1)) / length[long]
    cos_apex = v3.dot(e0, e1) / (v3.norm(e0) * v3.norm(e1))
    if height <= cap_height or cos_apex < cap_cos:
        return True, 2.0 + cos_apex, _CAP, long
    return False, 0.0, _NEEDLE, short


@njit(cache=True, error_model="numpy")
def _candidates(points, faces, needle, cap_height, cap_cos):
    """Faces to fix, needles (shortest edge first) before caps (most obtuse first): (face, kind, corner), the edge
    to act on running from ``corner`` to the next corner (a needle's shortest edge, a cap's longest)."""
    n_faces = faces.shape[0]
    key = np.empty(n_faces)
    face = np.empty(n_faces, np.int64)
    kind = np.empty(n_faces, np.int64)
    corner = np.empty(n_faces, np.int64)
    length = np.empty(3)
    n = 0
    for f in range(n_faces):
        found, key[n], kind[n], corner[n] = _face_candidate(points, faces, f, needle, cap_height, cap_cos, length)
        if found:
            face[n] = f
            n += 1
    order = np.argsort(key[:n], kind="mergesort")
    return face[order], kind[order], corner[order]


@njit(cache=True, error_model="numpy")
def _has_candidate(points, faces, needle, cap_height, cap_cos):
    """Whether :func:`_candidates` would find a face; compiles in a fraction of the time of the pass."""
    length = np.empty(3)
    for f in range(faces.shape[0]):
        if _face_candidate(points, faces, f, needle, cap_height, cap_cos, length)[0]:
            return True
    return False


@njit(cache=True, error_model="numpy")
def _min_cos(p0, p1, p2):
    """Cosine of the largest angle of a triangle."""
    out = 1.0
    for k in range(3):
        o = p0 if k == 0 else (p1 if k == 1 else p2)
        u = v3.sub(p1 if k == 0 else (p2 if k == 1 else p0), o)
        w = v3.sub(p2 if k == 0 else (p0 if k == 1 else p1), o)
        out = min(out, v3.dot(u, w) / max(v3.norm(u) * v3.norm(w), 1e-300))
    return out


@njit(cache=True, error_model="numpy")
def _star_min_cos(points, faces, indptr, face_ids, a, b, pos, moved):
    """Cosine of the largest angle of the faces around edge (a, b) but those on it, with a and b at ``pos`` when
    ``moved`` (after the collapse) or where they are."""
    out = 1.0
    for end in range(2):
        v = a if end == 0 else b
        for s in range(indptr[v], indptr[v + 1]):
            f = face_ids[s]
            i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
            if (i0 == a or i1 == a or i2 == a) and (i0 == b or i1 == b or i2 == b):
                continue
            q0 = pos if moved and (i0 == a or i0 == b) else v3.row(points, i0)
            q1 = pos if moved and (i1 == a or i1 == b) else v3.row(points, i1)
            q2 = pos if moved and (i2 == a or i2 == b) else v3.row(points, i2)
            out = min(out, _min_cos(q0, q1, q2))
    return out


@njit(cache=True, error_model="numpy")
def _is_curve_edge(curve_keys, n_vertices, a, b):
    key = min(a, b) * n_vertices + max(a, b)
    at = np.searchsorted(curve_keys, key)
    return at < curve_keys.shape[0] and curve_keys[at] == key


@njit(cache=True, error_model="numpy")
def _freeze_ring(frozen, ring, n):
    for i in range(n):
        frozen[ring[i]] = True


@njit(cache=True, error_model="numpy")
def _ring_free(frozen, ring, n):
    for i in range(n):
        if frozen[ring[i]]:
            return False
    return True


@njit(cache=True, error_model="numpy")
def _other_face(faces, indptr, face_ids, f, a, b):
    """The one face other than ``f`` on edge (a, b), or -1 (none, or more than one)."""
    g = -1
    for s in range(indptr[a], indptr[a + 1]):
        h = face_ids[s]
        if h != f and (faces[h, 0] == b or faces[h, 1] == b or faces[h, 2] == b):
            if g >= 0:
                return -1
            g = h
    return g


@njit(cache=True, error_model="numpy")
def _pass(points, faces, on_curve, curve_degree, curve_keys, locked, needle, cap_height, cap_cos, crease_cos, tol):
    """One pass over the faces to fix. Returns the grown points and faces, which faces are alive, the vertex each
    vertex merged into (itself if none), the face each face comes from, the curve flags, the splits (edge a-b
    split at m: rows (a, b, m)) and the numbers of collapses, flips and splits."""
    n_v, n_f = points.shape[0], faces.shape[0]
    face, kind, corner = _candidates(points, faces, needle, cap_height, cap_cos)
    if face.shape[0] == 0:
        return (points, faces, np.ones(n_f, np.bool_), np.arange(n_v), np.arange(n_f), on_curve,
                np.empty((0, 3), np.int64), 0, 0, 0)
    n_caps = int(np.sum(kind == _CAP))
    # element loops, not slice assignments: those compile numba's formatting of shape errors
    pts = np.empty((n_v + n_caps, 3))
    curve = np.zeros(n_v + n_caps, np.bool_)
    frozen = np.zeros(n_v + n_caps, np.bool_)
    for v in range(n_v):
        for d in range(3):
            pts[v, d] = points[v, d]
        curve[v] = on_curve[v]
        frozen[v] = locked[v]
    fcs = np.empty((n_f + 2 * n_caps, 3), np.int64)
    for f in range(n_f):
        for k in range(3):
            fcs[f, k] = faces[f, k]
    parent = np.arange(n_f + 2 * n_caps)
    alive = np.ones(n_f + 2 * n_caps, np.bool_)
    merged = np.arange(n_v + n_caps)
    splits = np.empty((n_caps, 3), np.int64)
    indptr, face_ids, _ = _incidence(faces, n_v)
    ring_a = np.empty(256, np.int64)
    ring_b = np.empty(256, np.int64)
    ring_c = np.empty(256, np.int64)
    nv, nf = n_v, n_f
    n_collapsed = n_flipped = n_split = 0
    for c in range(face.shape[0]):
        f = face[c]
        if frozen[fcs[f, 0]] or frozen[fcs[f, 1]] or frozen[fcs[f, 2]]:
            continue  # a face next to an earlier operation of this pass: next pass
        k = corner[c]
        a, b, apex = fcs[f, k], fcs[f, (k + 1) % 3], fcs[f, (k + 2) % 3]
        on_curve_edge = curve[a] and curve[b] and _is_curve_edge(curve_keys, n_v, a, b)
        if kind[c] == _NEEDLE:
            # b merges into a; a curve vertex stays where it is
            fixed = curve[a] or curve[b]
            if curve[a] and curve[b]:
                if not on_curve_edge or (curve_degree[b] != 2 and curve_degree[a] != 2):
                    continue
                if curve_degree[b] != 2:
                    a, b = b, a
            elif curve[b]:
                a, b = b, a
            na, nb = collapsible(fcs, indptr, face_ids, a, b, ring_a, ring_b, ring_c)
            if na < 0 or not (_ring_free(frozen, ring_a, na) and _ring_free(frozen, ring_b, nb)):
                continue
            pa, pb = v3.row(pts, a), v3.row(pts, b)
            best = np.inf
            best_pos = pa
            worst = min(cap_cos, _star_min_cos(pts, fcs, indptr, face_ids, a, b, pa, False))
            for option in range(1 if fixed else 3):
                pos = pa if option == 0 else (pb if option == 1 else v3.scale(v3.add(pa, pb), 0.5))
                cost = abs(collapse_cost(pts, fcs, indptr, face_ids, a, b, pos, tol))
                if cost < best and _star_min_cos(pts, fcs, indptr, face_ids, a, b, pos, True) >= worst:
                    best, best_pos = cost, pos
            if best == np.inf:
                continue
            merge_vertices(pts, fcs, indptr, face_ids, alive, a, b, best_pos)
            merged[b] = a
            frozen[a] = frozen[b] = True
            _freeze_ring(frozen, ring_a, na)
            _freeze_ring(frozen, ring_b, nb)
            n_collapsed += 1
            continue
        g = _other_face(fcs, indptr, face_ids, f, a, b)
        if g < 0:
            continue
        d = fcs[g, 0] + fcs[g, 1] + fcs[g, 2] - a - b
        if frozen[d] or d == apex:
            continue
        pa, pb, pc, pd = v3.row(pts, a), v3.row(pts, b), v3.row(pts, apex), v3.row(pts, d)
        if on_curve_edge:
            # split the curve edge at the foot of the apex: (a, b, c) + (b, a, d) -> (a, m, c), (m, b, c), (b, m, d),
            # (m, a, d)
            ab = v3.sub(pb, pa)
            t = v3.dot(v3.sub(pc, pa), ab) / v3.dot(ab, ab)
            foot = v3.add(pa, v3.scale(ab, t))
            if not 0.1 <= t <= 0.9 or min(_min_cos(pb, foot, pd), _min_cos(foot, pa, pd)) <= _min_cos(pa, pb, pc):
                continue
            m = nv
            nv += 1
            v3.store(pts, m, foot)
            curve[m] = True
            fcs[f, (k + 1) % 3] = m
            fcs[nf, 0], fcs[nf, 1], fcs[nf, 2] = m, b, apex
            parent[nf] = f
            for j in range(3):
                if fcs[g, j] == a:
                    fcs[g, j] = m
            fcs[nf + 1, 0], fcs[nf + 1, 1], fcs[nf + 1, 2] = m, a, d
            parent[nf + 1] = g
            nf += 2
            splits[n_split, 0], splits[n_split, 1], splits[n_split, 2] = a, b, m
            n_split += 1
            frozen[a] = frozen[b] = frozen[apex] = frozen[d] = frozen[m] = True
            continue
        # flip edge a-b: (a, b, c) + (b, a, d) -> (a, d, c), (d, b, c)
        if _ring_contains(fcs, indptr, face_ids, apex, d, ring_c):
            continue
        n_f_old = v3.cross(v3.sub(pb, pa), v3.sub(pc, pa))
        n_g_old = v3.cross(v3.sub(pa, pb), v3.sub(pd, pb))
        pair = v3.add(n_f_old, n_g_old)
        n1 = v3.cross(v3.sub(pd, pa), v3.sub(pc, pa))
        n2 = v3.cross(v3.sub(pb, pd), v3.sub(pc, pd))
        span = tol * v3.norm(v3.sub(pc, pd))
        if v3.norm(n1) <= span or v3.norm(n2) <= span or v3.dot(n1, pair) <= 0.0 or v3.dot(n2, pair) <= 0.0:
            continue
        if v3.norm(n_f_old) > cap_height * v3.norm(v3.sub(pb, pa)):  # a cap with an area: keep creases, improve
            if v3.dot(n_f_old, n_g_old) < crease_cos * v3.norm(n_f_old) * v3.norm(n_g_old):
                continue
            if min(_min_cos(pa, pd, pc), _min_cos(pd, pb, pc)) <= _min_cos(pa, pb, pc):
                continue
        fcs[f, 0], fcs[f, 1], fcs[f, 2] = a, d, apex
        fcs[g, 0], fcs[g, 1], fcs[g, 2] = d, b, apex
        frozen[a] = frozen[b] = frozen[apex] = frozen[d] = True
        n_flipped += 1
    return (pts[:nv], fcs[:nf], alive[:nf], merged[:nv], parent[:nf], curve[:nv], splits[:n_split],
            n_collapsed, n_flipped, n_split)


@njit(cache=True, error_model="numpy")
def _ring_contains(faces, indptr, face_ids, v, w, ring):
    n = star_vertices(faces, indptr, face_ids, v, ring)
    for i in range(n):
        if ring[i] == w:
            return True
    return False


def _curve_edges(polylines: list, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Sorted keys min * V + max of the curves' edges, and the number of curve edges at every vertex (V,)."""
    if not polylines:
        return np.empty(0, np.int64), np.zeros(n_vertices, np.int64)
    a = np.concatenate([line[:-1] for line in polylines])
    b = np.concatenate([line[1:] for line in polylines])
    keys = np.unique(np.minimum(a, b) * n_vertices + np.maximum(a, b))
    degree = np.bincount(np.concatenate([keys // n_vertices, keys % n_vertices]), minlength=n_vertices)
    return keys, degree


def _follow(line: np.ndarray, merged: np.ndarray, splits: np.ndarray) -> np.ndarray:
    """A polyline after a pass: split points put between the ends of their edges, merged points replaced."""
    if len(splits):
        n = len(merged)
        inserted = dict(zip((np.minimum(splits[:, 0], splits[:, 1]) * n
                             + np.maximum(splits[:, 0], splits[:, 1])).tolist(), splits[:, 2].tolist()))
        keys = (np.minimum(line[:-1], line[1:]) * n + np.maximum(line[:-1], line[1:])).tolist()
        out = [int(line[0])]
        for key, q in zip(keys, line[1:].tolist()):
            if key in inserted:
                out.append(inserted[key])
            out.append(q)
        line = np.asarray(out, np.int64)
    line = merged[line]
    return line[np.r_[True, line[1:] != line[:-1]]]


def remove_degenerate_faces(
    points: np.ndarray,
    faces: np.ndarray,
    *,
    needle_length: float,
    cap_height: float = 0.0,
    max_angle: float | None = None,
    crease_angle: float = 30.0,
    polylines: list | None = None,
    locked: np.ndarray | None = None,
    max_passes: int = 32,
) -> DegenerateCleanup:
    """Collapse needles and flip or split caps until none is left (or no operation applies).

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3), int64
        A closed, consistently oriented mesh.
    needle_length : float
        Faces with an edge shorter than this are needles.
    cap_height : float, default: 0.0
        Faces with a corner at most this far from the opposite edge are caps
        (they have no area to speak of: they flip whatever the crease angle).
    max_angle : float, optional
        Faces with an angle above this (degrees) are caps too.
    crease_angle : float, default: 30.0
        A cap with an area flips only where its neighbour's normal is within
        this angle (degrees) of its own.
    polylines : list of numpy.ndarray, optional
        Curves (vertex indices) whose vertices must stay and whose edges
        must not flip.
    locked : numpy.ndarray, shape (V,), bool, optional
        Vertices no operation may touch.
    max_passes : int, default: 32

    Returns
    -------
    DegenerateCleanup
    """
    pts = np.asarray(points, dtype=np.float64)
    fcs = np.asarray(faces, dtype=np.int64)
    lines = [np.asarray(line, np.int64) for line in (polylines or [])]
    curve = np.zeros(len(pts), bool)
    for line in lines:
        curve[line] = True
    frozen = np.zeros(len(pts), bool) if locked is None else np.asarray(locked, bool).copy()
    vertex_source = np.arange(len(pts))
    face_source = np.arange(len(fcs))
    cap_cos = -2.0 if max_angle is None else float(np.cos(np.radians(max_angle)))
    crease_cos = float(np.cos(np.radians(crease_angle)))
    totals = np.zeros(3, np.int64)
    if not _has_candidate(pts, fcs, float(needle_length), float(cap_height), cap_cos):
        max_passes = 0  # no needle or cap: the mesh stays as it is, without compiling the pass kernel
    for _ in range(max_passes):
        keys, degree = _curve_edges(lines, len(pts))
        (new_pts, new_fcs, alive, merged, parent, curve, splits, *counts) = _pass(
            pts, fcs, curve, degree, keys, frozen, float(needle_length), float(cap_height), cap_cos, crease_cos,
            float(cap_height))
        if not any(counts):
            break
        totals += counts
        kept = np.flatnonzero(merged == np.arange(len(merged)))
        index = np.full(len(merged), -1, np.int64)
        index[kept] = np.arange(len(kept))
        lines = [index[_follow(line, merged, splits)] for line in lines]
        pts, fcs = new_pts[kept], index[new_fcs[alive]]
        vertex_source = np.r_[vertex_source, np.full(len(merged) - len(vertex_source), -1)][kept]
        face_source = face_source[parent[alive]]
        curve = curve[kept]
        frozen = np.r_[frozen, np.zeros(len(merged) - len(frozen), bool)][kept]
    return DegenerateCleanup(points=pts, faces=fcs, vertex_source=vertex_source, face_source=face_source,
                             on_curve=curve, polylines=lines, collapsed=int(totals[0]), flipped=int(totals[1]),
                             split=int(totals[2]))
