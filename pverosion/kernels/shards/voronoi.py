"""Voronoi cells of seed points, one convex polyhedron at a time (the voro++ approach).

Each cell starts as the bounding box and is cut by the bisector planes of
nearby seeds, found on a uniform grid in rings of growing distance, until no
remaining seed can be closer than twice the cell's farthest vertex. Cells
are independent, so they are computed in parallel and the result does not
depend on the thread count.

A cell is a list of planar faces, each a polygon whose vertices run
counter-clockwise seen from outside, with a **label** (the index of the
neighbouring seed, or a negative box-wall label) and, for every edge, the
label of the face on its other side. Crossing points on an edge are computed
from the edge's endpoints in a fixed (lexicographic) order, so the two faces
that share an edge get bit-identical points.
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels.spatial.grid import bucket_points, grid_over

__all__ = ["MAX_FACES", "MAX_FACE_VERTICES", "box_cell", "cell_polygons", "seed_grid"]

MAX_FACES = 128
MAX_FACE_VERTICES = 48
_BOX_CORNERS = np.array([  # the corners of each wall, counter-clockwise seen from outside
    [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]],
    [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]],
    [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]],
    [[0, 1, 0], [0, 1, 1], [1, 1, 1], [1, 1, 0]],
    [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]],
    [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
])


@njit(cache=True)
def box_cell(lo, hi):
    """The box [lo, hi] as a cell: faces (6, 4, 3), edge labels (6, 4), counts (6,), labels (6,).

    Wall labels: -1 (x = lo), -2 (x = hi), -3, -4 (y), -5, -6 (z).
    """
    verts = np.empty((MAX_FACES, MAX_FACE_VERTICES, 3))
    edges = np.empty((MAX_FACES, MAX_FACE_VERTICES), np.int64)
    count = np.zeros(MAX_FACES, np.int64)
    label = np.zeros(MAX_FACES, np.int64)
    corner = _BOX_CORNERS
    for f in range(6):
        label[f] = -1 - f
        count[f] = 4
        for m in range(4):
            for a in range(3):
                verts[f, m, a] = hi[a] if corner[f, m, a] == 1 else lo[a]
        for m in range(4):
            c0 = corner[f, m]
            c1 = corner[f, (m + 1) % 4]
            for a in range(3):  # the axis along which the edge is constant, other than the wall's
                if a != f // 2 and c0[a] == c1[a]:
                    edges[f, m] = -1 - (2 * a + c0[a])
    return verts, edges, count, label, 6


@njit(cache=True, inline="always")
def _crossing(u, w, su, sw):
    """Point where segment u-w meets the plane, computed from the lexicographically smaller end."""
    swap = (w[0] < u[0]) or (w[0] == u[0] and (w[1] < u[1] or (w[1] == u[1] and w[2] < u[2])))
    if swap:
        t = sw / (sw - su)
        return w[0] + t * (u[0] - w[0]), w[1] + t * (u[1] - w[1]), w[2] + t * (u[2] - w[2])
    t = su / (su - sw)
    return u[0] + t * (w[0] - u[0]), u[1] + t * (w[1] - u[1]), u[2] + t * (w[2] - u[2])


@njit(cache=True)
def _scratch():
    """Work arrays of :func:`_clip`, allocated once per cell."""
    return (np.empty((MAX_FACE_VERTICES, 3)), np.empty(MAX_FACE_VERTICES, np.int64), np.empty((MAX_FACES, 3)),
            np.empty((MAX_FACES, 3)), np.empty(MAX_FACES, np.int64), np.empty(MAX_FACES, np.bool_),
            np.empty((MAX_FACES, MAX_FACE_VERTICES)), np.empty(MAX_FACES, np.int64))


@njit(cache=True)
def _clip(verts, edges, count, label, nf, n, d, new_label, scratch):
    """Keep the part of the cell with n.x <= d; the cut becomes a face labelled ``new_label``.

    Returns the new face count (0 when nothing is left, -1 on overflow) and
    whether the plane cut the cell at all.
    """
    # exit/entry: where a cut face leaves/re-enters; side: signed distance of every vertex, outside: count per face
    out_v, out_e, exit_pt, entry_pt, cut_label, used, side, outside = scratch
    nx, ny, nz = n[0], n[1], n[2]
    total = 0
    n_out = 0
    for f in range(nf):
        k = 0
        for m in range(count[f]):
            s = nx * verts[f, m, 0] + ny * verts[f, m, 1] + nz * verts[f, m, 2] - d
            side[f, m] = s
            if s > 0.0:
                k += 1
        outside[f] = k
        n_out += k
        total += count[f]
    if n_out == 0:
        return nf, False
    if n_out == total:
        return 0, True
    ncut = 0
    kept = 0
    for f in range(nf):
        c = count[f]
        if outside[f] == c:  # the whole face is cut away
            continue
        if outside[f] == 0:  # the whole face is kept: move it down over the faces cut away
            if c + 1 > MAX_FACE_VERTICES:
                return -1, True
            if kept != f:
                for m in range(c):
                    verts[kept, m, 0], verts[kept, m, 1], verts[kept, m, 2] = verts[f, m, 0], verts[f, m, 1], verts[f, m, 2]
                    edges[kept, m] = edges[f, m]
                count[kept] = c
                label[kept] = label[f]
            kept += 1
            continue
        k = 0
        cut = False
        for m in range(c):
            m1 = m + 1 if m + 1 < c else 0
            su = side[f, m]
            sw = side[f, m1]
            if k + 2 > MAX_FACE_VERTICES:
                return -1, True
            if su <= 0.0:
                out_v[k, 0], out_v[k, 1], out_v[k, 2] = verts[f, m, 0], verts[f, m, 1], verts[f, m, 2]
                out_e[k] = edges[f, m]
                k += 1
                if sw > 0.0:
                    x, y, z = _crossing((verts[f, m, 0], verts[f, m, 1], verts[f, m, 2]),
                                        (verts[f, m1, 0], verts[f, m1, 1], verts[f, m1, 2]), su, sw)
                    out_v[k, 0], out_v[k, 1], out_v[k, 2] = x, y, z
                    out_e[k] = new_label
                    exit_pt[ncut, 0], exit_pt[ncut, 1], exit_pt[ncut, 2] = x, y, z
                    cut = True
                    k += 1
            elif sw <= 0.0:
                x, y, z = _crossing((verts[f, m, 0], verts[f, m, 1], verts[f, m, 2]),
                                    (verts[f, m1, 0], verts[f, m1, 1], verts[f, m1, 2]), su, sw)
                out_v[k, 0], out_v[k, 1], out_v[k, 2] = x, y, z
                out_e[k] = edges[f, m]
                entry_pt[ncut, 0], entry_pt[ncut, 1], entry_pt[ncut, 2] = x, y, z
                k += 1
        if k >= 3:
            if cut:
                cut_label[ncut] = label[f]
                ncut += 1
            for m in range(k):
                verts[kept, m, 0], verts[kept, m, 1], verts[kept, m, 2] = out_v[m, 0], out_v[m, 1], out_v[m, 2]
                edges[kept, m] = out_e[m]
            count[kept] = k
            label[kept] = label[f]
            kept += 1
    if ncut < 3 or kept >= MAX_FACES or ncut > MAX_FACE_VERTICES:
        return (kept if ncut < 3 else -1), True
    # the cap runs entry -> exit along each cut face, reversed; chain exit of one to entry of the next
    used[:ncut] = False
    cur = 0
    for m in range(ncut):
        used[cur] = True
        verts[kept, m, 0], verts[kept, m, 1], verts[kept, m, 2] = entry_pt[cur, 0], entry_pt[cur, 1], entry_pt[cur, 2]
        edges[kept, m] = cut_label[cur]
        best = -1
        best_d = np.inf
        for g in range(ncut):
            if used[g]:
                continue
            dd = ((entry_pt[g, 0] - exit_pt[cur, 0]) ** 2 + (entry_pt[g, 1] - exit_pt[cur, 1]) ** 2
                  + (entry_pt[g, 2] - exit_pt[cur, 2]) ** 2)
            if dd < best_d:
                best_d = dd
                best = g
        if best < 0:
            break
        cur = best
    count[kept] = ncut
    label[kept] = new_label
    return kept + 1, True


def seed_grid(seeds: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Bucket the seeds on a uniform grid of about one seed per bucket.

    Returns
    -------
    start : numpy.ndarray of int64, shape (n_buckets + 1,)
        CSR offsets into ``order`` (buckets x-fastest).
    order : numpy.ndarray of int64, shape (n_seeds,)
    dims : numpy.ndarray of int64, shape (3,)
    size : float
        Bucket edge.
    """
    extent = hi - lo
    size = float((np.prod(extent) / max(len(seeds), 1)) ** (1.0 / 3.0))
    dims = grid_over(lo, hi, size)
    start, order = bucket_points(np.ascontiguousarray(seeds, dtype=np.float64), np.asarray(lo, np.float64), size, dims)
    return start, order, dims, size


