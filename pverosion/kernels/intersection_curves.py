"""Intersection boundary of triangle meshes: exact segments, their points, and the closed curves they form.

Skorkovská's thesis (§10.1, after Lo and Wang's tracing of the neighbours of
intersecting triangles, TNOIT) classifies the line where the planes of two
triangles meet against the edges of each triangle: every edge's line meets
it outside the edge (0), at a vertex (1) or inside the edge (2), giving the
cases 000 ... 222 once sorted. Computed in floating point the classification
can come out as one of the impossible cases 001, 002, 012, 122, 222, and a
tracing must recover from it. Here every decision is the exact sign of an
orientation determinant (:mod:`pverosion.kernels.predicates`), so the
classification is exact and the impossible cases cannot occur; their counts
are still kept (:data:`CASES`) as the thesis' Table 10.1 does.

Each intersection point is identified by what produces it, not by its
coordinates, so two triangle pairs that meet at the same point name it alike:

- an input vertex (coincident input vertices are one point), when a vertex of
  one triangle lies on the other;
- an edge and a face, when an edge crosses a face's interior;
- two edges, when they cross each other inside both.

The segments of all pairs then link up through their shared points into
polylines (:func:`trace_polylines`): following a segment's end to the next
segment is the step of TNOIT to the neighbouring triangle across the edge
(or around the vertex) where the segment leaves its triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from pverosion.kernels.intersection import candidate_pairs
from pverosion.kernels.predicates import sign_orient2d, sign_orient3d
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["CASES", "IMPOSSIBLE_CASES", "IntersectionCurves", "canonical_vertices", "intersection_curves", "trace_polylines"]

CASES = ("000", "001", "002", "011", "012", "022", "111", "112", "122", "222")
"""The thesis' classification of a line against a triangle: per edge, 0 (meets outside), 1 (at a vertex),
2 (inside), sorted."""
IMPOSSIBLE_CASES = ("001", "002", "012", "122", "222")
"""Cases no line can produce; a floating-point classification can."""

VERTEX, EDGE_FACE, EDGE_EDGE = 0, 1, 2
"""Kinds of intersection points (first column of :attr:`IntersectionCurves.point_keys`)."""

# location of a point on a triangle: 0..2 its vertex k, 3..5 inside its edge k (from vertex k to k + 1),
# 6 inside the triangle, -1 outside
_EDGE = 3
_INSIDE = 6
_OUT = -1

# status of a pair
_APART, _TOUCH, _CROSS, _COPLANAR = 0, 1, 2, 3


@dataclass(frozen=True)
class IntersectionCurves:
    """Where the faces of a mesh (or of several meshes put together) intersect.

    Attributes
    ----------
    points : numpy.ndarray, shape (P, 3), float64
        The intersection points (input vertices among them).
    point_keys : numpy.ndarray, shape (P, 3), int64
        What produces each point: ``(VERTEX, v, 0)`` with ``v`` the lowest
        index of the input vertices at that position; ``(EDGE_FACE, e, f)``
        with ``e = a * V + b`` the edge between vertices a < b and ``f`` the
        face; ``(EDGE_EDGE, e1, e2)`` with ``e1 < e2``.
    segments : numpy.ndarray, shape (S, 2), int64
        Point indices of the intersection segment of each intersecting pair.
    pairs : numpy.ndarray, shape (S, 2), int64
        The two faces ``(f, g)``, ``f < g``, of each segment.
    locations : numpy.ndarray, shape (S, 2, 2), int64
        Where each end of each segment lies on each face of its pair
        (``locations[s, end, side]``, side 0 for f and 1 for g): 0, 1, 2 at
        that vertex of the face, 3 + k inside its edge k (from vertex k to
        vertex k + 1), 6 inside the face.
    cases : numpy.ndarray, shape (10,), int64
        How often each case of :data:`CASES` occurred, counting both
        triangles of every intersecting pair.
    touching : int
        Pairs that meet in a single point only (no segment).
    coplanar : numpy.ndarray, shape (C, 2), int64
        Pairs of faces in one plane whose boxes meet (not cut; they may or
        may not overlap).
    """

    points: np.ndarray
    point_keys: np.ndarray
    segments: np.ndarray
    pairs: np.ndarray
    locations: np.ndarray
    cases: np.ndarray
    touching: int
    coplanar: np.ndarray

    @property
    def case_table(self) -> dict[str, int]:
        """Counts per case name, plus the totals ``"valid"`` and ``"impossible"``."""
        table = {name: int(n) for name, n in zip(CASES, self.cases)}
        table["impossible"] = sum(table[name] for name in IMPOSSIBLE_CASES)
        table["valid"] = int(self.cases.sum()) - table["impossible"] - table["000"]
        return table

    def faces(self) -> np.ndarray:
        """The faces that take part in an intersection segment, sorted (K,)."""
        return np.unique(self.pairs)


# --- exact classification of one pair ------------------------------------------------------------------------


@njit(cache=True)
def _o3(p, a, b, c, d):
    """Exact sign of orient3d of the points with indices a, b, c, d."""
    return sign_orient3d(p[a, 0], p[a, 1], p[a, 2], p[b, 0], p[b, 1], p[b, 2], p[c, 0], p[c, 1], p[c, 2],
                         p[d, 0], p[d, 1], p[d, 2])


@njit(cache=True)
def _o2(p, axis, a, b, c):
    """Exact sign of orient2d of the points a, b, c projected along ``axis`` (cyclic: the sign is that of the
    axis component of (b - a) x (c - a))."""
    i, j = (axis + 1) % 3, (axis + 2) % 3
    return sign_orient2d(p[a, i], p[a, j], p[b, i], p[b, j], p[c, i], p[c, j])


@njit(cache=True)
def _drop_axis(p, tri):
    """Axis along which the face's normal is largest (the projection along it keeps the face's shape)."""
    a, b, c = tri[0], tri[1], tri[2]
    ux, uy, uz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    vx, vy, vz = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1], p[c, 2] - p[a, 2]
    nx, ny, nz = abs(uy * vz - uz * vy), abs(uz * vx - ux * vz), abs(ux * vy - uy * vx)
    if nx >= ny and nx >= nz:
        return 0
    return 1 if ny >= nz else 2


@njit(cache=True)
def _location(left0, left1, left2):
    """Location on a triangle from the sides (+1 left, 0 on, -1 right) of its three directed edges."""
    if left0 < 0 or left1 < 0 or left2 < 0:
        return _OUT
    zeros = (left0 == 0) + (left1 == 0) + (left2 == 0)
    if zeros == 0:
        return _INSIDE
    if zeros == 1:
        return _EDGE + (0 if left0 == 0 else (1 if left1 == 0 else 2))
    if zeros == 2:  # on two edges: at their common vertex
        if left0 != 0:
            return 2  # edges 1 and 2 meet at vertex 2
        return 1 if left2 != 0 else 0
    return _OUT  # a degenerate triangle


@njit(cache=True)
def _vertex_in(p, tri, axis, orientation, v):
    """Location of vertex ``v``, which lies in the plane of ``tri``, on the triangle."""
    s0 = _o2(p, axis, tri[0], tri[1], v) * orientation
    s1 = _o2(p, axis, tri[1], tri[2], v) * orientation
    s2 = _o2(p, axis, tri[2], tri[0], v) * orientation
    return _location(s0, s1, s2)


@njit(cache=True)
def _crossing_in(p, tri, a, b, side_b):
    """Location on ``tri`` of the point where edge (a, b) crosses the triangle's plane (``side_b``: the sign of
    orient3d(tri, b), nonzero)."""
    s0 = _o3(p, tri[0], tri[1], a, b) * side_b
    s1 = _o3(p, tri[1], tri[2], a, b) * side_b
    s2 = _o3(p, tri[2], tri[0], a, b) * side_b
    return _location(s0, s1, s2)


@njit(cache=True)
def _case(s):
    """Index into CASES of a triangle whose vertices lie on the sides ``s`` of the other plane."""
    digits = np.empty(3, np.int64)
    for k in range(3):
        a, b = s[k], s[(k + 1) % 3]
        if a * b < 0:
            digits[k] = 2
        elif a == 0 or b == 0:
            digits[k] = 1
        else:
            digits[k] = 0
    digits.sort()
    code = digits[0] * 100 + digits[1] * 10 + digits[2]
    for i, c in enumerate((0, 1, 2, 11, 12, 22, 111, 112, 122, 222)):
        if c == code:
            return i
    return -1


@njit(cache=True)
def _ends(s):
    """Ends of a triangle's interval on the other plane: (n, kind (0 vertex / 1 edge), index) x up to 2."""
    kinds = np.zeros(3, np.int64)
    index = np.zeros(3, np.int64)
    n = 0
    for k in range(3):
        if s[k] == 0:
            kinds[n], index[n] = 0, k
            n += 1
    for k in range(3):
        if s[k] * s[(k + 1) % 3] < 0:
            kinds[n], index[n] = 1, k
            n += 1
    return n, kinds, index


