"""Triangle-triangle intersection detection for triangle meshes.

Broad phase: every triangle's bounding box is entered into the cells of a
uniform grid stored as a spatial hash (so memory follows the surface, not
the bounding volume); two triangles are compared only when they share a cell,
and only in the first cell they share, so every pair is tested once.
Narrow phase: Möller's (1997) interval test on the line where the two planes
meet, with the plane side of each vertex taken from the sign of an orientation
determinant (snapped to zero within rounding of the plane), and an
edge-crossing/containment test for coplanar pairs. Touching counts as
intersecting.

Faces that share a vertex are adjacent and never reported; degenerate faces
(zero area) are skipped.
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit, unsigned
from pverosion.kernels._threads import HEAVY_ITEMS_PER_RANGE, for_ranges
from pverosion.kernels.tolerances import COPLANAR
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["candidate_pairs", "canonical_vertices", "intersecting_faces", "intersecting_pairs", "spatial_order",
           "triangles_intersect"]




@njit(cache=True, error_model="numpy")
def _side(a, b, c, p):
    """Orientation determinant of ``p`` against the plane through a, b, c; 0 when within rounding of the plane.

    Points of a flat but tilted wall are rarely exactly coplanar in floating
    point; a distance below :data:`COPLANAR` times the size of the configuration
    is taken as zero, so such pairs go to the coplanar test.
    """
    ab, ac, ap = v3.sub(b, a), v3.sub(c, a), v3.sub(p, a)
    n = v3.cross(ab, ac)
    d = v3.dot(n, ap)
    size2 = max(v3.dot(ab, ab), v3.dot(ac, ac), v3.dot(ap, ap))
    if d * d <= COPLANAR * COPLANAR * v3.dot(n, n) * size2:
        return 0.0
    return d


@njit(cache=True, error_model="numpy")
def _interval(p0, p1, p2, d0, d1, d2):
    """Sorted parameter interval of a triangle on the intersection line.

    ``p*`` are the vertex projections on the line, ``d*`` their signed
    distances to the other plane (not all of one strict sign, not all zero).
    """
    if d0 * d1 > 0.0:  # p2 alone on its side
        a = p2 + (p0 - p2) * d2 / (d2 - d0)
        b = p2 + (p1 - p2) * d2 / (d2 - d1)
    elif d0 * d2 > 0.0:  # p1 alone
        a = p1 + (p0 - p1) * d1 / (d1 - d0)
        b = p1 + (p2 - p1) * d1 / (d1 - d2)
    elif d1 * d2 > 0.0 or d0 != 0.0:  # p0 alone
        a = p0 + (p1 - p0) * d0 / (d0 - d1)
        b = p0 + (p2 - p0) * d0 / (d0 - d2)
    elif d1 != 0.0:
        a = p1 + (p0 - p1) * d1 / (d1 - d0)
        b = p1 + (p2 - p1) * d1 / (d1 - d2)
    else:
        a = p2 + (p0 - p2) * d2 / (d2 - d0)
        b = p2 + (p1 - p2) * d2 / (d2 - d1)
    return min(a, b), max(a, b)


@njit(cache=True, error_model="numpy")
def _orient2d(a, b, c):
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


@njit(cache=True, error_model="numpy")
def _segments_cross_2d(a, b, c, d):
    """Closed 2D segments ab and cd share a point."""
    o1, o2 = _orient2d(a, b, c), _orient2d(a, b, d)
    o3, o4 = _orient2d(c, d, a), _orient2d(c, d, b)
    if ((o1 > 0 and o2 < 0) or (o1 < 0 and o2 > 0)) and ((o3 > 0 and o4 < 0) or (o3 < 0 and o4 > 0)):
        return True
    if o1 == 0 and o2 == 0:  # collinear: overlap of projections
        for k in range(2):
            if max(min(a[k], b[k]), min(c[k], d[k])) > min(max(a[k], b[k]), max(c[k], d[k])):
                return False
        return True
    return (
        (o1 == 0 and _on_segment(a, b, c))
        or (o2 == 0 and _on_segment(a, b, d))
        or (o3 == 0 and _on_segment(c, d, a))
        or (o4 == 0 and _on_segment(c, d, b))
    )


@njit(cache=True, error_model="numpy")
def _on_segment(a, b, p):
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


@njit(cache=True, error_model="numpy")
def _inside_2d(p, a, b, c):
    o1, o2, o3 = _orient2d(a, b, p), _orient2d(b, c, p), _orient2d(c, a, p)
    return (o1 >= 0 and o2 >= 0 and o3 >= 0) or (o1 <= 0 and o2 <= 0 and o3 <= 0)


@njit(cache=True, error_model="numpy")
def _coplanar(normal, p0, p1, p2, q0, q1, q2):
    """Intersection test of two coplanar triangles, projected along the normal's largest axis."""
    ax, ay, az = abs(normal[0]), abs(normal[1]), abs(normal[2])
    if ax >= ay and ax >= az:
        i, j = 1, 2
    elif ay >= az:
        i, j = 0, 2
    else:
        i, j = 0, 1
    P = ((p0[i], p0[j]), (p1[i], p1[j]), (p2[i], p2[j]))
    Q = ((q0[i], q0[j]), (q1[i], q1[j]), (q2[i], q2[j]))
    for a in range(3):
        for b in range(3):
            if _segments_cross_2d(P[a], P[(a + 1) % 3], Q[b], Q[(b + 1) % 3]):
                return True
    return _inside_2d(P[0], Q[0], Q[1], Q[2]) or _inside_2d(Q[0], P[0], P[1], P[2])