@njit(cache=True)
def _extent(verts, count, nf, p, box):
    """Squared distance from ``p`` to the cell's farthest vertex; writes the cell's bounding box to ``box`` (2, 3)."""
    r2 = 0.0
    box[0] = np.inf
    box[1] = -np.inf
    for f in range(nf):
        for m in range(count[f]):
            d = (verts[f, m, 0] - p[0]) ** 2 + (verts[f, m, 1] - p[1]) ** 2 + (verts[f, m, 2] - p[2]) ** 2
            r2 = max(r2, d)
            for a in range(3):
                box[0, a] = min(box[0, a], verts[f, m, a])
                box[1, a] = max(box[1, a], verts[f, m, a])
    return r2


@njit(cache=True, inline="always")
def _misses(box, n, d):
    """Whether the plane n.x = d leaves the box (2, 3) on its n.x <= d side."""
    s = 0.0
    for a in range(3):
        s += max(n[a] * box[0, a], n[a] * box[1, a])
    return s <= d


@njit(cache=True)
def cell_polygons(i, seeds, start, order, dims, size, lo, hi, bound_n, bound_d):
    """Voronoi cell of seed ``i`` inside the box [lo, hi], cut by bounding planes.

    The bounding planes ``bound_n . x <= bound_d`` (for example a bounding
    polytope of a mesh all the cells are clipped to later) are applied after
    the nearest seeds, to the cells that reach them: a cell at the edge of
    the seeds would otherwise stretch to the box and its neighbour search
    would scan every empty bucket on the way. Their faces are labelled
    ``-7 - h``.

    Returns
    -------
    verts : (MAX_FACES, MAX_FACE_VERTICES, 3) float64
    edges : (MAX_FACES, MAX_FACE_VERTICES) int64
        Label of the face across each edge (from vertex m to m + 1).
    count : (MAX_FACES,) int64
        Vertices per face.
    label : (MAX_FACES,) int64
        Neighbouring seed of each face, or a negative wall label.
    nf : int
        Number of faces; 0 when the cell lies outside the bounding planes, -1
        when a fixed capacity was exceeded.
    """
    verts, edges, count, label, nf = box_cell(lo, hi)
    p = seeds[i]
    n = np.empty(3)
    scratch = _scratch()
    box = np.empty((2, 3))
    r2 = _extent(verts, count, nf, p, box)
    ci = min(max(int((p[0] - lo[0]) / size), 0), dims[0] - 1)
    cj = min(max(int((p[1] - lo[1]) / size), 0), dims[1] - 1)
    ck = min(max(int((p[2] - lo[2]) / size), 0), dims[2] - 1)
    ring = 0
    max_ring = max(dims[0], max(dims[1], dims[2]))
    cand = np.empty(64, np.int64)
    cand_d2 = np.empty(64)
    while ring <= max_ring:
        if ring == 2:
            for h in range(bound_d.size):
                dist = bound_d[h] - (bound_n[h, 0] * p[0] + bound_n[h, 1] * p[1] + bound_n[h, 2] * p[2])
                if (dist < 0.0 or dist * dist < r2) and not _misses(box, bound_n[h], bound_d[h]):
                    nf, cut = _clip(verts, edges, count, label, nf, bound_n[h], bound_d[h], -7 - h, scratch)
                    if nf <= 0:  # nothing of the cell is within the bounds (0), or capacity exceeded (-1)
                        return verts, edges, count, label, nf
                    if cut:
                        r2 = _extent(verts, count, nf, p, box)
        if ring >= 2 and ((ring - 1) * size) ** 2 > 4.0 * r2:
            break
        # the seeds of this ring's buckets that may cut, nearest first: the cell shrinks fastest that way
        nc = 0
        for dk in range(-ring, ring + 1):
            kk = ck + dk
            if kk < 0 or kk >= dims[2]:
                continue
            for dj in range(-ring, ring + 1):
                jj = cj + dj
                if jj < 0 or jj >= dims[1]:
                    continue
                for di in range(-ring, ring + 1):
                    if max(abs(di), max(abs(dj), abs(dk))) != ring:
                        continue
                    ii = ci + di
                    if ii < 0 or ii >= dims[0]:
                        continue
                    # nearest point of the bucket: a seed there cuts only if closer than 2R
                    gap2 = 0.0
                    for a, cell in ((0, ii), (1, jj), (2, kk)):
                        low = lo[a] + cell * size
                        if p[a] < low:
                            gap2 += (low - p[a]) ** 2
                        elif p[a] > low + size:
                            gap2 += (p[a] - low - size) ** 2
                    if gap2 >= 4.0 * r2:
                        continue
                    b = ii + dims[0] * (jj + dims[1] * kk)
                    for q in range(start[b], start[b + 1]):
                        j = order[q]
                        if j == i:
                            continue
                        dist2 = (seeds[j, 0] - p[0]) ** 2 + (seeds[j, 1] - p[1]) ** 2 + (seeds[j, 2] - p[2]) ** 2
                        if dist2 >= 4.0 * r2:
                            continue
                        if nc == cand.shape[0]:
                            grown = np.empty(2 * nc, np.int64)
                            grown[:nc] = cand
                            cand = grown
                            grown_d = np.empty(2 * nc)
                            grown_d[:nc] = cand_d2
                            cand_d2 = grown_d
                        cand[nc] = j
                        cand_d2[nc] = dist2
                        nc += 1
        for q in np.argsort(cand_d2[:nc], kind="mergesort"):
            j = cand[q]
            if cand_d2[q] >= 4.0 * r2:
                break
            n[0] = seeds[j, 0] - p[0]
            n[1] = seeds[j, 1] - p[1]
            n[2] = seeds[j, 2] - p[2]
            d = 0.5 * (n[0] * (seeds[j, 0] + p[0]) + n[1] * (seeds[j, 1] + p[1]) + n[2] * (seeds[j, 2] + p[2]))
            if _misses(box, n, d):
                continue
            nf, cut = _clip(verts, edges, count, label, nf, n, d, j, scratch)
            if nf <= 0:  # capacity exceeded (-1), or nothing left of a cell the bounds cut off its seed (0)
                return verts, edges, count, label, nf
            if cut:
                r2 = _extent(verts, count, nf, p, box)
        ring += 1
    return verts, edges, count, label, nf
