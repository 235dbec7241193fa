"""Hashed uniform grids of the particle fluid: particle neighbour lists and the mesh's face grid.

Part of :mod:`pverosion.kernels.fluid.particle_fluid` (its docstring describes the method).
"""

from __future__ import annotations

import numpy as np
from numba import prange

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels._scatter import CHUNKS, chunk_range
from pverosion.kernels.fluid.params import _CELL_CHUNK, _LIMIT, _MARGIN, _MESH_CELL, _MESH_CELLS, _PAIRS, _SPHERE_GROWTH

__all__: list[str] = []


@njit(cache=True, inline="always")
def _corner(data, f, m):
    return (data[f, 3 * m], data[f, 3 * m + 1], data[f, 3 * m + 2])

# --- grids -----------------------------------------------------------------------------------------------------


@njit(cache=True)
def _cell(x, lo, size):
    """Grid coordinate of ``x`` along one axis, clamped to +-_LIMIT."""
    return int(np.floor(min(max((x - lo) / size, -_LIMIT), _LIMIT)))


@njit(cache=True)
def _table_size(n):
    """Power of two >= n (at least 64)."""
    t = 64
    while t < n:
        t *= 2
    return t


@njit(cache=True)
def _particle_grid(pos, lo, size):
    """Counting sort of points into hashed cells of edge ``size``.

    Returns
    -------
    order : (N,) int64
        Points in bucket order, the cells of a bucket in order of their
        linear index (each cell's points contiguous, in increasing index).
    start : (T + 1,) int64
        CSR offsets of the T buckets into the sorted points.
    keys : (N,) int64
        Linear cell index of every sorted point (to tell apart cells sharing a bucket).
    cells : (N, 3) int64
        Cell coordinates of every sorted point, relative to the lowest cell.
    dims : (3,) int64
        Cells along each axis of the box of occupied cells.
    runs : (M + 1,) int64
        Offsets of the M occupied cells into the sorted points.
    """
    n = pos.shape[0]
    cell = np.empty((n, 3), np.int64)
    cmin = np.full(3, _LIMIT, np.int64)
    cmax = np.full(3, -_LIMIT, np.int64)
    for i in range(n):
        for a in range(3):
            c = _cell(pos[i, a], lo[a], size)
            cell[i, a] = c
            cmin[a] = min(cmin[a], c)
            cmax[a] = max(cmax[a], c)
    dims = np.maximum(cmax - cmin + 1, 1)
    table = _table_size(2 * n)
    mask = table - 1
    key = np.empty(n, np.int64)
    start = np.zeros(table + 1, np.int64)
    for i in range(n):
        for a in range(3):
            cell[i, a] -= cmin[a]
        key[i] = cell[i, 0] + dims[0] * (cell[i, 1] + dims[1] * cell[i, 2])
        start[(key[i] & mask) + 1] += 1
    for b in range(table):
        start[b + 1] += start[b]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        b = key[i] & mask
        order[fill[b]] = i
        fill[b] += 1
    for b in range(table):  # cells sharing a bucket: stable insertion sort by cell (buckets are small)
        for q in range(start[b] + 1, start[b + 1]):
            item = order[q]
            p = q - 1
            while p >= start[b] and key[order[p]] > key[item]:
                order[p + 1] = order[p]
                p -= 1
            order[p + 1] = item
    keys = key[order]
    runs = np.empty(n + 1, np.int64)
    m = 0
    for q in range(n):
        if q == 0 or keys[q] != keys[q - 1]:
            runs[m] = q
            m += 1
    runs[m] = n
    return order, start, keys, cell[order], dims, runs[:m + 1]


@njit(cache=True, inline="always")
def _row(i0, i1, base, mask, start):
    """Sorted ranges (two when the buckets wrap) and key bounds of cells i0..i1 of the row at key ``base``."""
    k0 = base + i0
    k1 = base + i1
    b0 = k0 & mask
    b1 = k1 & mask
    if b0 <= b1:
        return k0, k1, start[b0], start[b1 + 1], 0, 0
    return k0, k1, start[b0], start[mask + 1], start[0], start[b1 + 1]


