"""Shards: Voronoi cells of seed points clipped to a closed mesh, and their link graphs (Mateos et al. §4).

The mesh may be non-convex. The triangles that may meet a cell come from a
grid of the triangles meeting each bucket of the seed grid, less those a
plane of the cell or the triangle's own plane separates from the cell. A
cell that no triangle meets is kept whole when its seed is inside the mesh
and dropped otherwise. A cell that the surface crosses is clipped exactly:

- each of its faces keeps the part inside the mesh. That part's boundary is
  the face's edges where they run inside (split where they cross the
  surface, starting from a ray-parity test of the edge's first vertex) and
  the face plane's section of the mesh triangles, clipped to the face. Area,
  centroid and the cell's volume follow from the boundary segments alone
  (Green's and Gauss' theorems), so no polygon has to be rebuilt;
- each mesh triangle keeps the part inside the cell (a convex clip), a
  surface piece.

Links are neighbours in the links graph when their faces share an edge: two
faces of one cell along a Voronoi edge that runs inside the mesh, a face
and a surface piece along their section, two surface pieces of one cell
along a mesh edge, and the surface pieces of one triangle in two cells.
Cells are computed in parallel batches with per-cell records, so the graph
is the same for any thread count; the records are then numbered into links
and the pairs resolved to link ids cell by cell.

An exterior link is then one connected surface patch of a cell: the surface
pieces of the cell joined across mesh edges are merged into one link, with
their total area, their area-weighted centroid and the direction of their
area vector as its normal. The links are thereby defined by the surface and
the cells, not by the surface's triangles: subdividing the mesh (or
retriangulating a flat or developable part of it) leaves the links, and the
freeze–thaw physics on them, as they were, up to rounding and the order of
the links.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import prange
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pverosion.kernels._jit import njit
from pverosion.kernels._search import lower_bound
from pverosion.kernels.exact.intersection import intersecting_faces
from pverosion.kernels.mesh.topology import halfedge_twins
from pverosion.kernels.shards.voronoi import MAX_FACE_VERTICES, MAX_FACES, cell_polygons, seed_grid
from pverosion.kernels.spatial.grid import box_items, grid_over
from pverosion.kernels.spatial.mesh_query import (
    _needle,
    overlap_grid,
    point_inside,
    segment_crossings,
    unit_normals,
)
from pverosion.kernels.validation import InvalidMeshError, as_triangle_mesh

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
        The two cells of an interior link; ``(cell, -1)`` for an exterior link
        (one connected surface patch of the cell).
    surface_start, surface_triangle : (n_links + 1,), (n_pieces,) int64
        CSR: the mesh triangles whose pieces inside the cell make up each
        exterior link, ascending (none for interior links).
    link_area : (n_links,) float64
    link_centroid : (n_links, 3) float64
        Area-weighted centroid (off the surface for a curved patch).
    link_normal : (n_links, 3) float64
        Unit normal, from the first cell to the second (outward for exterior
        links: the direction of the patch's area vector, zero if that vector
        vanishes).
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
    surface_start: np.ndarray
    surface_triangle: np.ndarray
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
def _face_section(t, f, planes, offsets, nf, points, faces, normals):
    """Where triangle t crosses face f of a cell: (ok, a, b), inside the mesh on the left, clipped to the cell.

    The region's boundary keeps the inside on its left: it runs along (face normal) x (triangle normal).
    """
    n = planes[f]
    ok, a, b = _section(t, n, offsets[f], points, faces)
    if not ok:
        return False, a, b
    dx = n[1] * normals[t, 2] - n[2] * normals[t, 1]
    dy = n[2] * normals[t, 0] - n[0] * normals[t, 2]
    dz = n[0] * normals[t, 1] - n[1] * normals[t, 0]
    if (b[0] - a[0]) * dx + (b[1] - a[1]) * dy + (b[2] - a[2]) * dz < 0.0:
        a, b = b, a
    ok, a, b = _clip_segment(a, b, planes, offsets, nf, f)
    return ok and a != b, a, b


@njit(cache=True)
def _near_triangles(verts, count, nf, planes, offsets, bmin, bmax, points, faces, normals, lo, size, dims, start, items,
                    margin):
    """Sorted mesh triangles that may meet the cell: all that do, and perhaps a few that pass within ``margin``.

    Candidates come from the buckets of ``start, items`` (an :func:`overlap_grid` on the seed grid) under the
    cell's box; a triangle is left out when its box misses the cell's, when one cell plane has all its
    vertices outside, or when all cell vertices are on one side of its plane (unless it is a needle), each
    by more than ``margin``.
    """
    found = box_items(bmin, bmax, lo, size, dims, start, items, True)
    if found.size == 0:
        return found
    found.sort()
    kept = 0
    for q in range(found.size):
        t = found[q]
        if (q > 0 and t == found[q - 1]) or not _may_meet(t, verts, count, nf, planes, offsets, bmin, bmax, points,
                                                         faces, normals, margin):
            continue
        found[kept] = t
        kept += 1
    return found[:kept]


@njit(cache=True)
def _may_meet(t, verts, count, nf, planes, offsets, bmin, bmax, points, faces, normals, margin):
    """False when triangle ``t`` is at least ``margin`` away from the cell (see :func:`_near_triangles`)."""
    a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
    for x in range(3):
        if (min(points[a, x], min(points[b, x], points[c, x])) > bmax[x] + margin
                or max(points[a, x], max(points[b, x], points[c, x])) < bmin[x] - margin):
            return False
    for g in range(nf):
        nx, ny, nz, d = planes[g, 0], planes[g, 1], planes[g, 2], offsets[g] + margin
        if (nx * points[a, 0] + ny * points[a, 1] + nz * points[a, 2] > d
                and nx * points[b, 0] + ny * points[b, 1] + nz * points[b, 2] > d
                and nx * points[c, 0] + ny * points[c, 1] + nz * points[c, 2] > d):
            return False
    if _needle(points, faces, t):  # rounding tilts its plane
        return True
    above = False
    below = False
    nx, ny, nz = normals[t, 0], normals[t, 1], normals[t, 2]
    for f in range(nf):
        for m in range(count[f]):
            s = (nx * (verts[f, m, 0] - points[a, 0]) + ny * (verts[f, m, 1] - points[a, 1])
                 + nz * (verts[f, m, 2] - points[a, 2]))
            if s >= -margin:
                above = True
            if s <= margin:
                below = True
            if above and below:
                return True
    return False


@njit(cache=True, inline="always")
def _reaches_plane(t, n, d, points, faces, margin):
    """Whether triangle ``t`` comes within ``margin`` of the plane n.x = d."""
    lo = np.inf
    hi = -np.inf
    for m in range(3):
        v = faces[t, m]
        s = n[0] * points[v, 0] + n[1] * points[v, 1] + n[2] * points[v, 2] - d
        lo = min(lo, s)
        hi = max(hi, s)
    return lo <= margin and hi >= -margin


@njit(cache=True)
def _twin_inside(label, edges, count, inside, nf, g_label, f_label):
    """Whether the face labelled ``g_label`` runs inside the mesh along its edge to the face labelled ``f_label``."""
    for g in range(nf):
        if label[g] == g_label:
            for m in range(count[g]):
                if edges[g, m] == f_label and inside[g, m]:
                    return True
    return False


@njit(cache=True)
def _cell(i, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tri_adj, tgrid, cgrid,
          margin, rec_label, rec_val, pair_a, pair_b, pair_cell):
    """Link records and neighbour pairs of cell ``i``; returns (n_records, n_pairs, volume, status).

    ``tgrid`` = (start, items, size, dims) lists the triangles meeting each bucket of a grid from ``lo``,
    ``cgrid`` likewise those meeting each (x, y) column of one (for :func:`point_inside`). status: 0 ok, 1 polygon
    capacity exceeded, 2 record/pair capacity (the arrays' lengths) exceeded.
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
    tstart, titems, tsize, tdims = tgrid
    cstart, citems, csize, cdims = cgrid
    tris = _near_triangles(verts, count, nf, planes, offsets, bmin, bmax, points, faces, normals, lo, tsize, tdims,
                           tstart, titems, margin)
    # a cell the surface does not cross is inside or outside as a whole, like its seed (no surface between them)
    if tris.size == 0 and not point_inside(seeds[i], points, faces, lo, csize, cdims, cstart, citems):
        return 0, 0, 0.0, 0
    nrec = 0
    npair = 0
    volume = 0.0
    acc = np.zeros(4)
    cross = np.empty(tris.size)
    near = np.empty(tris.size, np.int64)
    inside = np.empty((nf, MAX_FACE_VERTICES), np.bool_)  # does the face's edge m run inside the mesh?
    for f in range(nf):
        n = planes[f]
        o = (verts[f, 0, 0], verts[f, 0, 1], verts[f, 0, 2])
        acc[:] = 0.0
        state = True
        if tris.size > 0:  # later vertices follow from the parity of the crossings along the edges
            state = point_inside(verts[f, 0], points, faces, lo, csize, cdims, cstart, citems)
        nt = 0  # the triangles that reach the face's plane: only they can cross its edges or cut it
        for q in range(tris.size):
            if _reaches_plane(tris[q], n, offsets[f], points, faces, margin):
                near[nt] = tris[q]
                nt += 1
        face_tris = near[:nt]
        c = count[f]
        for m in range(c):
            u = (verts[f, m, 0], verts[f, m, 1], verts[f, m, 2])
            q1 = (m + 1) % c
            w = (verts[f, q1, 0], verts[f, q1, 1], verts[f, q1, 2])
            ncross = segment_crossings(u, w, face_tris, points, faces, normals, cross) if nt > 0 else 0
            inside[f, m] = False
            t0 = 0.0
            for q in range(ncross + 1):
                t1 = cross[q] if q < ncross else 1.0
                if state and t1 > t0:
                    a = u if q == 0 else (u[0] + (w[0] - u[0]) * t0, u[1] + (w[1] - u[1]) * t0,
                                          u[2] + (w[2] - u[2]) * t0)
                    b = w if q == ncross else (u[0] + (w[0] - u[0]) * t1, u[1] + (w[1] - u[1]) * t1,
                                               u[2] + (w[2] - u[2]) * t1)
                    _accumulate(acc, o, n, a, b)
                    inside[f, m] = True
                if q < ncross:
                    state = not state
                t0 = t1
        for q in range(nt):
            t = face_tris[q]
            ok, a, b = _face_section(t, f, planes, offsets, nf, points, faces, normals)
            if not ok:
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
    # two faces along a Voronoi edge that runs inside the mesh: one pair, from the face with the lower label
    # unless only the other face finds the edge inside (rounding)
    for f in range(nf):
        if label[f] < 0:
            continue
        for m in range(count[f]):
            e = edges[f, m]
            if e < 0 or not inside[f, m] or (label[f] > e and _twin_inside(label, edges, count, inside, nf, e,
                                                                             label[f])):
                continue
            if npair >= max_pair:
                return 0, 0, 0.0, 2
            pair_a[npair] = label[f]
            pair_b[npair] = e
            pair_cell[npair] = i
            npair += 1
    buf = (np.empty((nf + 3, 3)), np.empty((nf + 3, 3)))
    tri = np.empty((3, 3))
    for q in range(tris.size):
        t = tris[q]
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
        cen = (poly[0, 0] + acc[1] / (3.0 * acc[0]), poly[0, 1] + acc[2] / (3.0 * acc[0]),
               poly[0, 2] + acc[3] / (3.0 * acc[0]))
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
def _batch(first, last, rec_label, rec_val, pair_a, pair_b, pair_cell, seeds, start, order, dims, size, lo, hi, bound_n,
           bound_d, points, faces, normals, tri_adj, tgrid, cgrid, margin):
    """Cells first..last-1 into rows 0..last-first-1 of the record and pair slots (reused from batch to batch).

    Returns the number of records and of pairs, the volume and the status of every cell.
    """
    nb = last - first
    nrec = np.zeros(nb, np.int64)
    npair = np.zeros(nb, np.int64)
    volume = np.zeros(nb)
    status = np.zeros(nb, np.int64)
    for q in prange(nb):
        nrec[q], npair[q], volume[q], status[q] = _cell(
            first + q, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tri_adj,
            tgrid, cgrid, margin, rec_label[q], rec_val[q], pair_a[q], pair_b[q], pair_cell[q])
    return nrec, npair, volume, status


@njit(cache=True)
def _gather(first, rec_label, rec_val, pair_a, pair_b, pair_cell, nrec, npair, ok):
    """The filled slots of the cells where ``ok``: records (cell, label), their values, pairs (cell, a, cell, b)."""
    nr = 0
    npr = 0
    for q in range(nrec.size):
        if ok[q]:
            nr += nrec[q]
            npr += npair[q]
    recs = np.empty((nr, 2), np.int64)
    vals = np.empty((nr, 7))
    pairs = np.empty((npr, 4), np.int64)
    nr = 0
    npr = 0
    for q in range(nrec.size):
        if not ok[q]:
            continue
        for r in range(nrec[q]):
            recs[nr, 0] = first + q
            recs[nr, 1] = rec_label[q, r]
            for a in range(7):
                vals[nr, a] = rec_val[q, r, a]
            nr += 1
        for r in range(npair[q]):
            pairs[npr, 0] = first + q
            pairs[npr, 1] = pair_a[q, r]
            pairs[npr, 2] = pair_cell[q, r]
            pairs[npr, 3] = pair_b[q, r]
            npr += 1
    return recs, vals, pairs


# --- assembly ----------------------------------------------------------------------------------------------


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
    InvalidMeshError
        A face of zero area (its corners on a line): it bounds no piece of any
        cell, so the shards would leave a hole at it. A self-intersecting
        mesh (faces touching only where distinct vertices coincide do not
        count): its inside is undefined where it crosses itself.
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
    points = np.ascontiguousarray(points, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    partner, others = halfedge_twins(faces, len(points))
    if (others != 1).any():
        raise ValueError(f"the mesh must be closed and manifold: {int((others != 1).sum())} half-edges are on "
                         "the boundary or shared by more than two faces")
    lo = np.minimum(seeds.min(axis=0), points.min(axis=0))
    hi = np.maximum(seeds.max(axis=0), points.max(axis=0))
    pad = 0.01 * float((hi - lo).max()) + 1e-9
    lo, hi = lo - pad, hi + pad
    margin = 1e-7 * float((hi - lo).max())
    normals = unit_normals(points, faces)
    flat = np.flatnonzero(~normals.any(axis=1))
    if len(flat):
        raise InvalidMeshError(f"mesh has {len(flat)} faces of zero area, whose corners lie on a line (first faces: "
                               f"{flat[:5].tolist()}): the shards would leave a hole at each; pverosion repair "
                               "flips or collapses them")
    crossing = np.flatnonzero(intersecting_faces(points, faces, coincident="shared"))
    if len(crossing):
        raise InvalidMeshError(f"mesh intersects itself: {len(crossing)} faces meet faces they share no vertex with "
                               f"(first faces: {crossing[:5].tolist()}), so the solid the shards fill is undefined "
                               "there; pverosion repair (or pverosion.repair) makes it a surface without "
                               "intersections")
    start, order, dims, size = seed_grid(seeds, lo, hi)
    bound_n, bound_d = _bounding_planes(points, margin=margin)
    tri_adj = np.where(partner >= 0, partner // 3, -1).reshape(-1, 3)
    # the triangles meeting each bucket of a grid, and each (x, y) column of a finer one (for the +z ray);
    # buckets finer than the seed grid's (down to half a mean edge) list fewer triangles far from the query
    edge = float(np.linalg.norm(points[faces[:, 1]] - points[faces[:, 0]], axis=1).mean())
    tgrid = _triangle_grid(points, faces, lo, hi, min(size, max(size / 2, edge / 2)), margin, column=False)
    cgrid = _triangle_grid(points, faces, lo, hi, min(size, max(size / 8, edge / 2)), margin, column=True)
    args = (seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tri_adj, tgrid, cgrid,
            margin)
    n = len(seeds)
    recs, vals, pairs, volume = [], [], [], np.zeros(n)

    def slots(rows: int, capacity: int) -> tuple[np.ndarray, ...]:
        return (np.empty((rows, capacity * RECORDS), np.int64), np.empty((rows, capacity * RECORDS, 7)),
                np.empty((rows, capacity * PAIRS), np.int64), np.empty((rows, capacity * PAIRS), np.int64),
                np.empty((rows, capacity * PAIRS), np.int64))

    def run(first: int, last: int, buffers: tuple[np.ndarray, ...]) -> np.ndarray:
        """Cells first..last-1; keeps the results of those that fit, returns the status per cell."""
        nrec, npair, vol, status = _batch(first, last, *buffers, *args)
        if (status == 1).any():
            raise RuntimeError(f"a Voronoi cell has more than {MAX_FACES} faces; are seeds nearly coincident?")
        volume[first:last] = vol
        r, v, p = _gather(first, *buffers, nrec, npair, status == 0)
        recs.append(r)
        vals.append(v)
        pairs.append(p)
        return status

    buffers = slots(min(_BATCH, n), 1)
    for first in range(0, n, _BATCH):
        last = min(first + _BATCH, n)
        status = run(first, last, buffers)
        for i in np.flatnonzero(status == 2) + first:  # more surface pieces than a batch slot holds: alone, bigger
            capacity = 4
            while run(i, i + 1, slots(1, capacity))[0] == 2:
                capacity *= 4
        if progress is not None:
            progress(last - first)
    graph = _assemble(seeds, volume, np.concatenate(recs), np.concatenate(vals), np.concatenate(pairs), box=(lo, hi))
    graph.mesh_points, graph.mesh_faces = points, faces
    return graph


def _triangle_grid(points: np.ndarray, faces: np.ndarray, lo: np.ndarray, hi: np.ndarray, size: float, margin: float,
                   *, column: bool) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """(start, items, size, dims) of an :func:`overlap_grid` of cubes of edge ``size`` from ``lo`` covering ``hi``,
    or of (x, y) columns of that edge spanning the whole height when ``column``."""
    dims = grid_over(lo, hi, size)
    edges = np.full(3, size)
    if column:
        dims[2] = 1
        edges[2] = hi[2] - lo[2]
    start, items = overlap_grid(points, faces, lo, edges, dims, margin)
    return start, items, size, dims


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


@njit(cache=True)
def _group(recs, n):
    """Records by cell, each cell's sorted by label: (start, index into ``recs``, label), CSR over cells."""
    start = np.zeros(n + 1, np.int64)
    for r in range(recs.shape[0]):
        start[recs[r, 0] + 1] += 1
    start = np.cumsum(start)
    fill = start[:-1].copy()
    index = np.empty(recs.shape[0], np.int64)
    labels = np.empty(recs.shape[0], np.int64)
    for r in range(recs.shape[0]):
        c = recs[r, 0]
        q = fill[c]  # insertion sort: a cell has a few dozen records
        while q > start[c] and labels[q - 1] > recs[r, 1]:
            labels[q] = labels[q - 1]
            index[q] = index[q - 1]
            q -= 1
        labels[q] = recs[r, 1]
        index[q] = r
        fill[c] += 1
    return start, index, labels


@njit(cache=True)
def _find(start, labels, c, lab):
    """Position of cell ``c``'s record labelled ``lab`` in the grouped records, -1 if it has none."""
    lo = lower_bound(labels, start[c], start[c + 1], lab)
    return lo if lo < start[c + 1] and labels[lo] == lab else -1


@njit(cache=True)
def _number_links(start, labels, keep):
    """Links in the order of their keys: interior (a, b), a < b, by a then b; exterior by cell, then triangle.

    Returns, per grouped record, its link (-1 when the link touches a dropped cell), and per link its first and
    second cell (-1 for exterior), the grouped record that gives its values and whether that record is the
    second cell's (the normal is then reversed).
    """
    n = start.size - 1
    link_of = np.full(labels.size, -1, np.int64)
    # an interior link comes from its lower cell's record, or, when the lower cell has none (rounding), the higher's
    orphan_count = np.zeros(n + 1, np.int64)
    for c in range(n):
        for q in range(start[c], start[c + 1]):
            lab = labels[q]
            if 0 <= lab < c and keep[c] and keep[lab] and _find(start, labels, lab, c) < 0:
                orphan_count[lab + 1] += 1
    orphan_start = np.cumsum(orphan_count)
    fill = orphan_start[:-1].copy()
    orphans = np.empty(orphan_start[-1], np.int64)  # grouped records
    orphan_cell = np.empty(orphan_start[-1], np.int64)
    for c in range(n):  # in increasing c, so every lower cell's orphans are sorted
        for q in range(start[c], start[c + 1]):
            lab = labels[q]
            if 0 <= lab < c and keep[c] and keep[lab] and _find(start, labels, lab, c) < 0:
                orphans[fill[lab]] = q
                orphan_cell[fill[lab]] = c
                fill[lab] += 1
    n_links = orphans.size
    for c in range(n):
        if keep[c]:
            for q in range(start[c], start[c + 1]):
                lab = labels[q]
                if lab < 0 or (lab > c and keep[lab]):
                    n_links += 1
    first = np.empty(n_links, np.int64)
    second = np.empty(n_links, np.int64)
    source = np.empty(n_links, np.int64)
    flip = np.zeros(n_links, np.bool_)
    k = 0
    for c in range(n):
        if not keep[c]:
            continue
        q = start[c]
        o = orphan_start[c]
        while True:  # merge the cell's own records of higher cells with its orphans
            while q < start[c + 1] and (labels[q] <= c or not keep[labels[q]]):
                q += 1
            own = labels[q] if q < start[c + 1] else -1
            other = orphan_cell[o] if o < orphan_start[c + 1] else -1
            if own < 0 and other < 0:
                break
            first[k] = c
            if other < 0 or (0 <= own < other):
                second[k], source[k] = own, q
                q += 1
            else:
                second[k], source[k], flip[k] = other, orphans[o], True
                o += 1
            link_of[source[k]] = k
            k += 1
    for c in range(n):
        if not keep[c]:
            continue
        for q in range(start[c + 1] - 1, start[c] - 1, -1):  # labels -1 - t descending: triangles ascending
            if labels[q] < 0:
                first[k], second[k], source[k] = c, -1, q
                link_of[q] = k
                k += 1
    for c in range(n):  # the higher cell's records of the other interior links
        for q in range(start[c], start[c + 1]):
            lab = labels[q]
            if 0 <= lab < c and link_of[q] < 0:
                r = _find(start, labels, lab, c)
                if r >= 0:
                    link_of[q] = link_of[r]
    return link_of, first, second, source, flip


@njit(cache=True, inline="always")
def _link_of(start, labels, link_of, c, lab):
    """Link of the record labelled ``lab`` of cell ``c``; an interior link may be recorded by the other cell only."""
    q = _find(start, labels, c, lab)
    if q < 0 and lab >= 0:
        q = _find(start, labels, lab, c)
    return link_of[q] if q >= 0 else -1


@njit(cache=True, parallel=True)
def _pair_links(pairs, start, labels, link_of):
    """Both links of every neighbour pair (cell, label, cell, label); -1 for a link that does not exist."""
    ia = np.empty(pairs.shape[0], np.int64)
    ib = np.empty(pairs.shape[0], np.int64)
    for q in prange(pairs.shape[0]):
        ia[q] = _link_of(start, labels, link_of, pairs[q, 0], pairs[q, 1])
        ib[q] = _link_of(start, labels, link_of, pairs[q, 2], pairs[q, 3])
    return ia, ib


@njit(cache=True, parallel=True)
def _symmetric_csr(ia, ib, n):
    """CSR rows of the undirected graph with edges (ia, ib), each neighbour once, sorted.

    Edges with a negative end and loops are left out.
    """
    count = np.zeros(n + 1, np.int64)
    for q in range(ia.size):
        if ia[q] >= 0 and ib[q] >= 0 and ia[q] != ib[q]:
            count[ia[q] + 1] += 1
            count[ib[q] + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    cols = np.empty(start[-1], np.int64)
    for q in range(ia.size):
        if ia[q] >= 0 and ib[q] >= 0 and ia[q] != ib[q]:
            cols[fill[ia[q]]] = ib[q]
            fill[ia[q]] += 1
            cols[fill[ib[q]]] = ia[q]
            fill[ib[q]] += 1
    size = np.empty(n + 1, np.int64)
    size[0] = 0
    for r in prange(n):  # sort each row in place (insertion: rows are short) and drop repeats
        lo = start[r]
        k = lo
        for q in range(lo, start[r + 1]):
            v = cols[q]
            p = k
            while p > lo and cols[p - 1] > v:
                p -= 1
            if p > lo and cols[p - 1] == v:
                continue
            for s in range(k, p, -1):
                cols[s] = cols[s - 1]
            cols[p] = v
            k += 1
        size[r + 1] = k - lo
    out_start = np.cumsum(size)
    out = np.empty(out_start[-1], np.int64)
    for r in prange(n):
        out[out_start[r]:out_start[r + 1]] = cols[start[r]:start[r] + size[r + 1]]
    return out_start, out


@njit(cache=True)
def _cell_csr(first, second, n_cells):
    """Cells graph: the interior links of each cell, in increasing order."""
    count = np.zeros(n_cells + 1, np.int64)
    for k in range(first.size):
        if second[k] >= 0:
            count[first[k] + 1] += 1
            count[second[k] + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    cols = np.empty(start[-1], np.int64)
    for k in range(first.size):
        if second[k] >= 0:
            cols[fill[first[k]]] = k
            fill[first[k]] += 1
            cols[fill[second[k]]] = k
            fill[second[k]] += 1
    return start, cols


def _surface_patches(link_cells: np.ndarray, ia: np.ndarray, ib: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge the surface pieces of each cell that are joined across mesh edges into one link per patch.

    Parameters
    ----------
    link_cells : (m, 2) int64
        Cells of the links before merging (``(cell, -1)`` for a surface piece).
    ia, ib : (p,) int64
        Neighbouring links (-1 for none).

    Returns
    -------
    patch : (m,) int64
        The merged link of every link, numbered in the order of the lowest link each holds (so interior
        links, which come first and stay alone, keep their numbers).
    lowest : (n,) int64
        The lowest link of every merged link.
    """
    m = len(link_cells)
    exterior = link_cells[:, 1] < 0
    ok = (ia >= 0) & (ib >= 0)
    a, b = ia[ok], ib[ok]
    same = exterior[a] & exterior[b] & (link_cells[a, 0] == link_cells[b, 0])
    joins = coo_matrix((np.ones(int(same.sum())), (a[same], b[same])), shape=(m, m))
    _, label = connected_components(joins, directed=False)
    lowest = np.full(label.max() + 1 if m else 0, m, np.int64)
    np.minimum.at(lowest, label, np.arange(m))
    order = np.argsort(lowest, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[label], lowest[order]


def _assemble(seeds, volume, recs, vals, pairs, *, box) -> ShardGraph:
    """The graph from the cells' records (cell, label) with values (area, centroid, normal) and pairs."""
    n = len(seeds)
    keep_cell = volume > 0.0
    start, index, labels = _group(recs, n)
    link_of, first, second, source, flip = _number_links(start, labels, keep_cell)
    v = vals[index[source]]
    normal = v[:, 4:7].copy()
    normal[flip] *= -1.0
    triangle = np.where(second < 0, -1 - labels[source], -1)
    renumber = np.cumsum(keep_cell) - 1
    link_cells = np.stack([renumber[first], np.where(second >= 0, renumber[np.maximum(second, 0)], -1)], axis=1)
    n_cells = int(keep_cell.sum())
    ia, ib = _pair_links(pairs, start, labels, link_of)
    # one exterior link per connected surface patch of a cell
    patch, lowest = _surface_patches(link_cells, ia, ib)
    n_links = len(lowest)
    area = np.bincount(patch, v[:, 0], minlength=n_links)
    alone = (np.bincount(patch, minlength=n_links) == 1)[:, None]
    moment = np.stack([np.bincount(patch, v[:, 0] * v[:, 1 + k], minlength=n_links) for k in range(3)], axis=1)
    centroid = np.where(alone, v[lowest, 1:4], moment / area[:, None])
    vector = np.stack([np.bincount(patch, v[:, 0] * normal[:, k], minlength=n_links) for k in range(3)], axis=1)
    length = np.linalg.norm(vector, axis=1)[:, None]
    direction = np.divide(vector, length, out=np.zeros_like(vector), where=length > 0.0)
    link_normal = np.where(alone, normal[lowest], direction)
    pieces = np.flatnonzero(triangle >= 0)
    pieces = pieces[np.lexsort((triangle[pieces], patch[pieces]))]
    surface_start = np.searchsorted(patch[pieces], np.arange(n_links + 1)).astype(np.int64)
    link_start, link_neighbours = _symmetric_csr(np.where(ia >= 0, patch[ia], -1), np.where(ib >= 0, patch[ib], -1),
                                                 n_links)
    link_cells = link_cells[lowest]
    cell_start, cell_links = _cell_csr(link_cells[:, 0], link_cells[:, 1], n_cells)
    return ShardGraph(seeds=seeds[keep_cell], volume=volume[keep_cell], link_cells=link_cells.astype(np.int64),
                      surface_start=surface_start, surface_triangle=triangle[pieces].astype(np.int64),
                      link_area=area, link_centroid=np.ascontiguousarray(centroid),
                      link_normal=np.ascontiguousarray(link_normal), cell_start=cell_start, cell_links=cell_links,
                      link_start=link_start, link_neighbours=link_neighbours, box=box,
                      cell_seed=np.flatnonzero(keep_cell), input_seeds=seeds, mesh_points=np.empty((0, 3)),
                      mesh_faces=np.empty((0, 3), np.int64))