@njit(cache=True)
def _edge_key(canon, n_vertices, a, b):
    a, b = canon[a], canon[b]
    return min(a, b) * n_vertices + max(a, b)


@njit(cache=True)
def _key(canon, n_vertices, tri_f, tri_g, f, g, loc_f, loc_g):
    """Symbolic key of a point from its locations on faces f and g."""
    if loc_f < _EDGE:
        return VERTEX, canon[tri_f[loc_f]], 0
    if loc_g < _EDGE:
        return VERTEX, canon[tri_g[loc_g]], 0
    if loc_f < _INSIDE and loc_g < _INSIDE:
        k, j = loc_f - _EDGE, loc_g - _EDGE
        e1 = _edge_key(canon, n_vertices, tri_f[k], tri_f[(k + 1) % 3])
        e2 = _edge_key(canon, n_vertices, tri_g[j], tri_g[(j + 1) % 3])
        return EDGE_EDGE, min(e1, e2), max(e1, e2)
    if loc_f < _INSIDE:
        k = loc_f - _EDGE
        return EDGE_FACE, _edge_key(canon, n_vertices, tri_f[k], tri_f[(k + 1) % 3]), g
    j = loc_g - _EDGE
    return EDGE_FACE, _edge_key(canon, n_vertices, tri_g[j], tri_g[(j + 1) % 3]), f