@njit(cache=True, error_model="numpy")
def tri_tri(p0, p1, p2, q0, q1, q2):
    """Whether closed triangles (p0, p1, p2) and (q0, q1, q2), given as 3-tuples, meet."""
    dp0, dp1, dp2 = _side(q0, q1, q2, p0), _side(q0, q1, q2, p1), _side(q0, q1, q2, p2)
    if (dp0 > 0 and dp1 > 0 and dp2 > 0) or (dp0 < 0 and dp1 < 0 and dp2 < 0):
        return False
    dq0, dq1, dq2 = _side(p0, p1, p2, q0), _side(p0, p1, p2, q1), _side(p0, p1, p2, q2)
    if (dq0 > 0 and dq1 > 0 and dq2 > 0) or (dq0 < 0 and dq1 < 0 and dq2 < 0):
        return False
    n1 = v3.cross(v3.sub(p1, p0), v3.sub(p2, p0))
    if dp0 == 0.0 and dp1 == 0.0 and dp2 == 0.0:
        return _coplanar(n1, p0, p1, p2, q0, q1, q2)
    n2 = v3.cross(v3.sub(q1, q0), v3.sub(q2, q0))
    line = v3.cross(n1, n2)
    # project on the coordinate axis closest to the line direction (order is preserved)
    ax, ay, az = abs(line[0]), abs(line[1]), abs(line[2])
    k = 0 if ax >= ay and ax >= az else (1 if ay >= az else 2)
    a1, b1 = _interval(p0[k], p1[k], p2[k], dp0, dp1, dp2)
    a2, b2 = _interval(q0[k], q1[k], q2[k], dq0, dq1, dq2)
    return max(a1, a2) <= min(b1, b2)