@njit(cache=True, inline="always")
def _around(cells, dims, s):
    """Cell ranges (i0, i1, j0, j1, k0, k1) of the 27 cells around the cell of sorted point ``s``."""
    return (max(cells[s, 0] - 1, 0), min(cells[s, 0] + 1, dims[0] - 1), max(cells[s, 1] - 1, 0),
            min(cells[s, 1] + 1, dims[1] - 1), max(cells[s, 2] - 1, 0), min(cells[s, 2] + 1, dims[2] - 1))


@njit(cache=True)
def _candidates(start, cells, dims, s, mask):
    """Upper bound of the points in the 27 cells around the cell of sorted point ``s`` (whole buckets)."""
    i0, i1, j0, j1, k0, k1 = _around(cells, dims, s)
    total = 0
    for ck in range(k0, k1 + 1):
        for cj in range(j0, j1 + 1):
            _, _, a0, a1, w0, w1 = _row(i0, i1, dims[0] * (cj + dims[1] * ck), mask, start)
            total += a1 - a0 + w1 - w0
    return total


@njit(cache=True, fastmath=_PAIRS)
def _cell_lists(pos, grid, s0, s1, h2, nbr, count, bx, by, bz, d2, bj, kept):
    """Neighbour lists of the points of one cell (sorted points s0..s1), with buffers of :func:`_candidates` size.

    The points of the 27 cells around are copied into the buffers; every
    point of the cell keeps those within h, in buffer order. The compaction
    is branch-free: in a moving fluid, "within h" is a coin toss for the
    branch predictor.
    """
    order, start, keys, cells, dims, _ = grid
    mask = start.shape[0] - 2
    last = nbr.shape[1] - 1
    i0, i1, j0, j1, k0, k1 = _around(cells, dims, s0)
    m = 0
    for ck in range(k0, k1 + 1):
        for cj in range(j0, j1 + 1):
            key0, key1, a0, a1, w0, w1 = _row(i0, i1, dims[0] * (cj + dims[1] * ck), mask, start)
            for part in range(2):
                lo_q, hi_q = (a0, a1) if part == 0 else (w0, w1)
                for q in range(lo_q, hi_q):
                    if key0 <= keys[q] <= key1:
                        j = order[q]
                        bx[m], by[m], bz[m] = pos[j, 0], pos[j, 1], pos[j, 2]
                        bj[m] = j
                        m += 1
    for s in range(s0, s1):
        i = order[s]
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        for b in range(m):
            dx, dy, dz = px - bx[b], py - by[b], pz - bz[b]
            d2[b] = dx * dx + dy * dy + dz * dz
        n = 0
        for b in range(m):
            kept[n] = bj[b]
            n += (d2[b] < h2) & (bj[b] != i)
        for q in range(min(n, last + 1)):
            nbr[i, q] = kept[q]
        count[i] = n


