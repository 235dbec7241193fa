"""Shards: Voronoi cells of seed points clipped to a closed mesh, and their link graphs (Mateos et al. §4).

The mesh may be non-convex. A cell that no mesh triangle comes near is
kept whole when its seed is inside the mesh and dropped otherwise. A cell
that the surface crosses is clipped exactly:

- each of its faces keeps the part inside the mesh. That part's boundary is
  the face's edges where they run inside (split where they cross the
  surface, starting from a ray-parity test of the edge's first vertex) and
  the face plane's section of the mesh triangles, clipped to the face. Area,
  centroid and the cell's volume follow from the boundary segments alone
  (Green's and Gauss' theorems), so no polygon has to be rebuilt;
- each mesh triangle keeps the part inside the cell (a convex clip): one
  exterior link per (cell, triangle), as the surface faces of the paper.

Links are neighbours in the links graph when their faces share an edge: two
faces of one cell along a Voronoi edge that runs inside the mesh, a face
and a surface piece along their section, two surface pieces of one cell
along a mesh edge, and the surface pieces of one triangle in two cells.
Cells are computed in parallel batches with per-cell records, so the graph
is the same for any thread count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from pverosion.kernels.mesh_query import TriangleIndex, box_triangles, point_inside, segment_crossings
from pverosion.kernels.topology import halfedge_twins
from pverosion.kernels.validation import as_triangle_mesh
from pverosion.kernels.voronoi import MAX_FACES, cell_polygons, seed_grid

__all__ = ["ShardGraph", "build_shards"]

RECORDS = 192
"""Link records a cell may produce (faces plus surface pieces)."""
PAIRS = 1024
"""Link-neighbour pairs a cell may produce."""
_BATCH = 1024
_SOLID, _AIR, _CORE = 0, 1, 2


@dataclass
class ShardGraph:
    """Cells, links and the two graphs of Mateos et al. §4.2, as flat arrays.

    Attributes
    ----------
    seeds : (n_cells, 3) float64
        Seed of every cell (cells whose clipped volume is zero are already dropped).
    volume : (n_cells,) float64
    link_cells : (n_links, 2) int64
        The two cells of an interior link; ``(cell, -1)`` for an exterior link.
    link_triangle : (n_links,) int64
        Mesh triangle of an exterior link, -1 for interior links.
    link_area : (n_links,) float64
    link_centroid : (n_links, 3) float64
    link_normal : (n_links, 3) float64
        Unit normal, from the first cell to the second (outward for exterior links).
    cell_start, cell_links : int64 arrays
        Cells graph G_C in CSR form: the interior links of each cell.
    link_start, link_neighbours : int64 arrays
        Links graph G_L in CSR form.
    box : (lo, hi)
        The box the Voronoi cells were computed in.
    cell_seed : (n_cells,) int64
        Index of each cell's seed among the seeds given to :func:`build_shards`.
    input_seeds : (n_seeds, 3) float64
        All seeds given to :func:`build_shards` (dropped cells' seeds still shape their neighbours).
    mesh_points, mesh_faces : (m, 3) float64, (k, 3) int64
        The closed mesh the cells were clipped to.
    """

    seeds: np.ndarray
    volume: np.ndarray
    link_cells: np.ndarray
    link_triangle: np.ndarray
    link_area: np.ndarray
    link_centroid: np.ndarray
    link_normal: np.ndarray
    cell_start: np.ndarray
    cell_links: np.ndarray
    link_start: np.ndarray
    link_neighbours: np.ndarray
    box: tuple[np.ndarray, np.ndarray] = field(repr=False)
    cell_seed: np.ndarray = field(repr=False)
    input_seeds: np.ndarray = field(repr=False)
    mesh_points: np.ndarray = field(repr=False)
    mesh_faces: np.ndarray = field(repr=False)

    @property
    def n_cells(self) -> int:
        return len(self.volume)

    @property
    def n_links(self) -> int:
        return len(self.link_area)

    @property
    def exterior(self) -> np.ndarray:
        """(n_links,) bool: links on the mesh surface."""
        return self.link_cells[:, 1] < 0

    @property
    def mean_area(self) -> float:
        """Mean link area (the paper's a-bar)."""
        return float(self.link_area.mean()) if self.n_links else 0.0


# --- per cell ----------------------------------------------------------------------------------------------


@njit(cache=True)
def _plane(i, lab, seeds, lo, hi, bound_n, bound_d):
    """Unit outward normal and offset of the face of cell ``i`` labelled ``lab``."""
    n = np.zeros(3)
    if lab <= -7:
        h = -7 - lab
        n[:] = bound_n[h]
        return n, bound_d[h]
    if lab >= 0:
        for a in range(3):
            n[a] = seeds[lab, a] - seeds[i, a]
        length = math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
        n /= length
        d = 0.0
        for a in range(3):
            d += n[a] * 0.5 * (seeds[lab, a] + seeds[i, a])
        return n, d
    wall = -1 - lab
    axis, side = wall // 2, wall % 2
    n[axis] = 1.0 if side == 1 else -1.0
    return n, (hi[axis] if side == 1 else -lo[axis])


@njit(cache=True, inline="always")
def _accumulate(acc, o, n, a, b):
    """Add boundary segment a->b (3-tuples) of a planar region (normal n, origin o) to [2 area, moment x3]."""
    ax, ay, az = a[0] - o[0], a[1] - o[1], a[2] - o[2]
    bx, by, bz = b[0] - o[0], b[1] - o[1], b[2] - o[2]
    w = n[0] * (ay * bz - az * by) + n[1] * (az * bx - ax * bz) + n[2] * (ax * by - ay * bx)
    acc[0] += w
    acc[1] += w * (ax + bx)
    acc[2] += w * (ay + by)
    acc[3] += w * (az + bz)


@njit(cache=True)
def _clip_segment(a, b, planes, offsets, nplanes, skip):
    """Clip segment a->b (3-tuples) to n.x <= d for every plane but ``skip``; returns (ok, a', b')."""
    ax, ay, az = a
    bx, by, bz = b
    for g in range(nplanes):
        if g == skip:
            continue
        nx, ny, nz = planes[g, 0], planes[g, 1], planes[g, 2]
        sa = nx * ax + ny * ay + nz * az - offsets[g]
        sb = nx * bx + ny * by + nz * bz - offsets[g]
        if sa > 0.0 and sb > 0.0:
            return False, (ax, ay, az), (bx, by, bz)
        if sa > 0.0:
            t = sa / (sa - sb)
            ax, ay, az = ax + (bx - ax) * t, ay + (by - ay) * t, az + (bz - az) * t
        elif sb > 0.0:
            t = sb / (sb - sa)
            bx, by, bz = bx + (ax - bx) * t, by + (ay - by) * t, bz + (az - bz) * t
    return True, (ax, ay, az), (bx, by, bz)


@njit(cache=True)
def _clip_polygon(tri, planes, offsets, nplanes, buf):
    """Sutherland–Hodgman clip of a triangle to n.x <= d for every plane; (polygon, vertex count).

    ``buf`` holds two work arrays of at least ``nplanes + 3`` rows.
    """
    cur, nxt = buf
    cur[:3] = tri
    m = 3
    for g in range(nplanes):
        nx, ny, nz = planes[g, 0], planes[g, 1], planes[g, 2]
        k = 0
        for q in range(m):
            q1 = (q + 1) % m
            su = nx * cur[q, 0] + ny * cur[q, 1] + nz * cur[q, 2] - offsets[g]
            sw = nx * cur[q1, 0] + ny * cur[q1, 1] + nz * cur[q1, 2] - offsets[g]
            if su <= 0.0:
                nxt[k] = cur[q]
                k += 1
            if (su <= 0.0) != (sw <= 0.0):
                r = su / (su - sw)
                for a in range(3):
                    nxt[k, a] = cur[q, a] + (cur[q1, a] - cur[q, a]) * r
                k += 1
        cur, nxt = nxt, cur
        m = k
        if m < 3:
            return cur, 0
    return cur, m


@njit(cache=True)
def _section(t, n, d, points, faces):
    """Segment where triangle t meets the plane n.x = d; (ok, a, b) as 3-tuples."""
    ends = [(0.0, 0.0, 0.0), (0.0, 0.0, 0.0)]
    k = 0
    for m in range(3):
        i, j = faces[t, m], faces[t, (m + 1) % 3]
        if j < i:  # from the end with the smaller vertex index, so neighbours agree bit for bit
            i, j = j, i
        si = n[0] * points[i, 0] + n[1] * points[i, 1] + n[2] * points[i, 2] - d
        sj = n[0] * points[j, 0] + n[1] * points[j, 1] + n[2] * points[j, 2] - d
        if (si <= 0.0) != (sj <= 0.0):
            if k == 2:
                return False, ends[0], ends[1]
            r = si / (si - sj)
            ends[k] = (points[i, 0] + (points[j, 0] - points[i, 0]) * r,
                       points[i, 1] + (points[j, 1] - points[i, 1]) * r,
                       points[i, 2] + (points[j, 2] - points[i, 2]) * r)
            k += 1
    return k == 2, ends[0], ends[1]


@njit(cache=True)
def _cell(i, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tri_adj, tlo, tsize, tdims, tstart,
          titems, tstart2, titems2, rec_label, rec_val, pair_a, pair_b, pair_cell):
    """Link records and neighbour pairs of cell ``i``; returns (n_records, n_pairs, volume, status).

    status: 0 ok, 1 polygon capacity exceeded, 2 record/pair capacity (the arrays' lengths) exceeded.
    """
    max_rec = rec_label.size
    max_pair = pair_a.size
    verts, edges, count, label, nf = cell_polygons(i, seeds, start, order, dims, size, lo, hi, bound_n, bound_d)
    if nf <= 0:
        return 0, 0, 0.0, 1 if nf < 0 else 0
    planes = np.empty((nf, 3))
    offsets = np.empty(nf)
    bmin = np.full(3, np.inf)
    bmax = np.full(3, -np.inf)
    for f in range(nf):
        n, d = _plane(i, label[f], seeds, lo, hi, bound_n, bound_d)
        planes[f] = n
        offsets[f] = d
        for m in range(count[f]):
            for a in range(3):
                bmin[a] = min(bmin[a], verts[f, m, a])
                bmax[a] = max(bmax[a], verts[f, m, a])
    tris = box_triangles(bmin, bmax, points, faces, tlo, tsize, tdims, tstart, titems)
    nrec = 0
    npair = 0
    volume = 0.0
    acc = np.zeros(4)
    cross = np.empty(tris.size)
    buf = (np.empty((tris.size + nf + 3, 3)), np.empty((tris.size + nf + 3, 3)))
    if tris.size == 0 and not point_inside(seeds[i], points, faces, tlo, tsize, tdims, tstart2, titems2):
        return 0, 0, 0.0, 0
    for f in range(nf):
        n = planes[f]
        o = (verts[f, 0, 0], verts[f, 0, 1], verts[f, 0, 2])
        acc[:] = 0.0
        state = False
        c = count[f]
        for m in range(c):
            u = (verts[f, m, 0], verts[f, m, 1], verts[f, m, 2])
            q1 = (m + 1) % c
            w = (verts[f, q1, 0], verts[f, q1, 1], verts[f, q1, 2])
            if tris.size == 0:
                _accumulate(acc, o, n, u, w)
                inside_len = 1.0
            else:
                if m == 0:  # later vertices follow from the parity of the crossings
                    state = point_inside(verts[f, 0], points, faces, tlo, tsize, tdims, tstart2, titems2)
                ncross = segment_crossings(u, w, tris, points, faces, normals, cross)
                inside_len = 0.0
                t0 = 0.0
                for q in range(ncross + 1):
                    t1 = cross[q] if q < ncross else 1.0
                    if state and t1 > t0:
                        _accumulate(acc, o, n, (u[0] + (w[0] - u[0]) * t0, u[1] + (w[1] - u[1]) * t0,
                                                u[2] + (w[2] - u[2]) * t0),
                                    (u[0] + (w[0] - u[0]) * t1, u[1] + (w[1] - u[1]) * t1, u[2] + (w[2] - u[2]) * t1))
                        inside_len += t1 - t0
                    if q < ncross:
                        state = not state
                    t0 = t1
            if inside_len > 0.0 and label[f] >= 0 and edges[f, m] >= 0:
                if npair >= max_pair:
                    return 0, 0, 0.0, 2
                pair_a[npair] = label[f]
                pair_b[npair] = edges[f, m]
                pair_cell[npair] = i
                npair += 1
        for q in range(tris.size):
            t = tris[q]
            ok, a, b = _section(t, n, offsets[f], points, faces)
            if not ok:
                continue
            # the region's boundary keeps the inside on its left: along n x (triangle normal)
            dx = n[1] * normals[t, 2] - n[2] * normals[t, 1]
            dy = n[2] * normals[t, 0] - n[0] * normals[t, 2]
            dz = n[0] * normals[t, 1] - n[1] * normals[t, 0]
            if (b[0] - a[0]) * dx + (b[1] - a[1]) * dy + (b[2] - a[2]) * dz < 0.0:
                a, b = b, a
            ok, a, b = _clip_segment(a, b, planes, offsets, nf, f)
            if not ok or a == b:
                continue
            _accumulate(acc, o, n, a, b)
            if label[f] >= 0:
                if npair + 2 > max_pair:
                    return 0, 0, 0.0, 2
                pair_a[npair] = label[f]
                pair_b[npair] = -1 - t
                pair_cell[npair] = i
                # the same triangle's piece in the neighbouring cell shares this section
                pair_a[npair + 1] = -1 - t
                pair_b[npair + 1] = -1 - t
                pair_cell[npair + 1] = label[f]
                npair += 2
        area = 0.5 * acc[0]
        if area > 0.0:
            volume += offsets[f] * area
            if label[f] >= 0:
                if nrec >= max_rec:
                    return 0, 0, 0.0, 2
                rec_label[nrec] = label[f]
                rec_val[nrec, 0] = area
                for a in range(3):
                    rec_val[nrec, 1 + a] = o[a] + acc[1 + a] / (3.0 * acc[0])
                    rec_val[nrec, 4 + a] = n[a]
                nrec += 1
    for q in range(tris.size):
        t = tris[q]
        tri = np.empty((3, 3))
        for m in range(3):
            tri[m] = points[faces[t, m]]
        poly, k = _clip_polygon(tri, planes, offsets, nf, buf)
        if k < 3:
            continue
        acc[:] = 0.0
        o = (poly[0, 0], poly[0, 1], poly[0, 2])
        for m in range(k):
            q1 = (m + 1) % k
            _accumulate(acc, o, normals[t], (poly[m, 0], poly[m, 1], poly[m, 2]),
                        (poly[q1, 0], poly[q1, 1], poly[q1, 2]))
        area = 0.5 * acc[0]
        if not area > 0.0:
            continue
        cen = np.empty(3)
        for a in range(3):
            cen[a] = poly[0, a] + acc[1 + a] / (3.0 * acc[0])
        volume += area * (normals[t, 0] * cen[0] + normals[t, 1] * cen[1] + normals[t, 2] * cen[2])
        if nrec >= max_rec or npair + 3 > max_pair:
            return 0, 0, 0.0, 2
        rec_label[nrec] = -1 - t
        rec_val[nrec, 0] = area
        for a in range(3):
            rec_val[nrec, 1 + a] = cen[a]
            rec_val[nrec, 4 + a] = normals[t, a]
        nrec += 1
        for m in range(3):  # surface pieces of this cell across the triangle's edges
            nb = tri_adj[t, m]
            if nb < 0 or nb < t:
                continue
            q1 = (m + 1) % 3
            ok, a, b = _clip_segment((tri[m, 0], tri[m, 1], tri[m, 2]), (tri[q1, 0], tri[q1, 1], tri[q1, 2]),
                                     planes, offsets, nf, -1)
            if ok and a != b:
                pair_a[npair] = -1 - t
                pair_b[npair] = -1 - nb
                pair_cell[npair] = i
                npair += 1
    return nrec, npair, volume / 3.0, 0


@njit(cache=True, parallel=True)
def _batch(first, last, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tri_adj, tlo, tsize, tdims,
           tstart, titems, tstart2, titems2, capacity=1):
    """Cells first..last-1, with ``capacity`` times the default record and pair slots each."""
    nb = last - first
    rec_label = np.empty((nb, capacity * RECORDS), np.int64)
    rec_val = np.empty((nb, capacity * RECORDS, 7))
    pair_a = np.empty((nb, capacity * PAIRS), np.int64)
    pair_b = np.empty((nb, capacity * PAIRS), np.int64)
    pair_cell = np.empty((nb, capacity * PAIRS), np.int64)
    nrec = np.zeros(nb, np.int64)
    npair = np.zeros(nb, np.int64)
    volume = np.zeros(nb)
    status = np.zeros(nb, np.int64)
    for q in prange(nb):
        nrec[q], npair[q], volume[q], status[q] = _cell(
            first + q, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tri_adj, tlo, tsize, tdims,
            tstart, titems, tstart2, titems2, rec_label[q], rec_val[q], pair_a[q], pair_b[q], pair_cell[q])
    return rec_label, rec_val, pair_a, pair_b, pair_cell, nrec, npair, volume, status


# --- assembly ----------------------------------------------------------------------------------------------


def _csr(rows: np.ndarray, cols: np.ndarray, n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    order = np.lexsort((cols, rows))
    rows, cols = rows[order], cols[order]
    start = np.searchsorted(rows, np.arange(n_rows + 1)).astype(np.int64)
    return start, cols.astype(np.int64)


def build_shards(seeds: np.ndarray, points: np.ndarray, faces: np.ndarray, *, progress=None) -> ShardGraph:
    """Clip the Voronoi cells of ``seeds`` to the closed mesh (``points``, ``faces``) and build the graphs.

    Parameters
    ----------
    seeds : numpy.ndarray, shape (n, 3)
        Distinct seed points (seeds outside the mesh give cells only where
        their Voronoi cell reaches inside).
    points : numpy.ndarray, shape (m, 3)
    faces : numpy.ndarray, shape (k, 3), int
        A closed, consistently outward-oriented triangle mesh.
    progress : callable, optional
        Called with the number of cells done after every batch.

    Returns
    -------
    ShardGraph
        Cells with positive clipped volume, renumbered in seed order.

    Raises
    ------
    ValueError
        Seeds of the wrong shape, non-finite or repeated; a mesh that is
        empty, open or not made of triangles.
    """
    seeds = np.asarray(seeds)
    if seeds.ndim != 2 or seeds.shape[1] != 3 or len(seeds) == 0:
        raise ValueError(f"seeds must have shape (n, 3) with n >= 1; got {seeds.shape}")
    seeds = np.ascontiguousarray(seeds, dtype=np.float64)
    if not np.isfinite(seeds).all():
        raise ValueError("seeds contain NaN or infinite coordinates")
    if len(np.unique(seeds, axis=0)) != len(seeds):
        raise ValueError("seeds must be distinct; some are repeated")
    points, faces = as_triangle_mesh(points, faces)
    partner, others = halfedge_twins(faces, len(points))
    if (others != 1).any():
        raise ValueError(f"the mesh must be closed and manifold: {int((others != 1).sum())} half-edges are on "
                         "the boundary or shared by more than two faces")
    index = TriangleIndex.build(points, faces)
    lo = np.minimum(seeds.min(axis=0), index.points.min(axis=0))
    hi = np.maximum(seeds.max(axis=0), index.points.max(axis=0))
    pad = 0.01 * float((hi - lo).max()) + 1e-9
    lo, hi = lo - pad, hi + pad
    start, order, dims, size = seed_grid(seeds, lo, hi)
    bound_n, bound_d = _bounding_planes(index.points, margin=1e-7 * float((hi - lo).max()))
    tri_adj = np.where(partner >= 0, partner // 3, -1).reshape(-1, 3)
    args = (seeds, start, order, dims, size, lo, hi, bound_n, bound_d, index.points, index.faces, index.normals,
            tri_adj, index.lo, index.size, index.dims, index.start, index.items, index.start2, index.items2)
    n = len(seeds)
    recs, vals, pairs, volume = [], [], [], np.zeros(n)

    def run(first: int, last: int, capacity: int) -> np.ndarray:
        """Cells first..last-1; keeps the results of those that fit, returns the status per cell."""
        rl, rv, pa, pb, pc, nrec, npair, vol, status = _batch(first, last, *args, capacity)
        if (status == 1).any():
            raise RuntimeError(f"a Voronoi cell has more than {MAX_FACES} faces; are seeds nearly coincident?")
        volume[first:last] = vol
        cells = np.arange(first, last)
        mask = np.arange(rl.shape[1])[None, :] < nrec[:, None]  # a cell that did not fit has no records
        recs.append(np.stack([np.broadcast_to(cells[:, None], mask.shape)[mask], rl[mask]], axis=1))
        vals.append(rv[mask])
        pmask = np.arange(pa.shape[1])[None, :] < npair[:, None]
        pairs.append(np.stack([np.broadcast_to(cells[:, None], pmask.shape)[pmask], pa[pmask], pc[pmask],
                               pb[pmask]], axis=1))
        return status

    for first in range(0, n, _BATCH):
        last = min(first + _BATCH, n)
        status = run(first, last, 1)
        for i in np.flatnonzero(status == 2) + first:  # more surface pieces than a batch slot holds: alone, bigger
            capacity = 4
            while run(i, i + 1, capacity)[0] == 2:
                capacity *= 4
        if progress is not None:
            progress(last - first)
    recs = np.concatenate(recs)
    vals = np.concatenate(vals)
    pairs = np.concatenate(pairs)
    graph = _assemble(seeds, volume, recs, vals, pairs, n_triangles=len(index.faces), box=(lo, hi))
    graph.mesh_points, graph.mesh_faces = index.points, index.faces
    return graph


def _bounding_planes(points: np.ndarray, *, directions: int = 64, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """A bounding polytope of ``points``: support planes in the six axis and ``directions`` spread directions.

    Returns unit normals (k, 3) and offsets (k,) of ``n . x <= d``, pushed out by ``margin``.
    """
    k = np.arange(directions) + 0.5
    z = 1.0 - 2.0 * k / directions
    phi = np.pi * (1.0 + 5**0.5) * k
    r = np.sqrt(1.0 - z * z)
    normals = np.concatenate([np.eye(3), -np.eye(3), np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)])
    return np.ascontiguousarray(normals), (points @ normals.T).max(axis=0) + margin


def _link_key(cell: np.ndarray, lab: np.ndarray, n: int, n_triangles: int) -> np.ndarray:
    """Integer key of the link a cell's record labelled ``lab`` belongs to."""
    interior = lab >= 0
    a, b = np.minimum(cell, lab), np.maximum(cell, lab)
    return np.where(interior, a * n + b, n * n + cell * n_triangles + (-1 - lab))


def _assemble(seeds, volume, recs, vals, pairs, *, n_triangles, box) -> ShardGraph:
    n = len(seeds)
    cell, lab = recs[:, 0], recs[:, 1]
    keys = _link_key(cell, lab, n, n_triangles)
    # interior links appear in both cells: keep the record of the lower-numbered cell when it exists
    prefer = np.where(lab >= 0, (cell > lab).astype(np.int64), 0)
    order = np.lexsort((prefer, keys))
    keys_sorted = keys[order]
    first = np.ones(len(order), bool)
    first[1:] = keys_sorted[1:] != keys_sorted[:-1]
    pick = order[first]
    link_keys = keys[pick]
    c, lb, v = cell[pick], lab[pick], vals[pick]
    interior = lb >= 0
    link_cells = np.stack([c, np.where(interior, lb, -1)], axis=1)
    # orient interior links from the lower to the higher cell
    flip = interior & (link_cells[:, 0] > link_cells[:, 1])
    link_cells[flip] = link_cells[flip][:, ::-1]
    normal = v[:, 4:7].copy()
    normal[flip] *= -1.0
    keep_cell = volume > 0.0
    # drop links that touch a cell with no volume left (a record of an empty neighbour)
    ok = keep_cell[link_cells[:, 0]] & np.where(interior, keep_cell[np.maximum(link_cells[:, 1], 0)], True)
    link_keys, link_cells, v, normal = link_keys[ok], link_cells[ok], v[ok], normal[ok]
    tri = np.where(link_cells[:, 1] < 0, _triangle_of(link_keys, n, n_triangles), -1)
    renumber = np.cumsum(keep_cell) - 1
    link_cells = np.where(link_cells >= 0, renumber[np.maximum(link_cells, 0)], -1)
    n_cells = int(keep_cell.sum())
    # links graph: map both ends of every pair to link ids
    ka = _link_key(pairs[:, 0], pairs[:, 1], n, n_triangles)
    kb = _link_key(pairs[:, 2], pairs[:, 3], n, n_triangles)
    ia, ib = _lookup(link_keys, ka), _lookup(link_keys, kb)
    good = (ia >= 0) & (ib >= 0) & (ia != ib)
    ia, ib = ia[good], ib[good]
    link_start, link_neighbours = _symmetric_csr(ia, ib, len(link_keys))
    inner = np.flatnonzero(link_cells[:, 1] >= 0)
    rows = np.concatenate([link_cells[inner, 0], link_cells[inner, 1]])
    cols = np.concatenate([inner, inner])
    cell_start, cell_links = _csr(rows, cols, n_cells)
    return ShardGraph(seeds=seeds[keep_cell], volume=volume[keep_cell], link_cells=link_cells.astype(np.int64),
                      link_triangle=tri.astype(np.int64), link_area=v[:, 0].copy(), link_centroid=v[:, 1:4].copy(),
                      link_normal=normal, cell_start=cell_start, cell_links=cell_links,
                      link_start=link_start, link_neighbours=link_neighbours, box=box,
                      cell_seed=np.flatnonzero(keep_cell), input_seeds=seeds, mesh_points=np.empty((0, 3)),
                      mesh_faces=np.empty((0, 3), np.int64))


@njit(cache=True)
def _symmetric_csr(ia, ib, n):
    """CSR rows of the undirected graph with edges (ia, ib), each neighbour once, sorted."""
    count = np.zeros(n + 1, np.int64)
    for q in range(ia.size):
        count[ia[q] + 1] += 1
        count[ib[q] + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    cols = np.empty(start[-1], np.int64)
    for q in range(ia.size):
        cols[fill[ia[q]]] = ib[q]
        fill[ia[q]] += 1
        cols[fill[ib[q]]] = ia[q]
        fill[ib[q]] += 1
    out_start = np.zeros(n + 1, np.int64)
    k = 0
    for r in range(n):
        row = np.sort(cols[start[r]:start[r + 1]])
        for q in range(row.size):
            if q == 0 or row[q] != row[q - 1]:
                cols[k] = row[q]
                k += 1
        out_start[r + 1] = k
    return out_start, cols[:k].copy()


def _triangle_of(keys: np.ndarray, n: int, n_triangles: int) -> np.ndarray:
    return np.where(keys >= n * n, (keys - n * n) % max(n_triangles, 1), -1)


def _lookup(sorted_keys: np.ndarray, keys: np.ndarray) -> np.ndarray:
    pos = np.searchsorted(sorted_keys, keys)
    pos = np.minimum(pos, len(sorted_keys) - 1)
    return np.where(sorted_keys[pos] == keys, pos, -1)