def triangles_intersect(p, q) -> bool:
    """Whether two closed triangles in 3D meet (touching counts).

    Parameters
    ----------
    p, q : array_like, shape (3, 3)
        The vertices of each triangle, one per row.

    Returns
    -------
    bool
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if p.shape != (3, 3) or q.shape != (3, 3):
        raise ValueError(f"triangles must have shape (3, 3); got {p.shape} and {q.shape}")
    return bool(tri_tri(v3.row(p, 0), v3.row(p, 1), v3.row(p, 2), v3.row(q, 0), v3.row(q, 1), v3.row(q, 2)))


@njit(cache=True, error_model="numpy")
def _spread(x):
    """Spread the low 21 bits of x two bits apart (Morton code helper)."""
    x &= 0x1FFFFF
    x = (x | (x << 32)) & 0x1F00000000FFFF
    x = (x | (x << 16)) & 0x1F0000FF0000FF
    x = (x | (x << 8)) & 0x100F00F00F00F00F
    x = (x | (x << 4)) & 0x10C30C30C30C30C3
    x = (x | (x << 2)) & 0x1249249249249249
    return x


@njit(cache=True, error_model="numpy")
def _interleave(sx, sy, sz):
    """Morton code of a cell from its coordinates spread by :func:`_spread` (the one place of the bit layout)."""
    return (sx << 2) | (sy << 1) | sz


@njit(cache=True, error_model="numpy")
def _morton(ix, iy, iz):
    return _interleave(_spread(ix), _spread(iy), _spread(iz))


def _table_size(n: int) -> int:
    """Buckets of the spatial hash of ``n`` faces: the smallest power of two above 2 n, and at least 16 (a mask, not
    a division, finds a cell's bucket: the low bits of its Morton code, so that cells near in space mostly land in
    buckets near in memory; the bits above them and four flag bits make an entry's key, see :func:`_bucket_range`)."""
    return max(16, 1 << (2 * n).bit_length())


@njit(cache=True, error_model="numpy", nogil=True)
def _box_range(points, faces, order, local, box, ok, side, start, stop):
    """Faces ``start`` to ``stop`` of ``local`` = ``faces[order]``: their vertices, boxes (lowest then highest
    corner in one row of ``box``), whether they are non-degenerate and their largest side."""
    for f in range(start, stop):
        g = unsigned(order[f])
        a, b, c = faces[g, 0], faces[g, 1], faces[g, 2]
        local[f, 0], local[f, 1], local[f, 2] = a, b, c
        p0, p1, p2 = v3.row(points, unsigned(a)), v3.row(points, unsigned(b)), v3.row(points, unsigned(c))
        for d in range(3):
            box[f, d] = min(p0[d], p1[d], p2[d])
            box[f, 3 + d] = max(p0[d], p1[d], p2[d])
        c = v3.cross(v3.sub(p1, p0), v3.sub(p2, p0))
        ok[f] = v3.dot(c, c) > 0.0
        if ok[f]:
            side[f] = max(box[f, 3] - box[f, 0], box[f, 4] - box[f, 1], box[f, 5] - box[f, 2])


@njit(cache=True, error_model="numpy")
def _grid_frame(box, ok, side):
    """Origin (lowest box corner), cell edge and number of the non-degenerate faces."""
    n_ok = 0
    total = 0.0
    origin = np.full(3, np.inf)
    for f in range(ok.shape[0]):
        if ok[f]:
            n_ok += 1
            total += side[f]
            for d in range(3):
                origin[d] = min(origin[d], box[f, d])
    # cell edge: the mean of the boxes' largest side, so a face covers a few cells
    h = total / n_ok if n_ok > 0 and total > 0.0 else 1.0
    return origin, h, n_ok


@njit(cache=True, error_model="numpy", nogil=True)
def _key_range(box, ok, origin, h, inv_h, keys, cell, count, start, stop):
    """For the non-degenerate faces ``start`` to ``stop``: the ranges of grid cells their boxes cover (lowest x,
    y, z, then highest), the number of these cells (in ``count[f + 1]``) and, when ``keys`` has entries, the
    Morton keys of their lowest cells."""
    with_keys = keys.shape[0] > 0
    for f in range(start, stop):
        if ok[f]:
            if with_keys:
                keys[f] = _morton(
                    int((box[f, 0] - origin[0]) / h), int((box[f, 1] - origin[1]) / h), int((box[f, 2] - origin[2]) / h)
                )
            for d in range(3):
                cell[f, d] = int((box[f, d] - origin[d]) * inv_h)
                cell[f, 3 + d] = int((box[f, 3 + d] - origin[d]) * inv_h)
            count[f + 1] = (cell[f, 3] - cell[f, 0] + 1) * (cell[f, 4] - cell[f, 1] + 1) * (cell[f, 5] - cell[f, 2] + 1)


def _face_boxes(points: np.ndarray, faces: np.ndarray, order: np.ndarray | None = None, *,
                keys: bool = False) -> tuple:
    """The faces in ``order`` (by default as given) (F, 3), their boxes (F, 6) (lowest then highest corner, the
    row a pair test reads), whether they are
    non-degenerate (F,), Morton keys (F,) (with ``keys``, else none), the number of non-degenerate faces, the
    range of grid cells every box covers (F, 6) (set for non-degenerate faces) and the first grid entry of
    every face (F + 1,) (the cumulated numbers of cells the boxes cover, none for degenerate faces)."""
    n = faces.shape[0]
    if order is None:
        order = np.arange(n)
    local = np.empty_like(faces)
    box = np.empty((n, 6))
    ok = np.empty(n, np.bool_)
    side = np.empty(n)
    for_ranges(_box_range, n, points, faces, order, local, box, ok, side)
    origin, h, n_ok = _grid_frame(box, ok, side)
    morton = np.zeros(n if keys else 0, np.int64)
    cell = np.empty((n, 6), np.int64)  # rows of degenerate faces stay unset: never read
    offset = np.zeros(n + 1, np.int64)
    for_ranges(_key_range, n, box, ok, origin, h, 1.0 / h, morton, cell, offset)
    np.cumsum(offset, out=offset)
    return local, box, ok, morton, n_ok, cell, offset


@njit(cache=True, error_model="numpy", nogil=True)
def _bucket_range(cell, ok, query, offset, size, shift, bucket, keys, start, stop):
    """Buckets and keys of the grid entries of faces ``start`` to ``stop`` (every cell their boxes cover, in x, y, z
    loop order), from ``offset[f]`` on. The bucket of a cell is the low ``shift`` bits of its Morton code (``size``
    = 2 ** ``shift`` >= 16); the key holds the bits above them from bit 4 on (with the bucket, the cell) and flags
    in bits 0-3 (bits 0-2: the cell is the face's lowest along x, y, z; bit 3: ``query`` holds for the face)."""
    mask = size - 1
    for f in range(start, stop):
        if not ok[f]:
            continue
        k = offset[f]
        queried = 8 if query[f] else 0
        x0, y0, z0 = cell[f, 0], cell[f, 1], cell[f, 2]
        for ix in range(x0, cell[f, 3] + 1):
            sx = _spread(ix)
            for iy in range(y0, cell[f, 4] + 1):
                sy = _spread(iy)
                for iz in range(z0, cell[f, 5] + 1):
                    code = _interleave(sx, sy, _spread(iz))  # _morton, the spreads once per row
                    bucket[k] = code & mask
                    keys[k] = ((code >> shift) << 4) | queried | (ix == x0) | ((iy == y0) << 1) | ((iz == z0) << 2)
                    k += 1


@njit(cache=True, error_model="numpy")
def _bucket_fill(offset, bucket, keys, size):
    """The grid entries grouped by bucket (``bucket``, ``keys``: each entry's, in face and loop order, the entries
    of face f from ``offset[f]`` to ``offset[f + 1]``; stable): bucket starts (size + 1,), faces and keys."""
    n = bucket.shape[0]
    start = np.zeros(size + 1, np.int64)
    for k in range(n):
        start[unsigned(bucket[k] + 1)] += 1
    for b in range(size):
        start[b + 1] += start[b]
    fill = start[:-1].copy()
    entries = np.empty(n, np.int64)
    cells = np.empty(n, np.int64)
    for f in range(offset.shape[0] - 1):
        for k in range(offset[f], offset[f + 1]):
            u = unsigned(k)
            b = unsigned(bucket[u])
            i = unsigned(fill[b])
            entries[i] = f
            cells[i] = keys[u]
            fill[b] = i + 1
    return start, entries, cells


def _build_grid(cell: np.ndarray, offset: np.ndarray, ok: np.ndarray, query: np.ndarray, size: int) -> tuple:
    """Spatial hash of ``size`` buckets (:func:`_table_size`): the non-degenerate faces covering each bucket's
    cells (ranges ``cell`` (F, 6), first entries ``offset`` (F + 1,)), in face order, with each entry's key of
    :func:`_bucket_range` (``query`` (F,) sets bit 3)."""
    n = cell.shape[0]
    bucket = np.empty(int(offset[-1]), np.int32 if size < 2**31 else np.int64)
    keys = np.empty(int(offset[-1]), np.int64)
    # the hashes and keys in parallel, the serial grouping only moves them
    for_ranges(_bucket_range, n, cell, ok, query, offset, size, size.bit_length() - 1, bucket, keys)
    return _bucket_fill(offset, bucket, keys, size)


@njit(cache=True, error_model="numpy")
def _shared_vertices(faces, f, g):
    n = 0
    for a in range(3):
        for b in range(3):
            if faces[f, a] == faces[g, b]:
                n += 1
    return n


@njit(cache=True, error_model="numpy", nogil=True)
def _hits_range(points, faces, box, start, entries, cells, hits, first, last):
    """Flag in ``hits`` the faces that meet a non-adjacent face, testing the pairs with a queried face in the
    cells of buckets ``first`` to ``last``, each pair in the first cell both boxes cover (the cell where, along
    every axis, one of the two is lowest: the flags of the entries' keys together have all four bits); both faces
    of a hit
    are flagged, another range may flag the same face, with the same value. ``box`` (F, 6): every face's lowest
    then highest corner, in one row."""
    for b in range(first, last):
        for i in range(start[b], start[b + 1] - 1):
            key = cells[unsigned(i)]
            f = -1
            for j in range(i + 1, start[b + 1]):
                there = cells[unsigned(j)]
                if (there ^ key) >> 4 != 0 or (there | key) & 15 != 15:
                    continue  # another cell hashed here, the pair meets in an earlier cell, or neither is queried
                if f < 0:  # the face's box and corners, read once a pair needs them
                    f = entries[unsigned(i)]
                    fu = unsigned(f)
                    x0, y0, z0, x1, y1, z1 = box[fu, 0], box[fu, 1], box[fu, 2], box[fu, 3], box[fu, 4], box[fu, 5]
                    a, b_, c = faces[fu, 0], faces[fu, 1], faces[fu, 2]
                g = unsigned(entries[unsigned(j)])
                u, v, w = faces[g, 0], faces[g, 1], faces[g, 2]
                # one test without branches: most pairs here are adjacent, and whether their boxes meet is a coin toss
                adjacent = ((a == u) | (a == v) | (a == w) | (b_ == u) | (b_ == v) | (b_ == w)
                            | (c == u) | (c == v) | (c == w))
                apart = ((x0 > box[g, 3]) | (box[g, 0] > x1) | (y0 > box[g, 4]) | (box[g, 1] > y1)
                         | (z0 > box[g, 5]) | (box[g, 2] > z1))
                if adjacent | apart:
                    continue
                if tri_tri(v3.row(points, unsigned(a)), v3.row(points, unsigned(b_)), v3.row(points, unsigned(c)),
                           v3.row(points, unsigned(u)), v3.row(points, unsigned(v)), v3.row(points, unsigned(w))):
                    hits[fu] = True
                    hits[g] = True  # same value from any thread: a benign race


def _count_hits(points, faces, box, grid, size) -> np.ndarray:
    """Flag the faces that meet a non-adjacent face, testing the pairs with a queried face once (per cell of
    the grid, so each pair of faces in a cell is met once rather than from both faces); ``box`` (F, 6): lowest
    and highest corners; ``grid``: what :func:`_build_grid` returned."""
    hits = np.zeros(faces.shape[0], np.bool_)
    for_ranges(_hits_range, size, points, faces, box, *grid, hits, min_items=HEAVY_ITEMS_PER_RANGE)
    return hits


@njit(cache=True, error_model="numpy")
def _side_range(points, faces, h, other, m, o, shared):
    """Bounds of m . (p - o) over the vertices p of face h (but those of face ``other`` when ``shared``), widened
    by far more than their rounding (below 4 eps |m|_1 |p - o|_1)."""
    m1 = abs(m[0]) + abs(m[1]) + abs(m[2])
    lo, hi = np.inf, -np.inf
    for t in range(3):
        v = faces[h, t]
        if shared and (v == faces[other, 0] or v == faces[other, 1] or v == faces[other, 2]):
            continue
        d = v3.sub(v3.row(points, v), o)
        s = v3.dot(m, d)
        tol = 1e-12 * m1 * (abs(d[0]) + abs(d[1]) + abs(d[2]))
        lo, hi = min(lo, s - tol), max(hi, s + tol)
    return lo, hi


@njit(cache=True, error_model="numpy")
def _plane_separates(points, faces, f, g, m, o, shared):
    """Whether the plane through point ``o`` with normal ``m`` has face f strictly on one side and face g strictly
    on the other (but for their shared vertex ``o`` when ``shared``), by more than the rounding of the side values.
    The plane is defined by these floats exactly, so this never separates faces that meet (but at ``o``)."""
    lo_f, hi_f = _side_range(points, faces, f, g, m, o, shared)
    lo_g, hi_g = _side_range(points, faces, g, f, m, o, shared)
    if shared:
        return (hi_f < 0.0 < lo_g) or (hi_g < 0.0 < lo_f)
    return hi_f < lo_g or hi_g < lo_f


@njit(cache=True, error_model="numpy")
def _apart_by_a_plane(points, faces, f, g, shared):
    """Whether a separating plane shows that faces f and g meet at most in their shared vertex (``shared`` = 1).

    Faces in a common plane, or sharing a vertex, pass the tests of plane sides; the planes tried here separate
    most of them: the plane between the centroids; the planes through the edges of either face perpendicular to
    it (through an edge at the shared vertex, turned a little so that the edge's far end lies strictly on its
    face's side)."""
    m = (0.0, 0.0, 0.0)
    o = v3.row(points, faces[f, 0])
    for t in range(3):
        m = v3.add(m, v3.sub(v3.row(points, faces[g, t]), v3.row(points, faces[f, t])))
        if shared and (faces[f, t] == faces[g, 0] or faces[f, t] == faces[g, 1] or faces[f, t] == faces[g, 2]):
            o = v3.row(points, faces[f, t])
    if _plane_separates(points, faces, f, g, m, o, shared):
        return True
    for side in range(2):
        h = np.int64(f) if side == 0 else np.int64(g)
        other = np.int64(g) if side == 0 else np.int64(f)
        p0, p1, p2 = v3.row(points, faces[h, 0]), v3.row(points, faces[h, 1]), v3.row(points, faces[h, 2])
        c = v3.cross(v3.sub(p1, p0), v3.sub(p2, p0))
        for i in range(3):
            a, b = faces[h, i], faces[h, (i + 1) % 3]
            e = v3.sub(v3.row(points, b), v3.row(points, a))
            m = v3.cross(e, c)  # in h's plane, away from h
            if not shared:
                if _plane_separates(points, faces, f, g, m, v3.row(points, a), np.int64(0)):
                    return True
                continue
            m1 = abs(m[0]) + abs(m[1]) + abs(m[2])
            e1 = abs(e[0]) + abs(e[1]) + abs(e[2])
            turn = 1e-9 * m1 * e1 / v3.dot(e, e)
            for end in range(2):
                v, far = (a, e) if end == 0 else (b, v3.scale(e, -1.0))
                if v == faces[other, 0] or v == faces[other, 1] or v == faces[other, 2]:
                    tilted = v3.sub(m, v3.scale(far, turn))
                    if _plane_separates(points, faces, f, g, tilted, v3.row(points, v), np.int64(1)):
                        return True
    return False


@njit(cache=True, error_model="numpy")
def _face_box_pairs(points, faces, planes, box, group, query, cell, start, entries, cells, size, shift, f,
                    out, n_out):
    """Faces g whose boxes meet f's box, that share no edge with f, (with groups) are in another group, and
    that neither lies strictly on one side of the other's plane nor of a plane of :func:`_apart_by_a_plane`
    (apart from a shared vertex): g > f, or with a
    query any g not queried before f. Written to ``out`` as (min, max) from ``n_out`` on when it is large
    enough. Returns the count."""
    grouped = group.shape[0] > 0
    fx0, fy0, fz0, fx1, fy1, fz1 = cell[f, 0], cell[f, 1], cell[f, 2], cell[f, 3], cell[f, 4], cell[f, 5]
    for ix in range(fx0, fx1 + 1):
        for iy in range(fy0, fy1 + 1):
            for iz in range(fz0, fz1 + 1):
                code = _morton(ix, iy, iz)
                b = code & (size - 1)
                key = code >> shift
                for e in range(start[b], start[b + 1]):
                    g = entries[e]
                    # with a query: the pairs of queried faces f with any g, each pair once
                    if g == f or (g < f and (query.shape[0] == 0 or query[g])):
                        continue
                    if cells[e] >> 4 != key or (grouped and group[f] == group[g]):
                        continue
                    # visit the pair only in the first cell both boxes cover
                    if max(fx0, cell[g, 0]) != ix or max(fy0, cell[g, 1]) != iy or max(fz0, cell[g, 2]) != iz:
                        continue
                    if (box[f, 0] > box[g, 3] or box[g, 0] > box[f, 3] or box[f, 1] > box[g, 4]
                            or box[g, 1] > box[f, 4] or box[f, 2] > box[g, 5] or box[g, 2] > box[f, 5]):
                        continue
                    shared = _shared_vertices(faces, f, g)
                    if shared > 1:
                        continue
                    # faces that share a vertex meet beyond it only when neither has its other two vertices on
                    # one side of the other's plane
                    if ((not _nearly_one_plane(planes, f, g) and (_one_side(points, faces, planes, f, g, shared)
                                                                  or _one_side(points, faces, planes, g, f, shared)))
                            or _apart_by_a_plane(points, faces, f, g, shared)):
                        continue
                    if n_out < out.shape[0]:
                        out[n_out, 0] = min(f, g)
                        out[n_out, 1] = max(f, g)
                    n_out += 1
    return n_out


@njit(cache=True, error_model="numpy", nogil=True)
def _plane_range(points, faces, out, start, stop):
    """Rows ``start`` to ``stop`` of :func:`_face_planes`."""
    for f in range(start, stop):
        p0, p1, p2 = v3.row(points, faces[f, 0]), v3.row(points, faces[f, 1]), v3.row(points, faces[f, 2])
        n = v3.cross(v3.sub(p1, p0), v3.sub(p2, p0))
        length = v3.norm(n)
        if length == 0.0:
            out[f, 4] = np.inf
            continue
        n = v3.scale(n, 1.0 / length)
        out[f, 0], out[f, 1], out[f, 2] = n
        out[f, 3] = v3.dot(n, p0)
        scale = 0.0
        for p in (p0, p1, p2):
            scale = max(scale, abs(p[0]) + abs(p[1]) + abs(p[2]))
        out[f, 4] = 1e-9 * scale  # far above the rounding of n . p - d for the points near the face


def _face_planes(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normal, offset and a bound of the rounding of plane distances of every face: (F, 5)."""
    out = np.zeros((faces.shape[0], 5))
    for_ranges(_plane_range, faces.shape[0], points, faces, out)
    return out


@njit(cache=True, error_model="numpy")
def _one_side(points, faces, planes, f, g, shared):
    """Whether face g lies strictly on one side of face f's plane, by more than the rounding (a float test that
    never rejects a pair an exact test would call touching); with ``shared`` = 1, whether its two vertices that
    are not f's do."""
    above = below = 0
    for k in range(3):
        if shared and (faces[g, k] == faces[f, 0] or faces[g, k] == faces[f, 1] or faces[g, k] == faces[f, 2]):
            continue
        p = v3.row(points, faces[g, k])
        d = planes[f, 0] * p[0] + planes[f, 1] * p[1] + planes[f, 2] * p[2] - planes[f, 3]
        tol = planes[f, 4] + 1e-9 * (abs(p[0]) + abs(p[1]) + abs(p[2]))
        if d > tol:
            above += 1
        elif d < -tol:
            below += 1
    return above == 3 - shared or below == 3 - shared


@njit(cache=True, error_model="numpy", inline="always")
def _nearly_one_plane(planes, f, g):
    """Whether faces f and g lie in nearly one plane (parallel unit normals, offsets within the rounding bounds):
    :func:`_one_side` would find neither on one side of the other, so the plane tests of
    :func:`_apart_by_a_plane` come first (skipping :func:`_one_side` only costs speed when it is wrong)."""
    return (planes[f, 0] * planes[g, 0] + planes[f, 1] * planes[g, 1] + planes[f, 2] * planes[g, 2] > 1.0 - 1e-12
            and abs(planes[f, 3] - planes[g, 3]) <= planes[f, 4] + planes[g, 4])


@njit(cache=True, error_model="numpy", nogil=True)
def _pair_range(points, faces, planes, box, todo, group, query, cell, start, entries, cells, size, shift, first,
                last):
    """The pairs of faces ``todo[first:last]`` (K, 2), face by face, in one pass: a face whose pairs overflow the
    buffer is searched again after the buffer has grown."""
    out = np.empty((max(16, (last - first) // 4), 2), np.int64)
    n = np.int64(0)
    for i in range(first, last):
        f = todo[i]
        m = _face_box_pairs(points, faces, planes, box, group, query, cell, start, entries, cells, size, shift, f,
                            out, n)
        if m > out.shape[0]:
            grown = np.empty((max(2 * out.shape[0], m), 2), np.int64)
            for j in range(n):  # element by element: an array slice assignment compiles numba's shape error
                grown[j, 0], grown[j, 1] = out[j, 0], out[j, 1]
            out = grown
            m = _face_box_pairs(points, faces, planes, box, group, query, cell, start, entries, cells, size, shift,
                                f, out, n)
        n = m
    return out[:n]


def _box_pairs(points, faces, planes, box, ok, group, query, cell, start, entries, cells, size) -> np.ndarray:
    """All face pairs (f < g) of :func:`candidate_pairs`, grouped by the queried face (by f without a query):
    (K, 2)."""
    parts = {}

    def part(*args):
        parts[args[-2]] = _pair_range(*args)

    # the usable (queried) faces, ascending, split evenly between the threads
    todo = np.flatnonzero(ok if query.shape[0] == 0 else ok & query)
    for_ranges(part, len(todo), points, faces, planes, box, todo, group, query, cell, start, entries, cells,
               size, size.bit_length() - 1, min_items=HEAVY_ITEMS_PER_RANGE)
    return parts[0] if len(parts) == 1 else np.concatenate([parts[first] for first in sorted(parts)])


@njit(cache=True, error_model="numpy")
def _near_query(box, ok, query):
    """``ok`` (F,) narrowed to the faces whose boxes (``box`` (F, 6): lowest then highest corner) meet the box
    around the queried
    usable faces (only they can meet a queried face), and its count; none when no usable face is queried."""
    top = np.full(3, -np.inf)
    bottom = np.full(3, np.inf)
    queried = False
    for f in range(ok.shape[0]):
        if ok[f] and query[f]:
            queried = True
            for d in range(3):
                top[d] = max(top[d], box[f, 3 + d])
                bottom[d] = min(bottom[d], box[f, d])
    near = np.zeros(ok.shape[0], np.bool_)
    n = 0
    if not queried:
        return near, n
    for f in range(ok.shape[0]):
        if (ok[f] and box[f, 0] <= top[0] and box[f, 3] >= bottom[0] and box[f, 1] <= top[1]
                and box[f, 4] >= bottom[1] and box[f, 2] <= top[2] and box[f, 5] >= bottom[2]):
            near[f] = True
            n += 1
    return near, n


def _entry_offsets(offset: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """First grid entries (F + 1,) of the faces still ``ok`` (F,) (``offset``: of a larger set), the entries of
    the others dropped."""
    count = np.diff(offset)
    count[~ok] = 0
    return np.concatenate(([0], np.cumsum(count)))


def candidate_pairs(points, faces, *, group=None, query=None) -> np.ndarray:
    """Pairs of non-degenerate faces that may meet and share no edge (broad phase).

    Their bounding boxes meet, and neither face lies on one side of the
    other's plane by more than a generous bound of the rounding (so every
    pair that touches in exact arithmetic is kept). Faces that share one
    vertex are kept only when neither has its two other vertices on one side
    of the other's plane: they may meet beyond the shared vertex. Faces in a
    common plane (or sharing a vertex) are dropped when a plane through an
    edge of either, between their centroids, or through the shared vertex
    has them strictly on its two sides by more than the rounding.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
    group : array_like of int, shape (F,), optional
        Only pairs of faces in different groups (e.g. the input mesh of each
        face); by default all pairs.
    query : array_like of bool, shape (F,), optional
        Only pairs with at least one of these faces; by default all pairs.

    Returns
    -------
    numpy.ndarray, shape (K, 2), int64
        Face pairs ``(f, g)`` with ``f < g``, sorted by ``f`` (without a
        query).
    """
    pts, fcs = as_triangle_mesh(points, faces)
    grp = np.zeros(0, np.int64) if group is None else np.asarray(group, dtype=np.int64)
    if group is not None and grp.shape != (len(fcs),):
        raise ValueError(f"group must have shape ({len(fcs)},); got {grp.shape}")
    wanted = np.zeros(0, bool) if query is None else np.asarray(query, dtype=bool)
    if query is not None and wanted.shape != (len(fcs),):
        raise ValueError(f"query must have shape ({len(fcs)},); got {wanted.shape}")
    _, box, ok, _, n_ok, cell, offset = _face_boxes(pts, fcs)
    if query is not None and n_ok:
        ok, n_ok = _near_query(box, ok, wanted)
        offset = _entry_offsets(offset, ok)
    if n_ok == 0:
        return np.zeros((0, 2), np.int64)
    size = _table_size(n_ok)
    start, entries, cells = _build_grid(cell, offset, ok, ok, size)
    return _box_pairs(pts, fcs, _face_planes(pts, fcs), box, ok, grp, wanted, cell, start, entries,
                      cells, size)


def spatial_order(points, faces) -> np.ndarray:
    """Face permutation along a Morton curve through the faces' bounding boxes.

    Intersection checks run fastest with faces that are near in space also
    near in memory; a mesh whose vertices only move a little keeps a good
    order, so compute it once and pass it to :func:`intersecting_faces`.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)

    Returns
    -------
    numpy.ndarray, shape (F,), int64
    """
    pts, fcs = as_triangle_mesh(points, faces)
    return np.argsort(_face_boxes(pts, fcs, keys=True)[3], kind="stable")


@njit(cache=True)
def _first_of_equal_rows(bits: np.ndarray) -> np.ndarray:
    """The lowest index of the rows equal to every row of ``bits`` (V, 3) int64, by an open-addressing hash table
    (one pass in index order, so the first row of every position is met first)."""
    n = bits.shape[0]
    size = np.int64(16)
    while size < 2 * n:
        size *= 2
    table = np.full(size, -1, np.int64)
    out = np.empty(n, np.int64)
    for i in range(n):
        h = (bits[i, 0] * 0x1E3779B97F4A7C15) ^ (bits[i, 1] * 0x42B2AE3D27D4EB4F) ^ (bits[i, 2] * 0x165667B19E3779F9)
        slot = (h ^ (h >> 29)) & (size - 1)
        while True:
            j = table[slot]
            if j < 0:
                table[slot] = i
                out[i] = i
                break
            if bits[j, 0] == bits[i, 0] and bits[j, 1] == bits[i, 1] and bits[j, 2] == bits[i, 2]:
                out[i] = j
                break
            slot = (slot + 1) & (size - 1)
    return out


def canonical_vertices(points: np.ndarray) -> np.ndarray:
    """The lowest index of the vertices at the position of every vertex (V,): coincident vertices as one
    (finite coordinates; -0.0 and 0.0 are one position)."""
    # adding 0.0 turns -0.0 into 0.0, so that equal positions have equal bits
    bits = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 3) + 0.0).view(np.int64)
    return _first_of_equal_rows(bits)


def intersecting_faces(points, faces, *, query=None, order=None, coincident: str = "apart") -> np.ndarray:
    """Faces that intersect a non-adjacent face of the same mesh.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
    query : array_like of bool, shape (F,), optional
        Test only the pairs that involve these faces; by default all pairs.
        Use it for incremental checks of the faces near moved vertices.
    order : array_like of int, shape (F,), optional
        A face permutation from :func:`spatial_order` (of this or an earlier
        state of the mesh). It only affects speed; by default it is computed.
    coincident : {"apart", "shared"}
        Distinct vertices at one position: two vertices, so faces touching
        there intersect ("apart"), or one vertex, which makes the faces that
        use it adjacent, as faces that share a vertex are ("shared": the
        surface that ``pverosion repair`` makes of two parts meeting at a
        point, whose contact is the input's, not an intersection).

    Returns
    -------
    numpy.ndarray, shape (F,), bool
        Faces that meet a non-adjacent face (in a tested pair).
        ``result.any()`` tells whether the mesh self-intersects.
    """
    if coincident not in ("apart", "shared"):
        raise ValueError(f"coincident must be 'apart' or 'shared'; got {coincident!r}")
    hits = _intersecting_faces(points, faces, query, order)
    if coincident == "shared" and hits.any():
        pts, fcs = as_triangle_mesh(points, faces)
        joined = canonical_vertices(pts)[fcs]
        if not np.array_equal(joined, fcs):  # a pair that meets with the vertices joined meets apart: both are hits
            hits = _intersecting_faces(pts, joined, hits if query is None else hits & np.asarray(query, bool), order)
    return hits


def _intersecting_faces(points, faces, query, order) -> np.ndarray:
    """:func:`intersecting_faces` with distinct vertices apart."""
    pts, fcs = as_triangle_mesh(points, faces)
    q = np.ones(len(fcs), bool) if query is None else np.asarray(query, dtype=bool)
    if q.shape != (len(fcs),):
        raise ValueError(f"query must have shape ({len(fcs)},); got {q.shape}")
    if order is None:
        order = spatial_order(pts, fcs)
    order = np.asarray(order, dtype=np.int64)
    if order.shape != (len(fcs),):
        raise ValueError(f"order must have shape ({len(fcs)},); got {order.shape}")
    if order.min(initial=0) < 0 or order.max(initial=-1) >= len(fcs):
        raise ValueError(f"order must hold face indices below {len(fcs)}")
    # visit the faces in Morton order, so neighbours in space are near in memory
    local, box, ok, _, n_ok, cell, offset = _face_boxes(pts, fcs, order)
    hits = np.zeros(len(fcs), bool)
    local_query = q[order]
    # few faces near a local query (vertices moved in one place); the box around half the faces or more holds
    # nearly all of them
    if query is not None and n_ok and 2 * np.count_nonzero(q) < n_ok:
        ok, n_ok = _near_query(box, ok, local_query)
        offset = _entry_offsets(offset, ok)
    if n_ok == 0:
        return hits
    size = _table_size(n_ok)
    grid = _build_grid(cell, offset, ok, local_query, size)
    hits[order] = _count_hits(pts, local, box, grid, size)
    return hits


def intersecting_pairs(points, faces) -> np.ndarray:
    """All pairs of non-adjacent faces that intersect.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)

    Returns
    -------
    numpy.ndarray, shape (K, 2), int64
        Face index pairs ``(f, g)`` with ``f < g``, sorted.
    """
    pts, fcs = as_triangle_mesh(points, faces)
    hits = intersecting_faces(pts, fcs)
    flagged = np.flatnonzero(hits)
    pairs = set()
    for f in flagged:
        for g in flagged:
            if f < g and not set(fcs[f]) & set(fcs[g]) and triangles_intersect(pts[fcs[f]], pts[fcs[g]]):
                pairs.add((int(f), int(g)))
    return np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)