@njit(cache=True, parallel=True)
def _neighbour_lists(pos, grid, h, nbr, count):
    """Neighbours closer than h of every point (itself excluded), up to nbr.shape[1] each; count gets all.

    ``grid`` is :func:`_particle_grid` of the points with cell edge h. The
    occupied cells go in chunks of :data:`_CELL_CHUNK` to the threads, each
    chunk with buffers as large as its largest cell needs.
    """
    start, cells, dims, runs = grid[1], grid[3], grid[4], grid[5]
    mask = start.shape[0] - 2
    n_cells = runs.shape[0] - 1
    for c in prange((n_cells + _CELL_CHUNK - 1) // _CELL_CHUNK):
        r0, r1 = c * _CELL_CHUNK, min((c + 1) * _CELL_CHUNK, n_cells)
        size = 0
        for r in range(r0, r1):
            size = max(size, _candidates(start, cells, dims, runs[r], mask))
        bx, by, bz, d2 = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
        bj, kept = np.empty(size, np.int32), np.empty(size, np.int32)
        for r in range(r0, r1):
            _cell_lists(pos, grid, runs[r], runs[r + 1], h * h, nbr, count, bx, by, bz, d2, bj, kept)


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _density_sum(pos, nbr, count, h, k6, inv_rho0, out):
    """rho / rho0 of every point from its neighbour list (fluid only)."""
    h2 = h * h
    for i in prange(pos.shape[0]):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        rho = k6 * h2 * h2 * h2
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = px - pos[j, 0], py - pos[j, 1], pz - pos[j, 2]
            q = max(h2 - dx * dx - dy * dy - dz * dz, 0.0)
            rho += k6 * q * q * q
        out[i] = rho * inv_rho0


@njit(cache=True, inline="always")
def _store_face(points, faces, f, data):
    """Row ``f`` of :func:`_face_data`."""
    a, b, c = v3.row(points, faces[f, 0]), v3.row(points, faces[f, 1]), v3.row(points, faces[f, 2])
    n = v3.cross(v3.sub(b, a), v3.sub(c, a))
    length = v3.norm(n)
    n = v3.scale(n, 1.0 / length) if length > 0.0 else (0.0, 0.0, 0.0)
    for m in range(3):
        data[f, m] = a[m]
        data[f, 3 + m] = b[m]
        data[f, 6 + m] = c[m]
        data[f, 9 + m] = n[m]


@njit(cache=True, parallel=True)
def _face_data(points, faces):
    """Vertices a, b, c and unit normal n (right-hand rule, zero if degenerate) of every face: (F, 12)."""
    data = np.empty((faces.shape[0], 12))
    for f in prange(faces.shape[0]):
        _store_face(points, faces, f, data)
    return data


@njit(cache=True, parallel=True)
def _face_cells(data, lo, size, dims, margin):
    """Cell range (F, 6) of every face's bounding box grown by ``margin`` and its number of cells (F,)."""
    n = data.shape[0]
    box = np.empty((n, 6), np.int64)
    cnt = np.empty(n, np.int64)
    for f in prange(n):
        total = 1
        for a in range(3):
            x0, x1, x2 = data[f, a], data[f, 3 + a], data[f, 6 + a]
            c0 = min(max(int(np.floor((min(x0, min(x1, x2)) - margin - lo[a]) / size)), 0), dims[a] - 1)
            c1 = min(max(int(np.floor((max(x0, max(x1, x2)) + margin - lo[a]) / size)), 0), dims[a] - 1)
            box[f, a] = c0
            box[f, a + 3] = c1
            total *= c1 - c0 + 1
        cnt[f] = total
    return box, cnt


@njit(cache=True, parallel=True)
def _face_entries(box, offset, dims, mask, bucket, key, face, first):
    """Bucket, linear cell index, face and packed lowest cell of the face's box for every (face, cell) pair."""
    for f in prange(box.shape[0]):
        q = offset[f]
        low = box[f, 0] | (box[f, 1] << 21) | (box[f, 2] << 42)
        for k in range(box[f, 2], box[f, 5] + 1):
            for j in range(box[f, 1], box[f, 4] + 1):
                for i in range(box[f, 0], box[f, 3] + 1):
                    key[q] = i + dims[0] * (j + dims[1] * k)
                    bucket[q] = key[q] & mask
                    face[q] = f
                    first[q] = low
                    q += 1


@njit(cache=True, parallel=True)
def _bucket_sort(bucket, key, face, first, table):
    """Stable counting sort of the entries by bucket: (start (T + 1,), keys, faces, firsts).

    The entries are split in CHUNKS fixed chunks, counted and placed in parallel.
    """
    n = bucket.shape[0]
    counts = np.zeros((CHUNKS, table), np.int64)
    for c in prange(CHUNKS):
        lo, hi = chunk_range(n, c)
        for q in range(lo, hi):
            counts[c, bucket[q]] += 1
    start = np.zeros(table + 1, np.int64)
    for b in range(table):  # counts become each chunk's first slot in the bucket
        total = start[b]
        for c in range(CHUNKS):
            count = counts[c, b]
            counts[c, b] = total
            total += count
        start[b + 1] = total
    keys = np.empty(n, np.int64)
    items = np.empty(n, np.int64)
    firsts = np.empty(n, np.int64)
    for c in prange(CHUNKS):
        lo, hi = chunk_range(n, c)
        for q in range(lo, hi):
            b = bucket[q]
            slot = counts[c, b]
            keys[slot] = key[q]
            items[slot] = face[q]
            firsts[slot] = first[q]
            counts[c, b] = slot + 1
    return start, keys, items, firsts


@njit(cache=True, inline="always")
def _face_sphere(data, f):
    """Bounding sphere (x, y, z, radius) of face ``f``, grown by :data:`_SPHERE_GROWTH` for rounding."""
    c = v3.scale(v3.add(v3.add(_corner(data, f, 0), _corner(data, f, 1)), _corner(data, f, 2)), 1.0 / 3.0)
    radius = 0.0
    for m in range(3):
        radius = max(radius, v3.norm(v3.sub(_corner(data, f, m), c)))
    return c[0], c[1], c[2], radius + _SPHERE_GROWTH * (radius + abs(c[0]) + abs(c[1]) + abs(c[2]))


@njit(cache=True, parallel=True)
def _entry_spheres(data, items):
    """Bounding sphere (centre, radius) of the face of every grid entry, in entry order, and where each face's
    entries are: (E, 4) spheres and the CSR (F + 1,), (E,) of the entries of every face.

    The collision queries test the spheres before touching a face, reading
    them in the order they scan the entries.
    """
    n_faces = data.shape[0]
    first = np.zeros(n_faces + 1, np.int64)
    for q in range(items.shape[0]):
        first[items[q] + 1] += 1
    for f in range(n_faces):
        first[f + 1] += first[f]
    fill = first[:-1].copy()
    entries = np.empty(items.shape[0], np.int64)
    for q in range(items.shape[0]):
        entries[fill[items[q]]] = q
        fill[items[q]] += 1
    out = np.empty((items.shape[0], 4))
    for f in prange(n_faces):
        sphere = _face_sphere(data, f)
        for q in range(first[f], first[f + 1]):
            for m in range(4):
                out[entries[q], m] = sphere[m]
    return out, first, entries


@njit(cache=True, parallel=True)
def _face_moves(points, before, faces):
    """Largest coordinate change of the vertices of every face (F,) from ``before`` to ``points``, and of any point."""
    moved = np.empty(points.shape[0])
    for i in prange(points.shape[0]):
        moved[i] = max(abs(points[i, 0] - before[i, 0]), abs(points[i, 1] - before[i, 1]),
                       abs(points[i, 2] - before[i, 2]))
    out = np.empty(faces.shape[0])
    for f in prange(faces.shape[0]):
        out[f] = max(moved[faces[f, 0]], moved[faces[f, 1]], moved[faces[f, 2]])
    return out, moved.max() if points.shape[0] else 0.0


@njit(cache=True, parallel=True)
def _refit(points, faces, face_move, data, spheres, first, entries):
    """Update the face data and entry spheres of the faces that moved (``face_move > 0``), in place."""
    for f in prange(faces.shape[0]):
        if face_move[f] > 0.0:
            _store_face(points, faces, f, data)
            sphere = _face_sphere(data, f)
            for q in range(first[f], first[f + 1]):
                for m in range(4):
                    spheres[entries[q], m] = sphere[m]


@njit(cache=True)
def _bounds(points, data):
    """Lower and upper corners of ``points`` and the mean length of the faces' first edges."""
    lo = points[0].copy()
    hi = points[0].copy()
    for i in range(points.shape[0]):
        for a in range(3):
            lo[a] = min(lo[a], points[i, a])
            hi[a] = max(hi[a], points[i, a])
    total = 0.0
    for f in range(data.shape[0]):
        total += v3.norm(v3.sub(_corner(data, f, 1), _corner(data, f, 0)))
    return lo, hi, total / max(data.shape[0], 1)


@njit(cache=True, parallel=True)
def _largest_move(points, before):
    """Largest coordinate change of any point (deterministic: a maximum)."""
    moved = np.zeros(points.shape[0])
    for i in prange(points.shape[0]):
        moved[i] = max(abs(points[i, 0] - before[i, 0]), abs(points[i, 1] - before[i, 1]),
                       abs(points[i, 2] - before[i, 2]))
    return moved.max() if points.shape[0] else 0.0


def _mesh_grid(points: np.ndarray, faces: np.ndarray, radius: float) -> tuple[tuple, float, tuple]:
    """Face data and hashed bounding-box grid of a mesh, as the tuple the collision kernels take, its margin, and
    the grid entries of every face (CSR offsets (F + 1,) and entries (E,)) for refits.

    Faces are listed in the cells of their bounding boxes grown by the margin
    (:data:`_MARGIN` of a cell), so the grid stays valid while no point moves farther.
    The tuple is (face data, lower corner, cell size, cells per axis, bucket
    offsets, cell keys, faces and packed lowest cells of the entries, entry
    spheres).
    """
    data = _face_data(points, faces)
    lo, hi, edge = _bounds(points, data)
    size = max(_MESH_CELL * radius, edge, float((hi - lo).max()) / (_MESH_CELLS - 2))
    margin = _MARGIN * size
    lo = lo - margin
    dims = np.floor((hi + margin - lo) / size).astype(np.int64) + 1
    box, cnt = _face_cells(data, lo, size, dims, margin)
    offset = np.zeros(len(faces) + 1, np.int64)
    np.cumsum(cnt, out=offset[1:])
    table = int(_table_size(int(offset[-1]) // 4))
    bucket, key, face, first = (np.empty(offset[-1], np.int64) for _ in range(4))
    _face_entries(box, offset, dims, table - 1, bucket, key, face, first)
    start, keys, items, firsts = _bucket_sort(bucket, key, face, first, table)
    spheres, face_first, face_entries = _entry_spheres(data, items)
    return (data, lo, size, dims, start, keys, items, firsts, spheres), margin, (face_first, face_entries)


def _empty_grid() -> tuple:
    """The grid tuple of no mesh (same types as :func:`_mesh_grid`)."""
    return (np.zeros((0, 12)), np.zeros(3), 1.0, np.ones(3, np.int64), np.zeros(65, np.int64),
            np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)))


@njit(cache=True, inline="always")
def _cell_box(lo_box, hi_box, lo, size, dims):
    """Mesh-grid cell range (i0, j0, k0, i1, j1, k1) of the box [lo_box, hi_box]; i0 > i1 when outside."""
    i0 = max(int(np.floor((lo_box[0] - lo[0]) / size)), 0)
    j0 = max(int(np.floor((lo_box[1] - lo[1]) / size)), 0)
    k0 = max(int(np.floor((lo_box[2] - lo[2]) / size)), 0)
    i1 = min(int(np.floor((hi_box[0] - lo[0]) / size)), dims[0] - 1)
    j1 = min(int(np.floor((hi_box[1] - lo[1]) / size)), dims[1] - 1)
    k1 = min(int(np.floor((hi_box[2] - lo[2]) / size)), dims[2] - 1)
    if j0 > j1 or k0 > k1:
        i0 = i1 + 1
    return i0, j0, k0, i1, j1, k1


@njit(cache=True, inline="always")
def _first_visit(first, key, base, i0, j, k, j0, k0):
    """Whether the cell at ``key`` is the first cell of the query range the face's box meets (visit it once)."""
    return (key - base == max(i0, first & 0x1FFFFF) and j == max(j0, (first >> 21) & 0x1FFFFF)
            and k == max(k0, first >> 42))