@njit(cache=True)
def _classify(p, faces, canon, f, g, keys, locs, cases):
    """Intersection of faces f and g: its status, and for a segment the keys (2, 3) and locations (2, 2) of its
    ends (filled in place); ``cases`` gets the case index of each face (2,)."""
    tf, tg = faces[f], faces[g]
    sf = np.empty(3, np.int64)
    sg = np.empty(3, np.int64)
    for k in range(3):
        sf[k] = _o3(p, tg[0], tg[1], tg[2], tf[k])
        sg[k] = _o3(p, tf[0], tf[1], tf[2], tg[k])
    cases[0], cases[1] = _case(sf), _case(sg)
    if sf[0] == 0 and sf[1] == 0 and sf[2] == 0:
        return _COPLANAR
    if abs(sf[0] + sf[1] + sf[2]) == 3 or abs(sg[0] + sg[1] + sg[2]) == 3:
        return _APART
    n_vertices = p.shape[0]
    axis_f, axis_g = _drop_axis(p, tf), _drop_axis(p, tg)
    orient_f = _o2(p, axis_f, tf[0], tf[1], tf[2])
    orient_g = _o2(p, axis_g, tg[0], tg[1], tg[2])
    found = 0
    for side in range(2):  # ends of f's interval located on g, then ends of g's interval located on f
        tri, other, s = (tf, tg, sf) if side == 0 else (tg, tf, sg)
        axis, orientation = (axis_g, orient_g) if side == 0 else (axis_f, orient_f)
        n, kinds, index = _ends(s)
        for e in range(n):
            k = index[e]
            if kinds[e] == 0:
                own = k
                there = _vertex_in(p, other, axis, orientation, tri[k])
            else:
                b = tri[(k + 1) % 3]
                own = _EDGE + k
                there = _crossing_in(p, other, tri[k], b, s[(k + 1) % 3])
            if there == _OUT:
                continue
            loc_f, loc_g = (own, there) if side == 0 else (there, own)
            kind, x, y = _key(canon, n_vertices, tf, tg, f, g, loc_f, loc_g)
            known = False
            for q in range(found):
                if keys[q, 0] == kind and keys[q, 1] == x and keys[q, 2] == y:
                    known = True
            if known:
                continue
            if found == 2:
                return -1  # cannot happen with exact signs
            keys[found, 0], keys[found, 1], keys[found, 2] = kind, x, y
            locs[found, 0], locs[found, 1] = loc_f, loc_g
            found += 1
    if found == 0:
        return _APART
    return _TOUCH if found == 1 else _CROSS


