"""Overhangs: vertices of a triangle mesh with more of the mesh straight above them.

A vertex overhangs when a vertical ray going up (+z) from it meets a face
that is not incident to it; a height field z(x, y) cannot represent such a
vertex. The faces are listed in a uniform 2-D (x, y) bucket grid by their
bounding boxes, highest first, so every ray only visits the faces of one
bucket that reach above its start.

Grazing rays are decided by nudging: the ray starts a tiny ``eps`` above the
vertex, and a vertex whose (area-weighted) normal has a horizontal part
casts two rays, shifted a tiny ``shift`` to either side along that part; it
overhangs only when both rays meet a face. So a vertex on a vertical wall,
whose ray runs along the wall and touches the rim at its top, does not
overhang (the ray on the air side sees nothing), while a vertex under a cap
does (both see the cap), whichever way the faces are oriented. The nudges
are 1e-9 (``eps``) and 1e-8 (``shift``) of the mesh's bounding-box diagonal;
a ray that misses a face's (x, y) shadow by less than 1e-12 of the diagonal
still meets the face, so rays through shared edges and vertices are not lost
to rounding.
"""

from __future__ import annotations

import math

import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels.spatial.grid import bucket_boxes
from pverosion.kernels.tolerances import RAY_SHADOW, RAY_SHIFT, RAY_START
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["overhanging_vertices"]




_MAX_BUCKETS = 1024
"""Largest number of buckets along x or y."""


@njit(cache=True, error_model="numpy")
def _grid(points, faces, lo, extent):
    """Bucket grid of the faces' (x, y) bounding boxes, each bucket's faces sorted by falling top height.

    Returns the bucket edge, the buckets along x and y (3,) (the third is 1),
    the CSR arrays (start, items) and every face's top height.
    """
    n = faces.shape[0]
    box = np.empty((n, 4))
    top = np.empty(n)
    mean = 0.0
    for t in range(n):
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        box[t, 0] = min(points[a, 0], points[b, 0], points[c, 0])
        box[t, 1] = min(points[a, 1], points[b, 1], points[c, 1])
        box[t, 2] = max(points[a, 0], points[b, 0], points[c, 0])
        box[t, 3] = max(points[a, 1], points[b, 1], points[c, 1])
        top[t] = max(points[a, 2], points[b, 2], points[c, 2])
        mean += box[t, 2] - box[t, 0] + box[t, 3] - box[t, 1]
    size = max(mean / max(n, 1), max(extent[0], extent[1]) / _MAX_BUCKETS, 1e-300)  # twice the mean box side
    dims = np.ones(3, np.int64)
    for d in range(2):
        dims[d] = max(math.ceil(extent[d] / size), 1)
    blo = np.zeros((n, 3), np.int64)
    bhi = np.zeros((n, 3), np.int64)
    for t in range(n):
        for d in range(2):
            blo[t, d] = min(max(int((box[t, d] - lo[d]) / size), 0), dims[d] - 1)
            bhi[t, d] = min(max(int((box[t, d + 2] - lo[d]) / size), 0), dims[d] - 1)
    start, items = bucket_boxes(blo, bhi, dims)
    for b in range(dims[0] * dims[1]):
        chunk = items[start[b]:start[b + 1]]
        items[start[b]:start[b + 1]] = chunk[np.argsort(-top[chunk])]
    return size, dims, start, items, top


