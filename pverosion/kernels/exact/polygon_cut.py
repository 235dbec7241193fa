"""Cutting a triangle along constraint segments and triangulating the pieces.

This is the per-triangle step of mesh intersection repair (Skorkovská, ch.
10.2): once the intersection curves between two meshes are known, every
triangle they cross is cut along the intersection segments lying on it, the
resulting polygons are rebuilt, and every polygon is triangulated by ear
clipping (Meisters 1975). Everything works on 2-D coordinates (the caller
projects the triangle and its points to a plane beforehand) and every
orientation decision is taken with the exact predicate
:func:`~pverosion.kernels.exact.predicates.orient2d`.

Input conventions
-----------------
The points of one triangle are rows of an (n, 2) array; rows 0, 1, 2 are the
corners in counter-clockwise order. ``location[i]`` tells where point ``i``
lies, exactly (it comes from exact predicates upstream and is never re-derived
from the coordinates here):

- ``0``, ``1``, ``2``: the point is corner ``k`` (rows 0..2 only);
- ``3 + k`` (:data:`LOCATION_EDGE` ``+ k``): the point lies in the interior of
  edge ``k``, which runs from corner ``k`` to corner ``(k + 1) % 3``;
  ``edge_param[i]`` in (0, 1) orders the points along that edge;
- ``6`` (:data:`LOCATION_INTERIOR`): the point lies inside the triangle.

Constraint segments are pairs of point indices. Segments with both ends on a
common edge of the triangle (two points on one edge, a corner and a point on
an adjacent edge, or two corners) lie along the boundary, which is split at
every edge point anyway; they are satisfied automatically (as the chain of
boundary pieces between their ends). All other segments are chords or
interior segments. Duplicates and zero-length segments (both ends the same
index) are dropped.

Method
------
1. **Planar graph.** The boundary cycle is corner 0, the points of edge 0 in
   ``edge_param`` order, corner 1, the points of edge 1, corner 2, the points
   of edge 2. Its pieces and the deduplicated interior segments form a planar
   straight-line graph, stored as half-edges. The half-edges leaving each
   vertex are sorted counter-clockwise by direction, comparing two directions
   by the half-plane they point into (upper: ``dy > 0`` or ``dy == 0, dx > 0``)
   and, within a half-plane, by the exact sign of ``orient2d`` (no angles are
   computed). Two edges leaving a vertex in the same direction mean
   overlapping segments: the input is rejected.
2. **Faces.** The successor of half-edge ``u -> v`` is the half-edge that
   follows ``v -> u`` clockwise around ``v``; its orbits are the face
   boundaries, each with its face on the left (bounded faces counter-clockwise).
   Dangling segments are walked on both sides. This is the boundary tracing of
   the thesis (corners in order, polyline ends inserted along the edges,
   pointers followed around each polygon) in half-edge form, which also
   covers interior loops, dangling chains and several chains per edge.
3. **Outer faces and holes.** The graph's connected components are found; in
   each, the lexicographically smallest vertex (x, then y) sees the
   component's outer face on its left side, so the outer face is the one to the
   left of the most counter-clockwise edge there. The outer face of the
   component containing the triangle boundary is discarded. Every other
   component (a closed loop, nested loops, a floating open polyline, ...) is a
   hole: its enclosing face is the innermost bounded face of another
   component that contains its lexicographically smallest vertex (winding
   numbers with exact ``orient2d``). The remaining faces are the regions of
   the result, numbered in face order.
4. **Bridges.** The holes of a face are merged into its boundary in
   increasing order of their smallest vertex: the hole's smallest vertex ``v``
   is joined to a vertex ``p`` of the boundary built so far (candidates are
   tried by increasing distance) by two coincident, opposite edges. The bridge
   must leave ``p`` and ``v`` into the face (exact wedge tests at the exact
   occurrence of ``p`` in the boundary, which matters for vertices already
   visited several times), must not pass through any vertex and must not cross
   any edge of the face, of its merged holes and bridges, or of its holes not
   merged yet. Because holes are merged from left to right, the nearest edge
   to the left of ``v`` belongs to the boundary built so far, so a visible
   vertex always exists.
5. **Ear clipping.** Each face is now one closed, weakly simple polygon
   (vertices may repeat at bridges and dangling segments) stored as a doubly
   linked list of vertex occurrences. A corner ``(a, b, c)`` is an ear when it
   turns strictly left and no polygon vertex other than ``a``, ``b``, ``c``
   (occurrences of those same points are skipped) lies inside the triangle or
   on its boundary; ears are clipped until three vertices remain. Every
   triangle therefore has a strictly positive exact orientation.
6. **Isolated interior points** (``location == 6`` and on no segment) are
   inserted afterwards: the triangle of the result containing the point is
   split in three, or the two triangles sharing the edge it lies on are split
   in two each. An isolated point that coincides with an existing vertex (or
   lies outside every output triangle, which requires coordinates that
   contradict its location) is ignored.

Assumptions and failure
-----------------------
The combinatorial input is trusted: locations are exact, distinct points
have distinct coordinates, segments do not cross or overlap each other and do
not pass through points that are ends of other segments, and the coordinates
realise this (points on an edge may deviate from the exact line by rounding,
as long as no segment is crossed). An isolated point lying exactly on a
segment is fine: it is inserted there and splits the segment. The kernel
never raises on such input. Inconsistencies that it detects (a location code
out of range or wrong for rows 0..2, a segment index out of range, a
clockwise or degenerate corner triangle, two graph edges overlapping, a hole
without an enclosing face, a hole that cannot be bridged, a polygon without an
ear) make it return an empty triangle array, which the caller must check;
undetected contradictions (e.g. segments that cross) yield an invalid tiling.

Cost is dominated by the bridges and the ear tests, both quadratic in the
number of vertices of a face in the worst case (about 2.5 us per triangle
with a 5-point chord, 13 ms for 2000 points on one triangle).
:func:`cut_triangles` runs the triangles serially.
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels._search import lower_bound
from pverosion.kernels._threads import HEAVY_ITEMS_PER_RANGE, for_ranges
from pverosion.kernels.exact.predicates import orient2d

__all__ = ["LOCATION_EDGE", "LOCATION_INTERIOR", "cut_triangle", "cut_triangles"]

LOCATION_EDGE = 3
"""``location`` of a point in the interior of edge ``k`` is ``LOCATION_EDGE + k``."""

LOCATION_INTERIOR = 6
"""``location`` of a point strictly inside the triangle."""


# ---------------------------------------------------------------------------
# Small exact geometric helpers
# ---------------------------------------------------------------------------


@njit(cache=True)
def _orient(xy: np.ndarray, a: int, b: int, c: int) -> float:
    """:func:`orient2d` of the points ``a, b, c`` (rows of ``xy``): exact sign, > 0 for a left turn."""
    return orient2d(xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], xy[c, 0], xy[c, 1])


@njit(cache=True)
def _edge_mask(loc: int) -> int:
    """Bit set of the triangle edges a point with location code ``loc`` lies on (corner k: edges k and k - 1)."""
    if loc < 3:
        return (1 << loc) | (1 << ((loc + 2) % 3))
    if loc < LOCATION_INTERIOR:
        return 1 << (loc - LOCATION_EDGE)
    return 0


@njit(cache=True)
def _angle_before(xy: np.ndarray, o: int, a: int, b: int) -> bool:
    """Whether direction ``o -> a`` comes strictly before ``o -> b`` counter-clockwise from angle 0.

    Directions are first split by half-plane, [0, pi) (``dy > 0``, or
    ``dy == 0`` and ``dx > 0``) before [pi, 2 pi), which only needs the exact
    signs of the coordinate differences; within a half-plane ``orient2d``
    decides. Neither comes before the other iff both point the same way.
    """
    ax = xy[a, 0] - xy[o, 0]
    ay = xy[a, 1] - xy[o, 1]
    bx = xy[b, 0] - xy[o, 0]
    by = xy[b, 1] - xy[o, 1]
    upper_a = ay > 0.0 or (ay == 0.0 and ax > 0.0)
    upper_b = by > 0.0 or (by == 0.0 and bx > 0.0)
    if upper_a != upper_b:
        return upper_a
    return _orient(xy, o, a, b) > 0.0


@njit(cache=True)
def _sign(x: float) -> int:
    """-1, 0 or 1: the sign of ``x``."""
    return (x > 0.0) - (x < 0.0)


@njit(cache=True)
def _in_wedge(xy: np.ndarray, prev: int, cur: int, nxt: int, q: int) -> bool:
    """Whether direction ``cur -> q`` lies strictly inside the polygon's angle at ``cur``.

    The polygon runs ``prev -> cur -> nxt`` with its interior on the left, so
    the interior angle sweeps counter-clockwise from ``cur -> nxt`` to
    ``cur -> prev``. A zero angle (``prev`` and ``nxt`` in the same direction,
    the tip of a dangling edge) is taken as a full turn minus that direction.
    """
    turn = _orient(xy, cur, nxt, prev)
    s_n = _orient(xy, cur, nxt, q)
    s_p = _orient(xy, cur, prev, q)
    if turn > 0.0:
        return s_n > 0.0 and s_p < 0.0
    if turn < 0.0:
        return s_n > 0.0 or s_p < 0.0
    # prev, cur, nxt collinear: compare the directions by the signs of their components
    sx = _sign(xy[nxt, 0] - xy[cur, 0])
    sy = _sign(xy[nxt, 1] - xy[cur, 1])
    if _sign(xy[prev, 0] - xy[cur, 0]) == sx and _sign(xy[prev, 1] - xy[cur, 1]) == sy:
        along = _sign(xy[q, 0] - xy[cur, 0]) == sx and _sign(xy[q, 1] - xy[cur, 1]) == sy
        return not (s_n == 0.0 and along)
    return s_n > 0.0


@njit(cache=True)
def _obstructs(xy: np.ndarray, a: int, b: int, p: int, v: int) -> bool:
    """Whether the polygon edge ``a -> b`` or its origin ``a`` blocks the bridge ``p - v``.

    Blocked when ``a`` (not ``p`` or ``v``) lies on the closed segment
    ``p - v``, or when the edge, not incident to ``p`` or ``v``, crosses it
    properly. Each vertex is the origin of some edge of the cycles tested, so
    all vertices are checked.
    """
    if a == p or a == v:
        return False
    s_a = _sign(_orient(xy, p, v, a))
    if s_a == 0:
        in_x = min(xy[p, 0], xy[v, 0]) <= xy[a, 0] <= max(xy[p, 0], xy[v, 0])
        in_y = min(xy[p, 1], xy[v, 1]) <= xy[a, 1] <= max(xy[p, 1], xy[v, 1])
        return in_x and in_y
    if b == p or b == v or s_a * _sign(_orient(xy, p, v, b)) >= 0:
        return False
    return _sign(_orient(xy, a, b, p)) * _sign(_orient(xy, a, b, v)) < 0


@njit(cache=True)
def _lex_less(xy: np.ndarray, a: int, b: int) -> bool:
    """Whether point ``a`` comes before ``b`` in (x, y) lexicographic order."""
    return xy[a, 0] < xy[b, 0] or (xy[a, 0] == xy[b, 0] and xy[a, 1] < xy[b, 1])


@njit(cache=True)
def _winding(xy: np.ndarray, first: int, next_he: np.ndarray, orig: np.ndarray, dest: np.ndarray, p: int) -> int:
    """Winding number of the face cycle starting at half-edge ``first`` around point ``p`` (not on it)."""
    py = xy[p, 1]
    w = np.int64(0)
    h = first
    while True:
        a = orig[h]
        b = dest[h]
        if xy[a, 1] <= py:
            if xy[b, 1] > py and _orient(xy, a, b, p) > 0.0:
                w += 1
        elif xy[b, 1] <= py and _orient(xy, a, b, p) < 0.0:
            w -= 1
        h = next_he[h]
        if h == first:
            break
    return w


@njit(cache=True)
def _is_ear(xy: np.ndarray, pt: np.ndarray, nxt: np.ndarray, a_occ: int, b_occ: int, c_occ: int) -> bool:
    """Whether the polygon corner ``a_occ, b_occ, c_occ`` (consecutive occurrences) is an ear.

    It must turn strictly left and no polygon vertex other than the points
    ``a, b, c`` themselves may lie inside the closed triangle ``a, b, c``.
    """
    a = pt[a_occ]
    b = pt[b_occ]
    c = pt[c_occ]
    if a == c or _orient(xy, a, b, c) <= 0.0:
        return False
    xmin = min(xy[a, 0], xy[b, 0], xy[c, 0])
    xmax = max(xy[a, 0], xy[b, 0], xy[c, 0])
    ymin = min(xy[a, 1], xy[b, 1], xy[c, 1])
    ymax = max(xy[a, 1], xy[b, 1], xy[c, 1])
    o = nxt[c_occ]
    while o != a_occ:
        q = pt[o]
        o = nxt[o]
        if q == a or q == b or q == c:
            continue
        if xy[q, 0] < xmin or xy[q, 0] > xmax or xy[q, 1] < ymin or xy[q, 1] > ymax:
            continue
        if _orient(xy, a, b, q) >= 0.0 and _orient(xy, b, c, q) >= 0.0 and _orient(xy, c, a, q) >= 0.0:
            return False
    return True


@njit(cache=True)
def _sift_down(values: np.ndarray, idx: np.ndarray, root: int, end: int) -> None:
    """Restore the max-heap property of ``values[idx[root:end]]`` below ``root``."""
    while True:
        child = 2 * root + 1
        if child >= end:
            return
        if child + 1 < end and values[idx[child]] < values[idx[child + 1]]:
            child += 1
        if not values[idx[root]] < values[idx[child]]:
            return
        idx[root], idx[child] = idx[child], idx[root]
        root = child


@njit(cache=True)
def _argsort(values: np.ndarray) -> np.ndarray:
    """(n,) int64 indices that sort the (n,) int64 array ``values`` ascending (heapsort, not stable; float keys
    go through :func:`_order_keys`).

    Used instead of ``np.argsort``, whose compilation costs seconds.
    """
    n = values.shape[0]
    idx = np.arange(n)
    for root in range(n // 2 - 1, -1, -1):
        _sift_down(values, idx, root, n)
    for end in range(n - 1, 0, -1):
        idx[0], idx[end] = idx[end], idx[0]
        _sift_down(values, idx, np.int64(0), end)  # not the literal 0: one compiled variant
    return idx


@njit(cache=True)
def _take(values: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(k,) int64 ``values[idx]`` of (n,) int64 ``values`` and (k,) int64 ``idx``: a loop, which compiles
    once, where every fancy-indexing expression would compile its own code."""
    out = np.empty(idx.shape[0], dtype=np.int64)
    for i in range(idx.shape[0]):
        out[i] = values[idx[i]]
    return out