@njit(cache=True, parallel=True)
def _classify_pairs(p, faces, canon, pairs):
    """:func:`_classify` of every pair: status (K,), keys (K, 2, 3), locations (K, 2, 2), cases (K, 2)."""
    n = pairs.shape[0]
    status = np.empty(n, np.int64)
    keys = np.zeros((n, 2, 3), np.int64)
    locs = np.zeros((n, 2, 2), np.int64)
    cases = np.zeros((n, 2), np.int64)
    for i in prange(n):
        status[i] = _classify(p, faces, canon, pairs[i, 0], pairs[i, 1], keys[i], locs[i], cases[i])
    return status, keys, locs, cases


# --- coordinates of the points -------------------------------------------------------------------------------


@njit(cache=True)
def _edge_face_point(p, a, b, f0, f1, f2):
    """Where segment (a, b) crosses the plane of face (f0, f1, f2), in floating point."""
    ux, uy, uz = p[f1, 0] - p[f0, 0], p[f1, 1] - p[f0, 1], p[f1, 2] - p[f0, 2]
    vx, vy, vz = p[f2, 0] - p[f0, 0], p[f2, 1] - p[f0, 1], p[f2, 2] - p[f0, 2]
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    da = nx * (p[a, 0] - p[f0, 0]) + ny * (p[a, 1] - p[f0, 1]) + nz * (p[a, 2] - p[f0, 2])
    db = nx * (p[b, 0] - p[f0, 0]) + ny * (p[b, 1] - p[f0, 1]) + nz * (p[b, 2] - p[f0, 2])
    t = min(max(da / (da - db), 0.0), 1.0)
    return p[a, 0] + t * (p[b, 0] - p[a, 0]), p[a, 1] + t * (p[b, 1] - p[a, 1]), p[a, 2] + t * (p[b, 2] - p[a, 2])


@njit(cache=True)
def _edge_edge_point(p, a, b, c, d):
    """Where segment (a, b) meets the (coplanar, crossing) segment (c, d), in floating point."""
    ux, uy, uz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    vx, vy, vz = p[d, 0] - p[c, 0], p[d, 1] - p[c, 1], p[d, 2] - p[c, 2]
    wx, wy, wz = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1], p[c, 2] - p[a, 2]
    # t with (w - t u) x v = 0: t = ((w x v) . (u x v)) / |u x v|^2
    cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    ex, ey, ez = wy * vz - wz * vy, wz * vx - wx * vz, wx * vy - wy * vx
    t = min(max((ex * cx + ey * cy + ez * cz) / (cx * cx + cy * cy + cz * cz), 0.0), 1.0)
    return p[a, 0] + t * ux, p[a, 1] + t * uy, p[a, 2] + t * uz


@njit(cache=True, parallel=True)
def _coordinates(p, faces, keys):
    """Coordinates (P, 3) of the points with the given keys, computed from the keys alone (so alike for every
    pair that produces a point)."""
    n_vertices = p.shape[0]
    out = np.empty((keys.shape[0], 3))
    for i in prange(keys.shape[0]):
        kind = keys[i, 0]
        if kind == VERTEX:
            v = keys[i, 1]
            out[i, 0], out[i, 1], out[i, 2] = p[v, 0], p[v, 1], p[v, 2]
        elif kind == EDGE_FACE:
            a, b = keys[i, 1] // n_vertices, keys[i, 1] % n_vertices
            f = keys[i, 2]
            x, y, z = _edge_face_point(p, a, b, faces[f, 0], faces[f, 1], faces[f, 2])
            out[i, 0], out[i, 1], out[i, 2] = x, y, z
        else:
            a, b = keys[i, 1] // n_vertices, keys[i, 1] % n_vertices
            c, d = keys[i, 2] // n_vertices, keys[i, 2] % n_vertices
            x, y, z = _edge_edge_point(p, a, b, c, d)
            out[i, 0], out[i, 1], out[i, 2] = x, y, z
    return out


# --- the whole boundary --------------------------------------------------------------------------------------


def canonical_vertices(points: np.ndarray) -> np.ndarray:
    """The lowest index of the vertices at the position of every vertex (V,): coincident vertices as one."""
    _, first, inverse = np.unique(points, axis=0, return_index=True, return_inverse=True)
    return first[inverse.ravel()].astype(np.int64)


