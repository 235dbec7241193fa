"""Spatial queries on a closed triangle mesh: inside/outside by ray parity, triangles near a box.

Both use uniform bucket grids (CSR arrays) built once per mesh: by the
triangles' bounding boxes (:class:`TriangleIndex`) or, tighter for long thin
triangles, by the triangles themselves (:func:`overlap_grid`). The parity
test casts a ray along +z and counts the triangles it crosses; a point on
the shared edge or vertex of triangles seen from above is claimed by
exactly one of them (the "top-left" rule of rasterisers), so edges and
vertices are not counted twice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels.exact.predicates import orient2d
from pverosion.kernels.spatial.grid import box_items, bucket_boxes

__all__ = ["TriangleIndex", "box_triangles", "overlap_grid", "point_inside", "ray_winding",
           "ray_winding_without", "segment_crossings", "unit_normals"]


@dataclass(frozen=True)
class TriangleIndex:
    """Bucket grids over a triangle mesh.

    Attributes
    ----------
    points : (n_points, 3) float64
    faces : (n_faces, 3) int64
    normals : (n_faces, 3) float64
        Unit face normals (right-hand rule).
    lo : (3,) float64
        Lower corner of the grids.
    size : float
        Bucket edge (both grids).
    dims : (3,) int64
        Buckets along x, y, z.
    start, items : int64 arrays
        3-D grid: triangles whose bounding box meets each bucket (x-fastest).
    start2, items2 : int64 arrays
        2-D (x, y) grid of the same buckets, for the +z ray.
    """

    points: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    lo: np.ndarray
    size: float
    dims: np.ndarray
    start: np.ndarray
    items: np.ndarray
    start2: np.ndarray
    items2: np.ndarray

    @classmethod
    def build(cls, points: np.ndarray, faces: np.ndarray, *, size: float | None = None) -> TriangleIndex:
        """Index ``faces`` (n, 3) over ``points`` (m, 3); bucket edge defaults to twice the mean edge."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        tri = points[faces]
        normals = unit_normals(points, faces)
        lo = points.min(axis=0)
        extent = np.maximum(points.max(axis=0) - lo, 1e-12)
        if size is None:
            edge = np.linalg.norm(tri[:, 1] - tri[:, 0], axis=1).mean() if len(faces) else 1.0
            size = max(2.0 * float(edge), float(extent.max()) / 256.0)
        dims = np.maximum(np.ceil(extent / size).astype(np.int64), 1)
        tlo = np.clip(((tri.min(axis=1) - lo) / size).astype(np.int64), 0, dims - 1)
        thi = np.clip(((tri.max(axis=1) - lo) / size).astype(np.int64), 0, dims - 1)
        start, items = bucket_boxes(tlo, thi, dims)
        d2 = np.array([dims[0], dims[1], 1])
        start2, items2 = bucket_boxes(tlo * [1, 1, 0], thi * [1, 1, 0], d2)
        return cls(points, faces, normals, lo, float(size), dims, start, items, start2, items2)