@njit(cache=True)
def _order_keys(values: np.ndarray) -> np.ndarray:
    """(n,) int64 keys in the order of the (n,) contiguous float64 ``values`` (not NaN; -0.0 before 0.0), so
    that one compiled :func:`_argsort` (int64) sorts both kinds of key.

    The bits of a float64 read as an int64 increase with the value for non-negative values and decrease for
    negative ones; flipping all but the sign bit of the negative ones makes them increase too.
    """
    bits = values.view(np.int64)
    keys = np.empty(bits.shape[0], np.int64)
    for i in range(bits.shape[0]):
        keys[i] = bits[i] ^ 0x7FFFFFFFFFFFFFFF if bits[i] < 0 else bits[i]
    return keys


@njit(cache=True)
def _empty_result() -> tuple[np.ndarray, np.ndarray]:
    """The failure result: an empty (0, 3) triangle array and an empty region array."""
    return np.empty((0, 3), dtype=np.int64), np.empty(0, dtype=np.int64)


# ---------------------------------------------------------------------------
# Isolated interior points
# ---------------------------------------------------------------------------


@njit(cache=True, inline='always')
def _insert_point(xy: np.ndarray, tri: np.ndarray, reg: np.ndarray, nt: int, q: int) -> int:
    """Insert point ``q`` into the triangulation ``tri[:nt]`` (room for two more rows); return the new count.

    The containing triangle is split in three, or, when ``q`` lies on one of
    its edges, it and the triangle across that edge (if any) are split in two.
    Nothing happens when ``q`` coincides with a vertex or lies in no triangle.
    """
    for t in range(nt):
        zero = np.int64(-1)
        n_zero = np.int64(0)
        inside = True
        for j in range(3):
            s = _orient(xy, tri[t, j], tri[t, (j + 1) % 3], q)
            if s < 0.0:
                inside = False
                break
            if s == 0.0:
                zero = j
                n_zero += 1
        if not inside:
            continue
        if n_zero >= 2:
            return nt
        if n_zero == 0:
            a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
            tri[t, 2] = q
            tri[nt, 0], tri[nt, 1], tri[nt, 2] = b, c, q
            tri[nt + 1, 0], tri[nt + 1, 1], tri[nt + 1, 2] = c, a, q
            reg[nt] = reg[t]
            reg[nt + 1] = reg[t]
            return nt + 2
        a = tri[t, zero]
        b = tri[t, (zero + 1) % 3]
        c = tri[t, (zero + 2) % 3]
        tri[t, 0], tri[t, 1], tri[t, 2] = a, q, c
        tri[nt, 0], tri[nt, 1], tri[nt, 2] = q, b, c
        reg[nt] = reg[t]
        new_nt = nt + 1
        for u in range(nt):
            for j in range(3):
                if tri[u, j] == b and tri[u, (j + 1) % 3] == a:
                    d = tri[u, (j + 2) % 3]
                    tri[u, 0], tri[u, 1], tri[u, 2] = b, q, d
                    tri[new_nt, 0], tri[new_nt, 1], tri[new_nt, 2] = q, a, d
                    reg[new_nt] = reg[u]
                    return new_nt + 1
        return new_nt
    return nt


