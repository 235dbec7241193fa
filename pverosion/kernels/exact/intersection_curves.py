"""Intersection boundary of triangle meshes: exact segments, their points, and the closed curves they form.

Skorkovská's thesis (§10.1, after Lo and Wang's tracing of the neighbours of
intersecting triangles, TNOIT) classifies the line where the planes of two
triangles meet against the edges of each triangle: every edge's line meets
it outside the edge (0), at a vertex (1) or inside the edge (2), giving the
cases 000 ... 222 once sorted. Computed in floating point the classification
can come out as one of the impossible cases 001, 002, 012, 122, 222, and a
tracing must recover from it. Here every decision is the exact sign of an
orientation determinant (:mod:`pverosion.kernels.exact.predicates`), so the
classification is exact and the impossible cases cannot occur; their counts
are still kept (:data:`CASES`) as the thesis' Table 10.1 does.

Each intersection point is identified by what produces it, not by its
coordinates, so two triangle pairs that meet at the same point name it alike:

- an input vertex (coincident input vertices are one point), when a vertex of
  one triangle lies on the other;
- an edge and a face, when an edge crosses a face's interior;
- two edges, when they cross each other inside both;
- three faces, where the segments of two pairs cross inside a face (three
  surfaces meet at a point).

A point that several of these name (an edge crossing two faces in one plane,
two edges crossing where a third face's edge crosses the plane of one of
them, a vertex exactly where two edges cross) keeps one name, so that every
face cut there sees one point; a point lying inside a segment of another
pair on a face (a T-junction of three surfaces) cuts that segment.

The segments of all pairs then link up through their shared points into
polylines (:func:`trace_polylines`): following a segment's end to the next
segment is the step of TNOIT to the neighbouring triangle across the edge
(or around the vertex) where the segment leaves its triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels._threads import HEAVY_ITEMS_PER_RANGE, for_ranges
from pverosion.kernels.exact.intersection import candidate_pairs, canonical_vertices
from pverosion.kernels.exact.predicates import sign_orient2d, sign_orient3d
from pverosion.kernels.validation import as_triangle_mesh, unique_rows

__all__ = ["CASES", "IMPOSSIBLE_CASES", "IntersectionCurves", "canonical_vertices", "coplanar_segments",
           "intersection_curves", "trace_polylines", "unique_rows"]

CASES = ("000", "001", "002", "011", "012", "022", "111", "112", "122", "222")
"""The thesis' classification of a line against a triangle: per edge, 0 (meets outside), 1 (at a vertex),
2 (inside), sorted."""
IMPOSSIBLE_CASES = ("001", "002", "012", "122", "222")
"""Cases no line can produce; a floating-point classification can."""

VERTEX, EDGE_FACE, EDGE_EDGE, FACE_FACE_FACE = 0, 1, 2, 3
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
        face (the lowest of the faces known to lie in its plane);
        ``(EDGE_EDGE, e1, e2)`` with ``e1 < e2``; ``(FACE_FACE_FACE, f,
        g * F + h)`` where three faces f < g < h meet (their segments cross).
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
        Pairs of faces in one plane whose boxes meet and that no edge line
        strictly separates in that plane (not cut; they may or may not
        overlap).
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


@njit(cache=True, inline="always")
def _vertex_in(p, tri, axis, orientation, v):
    """Location of vertex ``v``, which lies in the plane of ``tri``, on the triangle."""
    s0 = _o2(p, axis, tri[0], tri[1], v) * orientation
    s1 = _o2(p, axis, tri[1], tri[2], v) * orientation
    s2 = _o2(p, axis, tri[2], tri[0], v) * orientation
    return _location(s0, s1, s2)


@njit(cache=True, inline="always")
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
    # np.int64, not literals, for values a loop updates: numba types them in its first inference pass
    low, high, total = np.int64(2), np.int64(0), np.int64(0)
    for k in range(3):
        a, b = s[k], s[(k + 1) % 3]
        digit = 2 if a * b < 0 else (1 if a == 0 or b == 0 else 0)
        low, high, total = min(low, digit), max(high, digit), total + digit
    code = low * 100 + (total - low - high) * 10 + high  # the digits in ascending order
    for i, c in enumerate((0, 1, 2, 11, 12, 22, 111, 112, 122, 222)):
        if c == code:
            return i
    return -1


@njit(cache=True, inline="always")
def _ends(s):
    """Ends of a triangle's interval on the other plane: their number n and each end's 3 * kind (0 vertex / 1 edge)
    + index, packed 3 bits an end (end e: ``(ends >> 3 * e) & 7``); no arrays, as this runs for every pair."""
    ends = np.int64(0)
    n = np.int64(0)
    for k in range(3):
        if s[k] == 0:
            ends |= k << (3 * n)
            n += 1
    for k in range(3):
        if s[k] * s[(k + 1) % 3] < 0:
            ends |= (3 + k) << (3 * n)
            n += 1
    return n, ends


@njit(cache=True)
def _edge_key(canon, n_vertices, a, b):
    a, b = canon[a], canon[b]
    return min(a, b) * n_vertices + max(a, b)


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _apart_in_projection(p, tf, tg):
    """Whether two faces surely do not meet (faces that share one vertex: meet only there), decided exactly in
    the projection along the first face's largest normal component, where an edge line of either face must
    separate them (strictly, or through the shared vertex): what two faces share projects into what their
    projections share. Nearby faces of a flat region are settled so without the exact zeros of their
    orientations in space."""
    shared = np.int64(0)
    for k in range(3):
        shared += tf[k] == tg[0] or tf[k] == tg[1] or tf[k] == tg[2]
    if shared > 1:
        return False
    axis = _drop_axis(p, tf)
    if _o2(p, axis, tf[0], tf[1], tf[2]) == 0:
        return False
    if _separated(p, axis, tf, tg, shared == 0):
        return True
    return _o2(p, axis, tg[0], tg[1], tg[2]) != 0 and _separated(p, axis, tg, tf, shared == 0)


@njit(cache=True)
def _is_corner(canon, tri, v):
    """Whether canonical vertex ``v`` is a corner of ``tri``."""
    return canon[tri[0]] == v or canon[tri[1]] == v or canon[tri[2]] == v


@njit(cache=True, inline="always")
def _side(p, t, v):
    """Side of vertex ``v`` on the plane of face ``t`` (3,): 0 when it is a corner of ``t``."""
    return 0 if v == t[0] or v == t[1] or v == t[2] else _o3(p, t[0], t[1], t[2], v)


@njit(cache=True)
def _classify(p, faces, canon, f, g, keys, locs, cases):
    """Intersection of faces f and g: its status, and for a segment the keys (2, 3) and locations (2, 2) of its
    ends (filled in place); ``cases`` gets the case index of each face (2,)."""
    tf, tg = faces[f], faces[g]
    if _apart_in_projection(p, tf, tg):
        return _APART
    # the sides of f's vertices on g's plane and of g's on f's (a shared vertex lies in both planes)
    sf = (_side(p, tg, tf[0]), _side(p, tg, tf[1]), _side(p, tg, tf[2]))
    sg = (_side(p, tf, tg[0]), _side(p, tf, tg[1]), _side(p, tf, tg[2]))
    shared = np.int64(0)
    for k in range(3):
        shared += tf[k] == tg[0] or tf[k] == tg[1] or tf[k] == tg[2]
    cases[0], cases[1] = _case(sf), _case(sg)
    if sf[0] == 0 and sf[1] == 0 and sf[2] == 0:
        return _COPLANAR
    if abs(sf[0] + sf[1] + sf[2]) == 3 or abs(sg[0] + sg[1] + sg[2]) == 3:
        return _APART
    if shared and (abs(sf[0] + sf[1] + sf[2]) == 2 or abs(sg[0] + sg[1] + sg[2]) == 2):
        return _APART  # neighbours that meet only at their shared vertex
    n_vertices = p.shape[0]
    axis_f, axis_g = _drop_axis(p, tf), _drop_axis(p, tg)
    orient_f = _o2(p, axis_f, tf[0], tf[1], tf[2])
    orient_g = _o2(p, axis_g, tg[0], tg[1], tg[2])
    found = np.int64(0)
    for side in range(2):  # ends of f's interval located on g, then ends of g's interval located on f
        tri, other, s = (tf, tg, sf) if side == 0 else (tg, tf, sg)
        axis, orientation = (axis_g, orient_g) if side == 0 else (axis_f, orient_f)
        n, ends = _ends(s)
        for e in range(n):
            end = (ends >> (3 * e)) & 7
            k = end % 3
            if end < 3:
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
            known = np.bool_(False)
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
    if found == 0 or (found == 1 and shared and keys[0, 0] == VERTEX and _is_corner(canon, tf, keys[0, 1])
                      and _is_corner(canon, tg, keys[0, 1])):
        return _APART  # neighbours meeting only at their shared vertex are not touching
    return _TOUCH if found == 1 else _CROSS


@njit(cache=True, nogil=True)
def _classify_range(p, faces, canon, pairs, status, keys, locs, cases, start, stop):
    for i in range(start, stop):
        status[i] = _classify(p, faces, canon, pairs[i, 0], pairs[i, 1], keys[i], locs[i], cases[i])


def _classify_pairs(p, faces, canon, pairs) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_classify` of every pair: status (K,), keys (K, 2, 3), locations (K, 2, 2), cases (K, 2)."""
    n = pairs.shape[0]
    status = np.empty(n, np.int64)
    keys = np.zeros((n, 2, 3), np.int64)
    locs = np.zeros((n, 2, 2), np.int64)
    cases = np.zeros((n, 2), np.int64)
    for_ranges(_classify_range, n, p, faces, canon, pairs, status, keys, locs, cases,
               min_items=HEAVY_ITEMS_PER_RANGE)
    return status, keys, locs, cases