def intersection_curves(points, faces, *, group=None) -> IntersectionCurves:
    """Exact intersection segments between the faces of a mesh, or between meshes put together.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        Faces that share a vertex index are neighbours and not tested.
    group : array_like of int, shape (F,), optional
        Test only pairs of faces of different groups (the mesh each face
        comes from); by default every pair of faces (self-intersections).

    Returns
    -------
    IntersectionCurves

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> a, b = pv.Icosphere(radius=1.0, nsub=2), pv.Icosphere(radius=1.0, nsub=2).translate((1.0, 0.2, 0.1))
    >>> points = np.vstack([a.points, b.points]).astype(float)
    >>> faces = np.vstack([a.regular_faces, b.regular_faces + a.n_points])
    >>> curves = intersection_curves(points, faces, group=np.repeat([0, 1], a.n_cells))
    >>> loops = trace_polylines(curves)
    >>> len(loops), curves.case_table["impossible"]
    (1, 0)
    """
    pts, fcs = as_triangle_mesh(points, faces)
    pairs = candidate_pairs(pts, fcs, group=group)
    canon = canonical_vertices(pts)
    status, keys, locs, cases = _classify_pairs(pts, fcs, canon, pairs)
    if np.any(status < 0):
        raise RuntimeError("inconsistent intersection of a face pair (the exact predicates should prevent this)")
    crossing = status == _CROSS
    case_counts = np.bincount(cases[status != _APART].ravel(), minlength=len(CASES)).astype(np.int64)
    seg_keys = keys[crossing].reshape(-1, 3)
    if len(seg_keys):
        unique, inverse = np.unique(seg_keys, axis=0, return_inverse=True)
        segments = inverse.reshape(-1, 2).astype(np.int64)
    else:
        unique, segments = np.zeros((0, 3), np.int64), np.zeros((0, 2), np.int64)
    return IntersectionCurves(
        points=_coordinates(pts, fcs, unique),
        point_keys=unique,
        segments=segments,
        pairs=pairs[crossing],
        locations=locs[crossing],
        cases=case_counts,
        touching=int(np.count_nonzero(status == _TOUCH)),
        coplanar=pairs[status == _COPLANAR],
    )


def trace_polylines(curves: IntersectionCurves) -> list[np.ndarray]:
    """The intersection segments linked end to end into polylines.

    A segment whose end lies inside an edge of its face continues on the
    face across that edge; one that ends at a vertex continues on a face
    around the vertex (TNOIT's step to the neighbouring triangle). Segments
    produced by several pairs (along an edge shared by two faces) count once.

    Parameters
    ----------
    curves : IntersectionCurves

    Returns
    -------
    list of numpy.ndarray
        Point indices of each polyline, in order; a closed polyline repeats
        its first point at the end. Where more than two segments meet
        (curves crossing or touching), polylines end there.
    """
    segs = np.unique(np.sort(curves.segments, axis=1), axis=0)
    n_points = len(curves.points)
    if len(segs) == 0:
        return []
    ends = np.concatenate([segs[:, 0], segs[:, 1]])
    other = np.concatenate([segs[:, 1], segs[:, 0]])
    seg_id = np.concatenate([np.arange(len(segs)), np.arange(len(segs))])
    order = np.argsort(ends, kind="stable")
    start = np.searchsorted(ends[order], np.arange(n_points + 1))
    degree = np.diff(start)
    used = np.zeros(len(segs), bool)
    lines = []

    def walk(point: int) -> list[int]:
        path = [point]
        while True:
            q = None
            if degree[point] == 2 or len(path) == 1:
                for j in order[start[point]:start[point + 1]]:
                    if not used[seg_id[j]]:
                        q, s = other[j], seg_id[j]
                        break
            if q is None:
                return path
            used[s] = True
            path.append(int(q))
            point = int(q)
            if point == path[0]:
                return path

    for first in np.flatnonzero((degree != 2) & (degree > 0)):  # open polylines start where they end
        while any(not used[seg_id[j]] for j in order[start[first]:start[first + 1]]):
            lines.append(np.array(walk(int(first)), dtype=np.int64))
    for s in range(len(segs)):  # closed loops
        if not used[s]:
            lines.append(np.array(walk(int(segs[s, 0])), dtype=np.int64))
    return lines