@njit(cache=True, error_model="numpy")
def _meets_above(points, faces, v, px, py, z0, tol, lo, size, dims, start, items, top):
    """Whether the ray up from (px, py, z0) meets a face not incident to vertex ``v`` above z0."""
    # clamped: a ray outside the grid finds no face in the border bucket's list either
    i = min(max(math.floor((px - lo[0]) / size), 0), dims[0] - 1)
    j = min(max(math.floor((py - lo[1]) / size), 0), dims[1] - 1)
    b = i + dims[0] * j
    for q in range(start[b], start[b + 1]):
        t = items[q]
        if top[t] <= z0:
            break  # this face and all after it lie below the ray's start
        a, bb, c = faces[t, 0], faces[t, 1], faces[t, 2]
        if a == v or bb == v or c == v:
            continue
        ax, ay = points[a, 0], points[a, 1]
        bx, by = points[bb, 0], points[bb, 1]
        cx, cy = points[c, 0], points[c, 1]
        if (px < min(ax, bx, cx) - tol or px > max(ax, bx, cx) + tol
                or py < min(ay, by, cy) - tol or py > max(ay, by, cy) + tol):
            continue
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)  # twice the signed area of the shadow
        if area == 0.0:
            continue  # a vertical face: its shadow is a segment
        az, bz, cz = points[a, 2], points[bb, 2], points[c, 2]
        if area < 0.0:  # seen from below: walk it the other way
            bx, by, bz, cx, cy, cz = cx, cy, cz, bx, by, bz
            area = -area
        wa = (cx - bx) * (py - by) - (cy - by) * (px - bx)  # barycentric weights times ``area``
        wb = (ax - cx) * (py - cy) - (ay - cy) * (px - cx)
        wc = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
        # outside by more than ``tol`` beyond an edge (weight = edge length x distance)
        if ((wa < 0.0 and wa * wa > tol * tol * ((cx - bx) ** 2 + (cy - by) ** 2))
                or (wb < 0.0 and wb * wb > tol * tol * ((ax - cx) ** 2 + (ay - cy) ** 2))
                or (wc < 0.0 and wc * wc > tol * tol * ((bx - ax) ** 2 + (by - ay) ** 2))):
            continue
        wa, wb, wc = max(wa, 0.0), max(wb, 0.0), max(wc, 0.0)  # their sum stays >= area > 0
        if (wa * az + wb * bz + wc * cz) / (wa + wb + wc) > z0:
            return True
    return False


@njit(cache=True, error_model="numpy")
def _horizontal_normals(points, faces):
    """(x, y) parts (V, 2) of the area-weighted vertex normals (unnormalised)."""
    out = np.zeros((points.shape[0], 2))
    for t in range(faces.shape[0]):
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
        wx, wy, wz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
        nx, ny = uy * wz - uz * wy, uz * wx - ux * wz
        for v in (a, b, c):
            out[v, 0] += nx
            out[v, 1] += ny
    return out


@njit(cache=True, error_model="numpy")
def _overhanging(points, faces, normals, mask, eps, shift, tol, lo, size, dims, start, items, top):
    out = np.zeros(points.shape[0], np.bool_)
    for v in range(points.shape[0]):
        if not mask[v]:
            continue
        px, py, z0 = points[v, 0], points[v, 1], points[v, 2] + eps
        horizontal = math.hypot(normals[v, 0], normals[v, 1])
        if horizontal == 0.0:
            out[v] = _meets_above(points, faces, v, px, py, z0, tol, lo, size, dims, start, items, top)
            continue
        dx = shift * normals[v, 0] / horizontal
        dy = shift * normals[v, 1] / horizontal
        out[v] = (_meets_above(points, faces, v, px + dx, py + dy, z0, tol, lo, size, dims, start, items, top)
                  and _meets_above(points, faces, v, px - dx, py - dy, z0, tol, lo, size, dims, start, items, top))
    return out


def overhanging_vertices(points, faces, *, mask=None) -> np.ndarray:
    """Vertices with a face of the mesh straight above them (which a height field cannot represent).

    A vertex is flagged when the vertical ray going up (+z) from it meets a
    face that is not incident to it. The ray starts a tiny epsilon above the
    vertex, and grazing rays are decided by nudging them a hair to both sides
    of the vertex, horizontally along its normal: the vertex is flagged only
    when both nudged rays meet a face (see the module notes). So vertices on
    vertical walls are not flagged, nor are the rims at their tops. On a
    closed solid every vertex with the solid above it is flagged, the bottom
    of a terrain block included: pass ``mask`` to test only the surface of
    interest.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        Triangles; their orientation does not matter.
    mask : array_like of bool, shape (V,), optional
        Test only these vertices (the others are returned False); default all.

    Returns
    -------
    numpy.ndarray, shape (V,), bool

    Raises
    ------
    ValueError
        An invalid mesh (:class:`~pverosion.kernels.validation.InvalidMeshError`)
        or a mask of the wrong shape.
    """
    pts, fcs = as_triangle_mesh(points, faces)
    if mask is None:
        test = np.ones(len(pts), bool)
    else:
        test = np.asarray(mask)
        if test.shape != (len(pts),) or test.dtype != np.bool_:
            raise ValueError(f"mask must be a boolean array of shape ({len(pts)},); got {test.dtype} {test.shape}")
    lo = pts[:, :2].min(axis=0)
    extent = pts[:, :2].max(axis=0) - lo
    diagonal = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    size, dims, start, items, top = _grid(pts, fcs, lo, extent)
    normals = _horizontal_normals(pts, fcs)
    return _overhanging(pts, fcs, normals, test, RAY_START * diagonal, RAY_SHIFT * diagonal, RAY_SHADOW * diagonal, lo, size,
                        dims, start, items, top)