_FLIP_SWEEPS = 64
"""Most passes of :func:`_delaunay_flips` over the triangles."""
_INCIRCLE_MARGIN = 1e-12
"""Relative margin an incircle determinant must exceed to flip (no flips back and forth on cocircular points)."""


@njit(cache=True)
def _incircle(xy: np.ndarray, a: int, b: int, c: int, d: int) -> tuple[float, float]:
    """Incircle determinant of d against the counter-clockwise triangle abc (> 0: inside) and its size."""
    adx, ady = xy[a, 0] - xy[d, 0], xy[a, 1] - xy[d, 1]
    bdx, bdy = xy[b, 0] - xy[d, 0], xy[b, 1] - xy[d, 1]
    cdx, cdy = xy[c, 0] - xy[d, 0], xy[c, 1] - xy[d, 1]
    al, bl, cl = adx * adx + ady * ady, bdx * bdx + bdy * bdy, cdx * cdx + cdy * cdy
    det = al * (bdx * cdy - cdx * bdy) + bl * (cdx * ady - adx * cdy) + cl * (adx * bdy - bdx * ady)
    size = al * (abs(bdx * cdy) + abs(cdx * bdy)) + bl * (abs(cdx * ady) + abs(adx * cdy)) + cl * (
        abs(adx * bdy) + abs(bdx * ady))
    return det, size