def unit_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals (n_faces, 3) of the triangles ``faces`` over ``points`` (right-hand rule; zero if degenerate)."""
    tri = points[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)


@njit(cache=True, inline="always")
def _needle(points, faces, t):
    """Whether triangle ``t`` has sides at less than about 1e-6 rad, so rounding tilts its computed plane."""
    a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
    ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
    wx, wy, wz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    return nx * nx + ny * ny + nz * nz <= 1e-12 * (ux * ux + uy * uy + uz * uz) * (wx * wx + wy * wy + wz * wz)


@njit(cache=True)
def _meets_box(points, faces, t, center, half):
    """Separating-axis test: may triangle ``t`` meet the box ``center`` +- ``half`` (3-tuples)?

    The plane of a needle (see :func:`_needle`) is not trusted to separate.
    """
    a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
    v = ((points[a, 0] - center[0], points[a, 1] - center[1], points[a, 2] - center[2]),
         (points[b, 0] - center[0], points[b, 1] - center[1], points[b, 2] - center[2]),
         (points[c, 0] - center[0], points[c, 1] - center[1], points[c, 2] - center[2]))
    if not _needle(points, faces, t):  # the triangle's plane
        ux, uy, uz = v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]
        wx, wy, wz = v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        if abs(nx * v[0][0] + ny * v[0][1] + nz * v[0][2]) > half[0] * abs(nx) + half[1] * abs(ny) + half[2] * abs(nz):
            return False
    for m in range(3):  # the nine cross products of a triangle edge and a box axis
        e = (v[(m + 1) % 3][0] - v[m][0], v[(m + 1) % 3][1] - v[m][1], v[(m + 1) % 3][2] - v[m][2])
        for k in range(3):
            i, j = (k + 1) % 3, (k + 2) % 3  # axis k x e has components -e[j] along i and e[i] along j
            p0 = e[i] * v[0][j] - e[j] * v[0][i]
            p1 = e[i] * v[1][j] - e[j] * v[1][i]
            p2 = e[i] * v[2][j] - e[j] * v[2][i]
            r = half[i] * abs(e[j]) + half[j] * abs(e[i])
            if min(p0, min(p1, p2)) > r or max(p0, max(p1, p2)) < -r:
                return False
    return True


@njit(cache=True)
def overlap_grid(points, faces, lo, size, dims, margin):
    """Bucket grid of the triangles that meet each bucket (not just their bounding boxes).

    Parameters
    ----------
    points : (m, 3) float64
    faces : (k, 3) int64
    lo : (3,) float64
        Lower corner of the grid.
    size : (3,) float64
        Bucket edge along each axis: bucket (i, j, l) is the box from
        ``lo + size * (i, j, l)`` to ``lo + size * (i + 1, j + 1, l + 1)``.
    dims : (3,) int64
        Buckets along x, y, z; they must cover the mesh.
    margin : float
        The buckets are grown by this much on every side, so a triangle
        that touches a bucket is listed despite rounding.

    Returns
    -------
    start : (n_buckets + 1,) int64
        CSR offsets into ``items``, buckets x-fastest.
    items : int64 array
        Triangles of each bucket, in increasing order.
    """
    half = (0.5 * size[0] + margin, 0.5 * size[1] + margin, 0.5 * size[2] + margin)
    cap = 4 * faces.shape[0] + 16
    bucket = np.empty(cap, np.int64)
    tri = np.empty(cap, np.int64)
    n = 0
    rng = np.empty((3, 2), np.int64)
    for t in range(faces.shape[0]):
        for a in range(3):
            tmin = min(points[faces[t, 0], a], min(points[faces[t, 1], a], points[faces[t, 2], a]))
            tmax = max(points[faces[t, 0], a], max(points[faces[t, 1], a], points[faces[t, 2], a]))
            rng[a, 0] = min(max(int((tmin - margin - lo[a]) / size[a]), 0), dims[a] - 1)
            rng[a, 1] = min(max(int((tmax + margin - lo[a]) / size[a]), 0), dims[a] - 1)
        for k in range(rng[2, 0], rng[2, 1] + 1):
            for j in range(rng[1, 0], rng[1, 1] + 1):
                for i in range(rng[0, 0], rng[0, 1] + 1):
                    center = (lo[0] + (i + 0.5) * size[0], lo[1] + (j + 0.5) * size[1], lo[2] + (k + 0.5) * size[2])
                    if not _meets_box(points, faces, t, center, half):
                        continue
                    if n == cap:
                        cap *= 2
                        bucket = np.concatenate((bucket, np.empty(n, np.int64)))
                        tri = np.concatenate((tri, np.empty(n, np.int64)))
                    bucket[n] = i + dims[0] * (j + dims[1] * k)
                    tri[n] = t
                    n += 1
    start = np.zeros(dims[0] * dims[1] * dims[2] + 1, np.int64)
    for q in range(n):
        start[bucket[q] + 1] += 1
    start = np.cumsum(start)
    fill = start[:-1].copy()
    items = np.empty(n, np.int64)
    for q in range(n):  # in triangle order, so every bucket's list is sorted
        items[fill[bucket[q]]] = tri[q]
        fill[bucket[q]] += 1
    return start, items


@njit(cache=True, inline="always")
def _edge_claims(ax, ay, bx, by, px, py):
    """Orientation of p against edge a->b, with ties broken by the top-left rule (CCW triangle).

    The orientation is exact, so the two triangles of an edge always see p on opposite sides of it (a float
    determinant can put p outside both when the ray passes through the edge).
    """
    w = orient2d(ax, ay, bx, by, px, py)
    if w != 0.0:
        return w > 0.0
    return (by < ay) or (by == ay and bx > ax)


@njit(cache=True)
def point_inside(p, points, faces, lo, size, dims, start2, items2):
    """True when ``p`` is inside the closed mesh (parity of the +z ray's crossings)."""
    return ray_winding(p, points, faces, lo, size, dims, start2, items2, -1, np.zeros(0, np.int64), -1) % 2 != 0


@njit(cache=True, inline="always")
def _ray_crossing(p, points, faces, t):
    """+1 when the +z ray from ``p`` crosses triangle ``t`` above ``p`` and the triangle faces up, -1 when it faces
    down, 0 when the ray misses it (claims on shared edges as in :func:`point_inside`)."""
    a, bb, c = faces[t, 0], faces[t, 1], faces[t, 2]
    ax, ay, az = points[a, 0], points[a, 1], points[a, 2]
    bx, by, bz = points[bb, 0], points[bb, 1], points[bb, 2]
    cx, cy, cz = points[c, 0], points[c, 1], points[c, 2]
    area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    if area == 0.0:
        return 0
    up = area > 0.0
    if not up:  # seen from below: walk it the other way
        bx, by, bz, cx, cy, cz = cx, cy, cz, bx, by, bz
        area = -area
    if not (_edge_claims(ax, ay, bx, by, p[0], p[1]) and _edge_claims(bx, by, cx, cy, p[0], p[1])
            and _edge_claims(cx, cy, ax, ay, p[0], p[1])):
        return 0
    wa = (bx - p[0]) * (cy - p[1]) - (by - p[1]) * (cx - p[0])  # barycentric weights times area
    wb = (cx - p[0]) * (ay - p[1]) - (cy - p[1]) * (ax - p[0])
    z = (wa * az + wb * bz + (area - wa - wb) * cz) / area
    if z > p[2]:
        return 1 if up else -1
    return 0


@njit(cache=True, inline="always")
def _column(p, lo, size, dims):
    """Column of the (x, y) grid that holds ``p``, -1 outside the grid."""
    i = int((p[0] - lo[0]) / size)
    j = int((p[1] - lo[1]) / size)
    if i < 0 or j < 0 or i >= dims[0] or j >= dims[1] or p[0] < lo[0] or p[1] < lo[1]:
        return -1
    return i + dims[0] * j


@njit(cache=True)
def ray_winding(p, points, faces, lo, size, dims, start2, items2, skip, face_group, group):
    """Winding number at ``p`` of the faces of ``group`` (all when ``group`` < 0), by the +z ray.

    Every triangle the ray crosses above ``p`` counts +1 when it faces up
    and -1 when it faces down (claims on shared edges as in
    :func:`point_inside`), which sums to the winding number of closed
    surfaces. Face ``skip`` is left out: at a point on that face this gives
    the winding number just in front of it when it faces up, just behind it
    when it faces down. ``face_group`` (n_faces,) holds each face's group.
    """
    b = _column(p, lo, size, dims)
    if b < 0:
        return 0
    total = 0
    for q in range(start2[b], start2[b + 1]):
        t = items2[q]
        if t == skip or (group >= 0 and face_group[t] != group):
            continue
        total += _ray_crossing(p, points, faces, t)
    return total


@njit(cache=True)
def ray_winding_without(p, points, faces, lo, size, dims, start2, items2, source, left_out, face_group, group):
    """:func:`ray_winding` leaving out every face whose ``source`` (n_faces,) is one of ``left_out`` (small, any
    order) instead of a single face: at a point where several faces lie on top of each other (all of
    ``left_out``), the winding number on the side of the ray without any of them."""
    b = _column(p, lo, size, dims)
    if b < 0:
        return 0
    total = 0
    for q in range(start2[b], start2[b + 1]):
        t = items2[q]
        if group >= 0 and face_group[t] != group:
            continue
        skipped = False
        for s in range(left_out.shape[0]):
            if source[t] == left_out[s]:
                skipped = True
        if not skipped:
            total += _ray_crossing(p, points, faces, t)
    return total


@njit(cache=True)
def box_triangles(lo_box, hi_box, points, faces, lo, size, dims, start, items):
    """Sorted indices of the triangles whose bounding box meets the box [lo_box, hi_box]."""
    found = np.unique(box_items(lo_box, hi_box, lo, size, dims, start, items, False))
    keep = np.ones(found.size, np.bool_)
    for q in range(found.size):
        t = found[q]
        for a in range(3):
            tmin = min(points[faces[t, 0], a], min(points[faces[t, 1], a], points[faces[t, 2], a]))
            tmax = max(points[faces[t, 0], a], max(points[faces[t, 1], a], points[faces[t, 2], a]))
            if tmax < lo_box[a] or tmin > hi_box[a]:
                keep[q] = False
    return found[keep]


@njit(cache=True)
def segment_crossings(u, w, tris, points, faces, normals, out):
    """Parameters in (0, 1) where segment u->w (3-tuples) crosses the triangles ``tris``.

    They are written sorted into ``out`` (at least ``tris.size`` long); returns their number.
    """
    n = 0
    for q in range(tris.size):
        t = tris[q]
        a = faces[t, 0]
        nx, ny, nz = normals[t, 0], normals[t, 1], normals[t, 2]
        su = nx * (u[0] - points[a, 0]) + ny * (u[1] - points[a, 1]) + nz * (u[2] - points[a, 2])
        sw = nx * (w[0] - points[a, 0]) + ny * (w[1] - points[a, 1]) + nz * (w[2] - points[a, 2])
        if (su <= 0.0) == (sw <= 0.0):
            continue
        s = su / (su - sw)
        x0, x1, x2 = u[0] + s * (w[0] - u[0]), u[1] + s * (w[1] - u[1]), u[2] + s * (w[2] - u[2])
        ok = True
        for m in range(3):
            i, j = faces[t, m], faces[t, (m + 1) % 3]
            ex, ey, ez = points[j, 0] - points[i, 0], points[j, 1] - points[i, 1], points[j, 2] - points[i, 2]
            rx, ry, rz = x0 - points[i, 0], x1 - points[i, 1], x2 - points[i, 2]
            if (ey * rz - ez * ry) * nx + (ez * rx - ex * rz) * ny + (ex * ry - ey * rx) * nz < 0.0:
                ok = False
                break
        if ok:
            k = n  # insertion sort: a segment crosses few triangles
            while k > 0 and out[k - 1] > s:
                out[k] = out[k - 1]
                k -= 1
            out[k] = s
            n += 1
    return n