@njit(cache=True)
def _separated(p, axis, t, u, strict=False):
    """Whether a line through an edge of face ``t`` has all of face ``u`` on or beyond it (strictly beyond it)
    (exact)."""
    s = _o2(p, axis, t[0], t[1], t[2])
    bound = -1 if strict else 0
    for k in range(3):
        a, b = t[k], t[(k + 1) % 3]
        if (_o2(p, axis, a, b, u[0]) * s <= bound and _o2(p, axis, a, b, u[1]) * s <= bound
                and _o2(p, axis, a, b, u[2]) * s <= bound):
            return True
    return False


@njit(cache=True, nogil=True)
def _overlap_range(p, faces, pairs, out, start, stop):
    for i in range(start, stop):
        t, u = faces[pairs[i, 0]], faces[pairs[i, 1]]
        axis = _drop_axis(p, t)
        if _o2(p, axis, t[0], t[1], t[2]) != 0 and _o2(p, axis, u[0], u[1], u[2]) != 0:
            out[i] = not (_separated(p, axis, t, u) or _separated(p, axis, u, t))


def _coplanar_overlaps(p: np.ndarray, faces: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Which coplanar pairs (K, 2) overlap with their interiors (exact, in the projection along the axis of the
    first face's largest normal component: no edge line of either face separates them)."""
    out = np.zeros(pairs.shape[0], np.bool_)
    for_ranges(_overlap_range, pairs.shape[0], p, faces, pairs, out, min_items=HEAVY_ITEMS_PER_RANGE)
    return out


def coplanar_overlaps(points: np.ndarray, faces: np.ndarray, curves: IntersectionCurves) -> np.ndarray:
    """The pairs of ``curves.coplanar`` whose faces overlap with their interiors, (K', 2)."""
    if len(curves.coplanar) == 0:
        return curves.coplanar
    pts = np.ascontiguousarray(points, dtype=np.float64)
    return curves.coplanar[_coplanar_overlaps(pts, np.ascontiguousarray(faces, dtype=np.int64), curves.coplanar)]


@njit(cache=True)
def _strictly_between(p, axis, a, b, v):
    """Whether ``v``, on the line through a and b in the projection along ``axis``, lies strictly between them
    (exact: coordinates compare exactly, and the projection keeps the order on the line)."""
    i, j = (axis + 1) % 3, (axis + 2) % 3
    c = i if p[a, i] != p[b, i] else j
    return min(p[a, c], p[b, c]) < p[v, c] < max(p[a, c], p[b, c])


@njit(cache=True)
def _chord(p, canon, own, other, axis, orientation, k, keys, locs):
    """The part of edge k of face ``own`` inside the coplanar face ``other`` (closed), exactly in the projection
    along ``axis`` (``orientation``: the sign of ``other`` there): the number of its distinct ends (0, 1, 2 or
    more when inconsistent), their keys (filled in ``keys`` (3, 3)) and locations on own and other (``locs``
    (3, 2))."""
    n_vertices = p.shape[0]
    a, b = own[k], own[(k + 1) % 3]
    found = 0
    for end in range(2):  # the edge's ends inside the other face
        v = a if end == 0 else b
        there = _vertex_in(p, other, axis, orientation, v)
        if there != _OUT and found < 3:
            keys[found, 0], keys[found, 1], keys[found, 2] = VERTEX, canon[v], 0
            locs[found, 0], locs[found, 1] = (k if end == 0 else (k + 1) % 3), there
            found += 1
    for j in range(3):
        v = other[j]
        if canon[v] == canon[a] or canon[v] == canon[b]:
            continue
        if _o2(p, axis, a, b, v) == 0 and _strictly_between(p, axis, a, b, v):  # the other's corner on the edge
            if found == 3:
                return 4
            keys[found, 0], keys[found, 1], keys[found, 2] = VERTEX, canon[v], 0
            locs[found, 0], locs[found, 1] = _EDGE + k, j
            found += 1
    for j in range(3):  # the edge crossing an edge of the other inside both
        c, d = other[j], other[(j + 1) % 3]
        if (_o2(p, axis, a, b, c) * _o2(p, axis, a, b, d) < 0
                and _o2(p, axis, c, d, a) * _o2(p, axis, c, d, b) < 0):
            if found == 3:
                return 4
            e1, e2 = _edge_key(canon, n_vertices, a, b), _edge_key(canon, n_vertices, c, d)
            keys[found, 0], keys[found, 1], keys[found, 2] = EDGE_EDGE, min(e1, e2), max(e1, e2)
            locs[found, 0], locs[found, 1] = _EDGE + k, _EDGE + j
            found += 1
    return found


@njit(cache=True, nogil=True)
def _chords_range(p, faces, canon, pairs, keys, locs, used, status, start, stop):
    for i in range(start, stop):
        tf, tg = faces[pairs[i, 0]], faces[pairs[i, 1]]
        axis = _drop_axis(p, tf)
        orient_f = _o2(p, axis, tf[0], tf[1], tf[2])
        orient_g = _o2(p, axis, tg[0], tg[1], tg[2])
        ends = np.zeros((3, 3), np.int64)
        where = np.zeros((3, 2), np.int64)
        for side in range(2):
            own, other, orientation = (tf, tg, orient_g) if side == 0 else (tg, tf, orient_f)
            for k in range(3):
                found = _chord(p, canon, own, other, axis, orientation, k, ends, where)
                if found > 2:
                    status[i] = -1
                if found != 2:
                    continue
                slot = 3 * side + k
                used[i, slot] = True
                for e in range(2):
                    for c in range(3):
                        keys[i, slot, e, c] = ends[e, c]
                    locs[i, slot, e, side] = where[e, 0]  # on the face whose edge it is
                    locs[i, slot, e, 1 - side] = where[e, 1]


def _coplanar_chords(p, faces, canon, pairs) -> tuple:
    """The cuts of overlapping coplanar pairs (K, 2): for every pair, the parts of each face's edges inside the
    other face, as segments with keys (K, 6, 2, 3) and locations (K, 6, 2, 2) like those of crossing pairs,
    and how many of the 6 slots (3 edges of f, then 3 of g) hold one (K, 6) bool; -1 in the first slot's flag
    count (returned per pair, (K,)) when a part was inconsistent."""
    n = pairs.shape[0]
    keys = np.zeros((n, 6, 2, 3), np.int64)
    locs = np.zeros((n, 6, 2, 2), np.int64)
    used = np.zeros((n, 6), np.bool_)
    status = np.zeros(n, np.int64)
    for_ranges(_chords_range, n, p, faces, canon, pairs, keys, locs, used, status, min_items=HEAVY_ITEMS_PER_RANGE)
    return keys, locs, used, status


def coplanar_segments(pts: np.ndarray, fcs: np.ndarray, canon: np.ndarray, coplanar: np.ndarray):
    """Segments that cut overlapping coplanar faces into pieces wholly inside or outside each other.

    For every pair of ``coplanar`` (K, 2) whose faces overlap with their
    interiors, the part of each edge of either face that lies inside the
    other (closed) face, found exactly in the projection along the axis of
    the first face's largest normal component. Its ends are vertices of
    either face or the crossings of an edge of each (:data:`EDGE_EDGE`), keyed
    like the ends of crossing pairs' segments.

    Returns
    -------
    pairs : numpy.ndarray, shape (S, 2)
    keys : numpy.ndarray, shape (S, 2, 3)
    locations : numpy.ndarray, shape (S, 2, 2)
    """
    pts = np.ascontiguousarray(pts, dtype=np.float64)
    fcs = np.ascontiguousarray(fcs, dtype=np.int64)
    if len(coplanar):
        coplanar = coplanar[_coplanar_overlaps(pts, fcs, coplanar)]
    if len(coplanar) == 0:
        return np.zeros((0, 2), np.int64), np.zeros((0, 2, 3), np.int64), np.zeros((0, 2, 2), np.int64)
    keys, locs, used, status = _coplanar_chords(pts, fcs, canon, coplanar)
    if np.any(status < 0):
        raise RuntimeError("inconsistent overlap of a coplanar face pair (the exact predicates should prevent this)")
    pair, slot = np.nonzero(used)
    return coplanar[pair], keys[pair, slot], locs[pair, slot]


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


def _coordinates(p: np.ndarray, faces: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """Coordinates (P, 3) of the points with the given keys, computed from the keys alone (so alike for every
    pair that produces a point)."""
    out = np.empty((keys.shape[0], 3))
    for_ranges(_coordinate_range, keys.shape[0], p, faces, keys, out)
    for i in np.flatnonzero(keys[:, 0] == FACE_FACE_FACE):  # rare: points where three faces meet
        out[i] = _three_planes(p, faces, keys[i, 1], keys[i, 2] // faces.shape[0], keys[i, 2] % faces.shape[0])
    return out


@njit(cache=True, nogil=True)
def _coordinate_range(p, faces, keys, out, start, stop):
    n_vertices = p.shape[0]
    for i in range(start, stop):
        kind = keys[i, 0]
        if kind == VERTEX:
            v = keys[i, 1]
            out[i, 0], out[i, 1], out[i, 2] = p[v, 0], p[v, 1], p[v, 2]
        elif kind == EDGE_FACE:
            a, b = keys[i, 1] // n_vertices, keys[i, 1] % n_vertices
            f = keys[i, 2]
            x, y, z = _edge_face_point(p, a, b, faces[f, 0], faces[f, 1], faces[f, 2])
            out[i, 0], out[i, 1], out[i, 2] = x, y, z
        elif kind == EDGE_EDGE:
            a, b = keys[i, 1] // n_vertices, keys[i, 1] % n_vertices
            c, d = keys[i, 2] // n_vertices, keys[i, 2] % n_vertices
            x, y, z = _edge_edge_point(p, a, b, c, d)
            out[i, 0], out[i, 1], out[i, 2] = x, y, z
        # FACE_FACE_FACE: _coordinates solves those


def _three_planes(p: np.ndarray, faces: np.ndarray, f: int, g: int, h: int) -> np.ndarray:
    """The point where the planes of faces f, g and h meet, (3,) (LAPACK's ``dgesv``, in floating point).

    Solved outside numba: its ``np.linalg.solve`` would take seconds to
    compile for a case that few runs meet. ``dgesv`` is the routine numba
    calls, from the same library, so the result is the same.

    Raises
    ------
    numpy.linalg.LinAlgError
        If the planes do not meet in one point (or the points are not finite).
    """
    from scipy.linalg import lapack

    rows = np.empty((3, 3))
    rhs = np.empty(3)
    for r, t in enumerate((f, g, h)):
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        ux, uy, uz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
        vx, vy, vz = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1], p[c, 2] - p[a, 2]
        rows[r, 0], rows[r, 1], rows[r, 2] = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        rhs[r] = rows[r, 0] * p[a, 0] + rows[r, 1] * p[a, 1] + rows[r, 2] * p[a, 2]
    if not (np.all(np.isfinite(rows)) and np.all(np.isfinite(rhs))):
        raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
    _, _, x, info = lapack.dgesv(np.asfortranarray(rows), rhs)
    if info > 0:
        raise np.linalg.LinAlgError("Matrix is singular to machine precision.")
    return x


# --- where three surfaces meet -----------------------------------------------------------------------------


@njit(cache=True)
def _crossings_on_faces(p, faces, coords, segments, listed_face, listed_partner, listed_segment, start):
    """Segments of different partner faces that cross inside a face: rows (face, segment 1, segment 2).

    The listing holds every (face, partner, segment) sorted by face, the
    faces' runs starting at ``start``; two segments cross when their 2-D
    projections along the face's normal cross strictly (exact orient2d on
    the computed points).
    """
    found = []
    for i in range(start.shape[0] - 1):
        lo, hi = start[i], start[i + 1]
        if hi - lo < 2:
            continue
        f = listed_face[lo]
        axis = _drop_axis(p, faces[f])
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for m in range(lo, hi):
            s1 = listed_segment[m]
            a, b = segments[s1, 0], segments[s1, 1]
            for n in range(m + 1, hi):
                s2 = listed_segment[n]
                if listed_partner[m] == listed_partner[n]:
                    continue
                c, d = segments[s2, 0], segments[s2, 1]
                if a == c or a == d or b == c or b == d:
                    continue
                o1 = sign_orient2d(coords[a, u], coords[a, v], coords[b, u], coords[b, v], coords[c, u], coords[c, v])
                o2 = sign_orient2d(coords[a, u], coords[a, v], coords[b, u], coords[b, v], coords[d, u], coords[d, v])
                o3 = sign_orient2d(coords[c, u], coords[c, v], coords[d, u], coords[d, v], coords[a, u], coords[a, v])
                o4 = sign_orient2d(coords[c, u], coords[c, v], coords[d, u], coords[d, v], coords[b, u], coords[b, v])
                if o1 * o2 < 0 and o3 * o4 < 0:
                    found.append((f, s1, s2))
    out = np.empty((len(found), 3), np.int64)
    for k in range(len(found)):
        out[k, 0], out[k, 1], out[k, 2] = found[k]
    return out


@njit(cache=True)
def _junctions_on_faces(p, faces, coords, segments, listed_face, listed_segment, start):
    """Ends of segments lying strictly inside another segment of the same face: rows (face, segment, point).

    Where a vertex of a third surface lies on the curve of two others (a
    T-junction), the segment through it is cut there. Found, like
    :func:`_crossings_on_faces`, in the projection along the face's normal
    (exact orient2d on the computed points).
    """
    found = []
    for i in range(start.shape[0] - 1):
        lo, hi = start[i], start[i + 1]
        if hi - lo < 2:
            continue
        f = listed_face[lo]
        axis = _drop_axis(p, faces[f])
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for m in range(lo, hi):
            s1 = listed_segment[m]
            a, b = segments[s1, 0], segments[s1, 1]
            for n in range(lo, hi):
                s2 = listed_segment[n]
                for c in (segments[s2, 0], segments[s2, 1]):
                    if c == a or c == b:
                        continue
                    if sign_orient2d(coords[a, u], coords[a, v], coords[b, u], coords[b, v],
                                     coords[c, u], coords[c, v]) != 0:
                        continue
                    along = ((coords[c, u] - coords[a, u]) * (coords[b, u] - coords[a, u])
                             + (coords[c, v] - coords[a, v]) * (coords[b, v] - coords[a, v]))
                    length = ((coords[b, u] - coords[a, u]) ** 2 + (coords[b, v] - coords[a, v]) ** 2)
                    if 0.0 < along < length:
                        found.append((f, s1, c))
    out = np.empty((len(found), 3), np.int64)
    for k in range(len(found)):
        out[k, 0], out[k, 1], out[k, 2] = found[k]
    return out


_EDGE_BITS = np.array([0b101, 0b011, 0b110, 0b001, 0b010, 0b100, 0b000])
"""The edges of a face (bit k: edge k) that a location 0..6 lies on: a vertex on its two edges."""


def _edge_along(loc0: np.ndarray, loc1: np.ndarray) -> np.ndarray:
    """The edge (0..2) of a face that segments with their ends at locations ``loc0`` and ``loc1`` on it lie along,
    -1 for segments that do not lie along an edge."""
    common = _EDGE_BITS[loc0] & _EDGE_BITS[loc1]
    return np.where(common == 0, -1, np.where(common & 1, 0, np.where(common & 2, 1, 2)))


def _split_at_triple_points(pts, fcs, canon, plane, keys, coords, segments, pairs, locations):
    """Split the segments where the curves of three surfaces cross inside a face.

    The point where the segments of two partner faces g and h cross inside
    face f is named by what produces it: where an edge of g crosses h when
    the segment of g lies along that edge (a coplanar cut, or g's edge in f's
    plane), where an edge of g crosses an edge of h when both do, and where
    the three planes meet otherwise; in that last case the segment of g and
    h, where there is one, passes through it and is cut there too.

    Returns the keys, coordinates, segments, pairs and locations with the
    crossing points added and every crossed segment cut there.
    """
    n_seg = len(segments)
    if n_seg < 2:
        return keys, coords, segments, pairs, locations
    face = np.concatenate([pairs[:, 0], pairs[:, 1]])
    other = np.concatenate([pairs[:, 1], pairs[:, 0]])
    seg = np.concatenate([np.arange(n_seg), np.arange(n_seg)])
    order = np.argsort(face, kind="stable")
    face, other, seg = face[order], other[order], seg[order]
    start = np.flatnonzero(np.r_[True, face[1:] != face[:-1], True])
    crossings = _crossings_on_faces(pts, fcs, coords, segments, face, other, seg, start)
    if len(crossings):
        # a segment along an edge of f itself cannot cross another inside f: such a crossing is the rounding of the
        # computed points (where a segment ends on that edge)
        f, s1, s2 = crossings.T
        own1, own2 = (pairs[s1, 0] != f).astype(np.int64), (pairs[s2, 0] != f).astype(np.int64)
        on_rim = ((_edge_along(locations[s1, 0, own1], locations[s1, 1, own1]) >= 0)
                  | (_edge_along(locations[s2, 0, own2], locations[s2, 1, own2]) >= 0))
        crossings = crossings[~on_rim]
    junctions = _junctions_on_faces(pts, fcs, coords, segments, face, seg, start)
    if len(crossings) == 0 and len(junctions) == 0:
        return keys, coords, segments, pairs, locations
    n_faces, n_vertices = len(fcs), len(pts)
    f, s1, s2 = crossings.T
    # the partner of f in each segment's pair, its side there, and the partner's edge the segment lies along
    side1, side2 = (pairs[s1, 0] == f).astype(np.int64), (pairs[s2, 0] == f).astype(np.int64)
    g, h = pairs[s1, side1], pairs[s2, side2]
    j1 = _edge_along(locations[s1, 0, side1], locations[s1, 1, side1])
    j2 = _edge_along(locations[s2, 0, side2], locations[s2, 1, side2])

    def edge_key(face_ids, j):
        a, b = canon[fcs[face_ids, np.maximum(j, 0)]], canon[fcs[face_ids, (np.maximum(j, 0) + 1) % 3]]
        return np.minimum(a, b) * n_vertices + np.maximum(a, b)

    e1, e2 = edge_key(g, j1), edge_key(h, j2)
    tri = np.sort(np.stack([f, g, h], axis=1), axis=1)
    new_keys = np.stack([np.full(len(f), FACE_FACE_FACE), tri[:, 0], tri[:, 1] * n_faces + tri[:, 2]], axis=1)
    along1, along2 = j1 >= 0, j2 >= 0
    both = along1 & along2
    new_keys[both] = np.stack([np.full(both.sum(), EDGE_EDGE), np.minimum(e1, e2)[both], np.maximum(e1, e2)[both]],
                              axis=1)
    one = along1 & ~along2
    new_keys[one] = np.stack([np.full(one.sum(), EDGE_FACE), e1[one], h[one]], axis=1)
    one = along2 & ~along1
    new_keys[one] = np.stack([np.full(one.sum(), EDGE_FACE), e2[one], g[one]], axis=1)
    # locations of the new point on the two faces of each crossed segment: inside f, on the partner's edge or inside
    loc1 = np.full((len(f), 2), _INSIDE, np.int64)
    loc1[np.arange(len(f)), side1] = np.where(along1, _EDGE + j1, _INSIDE)
    loc2 = np.full((len(f), 2), _INSIDE, np.int64)
    loc2[np.arange(len(f)), side2] = np.where(along2, _EDGE + j2, _INSIDE)
    # the segment of the third pair (g, h), where there is one, passes through a point of three planes
    pair_key = np.minimum(pairs[:, 0], pairs[:, 1]) * n_faces + np.maximum(pairs[:, 0], pairs[:, 1])
    by_key = np.argsort(pair_key)
    wanted = np.minimum(g, h) * n_faces + np.maximum(g, h)
    at = np.minimum(np.searchsorted(pair_key[by_key], wanted), len(by_key) - 1)
    third = np.where((pair_key[by_key[at]] == wanted) & ~along1 & ~along2, by_key[at], -1)
    junction_seg, junction_loc = _junction_splits(pairs, locations, junctions)
    split_seg = np.concatenate([s1, s2, third, junction_seg])
    split_key = np.concatenate([new_keys, new_keys, new_keys, keys[junctions[:, 2]]])
    split_loc = np.concatenate([loc1, loc2, np.full((len(f), 2), _INSIDE, np.int64), junction_loc])
    valid = split_seg >= 0
    split_key, split_seg, split_loc = _by_plane(split_key[valid], plane), split_seg[valid], split_loc[valid]
    all_keys, inverse = unique_rows(np.concatenate([keys, split_key]))
    old = inverse[:len(keys)]
    all_coords = np.empty((len(all_keys), 3))
    added = np.ones(len(all_keys), bool)
    added[old] = False
    all_coords[old] = coords
    all_coords[added] = _coordinates(pts, fcs, all_keys[added])
    segments = old[segments]
    split_point = inverse[len(keys):]
    split = np.zeros(n_seg, bool)
    split[split_seg] = True
    # every split segment becomes the chain of its crossing points, in order along it
    rows, first_row = np.unique(split_seg * len(all_keys) + split_point, return_index=True)
    s_idx, p_idx, p_loc = split_seg[first_row], split_point[first_row], split_loc[first_row]
    seg_a, seg_b = segments[s_idx, 0], segments[s_idx, 1]
    along = np.einsum("ij,ij->i", all_coords[p_idx] - all_coords[seg_a], all_coords[seg_b] - all_coords[seg_a])
    order = np.lexsort((along, s_idx))
    s_idx, p_idx, p_loc = s_idx[order], p_idx[order], p_loc[order]
    first = np.r_[True, s_idx[1:] != s_idx[:-1]]
    last = np.r_[s_idx[1:] != s_idx[:-1], True]
    piece_start = np.where(first, segments[s_idx, 0], np.r_[-1, p_idx[:-1]])
    pieces = np.concatenate([np.stack([piece_start, p_idx], axis=1),
                             np.stack([p_idx[last], segments[s_idx[last], 1]], axis=1)])
    owner = np.concatenate([s_idx, s_idx[last]])
    start_loc = np.where(first[:, None], locations[s_idx, 0], np.r_[np.zeros((1, 2), np.int64), p_loc[:-1]])
    piece_loc = np.concatenate([np.stack([start_loc, p_loc], axis=1),
                                np.stack([p_loc[last], locations[s_idx[last], 1]], axis=1)])
    out_seg = [segments[~split], pieces]
    out_pairs = [pairs[~split], pairs[owner]]
    out_loc = [locations[~split], piece_loc]
    return all_keys, all_coords, np.concatenate(out_seg), np.concatenate(out_pairs), np.concatenate(out_loc)


def _junction_splits(pairs, locations, junctions):
    """The segments (J,) cut at the points of ``junctions`` (J, 3) rows (face, segment, point) and the points'
    locations on the segments' two faces (J, 2): on the edge the segment lies along, or inside the face."""
    seg = junctions[:, 1]
    loc = np.full((len(seg), 2), _INSIDE, np.int64)
    for side in range(2):
        j = _edge_along(locations[seg, 0, side], locations[seg, 1, side])
        loc[:, side] = np.where(j >= 0, _EDGE + j, _INSIDE)
    return seg, loc


# --- the whole boundary --------------------------------------------------------------------------------------


def _plane_representatives(n_faces: int, coplanar: np.ndarray) -> np.ndarray:
    """The lowest face of every face's group of faces in one plane (F,), the groups linked by ``coplanar`` (K, 2)
    pairs of faces in one plane (exact coplanarity is transitive)."""
    plane = np.arange(n_faces)
    if len(coplanar) == 0:
        return plane
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    links = coo_matrix((np.ones(len(coplanar)), (coplanar[:, 0], coplanar[:, 1])), shape=(n_faces, n_faces))
    _, label = connected_components(links, directed=False)
    lowest = np.full(label.max() + 1, n_faces)
    np.minimum.at(lowest, label, plane)
    return lowest[label]


def _by_plane(keys: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """Keys (N, 3) with the face of every :data:`EDGE_FACE` point replaced by its plane's lowest face: where an edge
    crosses faces in one plane, it crosses that plane at one point."""
    keys = keys.copy()
    edge_face = keys[:, 0] == EDGE_FACE
    keys[edge_face, 2] = plane[keys[edge_face, 2]]
    return keys


def _one_name_per_point(pts, fcs, canon, plane, keys, pairs, locs):
    """Unique point keys (P, 3) and the segments (S, 2) of segment end keys ``keys`` (2 S, 3), every point named
    once.

    An edge crossing faces in one plane crosses the plane at one point
    (:func:`_by_plane`); where an edge of face f crosses an edge of face g
    (not in one plane) at a point, that point is also where the edge of f
    crosses the plane of g and where the edge of g crosses the plane of f,
    as a third face in either plane names it: these names are linked and
    the point keeps the name of the two edges.
    """
    keys = _by_plane(keys, plane)
    end_locs = locs.reshape(-1, 2)  # (2 S, 2): the end's location on f and on g
    end_faces = np.repeat(pairs, 2, axis=0)
    transversal = ((keys[:, 0] == EDGE_EDGE) & (end_locs[:, 0] >= _EDGE) & (end_locs[:, 1] >= _EDGE)
                   & (end_locs[:, 0] < _INSIDE) & (end_locs[:, 1] < _INSIDE)
                   & ~_in_one_plane(plane, end_faces))
    rows = np.flatnonzero(transversal)
    if len(rows) == 0:  # no edge crosses another edge: every point has one name
        unique, inverse = unique_rows(keys)
        return unique, inverse.reshape(-1, 2)
    n_vertices = len(pts)
    named, aliases = [], []
    for side in range(2):  # the edge of face ``side`` crossing the plane of the other face (not lying in it)
        face, other = end_faces[rows, side], end_faces[rows, 1 - side]
        k = end_locs[rows, side] - _EDGE
        a, b = canon[fcs[face, k]], canon[fcs[face, (k + 1) % 3]]
        crossing = _crosses_plane(pts, fcs, a, b, other) if len(rows) else np.zeros(0, np.bool_)  # compiled if used
        named.append(rows[crossing])
        aliases.append(np.stack([np.full(crossing.sum(), EDGE_FACE),
                                 (np.minimum(a, b) * n_vertices + np.maximum(a, b))[crossing], plane[other[crossing]]],
                                axis=1))
    named = np.concatenate(named)
    unique, inverse = unique_rows(np.concatenate([keys, *aliases]))
    if len(named) == 0:
        return unique, inverse.reshape(-1, 2)
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    links = coo_matrix((np.ones(len(named)), (inverse[named], inverse[len(keys):])),
                       shape=(len(unique), len(unique)))
    _, label = connected_components(links, directed=False)
    index = np.arange(len(unique))
    rank = np.where(unique[:, 0] == EDGE_EDGE, index, index + len(unique))  # an edge-edge name first
    first = np.full(label.max() + 1, 2 * len(unique))
    np.minimum.at(first, label, rank)
    used, point = np.unique(first[label[inverse[:len(keys)]]] % len(unique), return_inverse=True)
    return unique[used], point.reshape(-1, 2)


@njit(cache=True)
def _crosses_plane(p, faces, a, b, f):
    """Whether each segment (a[i], b[i]) has its ends strictly on both sides of the plane of face f[i] (N,) bool,
    exactly."""
    out = np.empty(a.shape[0], np.bool_)
    for i in range(a.shape[0]):
        t = faces[f[i]]
        out[i] = _o3(p, t[0], t[1], t[2], a[i]) * _o3(p, t[0], t[1], t[2], b[i]) < 0
    return out


def _merge_coincident(keys, coords, segments, pairs, locations):
    """Points of different names at the same computed position as one, named by the first key (a vertex before a
    crossing): a vertex of a third surface exactly where two edges cross, say. Segments left with one point are
    dropped. Returns the keys, coordinates, segments, pairs and locations."""
    if len(coords) < 2:
        return keys, coords, segments, pairs, locations
    lowest = canonical_vertices(coords)
    if np.all(lowest == np.arange(len(coords))):
        return keys, coords, segments, pairs, locations
    used, point = np.unique(lowest, return_inverse=True)
    segments = point[segments]
    kept = segments[:, 0] != segments[:, 1]
    return keys[used], coords[used], segments[kept], pairs[kept], locations[kept]


def _in_one_plane(plane: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Whether the two faces of each pair (N, 2) are known to lie in one plane (N,) bool."""
    return plane[pairs[:, 0]] == plane[pairs[:, 1]]


def intersection_curves(points, faces, *, group=None) -> IntersectionCurves:
    """Exact intersection segments between the faces of a mesh, or between meshes put together.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        Faces that share an edge (two vertex indices) are neighbours and not
        tested; faces that share one vertex are, as they may meet beyond it
        (a fold), and touch there otherwise.
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
    return curves_of(pts, fcs, group, canonical_vertices(pts))


def curves_of(pts: np.ndarray, fcs: np.ndarray, group, canon: np.ndarray, query=None, *,
              coplanar_cuts: bool = False) -> IntersectionCurves:
    """:func:`intersection_curves` of a validated mesh whose :func:`canonical_vertices` are ``canon`` (only of
    the pairs with a face of ``query`` (F,) bool, when given). With ``coplanar_cuts``, the pairs of faces that
    overlap in a common plane get segments too: the parts of each face's edges inside the other (see
    :func:`coplanar_segments`), so that cutting along all segments leaves every piece of such a face wholly inside or
    outside the other."""
    pairs = candidate_pairs(pts, fcs, group=group, query=query)
    status, keys, locs, cases = _classify_pairs(pts, fcs, canon, pairs)
    if np.any(status < 0):
        raise RuntimeError("inconsistent intersection of a face pair (the exact predicates should prevent this)")
    crossing = status == _CROSS
    case_counts = np.bincount(cases[status != _APART].ravel(), minlength=len(CASES)).astype(np.int64)
    seg_pairs, seg_locs = pairs[crossing], locs[crossing]
    seg_keys = keys[crossing].reshape(-1, 3)
    if coplanar_cuts:
        chord_pairs, chord_keys, chord_locs = coplanar_segments(pts, fcs, canon, pairs[status == _COPLANAR])
        seg_pairs = np.concatenate([seg_pairs, chord_pairs])
        seg_locs = np.concatenate([seg_locs, chord_locs])
        seg_keys = np.concatenate([seg_keys, chord_keys.reshape(-1, 3)])
    plane = _plane_representatives(len(fcs), pairs[status == _COPLANAR])
    if len(seg_keys):
        unique, segments = _one_name_per_point(pts, fcs, canon, plane, seg_keys, seg_pairs, seg_locs)
    else:
        unique, segments = np.zeros((0, 3), np.int64), np.zeros((0, 2), np.int64)
    unique, coords, segments, seg_pairs, seg_locs = _merge_coincident(
        unique, _coordinates(pts, fcs, unique), segments, seg_pairs, seg_locs)
    unique, coords, segments, seg_pairs, seg_locs = _merge_coincident(*_split_at_triple_points(
        pts, fcs, canon, plane, unique, coords, segments, seg_pairs, seg_locs))
    return IntersectionCurves(
        points=coords,
        point_keys=unique,
        segments=segments,
        pairs=seg_pairs,
        locations=seg_locs,
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
    segs = unique_rows(np.sort(curves.segments, axis=1))[0]
    if len(segs) == 0:
        return []
    path, bounds = _walk_polylines(segs, len(curves.points))
    return np.split(path, bounds[1:-1])


@njit(cache=True)
def _walk(point, segs, start, order, degree, used, path, n):
    """Follow unused segments from ``point`` through points of degree 2; append to ``path`` from ``n`` on."""
    first = point
    path[n] = point
    n += 1
    steps = np.int64(0)
    while True:
        nxt = -1
        if degree[point] == 2 or steps == 0:
            for j in range(start[point], start[point + 1]):
                s = order[j] % segs.shape[0]
                if not used[s]:
                    used[s] = True
                    nxt = segs[s, 1] if segs[s, 0] == point else segs[s, 0]
                    break
        if nxt < 0:
            return n
        path[n] = nxt
        n += 1
        steps += 1
        point = nxt
        if point == first:
            return n


@njit(cache=True)
def _walk_polylines(segs, n_points):
    """Polylines through the segments (S, 2): the points of all in order (flat) and the offsets of each."""
    n_seg = segs.shape[0]
    ends = np.concatenate((segs[:, 0], segs[:, 1]))
    start = np.zeros(n_points + 1, np.int64)
    for j in range(2 * n_seg):
        start[ends[j] + 1] += 1
    degree = start[1:].copy()
    for v in range(n_points):
        start[v + 1] += start[v]
    order = np.empty(2 * n_seg, np.int64)  # entry j is segment j % S; stable counting sort by end point
    fill = start[:n_points].copy()
    for j in range(2 * n_seg):
        order[fill[ends[j]]] = j
        fill[ends[j]] += 1
    used = np.zeros(n_seg, np.bool_)
    path = np.empty(2 * n_seg + n_seg, np.int64)
    bounds = [0]
    n = np.int64(0)  # not the literal 0: _walk would be compiled for it as well as for int64
    for v in range(n_points):  # open polylines start where they end
        if degree[v] == 2 or degree[v] == 0:
            continue
        while True:
            free = np.bool_(False)
            for j in range(start[v], start[v + 1]):
                if not used[order[j] % n_seg]:
                    free = True
            if not free:
                break
            n = _walk(v, segs, start, order, degree, used, path, n)
            bounds.append(n)
    for s in range(n_seg):  # closed loops
        if not used[s]:
            n = _walk(segs[s, 0], segs, start, order, degree, used, path, n)
            bounds.append(n)
    return path[:n].copy(), np.array(bounds, np.int64)