@njit(cache=True, inline='always')
def _delaunay_flips(xy: np.ndarray, tri: np.ndarray, nt: int, eu: np.ndarray, ev: np.ndarray) -> None:
    """Flip the unconstrained edges of the first ``nt`` triangles towards the constrained Delaunay
    triangulation, in place (graph edges ``eu``-``ev`` stay).

    Ear clipping fans out from one vertex and leaves slivers along straight
    runs of points; a curve's points computed in floating point then sit a
    rounding error off the long diagonals of those slivers, on either side.
    Flipping to Delaunay connects them to the far corners instead. A flip
    needs both new triangles strictly counter-clockwise (exact orient2d), so
    the tiling stays valid whatever the incircle test's rounding.
    """
    n = xy.shape[0]
    fixed = np.empty(eu.shape[0], np.int64)
    for e in range(eu.shape[0]):
        fixed[e] = min(eu[e], ev[e]) * n + max(eu[e], ev[e])
    fixed = _take(fixed, _argsort(fixed))
    keys = np.empty(3 * nt, np.int64)
    for _ in range(_FLIP_SWEEPS):
        for t in range(nt):
            for k in range(3):
                keys[3 * t + k] = tri[t, k] * n + tri[t, (k + 1) % 3]
        order = _argsort(keys)
        sorted_keys = _take(keys, order)
        flipped = np.bool_(False)
        for t in range(nt):
            for k in range(3):
                a, b, c = tri[t, k], tri[t, (k + 1) % 3], tri[t, (k + 2) % 3]
                if a > b:
                    continue  # each edge once, from its triangle with a < b
                undirected = a * n + b
                q = lower_bound(fixed, 0, fixed.shape[0], undirected)
                if q < fixed.shape[0] and fixed[q] == undirected:
                    continue
                q = lower_bound(sorted_keys, 0, sorted_keys.shape[0], b * n + a)
                if q >= sorted_keys.shape[0] or sorted_keys[q] != b * n + a:
                    continue
                u = order[q] // 3
                j = order[q] % 3
                if keys[3 * u + j] != b * n + a or tri[u, j] != b:
                    continue  # its neighbour was flipped in this sweep already
                d = tri[u, (j + 2) % 3]
                det, size = _incircle(xy, a, b, c, d)
                if det <= _INCIRCLE_MARGIN * size:
                    continue
                if _orient(xy, c, a, d) <= 0.0 or _orient(xy, d, b, c) <= 0.0:
                    continue
                tri[t, 0], tri[t, 1], tri[t, 2] = c, a, d
                tri[u, 0], tri[u, 1], tri[u, 2] = d, b, c
                keys[3 * t], keys[3 * t + 1], keys[3 * t + 2] = -1, -1, -1  # stale until the next sweep
                keys[3 * u], keys[3 * u + 1], keys[3 * u + 2] = -1, -1, -1
                flipped = True
                break
        if not flipped:
            return


# ---------------------------------------------------------------------------
# One triangle
# ---------------------------------------------------------------------------


@njit(cache=True, inline='always')
def _boundary_cycle(location: np.ndarray, edge_param: np.ndarray) -> np.ndarray:
    """(nb,) int64 boundary cycle: corner 0, edge 0 points by ``edge_param``, corner 1, ..., edge 2 points."""
    n = location.shape[0]
    n_edge_points = np.int64(0)  # np.int64, not literals, for values a loop updates: typed in numba's first pass
    for i in range(3, n):
        if location[i] < LOCATION_INTERIOR:
            n_edge_points += 1
    bnd = np.empty(3 + n_edge_points, dtype=np.int64)
    nb = np.int64(0)
    for k in range(3):
        bnd[nb] = k
        nb += 1
        cnt = np.int64(0)
        for i in range(3, n):
            if location[i] == LOCATION_EDGE + k:
                cnt += 1
        idx = np.empty(cnt, dtype=np.int64)
        par = np.empty(cnt, dtype=np.float64)
        cnt = np.int64(0)
        for i in range(3, n):
            if location[i] == LOCATION_EDGE + k:
                idx[cnt] = i
                par[cnt] = edge_param[i]
                cnt += 1
        order = _argsort(_order_keys(par))
        for j in range(cnt):
            bnd[nb] = idx[order[j]]
            nb += 1
    return bnd


