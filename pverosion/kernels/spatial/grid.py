"""Uniform bucket grids: the one structure behind the spatial queries of the mesh stages.

A grid has a lower corner ``lo``, a bucket edge ``size`` and ``dims`` buckets along x, y, z
(x fastest).  Its contents are CSR arrays ``start`` (buckets + 1,) and ``items``: points bucketed
by :func:`bucket_points`, boxes (triangles, cells) by :func:`bucket_boxes`; :func:`box_items`
lists what the buckets under a query box hold.  Users: triangle indices and ray tests
(:mod:`~pverosion.kernels.spatial.mesh_query`), overhangs, repair, Voronoi seeds and shard clipping,
the vertices near hydraulic particles.  Two grids stay their own, for speed: the hashed,
Morton-ordered face grid of the intersection detector, and the particle fluid's grids rebuilt in
parallel every substep.
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels._jit import njit

__all__ = ["box_items", "bucket_boxes", "bucket_points", "grid_over"]


def grid_over(lo: np.ndarray, hi: np.ndarray, size: float) -> np.ndarray:
    """Bucket counts ``dims`` (3,) int64 of a grid of edge ``size`` from ``lo`` that covers ``hi`` (at least 1 each)."""
    return np.maximum(np.ceil((np.asarray(hi) - np.asarray(lo)) / size).astype(np.int64), 1)


@njit(cache=True)
def bucket_points(pos, lo, size, dims):
    """Counting sort of the points ``pos`` (N, 3) into the cells of a grid (x fastest; points beyond it go to its
    edge cells): CSR ``start`` (cells + 1,) and ``order`` (N,), points in index order within a cell."""
    n = pos.shape[0]
    n_cells = dims[0] * dims[1] * dims[2]
    cell = np.empty(n, np.int64)
    start = np.zeros(n_cells + 1, np.int64)
    for i in range(n):
        ix = min(max(int((pos[i, 0] - lo[0]) / size), 0), dims[0] - 1)
        iy = min(max(int((pos[i, 1] - lo[1]) / size), 0), dims[1] - 1)
        iz = min(max(int((pos[i, 2] - lo[2]) / size), 0), dims[2] - 1)
        cell[i] = ix + dims[0] * (iy + dims[1] * iz)
        start[cell[i] + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return start, order


@njit(cache=True)
def bucket_boxes(tlo, thi, dims):
    """CSR (offsets, items) of the items whose cell boxes ``tlo``..``thi`` (N, 3) meet each cell of a grid of
    ``dims`` cells (x fastest), items in index order within a cell."""
    counts = np.zeros(dims[0] * dims[1] * dims[2] + 1, np.int64)
    for t in range(tlo.shape[0]):
        for k in range(tlo[t, 2], thi[t, 2] + 1):
            for j in range(tlo[t, 1], thi[t, 1] + 1):
                for i in range(tlo[t, 0], thi[t, 0] + 1):
                    counts[1 + i + dims[0] * (j + dims[1] * k)] += 1
    start = np.cumsum(counts)
    fill = start[:-1].copy()
    items = np.empty(start[-1], np.int64)
    for t in range(tlo.shape[0]):
        for k in range(tlo[t, 2], thi[t, 2] + 1):
            for j in range(tlo[t, 1], thi[t, 1] + 1):
                for i in range(tlo[t, 0], thi[t, 0] + 1):
                    b = i + dims[0] * (j + dims[1] * k)
                    items[fill[b]] = t
                    fill[b] += 1
    return start, items


@njit(cache=True)
def box_items(lo_box, hi_box, lo, size, dims, start, items, clamp):
    """Items (unsorted, repeated where they fill several cells) in the cells of a :func:`bucket_boxes` grid that
    the box [lo_box, hi_box] meets; the grid starts at ``lo`` with cells of edge ``size``.

    With ``clamp``, a box beyond the grid takes the cells at its edge (the grid's last cells hold what lies
    beyond it too); without, it meets no cell.
    """
    top = 0 if clamp else -1
    i0 = min(max(int((lo_box[0] - lo[0]) / size), 0), dims[0] - 1 if clamp else dims[0])
    j0 = min(max(int((lo_box[1] - lo[1]) / size), 0), dims[1] - 1 if clamp else dims[1])
    k0 = min(max(int((lo_box[2] - lo[2]) / size), 0), dims[2] - 1 if clamp else dims[2])
    i1 = min(max(int((hi_box[0] - lo[0]) / size), top), dims[0] - 1)
    j1 = min(max(int((hi_box[1] - lo[1]) / size), top), dims[1] - 1)
    k1 = min(max(int((hi_box[2] - lo[2]) / size), top), dims[2] - 1)
    n = 0
    for k in range(k0, k1 + 1):
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                b = i + dims[0] * (j + dims[1] * k)
                n += start[b + 1] - start[b]
    found = np.empty(n, np.int64)
    n = 0
    for k in range(k0, k1 + 1):
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                b = i + dims[0] * (j + dims[1] * k)
                for q in range(start[b], start[b + 1]):
                    found[n] = items[q]
                    n += 1
    return found