@njit(cache=True, inline='always')
def _graph_edges(bnd: np.ndarray, location: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edges ``(eu[e], ev[e])``: the boundary pieces, then the deduplicated interior segments.

    Returns two (e,) int64 arrays, or two empty arrays if a segment index is
    out of range. Segments along the boundary and zero-length ones are left
    out.
    """
    n = location.shape[0]
    m = segments.shape[0]
    nb = bnd.shape[0]
    eu = np.empty(nb + m, dtype=np.int64)
    ev = np.empty(nb + m, dtype=np.int64)
    for i in range(nb):
        eu[i] = bnd[i]
        ev[i] = bnd[(i + 1) % nb]
    ne = nb
    keys = np.empty(m, dtype=np.int64)
    nk = np.int64(0)
    for s in range(m):
        a = segments[s, 0]
        b = segments[s, 1]
        if a < 0 or a >= n or b < 0 or b >= n:
            return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
        if a == b or (_edge_mask(location[a]) & _edge_mask(location[b])) != 0:
            continue  # zero length, or along the boundary (covered by its pieces)
        keys[nk] = min(a, b) * n + max(a, b)
        nk += 1
    used = keys[:nk]
    sorted_keys = _take(used, _argsort(used))
    for j in range(nk):
        if j > 0 and sorted_keys[j] == sorted_keys[j - 1]:
            continue
        eu[ne] = sorted_keys[j] // n
        ev[ne] = sorted_keys[j] % n
        ne += 1
    return eu[:ne], ev[:ne]


@njit(cache=True, inline='always')
def _half_edges(
    xy: np.ndarray, eu: np.ndarray, ev: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """Half-edges sorted counter-clockwise around their origins, and their face successors.

    Half-edge ``2 e`` runs ``eu[e] -> ev[e]``, ``2 e + 1`` the other way.

    Returns
    -------
    orig, dest : numpy.ndarray
        (h,) int64 origin and destination of every half-edge.
    out_start, out_he : numpy.ndarray
        (n + 1,) and (h,) int64 CSR lists of the half-edges leaving each
        vertex, counter-clockwise from angle 0.
    next_he : numpy.ndarray
        (h,) int64 successor of each half-edge along its face (the face on
        its left): the half-edge after its twin clockwise around its end.
    ok : bool
        False if two edges leave a vertex in the same direction (overlap).
    """
    n = xy.shape[0]
    ne = eu.shape[0]
    nh = 2 * ne
    orig = np.empty(nh, dtype=np.int64)
    dest = np.empty(nh, dtype=np.int64)
    deg = np.zeros(n, dtype=np.int64)
    for e in range(ne):
        orig[2 * e] = eu[e]
        dest[2 * e] = ev[e]
        orig[2 * e + 1] = ev[e]
        dest[2 * e + 1] = eu[e]
        deg[eu[e]] += 1
        deg[ev[e]] += 1
    out_start = np.zeros(n + 1, dtype=np.int64)
    for v in range(n):
        out_start[v + 1] = out_start[v] + deg[v]
    fill = out_start[:n].copy()
    out_he = np.empty(nh, dtype=np.int64)
    for h in range(nh):
        out_he[fill[orig[h]]] = h
        fill[orig[h]] += 1
    pos = np.empty(nh, dtype=np.int64)
    next_he = np.empty(nh, dtype=np.int64)
    ok = np.bool_(True)
    for v in range(n):
        s0 = out_start[v]
        d = deg[v]
        for i in range(1, d):  # insertion sort by direction
            h = out_he[s0 + i]
            j = i - 1
            while j >= 0 and _angle_before(xy, v, dest[h], dest[out_he[s0 + j]]):
                out_he[s0 + j + 1] = out_he[s0 + j]
                j -= 1
            out_he[s0 + j + 1] = h
        for i in range(d):
            pos[out_he[s0 + i]] = i
        if d >= 2:
            for i in range(d):
                w1 = dest[out_he[s0 + i]]
                w2 = dest[out_he[s0 + (i + 1) % d]]
                if not _angle_before(xy, v, w1, w2) and not _angle_before(xy, v, w2, w1):
                    ok = False  # same direction
    for h in range(nh):
        t = h ^ 1
        v = orig[t]
        d = deg[v]
        next_he[h] = out_he[out_start[v] + (pos[t] - 1 + d) % d]
    return orig, dest, out_start, out_he, next_he, ok


@njit(cache=True, inline='always')
def _faces(next_he: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(h,) int64 face of every half-edge and (f,) int64 first half-edge of every face (orbits of ``next_he``)."""
    nh = next_he.shape[0]
    face_of = np.full(nh, -1, dtype=np.int64)
    face_first = np.empty(nh, dtype=np.int64)
    nf = np.int64(0)
    for h in range(nh):
        if face_of[h] >= 0:
            continue
        g = h
        while face_of[g] < 0:
            face_of[g] = nf
            g = next_he[g]
        face_first[nf] = h
        nf += 1
    return face_of, face_first[:nf].copy()


@njit(cache=True, inline='always')
def _components(
    xy: np.ndarray, out_start: np.ndarray, out_he: np.ndarray, dest: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Connected components of the graph, their smallest vertex and the half-edge on their outer face.

    Returns
    -------
    comp : numpy.ndarray
        (n,) int64 component of each vertex, -1 for vertices on no edge.
    lexmin : numpy.ndarray
        (c,) int64 lexicographically (x, y) smallest vertex of each component.
    outer_he : numpy.ndarray
        (c,) int64 half-edge leaving ``lexmin`` whose left side is the
        component's outer face: the most counter-clockwise one, as all edges
        there point into the half-plane of angles (-pi/2, pi/2].
    """
    n = xy.shape[0]
    comp = np.full(n, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    lexmin = np.empty(n, dtype=np.int64)
    nc = np.int64(0)
    for s in range(n):
        if out_start[s + 1] == out_start[s] or comp[s] >= 0:
            continue
        comp[s] = nc
        lexmin[nc] = s
        top = np.int64(1)
        stack[0] = s
        while top > 0:
            top -= 1
            v = stack[top]
            if _lex_less(xy, v, lexmin[nc]):
                lexmin[nc] = v
            for i in range(out_start[v], out_start[v + 1]):
                w = dest[out_he[i]]
                if comp[w] < 0:
                    comp[w] = nc
                    stack[top] = w
                    top += 1
        nc += 1
    outer_he = np.empty(nc, dtype=np.int64)
    for c in range(nc):
        v = lexmin[c]
        best = out_he[out_start[v]]
        for i in range(out_start[v] + 1, out_start[v + 1]):
            h = out_he[i]
            if _orient(xy, v, dest[best], dest[h]) > 0.0:
                best = h
        outer_he[c] = best
    return comp, lexmin[:nc].copy(), outer_he


@njit(cache=True, inline='always')
def _hole_faces(
    xy: np.ndarray,
    lexmin: np.ndarray,
    skip: int,
    face_first: np.ndarray,
    face_comp: np.ndarray,
    is_outer: np.ndarray,
    next_he: np.ndarray,
    orig: np.ndarray,
    dest: np.ndarray,
) -> np.ndarray:
    """(c,) int64 innermost bounded face around every component but ``skip`` (-1 for it, -2 if none)."""
    nc = lexmin.shape[0]
    nf = face_first.shape[0]
    hole_face = np.full(nc, -1, dtype=np.int64)
    for c in range(nc):
        if c == skip:
            continue
        v = lexmin[c]
        best = np.int64(-2)
        for f in range(nf):
            if is_outer[f] or face_comp[f] == c:
                continue
            if _winding(xy, face_first[f], next_he, orig, dest, v) == 0:
                continue
            # the candidates are nested: f is inside best if one of its vertices is
            if best < 0 or _winding(xy, face_first[best], next_he, orig, dest, orig[face_first[f]]) != 0:
                best = f
        hole_face[c] = best
    return hole_face


@njit(cache=True)
def _bridge_target(
    xy: np.ndarray,
    pt: np.ndarray,
    nxt: np.ndarray,
    prv: np.ndarray,
    merged: np.ndarray,
    mc: int,
    o_v: int,
    pending: np.ndarray,
) -> int:
    """Occurrence in ``merged[:mc]`` to bridge the hole occurrence ``o_v`` to, or -1 if none is visible.

    ``pending`` holds one occurrence on each hole cycle of the face not merged
    yet (including the one of ``o_v``); their edges may not be crossed either.
    """
    v = pt[o_v]
    d2 = np.empty(mc, dtype=np.float64)
    for j in range(mc):
        p = pt[merged[j]]
        d2[j] = (xy[p, 0] - xy[v, 0]) ** 2 + (xy[p, 1] - xy[v, 1]) ** 2
    order = _argsort(_order_keys(d2))
    for jj in range(mc):
        cand = merged[order[jj]]
        p = pt[cand]
        if not _in_wedge(xy, pt[prv[cand]], p, pt[nxt[cand]], v):
            continue
        if not _in_wedge(xy, pt[prv[o_v]], v, pt[nxt[o_v]], p):
            continue
        blocked = False
        for j in range(mc):
            o = merged[j]
            if _obstructs(xy, pt[o], pt[nxt[o]], p, v):
                blocked = True
                break
        for jh in range(pending.shape[0]):
            if blocked:
                break
            o = pending[jh]
            while True:
                if _obstructs(xy, pt[o], pt[nxt[o]], p, v):
                    blocked = True
                    break
                o = nxt[o]
                if o == pending[jh]:
                    break
        if not blocked:
            return cand
    return -1


@njit(cache=True, inline='always')
def _merge_holes(
    xy: np.ndarray,
    pt: np.ndarray,
    nxt: np.ndarray,
    prv: np.ndarray,
    merged: np.ndarray,
    first: int,
    hole_he: np.ndarray,
    n_occ: int,
) -> tuple[int, int]:
    """Build one face's polygon: its cycle from occurrence ``first`` with the holes bridged in.

    ``hole_he`` (k,) int64 holds the outer half-edge (at the smallest vertex)
    of each hole of the face, sorted by that vertex. The linked list
    ``pt, nxt, prv`` is edited in place; new occurrences are numbered from
    ``n_occ``. All occurrences of the polygon end up in ``merged``.

    Returns
    -------
    tuple of int
        Number of occurrences in ``merged`` (-1 if a hole cannot be bridged)
        and the updated ``n_occ``.
    """
    mc = np.int64(0)
    o = first
    while True:
        merged[mc] = o
        mc += 1
        o = nxt[o]
        if o == first:
            break
    for ih in range(hole_he.shape[0]):
        o_v = hole_he[ih]
        o_p = _bridge_target(xy, pt, nxt, prv, merged, mc, o_v, hole_he[ih:])
        if o_p < 0:
            return -1, n_occ
        o = o_v
        while True:
            merged[mc] = o
            mc += 1
            o = nxt[o]
            if o == o_v:
                break
        # splice: p -> v -> (hole) -> v' -> p' -> next(p)
        v_copy = n_occ
        p_copy = n_occ + 1
        n_occ += 2
        pt[v_copy] = pt[o_v]
        pt[p_copy] = pt[o_p]
        p_next = nxt[o_p]
        v_prev = prv[o_v]
        nxt[o_p] = o_v
        prv[o_v] = o_p
        nxt[v_prev] = v_copy
        prv[v_copy] = v_prev
        nxt[v_copy] = p_copy
        prv[p_copy] = v_copy
        nxt[p_copy] = p_next
        prv[p_next] = p_copy
        merged[mc] = v_copy
        merged[mc + 1] = p_copy
        mc += 2
    return mc, n_occ


@njit(cache=True, inline='always')
def _ear_clip(
    xy: np.ndarray,
    pt: np.ndarray,
    nxt: np.ndarray,
    prv: np.ndarray,
    start: int,
    count: int,
    tri: np.ndarray,
    nt: int,
) -> int:
    """Triangulate the polygon of ``count`` occurrences through ``start`` into ``tri[nt:]`` by ear clipping.

    Returns the new number of triangles, or -1 if the polygon has no ear
    (only possible for inconsistent input).
    """
    cur = start
    misses = np.int64(0)
    while count > 3:
        a_occ = prv[cur]
        c_occ = nxt[cur]
        if _is_ear(xy, pt, nxt, a_occ, cur, c_occ):
            tri[nt, 0] = pt[a_occ]
            tri[nt, 1] = pt[cur]
            tri[nt, 2] = pt[c_occ]
            nt += 1
            nxt[a_occ] = c_occ
            prv[c_occ] = a_occ
            count -= 1
            misses = np.int64(0)
        else:
            misses += 1
            if misses > count:
                return -1
        cur = c_occ
    a_occ = prv[cur]
    c_occ = nxt[cur]
    if _orient(xy, pt[a_occ], pt[cur], pt[c_occ]) <= 0.0:
        return -1
    tri[nt, 0] = pt[a_occ]
    tri[nt, 1] = pt[cur]
    tri[nt, 2] = pt[c_occ]
    return nt + 1


@njit(cache=True)
def cut_triangle(
    xy: np.ndarray, location: np.ndarray, edge_param: np.ndarray, segments: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate one triangle cut along constraint segments.

    Parameters
    ----------
    xy : numpy.ndarray
        (n, 2) float64 2-D coordinates of the triangle's points; rows 0, 1, 2
        are its corners, counter-clockwise.
    location : numpy.ndarray
        (n,) int64 exact location of every point: ``k`` (0..2) for corner
        ``k`` (rows 0..2 only), ``3 + k`` for the interior of edge ``k``
        (corner ``k`` to corner ``(k + 1) % 3``), ``6`` for the interior.
    edge_param : numpy.ndarray
        (n,) float64 position in (0, 1) of each edge point along its edge,
        from corner ``k`` to corner ``k + 1``; only its order matters (no
        ties). Ignored for other points.
    segments : numpy.ndarray
        (m, 2) int64 constraint segments between point indices (any order,
        duplicates allowed). They may lie along the boundary, form chords,
        dangling or floating polylines and closed (nested) loops, but must not
        cross, overlap or touch other points except at shared ends.

    Returns
    -------
    triangles : numpy.ndarray
        (t, 3) int64 point indices of counter-clockwise triangles (strictly
        positive exact orientation) that tile the triangle: every edge point
        splits its edge, every segment is a union of triangle edges (split at
        the boundary points it covers, if it lies along the boundary), every
        point on a segment or edge is a vertex, and isolated interior points
        are inserted as vertices. ``(0, 3)`` when the input is detected to be
        inconsistent (see the module docstring).
    region : numpy.ndarray
        (t,) int64 index, in 0..R-1, of the face of the subdivision of the
        triangle by its segments that each triangle belongs to (a face with
        holes is one region; dangling segments do not separate regions).

    Notes
    -----
    Every orientation decision uses the exact ``orient2d``; coordinates are
    otherwise only used to order bridge candidates. The locations are
    trusted, never recomputed from ``xy``.
    """
    return _cut(xy, location, edge_param, segments, True)


@njit(cache=True)
def _cut(
    xy: np.ndarray, location: np.ndarray, edge_param: np.ndarray, segments: np.ndarray, insert_isolated: bool | None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cut_triangle`, whose result it returns; ``insert_isolated`` None (not False) compiles it
    without the insertion of isolated interior points, a sizeable part of the code that a Boolean
    operation never needs: a triangle with such points then returns no triangles and a region array of
    one element, for the caller to cut it with :func:`cut_triangle`."""
    n = xy.shape[0]
    if n < 3 or xy.shape[1] != 2 or location.shape[0] != n or edge_param.shape[0] != n or segments.shape[1] != 2:
        return _empty_result()
    for k in range(3):
        if location[k] != k:
            return _empty_result()
    for i in range(3, n):
        if location[i] < LOCATION_EDGE or location[i] > LOCATION_INTERIOR:
            return _empty_result()
    if _orient(xy, np.int64(0), np.int64(1), np.int64(2)) <= 0.0:  # not literals: one compiled variant
        return _empty_result()

    # planar graph and its faces
    bnd = _boundary_cycle(location, edge_param)
    eu, ev = _graph_edges(bnd, location, segments)
    if eu.shape[0] == 0:
        return _empty_result()
    orig, dest, out_start, out_he, next_he, ok = _half_edges(xy, eu, ev)
    if not ok:
        return _empty_result()
    nh = orig.shape[0]
    face_of, face_first = _faces(next_he)
    nf = face_first.shape[0]

    # outer faces, regions, holes
    comp, lexmin, outer_he = _components(xy, out_start, out_he, dest)
    nc = lexmin.shape[0]
    is_outer = np.zeros(nf, dtype=np.bool_)
    for c in range(nc):
        is_outer[face_of[outer_he[c]]] = True
    bc = comp[0]
    h_cw = np.int64(-1)  # corner 0 -> previous boundary point runs clockwise: on the outer face
    for i in range(out_start[0], out_start[1]):
        if dest[out_he[i]] == bnd[bnd.shape[0] - 1]:
            h_cw = out_he[i]
    if h_cw < 0 or face_of[h_cw] != face_of[outer_he[bc]]:
        return _empty_result()
    face_comp = np.empty(nf, dtype=np.int64)
    region_of_face = np.full(nf, -1, dtype=np.int64)
    n_regions = np.int64(0)
    for f in range(nf):
        face_comp[f] = comp[orig[face_first[f]]]
        if not is_outer[f]:
            region_of_face[f] = n_regions
            n_regions += 1
    hole_face = _hole_faces(xy, lexmin, bc, face_first, face_comp, is_outer, next_he, orig, dest)
    for c in range(nc):
        if hole_face[c] == -2:
            return _empty_result()

    # polygons as linked lists of vertex occurrences: occurrence h < nh is the
    # origin of half-edge h; every bridge adds two copies
    cap = nh + 2 * nc
    pt = np.empty(cap, dtype=np.int64)
    nxt = np.empty(cap, dtype=np.int64)
    prv = np.empty(cap, dtype=np.int64)
    for h in range(nh):
        pt[h] = orig[h]
        nxt[h] = next_he[h]
        prv[next_he[h]] = h
    n_occ = nh
    merged = np.empty(cap, dtype=np.int64)
    holes = np.empty(nc, dtype=np.int64)
    n_iso = np.int64(0)
    for i in range(3, n):
        if comp[i] < 0 and location[i] == LOCATION_INTERIOR:
            n_iso += 1
    if insert_isolated is None and n_iso > 0:  # left to the caller
        return np.empty((0, 3), dtype=np.int64), np.empty(1, dtype=np.int64)
    tri = np.empty((cap + 2 * n_iso, 3), dtype=np.int64)
    reg = np.empty(cap + 2 * n_iso, dtype=np.int64)
    nt = np.int64(0)  # not the literal 0: callees would be compiled for it as well as for int64
    for f in range(nf):
        if is_outer[f]:
            continue
        n_holes = np.int64(0)
        for c in range(nc):  # the face's holes, sorted by smallest vertex
            if hole_face[c] == f:
                j = n_holes
                while j > 0 and _lex_less(xy, lexmin[c], pt[holes[j - 1]]):
                    holes[j] = holes[j - 1]
                    j -= 1
                holes[j] = outer_he[c]
                n_holes += 1
        mc, n_occ = _merge_holes(xy, pt, nxt, prv, merged, face_first[f], holes[:n_holes], n_occ)
        if mc < 0:
            return _empty_result()
        new_nt = _ear_clip(xy, pt, nxt, prv, merged[0], mc, tri, nt)
        if new_nt < 0:
            return _empty_result()
        for t in range(nt, new_nt):
            reg[t] = region_of_face[f]
        nt = new_nt

    if insert_isolated is not None:  # pruned when compiled for None
        for i in range(3, n):
            if comp[i] < 0 and location[i] == LOCATION_INTERIOR:
                nt = _insert_point(xy, tri, reg, nt, i)
    _delaunay_flips(xy, tri, nt, eu, ev)
    return tri[:nt].copy(), reg[:nt].copy()


# ---------------------------------------------------------------------------
# Many triangles
# ---------------------------------------------------------------------------


def cut_triangles(
    xy: np.ndarray,
    location: np.ndarray,
    edge_param: np.ndarray,
    point_start: np.ndarray,
    segments: np.ndarray,
    segment_start: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run :func:`cut_triangle` on many triangles stored in CSR form, in parallel.

    A triangulation of the p points of a triangle has at most 2p - 5 triangles,
    so every triangle writes into its own slot of 2p rows and one copy packs
    the slots.

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 2) float64 2-D point coordinates of all triangles, concatenated.
    location : numpy.ndarray
        (N,) int64 location codes (see :func:`cut_triangle`).
    edge_param : numpy.ndarray
        (N,) float64 positions of edge points along their edges.
    point_start : numpy.ndarray
        (T + 1,) int64: the points of triangle ``i`` are rows
        ``point_start[i]:point_start[i + 1]``, its three corners first.
    segments : numpy.ndarray
        (M, 2) int64 constraint segments, with point indices *local* to their
        triangle (0 is the triangle's first point).
    segment_start : numpy.ndarray
        (T + 1,) int64: the segments of triangle ``i`` are rows
        ``segment_start[i]:segment_start[i + 1]``.

    Returns
    -------
    triangles : numpy.ndarray
        (K, 3) int64 output triangles, point indices local to their triangle.
    region : numpy.ndarray
        (K,) int64 region index of each output triangle, local to its triangle.
    triangle_start : numpy.ndarray
        (T + 1,) int64: the output of triangle ``i`` is rows
        ``triangle_start[i]:triangle_start[i + 1]``; an empty range marks a
        triangle whose input was inconsistent (or whose CSR range was invalid).
    """
    n_tri = point_start.shape[0] - 1
    slot = np.zeros(max(n_tri, 0) + 1, dtype=np.int64)  # 2p rows per triangle, never overlapping
    np.cumsum(2 * np.maximum(np.diff(point_start), 0), out=slot[1:])
    tri_out = np.empty((max(slot[-1], 0), 3), dtype=np.int64)
    reg_out = np.empty(max(slot[-1], 0), dtype=np.int64)
    count = np.zeros(max(n_tri, 0), dtype=np.int64)
    for_ranges(_cut_range, max(n_tri, 0), xy, location, edge_param, point_start, segments, segment_start, slot,
               tri_out, reg_out, count, min_items=HEAVY_ITEMS_PER_RANGE)
    for i in np.flatnonzero(count < 0):  # triangles with isolated interior points (rare): the full cut
        p0, p1, s0, s1 = point_start[i], point_start[i + 1], segment_start[i], segment_start[i + 1]
        t, r = cut_triangle(xy[p0:p1], location[p0:p1], edge_param[p0:p1], segments[s0:s1])
        count[i] = t.shape[0] if t.shape[0] <= slot[i + 1] - slot[i] else 0
        tri_out[slot[i]:slot[i] + count[i]] = t[:count[i]]
        reg_out[slot[i]:slot[i] + count[i]] = r[:count[i]]
    triangle_start = np.zeros(max(n_tri, 0) + 1, dtype=np.int64)
    np.cumsum(count, out=triangle_start[1:])
    keep = np.repeat(slot[:-1] - triangle_start[:-1], count) + np.arange(triangle_start[-1])
    return tri_out[keep], reg_out[keep], triangle_start


@njit(cache=True, nogil=True)
def _cut_range(xy, location, edge_param, point_start, segments, segment_start, slot, tri_out, reg_out, count, first,
               last):
    """:func:`cut_triangle` on triangles ``first`` to ``last``; each writes its slot of ``tri_out`` and
    ``reg_out`` and its count, -1 for a triangle with isolated interior points (left to the caller)."""
    n_pts = xy.shape[0]
    n_seg = segments.shape[0]
    for i in range(first, last):
        p0 = point_start[i]
        p1 = point_start[i + 1]
        s0 = segment_start[i]
        s1 = segment_start[i + 1]
        if 0 <= p0 <= p1 <= n_pts and 0 <= s0 <= s1 <= n_seg:
            t, r = _cut(xy[p0:p1], location[p0:p1], edge_param[p0:p1], segments[s0:s1], None)
            k = t.shape[0]
            if r.shape[0] > k:
                count[i] = -1
                continue
            if k <= slot[i + 1] - slot[i]:
                for j in range(k):
                    tri_out[slot[i] + j, 0] = t[j, 0]
                    tri_out[slot[i] + j, 1] = t[j, 1]
                    tri_out[slot[i] + j, 2] = t[j, 2]
                    reg_out[slot[i] + j] = r[j]
                count[i] = k
