"""Repair of intersecting triangle meshes and Boolean operations (Skorkovská's thesis, §10.2-10.3).

0. A pre-pass removes nearly degenerate faces (needles by edge collapse,
   caps by edge flip; :mod:`pverosion.kernels.mesh.degenerate`): an exactly
   degenerate face on a curve has no plane to cut in.
1. The intersection curves are found exactly
   (:func:`pverosion.kernels.exact.intersection_curves.intersection_curves`).
2. Faces that overlap in a common plane get segments too: the parts of
   each one's edges inside the other, found exactly in 2-D
   (:func:`pverosion.kernels.exact.intersection_curves.coplanar_segments`), so that
   every piece of either lies wholly inside or outside the other.
   Every face that an intersection segment lies on, or whose edge a curve
   point splits, is cut along its segments: its polygons are rebuilt and
   triangulated by ear clipping (:func:`pverosion.kernels.exact.polygon_cut.cut_triangles`).
   The pieces on both sides of a curve share the curve's points, so the
   cut mesh is stitched along the curves by construction.
3. The curves divide the surface into patches (faces connected across edges
   that are not on a curve). Each patch lies wholly inside or outside every
   other part of the surface: its winding number is read once, by a ray from
   a point of its largest face. A patch lying on other input faces (a
   coplanar overlap) leaves all of them out of its ray, and each of them
   adds 1 to its operand's winding number on its back side.
4. Which patches stay depends on the operation. A repair keeps the boundary
   of the region of winding number >= 1: patches with winding number 0 just
   in front of them. A Boolean operation keeps, of each operand, the patches
   outside or inside the other, the thesis' temporary normals deciding
   which: a difference turns the subtracted operand's kept patches around.
   Of coincident patches (faces overlapping in a plane, cut alike), only
   those of the lowest input face stay, and only where the result lies on
   one side of them.
5. Optionally, the mesh is improved: the needles and caps the cutting made
   collapse, flip or split while the curve vertices stay; should faces come
   to meet, their vertices are locked and the improvement starts over.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels._search import lower_bound
from pverosion.kernels._threads import HEAVY_ITEMS_PER_RANGE, for_ranges
from pverosion.kernels.exact.intersection import intersecting_faces
from pverosion.kernels.exact.intersection_curves import (
    VERTEX,
    IntersectionCurves,
    canonical_vertices,
    coplanar_overlaps,
    curves_of,
    trace_polylines,
    unique_rows,
)
from pverosion.kernels.exact.polygon_cut import cut_triangles
from pverosion.kernels.exact.predicates import sign_orient2d
from pverosion.kernels.mesh.degenerate import remove_degenerate_faces
from pverosion.kernels.mesh.geometry import average_edge_length
from pverosion.kernels.mesh.orientation import orient_faces
from pverosion.kernels.mesh.topology import (
    _incidence,
    boundary_edges,
    edge_topology,
    find_root,
    halfedge_twins,
    join_sets,
)
from pverosion.kernels.spatial.grid import bucket_boxes
from pverosion.kernels.spatial.mesh_query import ray_winding, ray_winding_without
from pverosion.kernels.tolerances import REPAIR_TOLERANCE
from pverosion.kernels.validation import InvalidMeshError, as_triangle_mesh

__all__ = ["OPERATIONS", "CoplanarOverlapError", "RepairError", "RepairResult", "boolean_meshes", "mesh_problems",
           "outward_parts", "repair_intersections"]


class CoplanarOverlapError(ValueError):
    """Deprecated: no longer raised. Faces that overlap in a common plane are cut like any others; the name stays
    for code that catches it."""


DEFAULT_TOLERANCE = REPAIR_TOLERANCE
"""Default ``tolerance`` of :func:`repair_intersections` and :func:`boolean_meshes`
(:data:`pverosion.kernels.tolerances.REPAIR_TOLERANCE`)."""

OPERATIONS = ("union", "intersection", "difference", "reverse_difference")
"""Boolean operations: A ∪ B, A ∩ B, A ∖ B, B ∖ A."""


THIN_SHELL = 1e-9
"""A shell (edge-connected part) of the result whose |volume| is at most this times its area times its own
bounding-box diagonal encloses nothing: it is dropped, and :func:`mesh_problems` reports one."""

IMPROVE_EDGE_RATIO = 0.25
"""Mesh improvement after a repair: edges shorter than this times the input's average edge length collapse."""

IMPROVE_MAX_ANGLE = 150.0
"""Mesh improvement after a repair: faces with a larger angle (degrees) are caps, flipped or split."""

FEW_RAYS = 16
"""Winding numbers by at most this many rays test every face instead of building a grid of columns first."""

# the region of every operation, from whether a point is inside A and inside B (each: its winding number >= 1)
_REGION = {
    None: lambda a: a,
    "union": lambda a, b: a | b,
    "intersection": lambda a, b: a & b,
    "difference": lambda a, b: a & ~b,
    "reverse_difference": lambda a, b: b & ~a,
}


@dataclass(frozen=True)
class RepairResult:
    """A repaired mesh or the result of a Boolean operation.

    Attributes
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3), int64
    source_face : numpy.ndarray, shape (F,), int64
        The input face each output face is (a piece of); for a Boolean
        operation, faces of B are numbered after those of A.
    source_vertex : numpy.ndarray, shape (V,), int64
        The input vertex each output vertex is (of the lowest index where
        input vertices coincide), -1 for a new vertex on a curve.
    on_curve : numpy.ndarray, shape (V,), bool
        Vertices on an intersection curve.
    curves : IntersectionCurves
        The intersection boundary that was found (with the case table).
    polylines : list of numpy.ndarray
        The curves as point indices into ``points`` (closed ones repeat
        their first point).
    """

    points: np.ndarray
    faces: np.ndarray
    source_face: np.ndarray
    source_vertex: np.ndarray
    on_curve: np.ndarray
    curves: IntersectionCurves
    polylines: list


# --- cutting ---------------------------------------------------------------------------------------------------


@njit(cache=True)
def _edge_keys(canon, faces):
    """Key a * V + b (a < b, canonical vertices) of every face edge k (from corner k to k + 1): (F, 3)."""
    n = canon.shape[0]
    out = np.empty(faces.shape, np.int64)
    for f in range(faces.shape[0]):
        for k in range(3):
            a, b = canon[faces[f, k]], canon[faces[f, (k + 1) % 3]]
            out[f, k] = min(a, b) * n + max(a, b)
    return out


@njit(cache=True)
def _edge_matches(wanted, keys):
    """Every (i, j) with ``wanted[i] == keys[j]`` (W,) and (K,) int64 >= 0, as two arrays, by a hash table of
    ``wanted`` (one pass over ``keys`` instead of a sort of them)."""
    size = np.int64(16)  # np.int64, not literals, for values a loop updates: typed in numba's first pass
    while size < 2 * wanted.shape[0]:
        size *= 2
    table = np.full(size, -1, np.int64)  # the first row of every distinct wanted key
    chain = np.full(wanted.shape[0], -1, np.int64)  # the next row with the same key
    last = np.full(size, -1, np.int64)
    for i in range(wanted.shape[0]):
        slot = (wanted[i] * 0x1E3779B97F4A7C15 >> 17) & (size - 1)
        while table[slot] >= 0 and wanted[table[slot]] != wanted[i]:
            slot = (slot + 1) & (size - 1)
        if table[slot] < 0:
            table[slot] = i
        else:
            chain[last[slot]] = i
        last[slot] = i
    n = np.int64(0)
    for phase in range(2):  # count, then fill
        if phase == 1:
            rows = np.empty(n, np.int64)
            cols = np.empty(n, np.int64)
            n = np.int64(0)
        for j in range(keys.shape[0]):
            slot = (keys[j] * 0x1E3779B97F4A7C15 >> 17) & (size - 1)
            while table[slot] >= 0 and wanted[table[slot]] != keys[j]:
                slot = (slot + 1) & (size - 1)
            i = table[slot]
            while i >= 0:
                if phase == 1:
                    rows[n], cols[n] = i, j
                n += 1
                i = chain[i]
    return rows, cols


def _face_points(fcs: np.ndarray, canon: np.ndarray, curves: IntersectionCurves):
    """Every (face, curve point, location on the face) to cut with, sorted by face and point.

    The ends of each face's own segments, plus the curve points inside any
    edge of the face (also those a neighbour's segment put there), so that
    no cut leaves a T-junction.
    """
    return unique_rows(_face_point_rows(fcs, canon, curves.pairs, curves.segments, curves.locations))[0]


@njit(cache=True)
def _face_point_rows(fcs, canon, pairs, segments, locations):
    """The rows of :func:`_face_points`, unsorted and with repeats: (face, point, location) of every segment end
    on each of its two faces, then of every end inside an edge on every face with that edge."""
    n_seg = segments.shape[0]
    own = np.empty((4 * n_seg, 3), np.int64)
    n_edge = np.int64(0)
    for side in range(2):
        for s in range(n_seg):
            for e in range(2):
                r = 2 * n_seg * side + 2 * s + e
                own[r, 0], own[r, 1], own[r, 2] = pairs[s, side], segments[s, e], locations[s, e, side]
                if 3 <= locations[s, e, side] < 6:
                    n_edge += 1
    keys = _edge_keys(canon, fcs)
    on_edge = np.empty(n_edge, np.int64)  # the own rows inside an edge, and the key of that edge
    edge_key = np.empty(n_edge, np.int64)
    n_edge = np.int64(0)
    for r in range(own.shape[0]):
        if 3 <= own[r, 2] < 6:
            on_edge[n_edge] = r
            edge_key[n_edge] = keys[own[r, 0], own[r, 2] - 3]
            n_edge += 1
    rows, slots = _edge_matches(edge_key, keys.ravel())
    out = np.empty((own.shape[0] + rows.shape[0], 3), np.int64)
    for r in range(own.shape[0]):  # element by element: an array slice assignment compiles numba's shape error
        out[r, 0], out[r, 1], out[r, 2] = own[r, 0], own[r, 1], own[r, 2]
    for i in range(rows.shape[0]):
        r = own.shape[0] + i
        out[r, 0], out[r, 1], out[r, 2] = slots[i] // 3, own[on_edge[rows[i]], 1], 3 + slots[i] % 3
    return out


def _cut_faces(pts, fcs, canon, curves):
    """Cut the faces touched by the curves; returns the output faces (canonical / curve-point ids), their
    source faces, and the vertex id of every curve point."""
    n_vertices = len(pts)
    keys = curves.point_keys
    point_id = np.where(keys[:, 0] == VERTEX, keys[:, 1], n_vertices + np.arange(len(keys)))
    table = _face_points(fcs, canon, curves)
    # the table is sorted by face: the first row of every face is where the face changes
    first_row = np.flatnonzero(np.r_[True, table[1:, 0] != table[:-1, 0]]) if len(table) else np.zeros(0, np.int64)
    cut = table[first_row, 0]
    whole = np.ones(len(fcs), bool)
    whole[cut] = False
    kept = np.flatnonzero(whole)
    if len(cut) == 0:
        return canon[fcs[kept]], kept, point_id
    xy, location, param, point_start, ids, segments, seg_start = _cut_input(
        pts, fcs, canon, table, cut, np.r_[first_row, len(table)], curves.points, point_id, curves.pairs,
        curves.segments)
    triangles, _, tri_start = cut_triangles(xy, location, param, point_start, segments, seg_start)
    counts = np.diff(tri_start)
    if np.any(counts == 0):
        raise RepairError(f"face {cut[np.argmax(counts == 0)]} could not be cut along its intersection segments")
    tri_owner = np.repeat(np.arange(len(cut)), counts)
    pieces = ids[point_start[tri_owner][:, None] + triangles]
    return (np.concatenate([canon[fcs[kept]], pieces]), np.concatenate([kept, cut[tri_owner]]), point_id)


@njit(cache=True)
def _cut_input(pts, fcs, canon, table, cut, row_start, curve_points, point_id, pairs, segments):
    """The input of :func:`cut_triangles` for the faces ``cut`` (C,) from the rows (face, curve point, location)
    of :func:`_face_points` (``table`` (R, 3), the rows of ``cut[c]`` from ``row_start[c]`` on): every face's
    local points (its 3 corners, then its curve points that are not corners, in table order) projected along the
    axis its normal points most along (turned so that the face runs counterclockwise), their locations, their
    parameters along their edges, the CSR offsets (C + 1,), the output vertex id of every local point, and the
    faces' segments in local points with their CSR offsets (C + 1,) (a segment once for each of its two faces, in
    the order of ``pairs``' first column, then its second)."""
    n_cut = cut.shape[0]
    point_start = np.zeros(n_cut + 1, np.int64)
    for c in range(n_cut):
        n_other = np.int64(0)
        for r in range(row_start[c], row_start[c + 1]):
            if table[r, 2] >= 3:
                n_other += 1
        point_start[c + 1] = point_start[c] + 3 + n_other
    n = point_start[n_cut]
    xy = np.empty((n, 2))
    location = np.empty(n, np.int64)
    param = np.zeros(n)
    ids = np.empty(n, np.int64)
    local = np.empty(table.shape[0], np.int64)  # every row's point on its face
    for c in range(n_cut):
        f, at = cut[c], point_start[c]
        p0, p1, p2 = pts[fcs[f, 0]], pts[fcs[f, 1]], pts[fcs[f, 2]]
        ux, uy, uz = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
        wx, wy, wz = p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]
        normal = (uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx)
        axis = 0 if abs(normal[0]) >= abs(normal[1]) and abs(normal[0]) >= abs(normal[2]) else (
            1 if abs(normal[1]) >= abs(normal[2]) else 2)
        i, j = (axis + 1) % 3, (axis + 2) % 3
        if normal[axis] < 0.0:
            i, j = j, i
        for k in range(3):
            corner = pts[fcs[f, k]]
            xy[at + k, 0], xy[at + k, 1] = corner[i], corner[j]
            location[at + k] = k
            ids[at + k] = canon[fcs[f, k]]
        m = at + 3
        for r in range(row_start[c], row_start[c + 1]):
            loc = table[r, 2]
            if loc < 3:
                local[r] = loc
                continue
            local[r] = m - at
            q = curve_points[table[r, 1]]
            xy[m, 0], xy[m, 1] = q[i], q[j]
            location[m] = loc
            ids[m] = point_id[table[r, 1]]
            if loc < 6:
                a, b = pts[fcs[f, loc - 3]], pts[fcs[f, (loc - 2) % 3]]
                ex, ey, ez = b[0] - a[0], b[1] - a[1], b[2] - a[2]
                param[m] = ((q[0] - a[0]) * ex + (q[1] - a[1]) * ey + (q[2] - a[2]) * ez) / (ex * ex + ey * ey
                                                                                            + ez * ez)
            m += 1
    local_segments, seg_start = _local_segments(fcs.shape[0], table, cut, row_start, local, pairs, segments)
    return xy, location, param, point_start, ids, local_segments, seg_start


@njit(cache=True)
def _local_segments(n_faces, table, cut, row_start, local, pairs, segments):
    """The segments of every cut face in its local points, and their CSR offsets (see :func:`_cut_input`)."""
    slot = np.full(n_faces, -1, np.int64)
    for c in range(cut.shape[0]):
        slot[cut[c]] = c
    seg_start = np.zeros(cut.shape[0] + 1, np.int64)
    for side in range(2):
        for s in range(pairs.shape[0]):
            seg_start[slot[pairs[s, side]] + 1] += 1
    for c in range(cut.shape[0]):
        seg_start[c + 1] += seg_start[c]
    fill = seg_start[:-1].copy()
    out = np.empty((2 * pairs.shape[0], 2), np.int64)
    for side in range(2):
        for s in range(pairs.shape[0]):
            c = slot[pairs[s, side]]
            for e in range(2):  # the row of (face, point): rows of a face are sorted by point
                lo, hi = row_start[c], row_start[c + 1]
                while lo < hi:
                    mid = (lo + hi) // 2
                    if table[mid, 1] < segments[s, e]:
                        lo = mid + 1
                    else:
                        hi = mid
                out[fill[c], e] = local[lo]
            fill[c] += 1
    return out, seg_start


# --- patches and their winding numbers ---------------------------------------------------------------------------


@njit(cache=True)
def _patches(faces, n_vertices, cut_edges, pairs_only=False):
    """Patch of every face (F,), labels 0..C-1 in order of first face: faces connected across edges that are
    not intersection edges (sorted keys a * V + b, a < b); with ``pairs_only``, only across edges of exactly
    two faces (pieces of coincident faces cut alike have edges of four)."""
    indptr, face_ids, _ = _incidence(faces, n_vertices)
    parent = np.arange(faces.shape[0])
    for f in range(faces.shape[0]):
        for k in range(3):
            a, b = faces[f, k], faces[f, (k + 1) % 3]
            if a > b:
                continue  # every edge from the face where it runs upwards
            at = lower_bound(cut_edges, 0, cut_edges.shape[0], a * n_vertices + b)
            if at < cut_edges.shape[0] and cut_edges[at] == a * n_vertices + b:
                continue
            if pairs_only:
                others = np.int64(0)
                for s in range(indptr[a], indptr[a + 1]):
                    g = face_ids[s]
                    if g != f and (faces[g, 0] == b or faces[g, 1] == b or faces[g, 2] == b):
                        others += 1
                if others != 1:
                    continue
            for s in range(indptr[a], indptr[a + 1]):
                g = face_ids[s]
                if g != f and (faces[g, 0] == b or faces[g, 1] == b or faces[g, 2] == b):
                    join_sets(parent, f, g)
    label = np.full(faces.shape[0], -1, np.int64)
    count = np.int64(0)
    for f in range(faces.shape[0]):
        r = find_root(parent, f)
        if label[r] < 0:
            label[r] = count
            count += 1
        label[f] = label[r]
    return label


@njit(cache=True, nogil=True)
def _winding_range(queries, skip, group, points, faces, lo, size, dims, start2, items2, face_group, out, start, stop):
    for q in range(start, stop):
        out[q] = ray_winding(queries[q], points, faces, lo, size, dims, start2, items2, skip[q], face_group, group[q])


def _ray_windings(queries, skip, group, points, faces, lo, size, dims, start2, items2, face_group) -> np.ndarray:
    """:func:`ray_winding` of every query point (Q, 3) (coordinates already permuted for the ray's axis)."""
    out = np.empty(queries.shape[0], np.int64)
    for_ranges(_winding_range, queries.shape[0], queries, skip, group, points, faces, lo, size, dims, start2, items2,
               face_group, out, min_items=HEAVY_ITEMS_PER_RANGE)
    return out


@njit(cache=True)
def _columns(points, faces):
    """Grid of (x, y) columns over the faces' boxes, as :class:`TriangleIndex` builds for its +z ray:
    (lower corner, column edge, columns per axis (3,), CSR offsets, faces)."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    edge = 0.0
    for f in range(faces.shape[0]):
        for k in range(3):
            for a in range(3):
                lo[a] = min(lo[a], points[faces[f, k], a])
                hi[a] = max(hi[a], points[faces[f, k], a])
        edge += np.sqrt((points[faces[f, 1], 0] - points[faces[f, 0], 0]) ** 2
                        + (points[faces[f, 1], 1] - points[faces[f, 0], 1]) ** 2
                        + (points[faces[f, 1], 2] - points[faces[f, 0], 2]) ** 2)
    size = max(2.0 * edge / max(faces.shape[0], 1), max(hi[0] - lo[0], hi[1] - lo[1], 1e-12) / 256.0)
    dims = np.ones(3, np.int64)
    for a in range(2):
        dims[a] = max(int(np.ceil(max(hi[a] - lo[a], 1e-12) / size)), 1)
    low = np.zeros((faces.shape[0], 3), np.int64)  # column boxes (one layer along z)
    high = np.zeros((faces.shape[0], 3), np.int64)
    for f in range(faces.shape[0]):
        for a in range(2):
            x0 = min(points[faces[f, 0], a], points[faces[f, 1], a], points[faces[f, 2], a])
            x1 = max(points[faces[f, 0], a], points[faces[f, 1], a], points[faces[f, 2], a])
            low[f, a] = min(max(int((x0 - lo[a]) / size), 0), dims[a] - 1)
            high[f, a] = min(max(int((x1 - lo[a]) / size), 0), dims[a] - 1)
    start, items = bucket_boxes(low, high, dims)
    return lo, size, dims, start, items


def _ray_columns(points, faces, n_rays):
    """:func:`_columns`, or for at most :data:`FEW_RAYS` rays a single column holding every face (building the grid
    costs more than crossing-testing every face; the winding numbers are the same)."""
    if n_rays > FEW_RAYS:
        return _columns(points, faces)
    lo = _box(points)[0] if len(points) else np.zeros(3)
    return (lo, np.inf, np.ones(3, np.int64), np.array([0, len(faces)], np.int64),
            np.arange(len(faces), dtype=np.int64))


def _patch_windings(points, faces, face_group, reps, groups) -> tuple[np.ndarray, np.ndarray]:
    """Winding numbers of the faces of ``groups`` (< 0: all) at the centroids of the faces ``reps``, leaving
    those faces out, by rays along the axis their normals point most along (z where they are not vertical),
    and whether each rep faces down that axis."""
    if len(reps) <= FEW_RAYS:
        return _few_windings(points, faces, face_group, reps, groups)
    tri = points[faces[reps]]
    normal = _cross_rows(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    axis = np.where(normal[:, 2] != 0.0, 2, np.argmax(np.abs(normal), axis=1))
    centre = tri.mean(axis=1)
    out = np.zeros(len(reps), np.int64)
    for a in np.unique(axis):
        perm = [(a + 1) % 3, (a + 2) % 3, a]  # cyclic: the faces keep their orientation
        turned = np.ascontiguousarray(points[:, perm])
        rows = np.flatnonzero(axis == a)
        lo, size, dims, start, items = _ray_columns(turned, faces, len(rows))
        out[rows] = _ray_windings(np.ascontiguousarray(centre[rows][:, perm]), reps[rows], groups[rows], turned,
                                  faces, lo, size, dims, start, items, face_group)
    return out, normal[np.arange(len(reps)), axis] < 0.0


@njit(cache=True)
def _few_windings(points, faces, face_group, reps, groups):
    """:func:`_patch_windings` by testing every face (for a few rays): the same normals, centroids and rays."""
    n_reps = reps.shape[0]
    out = np.zeros(n_reps, np.int64)
    down = np.zeros(n_reps, np.bool_)
    axis = np.empty(n_reps, np.int64)
    centre = np.empty((n_reps, 3))
    for r in range(n_reps):
        p0, p1, p2 = points[faces[reps[r], 0]], points[faces[reps[r], 1]], points[faces[reps[r], 2]]
        ux, uy, uz = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
        wx, wy, wz = p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]
        normal = (uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx)
        a = 2
        if normal[2] == 0.0:  # the first largest, as numpy's argmax
            a = 1 if abs(normal[1]) > abs(normal[0]) else 0
        axis[r] = a
        down[r] = normal[a] < 0.0
        for k in range(3):
            centre[r, k] = (p0[k] + p1[k] + p2[k]) / 3.0
    dims = np.ones(3, np.int64)
    column = np.array([0, faces.shape[0]], np.int64)
    every = np.arange(faces.shape[0])
    turned = np.empty_like(points)
    query = np.empty(3)
    for a in range(3):
        wanted = np.bool_(False)
        for r in range(n_reps):
            wanted = wanted or axis[r] == a
        if not wanted:
            continue
        for v in range(points.shape[0]):  # cyclic: the faces keep their orientation
            turned[v, 0], turned[v, 1], turned[v, 2] = points[v, (a + 1) % 3], points[v, (a + 2) % 3], points[v, a]
        lo, _ = _box(turned)
        for r in range(n_reps):
            if axis[r] == a:
                query[0], query[1], query[2] = centre[r, (a + 1) % 3], centre[r, (a + 2) % 3], centre[r, a]
                out[r] = ray_winding(query, turned, faces, lo, np.inf, dims, column, every, reps[r], face_group,
                                     groups[r])
    return out, down


@njit(cache=True, nogil=True)
def _winding_without_range(queries, start, left_out, group, points, faces, lo, size, dims, start2, items2, source,
                           face_group, out, first, last):
    for q in range(first, last):
        out[q] = ray_winding_without(queries[q], points, faces, lo, size, dims, start2, items2, source,
                                     left_out[start[q]:start[q + 1]], face_group, group[q])


def _ray_windings_without(queries, start, left_out, group, points, faces, lo, size, dims, start2, items2, source,
                          face_group) -> np.ndarray:
    """:func:`ray_winding_without` of every query point (Q, 3), leaving out the faces whose source is one of
    ``left_out[start[q]:start[q + 1]]``."""
    out = np.empty(queries.shape[0], np.int64)
    for_ranges(_winding_without_range, queries.shape[0], queries, start, left_out, group, points, faces, lo, size,
               dims, start2, items2, source, face_group, out, min_items=HEAVY_ITEMS_PER_RANGE)
    return out


@njit(cache=True)
def _facing(p, tri, axis):
    """Exact sign of the ``axis`` component of the normal of triangle ``tri`` (three point indices)."""
    i, j = (axis + 1) % 3, (axis + 2) % 3
    return sign_orient2d(p[tri[0], i], p[tri[0], j], p[tri[1], i], p[tri[1], j], p[tri[2], i], p[tri[2], j])


@njit(cache=True)
def _coincident_faces(pts, fcs, centre, own, axis, start, partners):
    """The input faces lying on every query point (Q, 3) of input face ``own`` (Q,): ``own`` itself and those of
    its coplanar partners (CSR ``start``, ``partners`` over the input faces) that hold the point strictly inside,
    exactly in the projection along ``axis`` (Q,). Returns the CSR (Q + 1,), (K,) of the faces found."""
    counts = np.zeros(centre.shape[0] + 1, np.int64)
    size = centre.shape[0]
    for q in range(centre.shape[0]):
        size += start[own[q] + 1] - start[own[q]]
    found = np.empty(size, np.int64)
    n = np.int64(0)
    for q in range(centre.shape[0]):
        f, a = own[q], axis[q]
        i, j = (a + 1) % 3, (a + 2) % 3
        found[n] = f
        n += 1
        for s in range(start[f], start[f + 1]):
            g = partners[s]
            turn = _facing(pts, fcs[g], a)
            inside = turn != 0
            for k in range(3):
                b, c = fcs[g, k], fcs[g, (k + 1) % 3]
                if sign_orient2d(pts[b, i], pts[b, j], pts[c, i], pts[c, j], centre[q, i], centre[q, j]) != turn:
                    inside = False
            if inside:
                found[n] = g
                n += 1
        counts[q + 1] = n
    return counts, found[:n].copy()


def _coincident_windings(pts, fcs, input_group, overlaps, points, faces, source, face_group, reps, n_groups):
    """Winding numbers of every group (operand) just in front of and just behind the patches ``reps`` of the cut
    mesh (``points``, ``faces``, input face ``source`` and group ``face_group`` of every face) where they lie on
    input faces (``pts``, ``fcs``, groups ``input_group``) that overlap in a common plane (pairs ``overlaps``).

    At the centroid of a patch's face, the input faces lying on it (its own
    face f and the partners of f in ``overlaps`` that hold the point) are all
    left out of the ray, which meets their plane only there: that gives the
    winding numbers on the ray's side. Across the plane, each left-out face
    of an operand adds 1 to that operand's winding number behind it (as its
    own face does for a patch on no other face). Returns the windings in
    front and behind (n_groups, R), whether each patch lies on another input
    face (R,) bool, and whether f is the lowest of the input faces lying there
    (R,) bool: of pieces lying on each other, those of the lowest face stand
    for all.
    """
    both_ways = np.concatenate([overlaps, overlaps[:, ::-1]])
    both_ways = both_ways[np.argsort(both_ways[:, 0], kind="stable")]
    start = np.searchsorted(both_ways[:, 0], np.arange(len(fcs) + 1))
    tri = points[faces[reps]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    axis = np.where(normal[:, 2] != 0.0, 2, np.argmax(np.abs(normal), axis=1))
    centre = tri.mean(axis=1)
    own = source[reps]
    left_start, left_out = _coincident_faces(pts, fcs, centre, own, axis, start,
                                             np.ascontiguousarray(both_ways[:, 1]))
    count = np.diff(left_start)
    owner = np.repeat(np.arange(len(reps)), count)
    lowest = np.minimum.reduceat(left_out, left_start[:-1]) == own
    facing = _facings(pts, fcs, left_out, axis[owner])
    up = facing[left_start[:-1]] > 0  # f comes first in every list
    front = np.zeros((n_groups, len(reps)), np.int64)
    back = np.zeros((n_groups, len(reps)), np.int64)
    for a in np.unique(axis):
        perm = [(a + 1) % 3, (a + 2) % 3, a]  # cyclic: the faces keep their orientation
        turned = np.ascontiguousarray(points[:, perm])
        rows = np.flatnonzero(axis == a)
        lo, size, dims, col_start, items = _ray_columns(turned, faces, n_groups * len(rows))
        queries = np.ascontiguousarray(centre[rows][:, perm])
        in_rows = np.isin(owner, rows)
        sub_start = np.r_[0, np.cumsum(count[rows])]
        sub = np.ascontiguousarray(left_out[in_rows])
        for k in range(n_groups):
            ray_side = _ray_windings_without(queries, sub_start, sub, np.full(len(rows), k), turned, faces, lo, size,
                                             dims, col_start, items, source, face_group)
            across = ray_side + np.add.reduceat(np.where(input_group[left_out] == k, facing, 0),
                                                left_start[:-1])[rows]
            front[k, rows] = np.where(up[rows], ray_side, across)
            back[k, rows] = np.where(up[rows], across, ray_side)
    return front, back, count > 1, lowest


@njit(cache=True)
def _facings(pts, fcs, which, axis):
    """:func:`_facing` of the input faces ``which`` (K,) along ``axis`` (K,)."""
    out = np.empty(which.shape[0], np.int64)
    for q in range(which.shape[0]):
        out[q] = _facing(pts, fcs[which[q]], axis[q])
    return out


@njit(cache=True)
def _representatives(points, faces, patch):
    """A face of every patch, in patch order: the one whose normal has the largest z component (its centroid
    is away from the patch's rim on a coarse patch; rays along z need no second index), the first such face on
    a tie."""
    n_patches = np.int64(0)
    for f in range(patch.shape[0]):  # patch.max() + 1, whose compilation costs more
        n_patches = max(n_patches, patch[f] + 1)
    best = np.full(n_patches, -np.inf)
    out = np.zeros(n_patches, np.int64)
    for f in range(faces.shape[0]):
        p0, p1, p2 = faces[f, 0], faces[f, 1], faces[f, 2]
        ux, uy, uz = points[p1, 0] - points[p0, 0], points[p1, 1] - points[p0, 1], points[p1, 2] - points[p0, 2]
        vx, vy, vz = points[p2, 0] - points[p0, 0], points[p2, 1] - points[p0, 1], points[p2, 2] - points[p0, 2]
        size = (abs(ux) + abs(uy) + abs(uz)) * (abs(vx) + abs(vy) + abs(vz))  # stands in for vertical faces' area
        key = abs(ux * vy - uy * vx) + 1e-6 * size
        if key > best[patch[f]]:
            best[patch[f]] = key
            out[patch[f]] = f
    return out


# --- the guarantee: a closed, oriented 2-manifold without self-intersections -----------------------------------


class RepairError(RuntimeError):
    """The repair or Boolean could not produce a closed, consistently oriented 2-manifold without
    self-intersections; nothing broken is returned instead."""


@njit(cache=True)
def _fans(faces, partner, n_vertices):
    """Split every vertex into its fans: the vertex of every corner (3F,) after the split (a vertex whose faces
    form several fans gets a new vertex per further fan), and the number of vertices; -1 as the count when a
    half-edge has no twin running the other way (not a closed, oriented surface)."""
    n_corners = 3 * faces.shape[0]
    corner_vertex = np.full(n_corners, -1, np.int64)
    seen = np.zeros(n_vertices, np.bool_)
    count = n_vertices
    for c0 in range(n_corners):
        if corner_vertex[c0] >= 0:
            continue
        v = faces[c0 // 3, c0 % 3]
        vid = v
        if seen[v]:
            vid = count
            count += 1
        seen[v] = True
        c = c0
        while True:
            corner_vertex[c] = vid
            f, k = c // 3, c % 3
            t = partner[3 * f + (k + 2) % 3]  # twin of the half-edge into v: it runs out of v
            if t < 0 or faces[t // 3, t % 3] != v:
                return corner_vertex, -1
            c = t
            if c == c0:
                break
            if corner_vertex[c] >= 0:
                return corner_vertex, -1
    return corner_vertex, count


def _radial_twins(points, faces, partner, others):
    """``partner`` (3F,) completed at edges of more than two faces: each half-edge a -> b is paired with the
    face b -> a next to it around the edge on the side its solid lies (behind its normal), so that solids touching
    along the edge come apart there. Edges whose faces do not alternate in direction around it stay unpaired."""
    partner = partner.copy()
    many = np.flatnonzero(others >= 2)
    if len(many) == 0:
        return partner
    a = faces.ravel()[many]
    b = faces[many // 3, (many % 3 + 1) % 3]
    key = np.minimum(a, b) * len(points) + np.maximum(a, b)
    order = np.lexsort((many, key))
    many, a, b, key = many[order], a[order], b[order], key[order]
    for run in np.split(np.arange(len(key)), np.flatnonzero(np.diff(key)) + 1):
        lo, hi = min(a[run[0]], b[run[0]]), max(a[run[0]], b[run[0]])
        axis = points[hi] - points[lo]
        u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 * np.linalg.norm(axis) else [0.0, 1.0, 0.0])
        w = np.cross(axis, u)
        apex = points[faces[many[run] // 3, (many[run] % 3 + 2) % 3]] - points[lo]
        angle = np.arctan2(apex @ w, apex @ u)  # increasing in the right-hand turn about lo -> hi
        ring = run[np.argsort(angle, kind="stable")]
        up = a[ring] == lo  # faces running lo -> hi have their normal towards increasing angle
        if len(ring) % 2 or np.any(up == np.roll(up, 1)):
            continue
        for i in np.flatnonzero(up):
            h, t = many[ring[i]], many[ring[i - 1]]  # the solid of h lies towards decreasing angle
            partner[h], partner[t] = t, h
    return partner


def _split_touching(points, faces, twins):
    """Vertices and edges where sheets touch split apart (fans and radial pairing, see :func:`_fans`): the new
    points (V', 3), faces (F, 3), the old vertex of every new one (V',), or None when the faces do not pair up
    into a closed, oriented surface. ``twins``: :func:`halfedge_twins` of the faces."""
    partner, others = twins
    partner = _radial_twins(points, faces, partner, others)
    corner_vertex, count = _fans(faces, partner, len(points))
    if count < 0:
        return None
    origin = np.arange(count)
    new = corner_vertex >= len(points)
    origin[corner_vertex[new]] = faces.ravel()[new]
    return points[origin], corner_vertex.reshape(-1, 3), origin


def _shells(points, faces):
    """Shell (edge-connected part) of every face (F,), and the signed volume, area and bounding-box diagonal of
    every shell."""
    shell = _patches(faces, len(points), np.zeros(0, np.int64), False)
    volume, area, diagonal = _shell_sizes(points, faces, shell)
    return shell, volume, area, diagonal


@njit(cache=True)
def _shell_sizes(points, faces, shell):
    """Signed volume, area and bounding-box diagonal of every shell (labels ``shell`` (F,), 0..S-1): sums over the
    faces in order of the volumes of the tetrahedra from the shell's own lowest corner (so a shell far from the
    others keeps the rounding of its own size) and of the faces' areas."""
    n = np.int64(0)
    for f in range(shell.shape[0]):  # shell.max() + 1, whose compilation costs more
        n = max(n, shell[f] + 1)
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    for f in range(faces.shape[0]):
        for c in range(3):
            for a in range(3):
                lo[shell[f], a] = min(lo[shell[f], a], points[faces[f, c], a])
                hi[shell[f], a] = max(hi[shell[f], a], points[faces[f, c], a])
    volume = np.zeros(n)
    area = np.zeros(n)
    diagonal = np.zeros(n)
    for s in range(n):
        diagonal[s] = np.sqrt((hi[s, 0] - lo[s, 0]) ** 2 + (hi[s, 1] - lo[s, 1]) ** 2 + (hi[s, 2] - lo[s, 2]) ** 2)
    for f in range(faces.shape[0]):
        p0, p1, p2 = points[faces[f, 0]], points[faces[f, 1]], points[faces[f, 2]]
        ux, uy, uz = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
        wx, wy, wz = p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]
        cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        o = lo[shell[f]]
        volume[shell[f]] += ((p0[0] - o[0]) * cx + (p0[1] - o[1]) * cy + (p0[2] - o[2]) * cz) / 6.0
        area[shell[f]] += 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
    return volume, area, diagonal


def mesh_problems(points, faces, *, query=None) -> list[str]:
    """What keeps a mesh from being a closed, consistently oriented 2-manifold without self-intersections.

    Checked: every edge in exactly two faces, running opposite ways in them;
    the faces around every vertex form one fan; no shell (edge-connected
    part) whose volume is below :data:`THIN_SHELL` times its area times its
    own bounding-box diagonal; the winding number just in front of every shell
    is 0 (no part inside out or inside another); and, by the exact
    predicates of :func:`~pverosion.kernels.exact.intersection_curves.intersection_curves`,
    no two faces cross or overlap in a common plane (faces at coincident
    vertices may touch there).

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
    query : array_like of bool, shape (F,), optional
        Test only the face pairs that involve these faces for crossings
        (when the others are known not to meet each other); by default all.

    Returns
    -------
    list of str
        One sentence per kind of problem; empty for a valid mesh.
    """
    pts, fcs = as_triangle_mesh(points, faces)
    return _problems(pts, fcs, query, None)


def _problems(pts, fcs, query, shells, twins=None, one_fan=False) -> list[str]:
    """:func:`mesh_problems` of a validated mesh, with its :func:`_shells` and :func:`halfedge_twins` when
    known; ``one_fan``: the faces around every vertex are known to form one fan (:func:`_split_touching` split
    none of its vertices)."""
    n = len(pts)
    problems = []
    partner, others = halfedge_twins(fcs, n) if twins is None else twins
    start = fcs.ravel()
    # every edge in two faces (one other face at every half-edge), the twin running the other way: a valid
    # surface skips the counts below, which name the problems
    if not (np.all(others == 1) and np.all(start[partner] != start)):
        count = edge_topology(fcs, n).face_count
        if np.any(count != 2):
            problems.append(f"{np.count_nonzero(count != 2)} edges are not in exactly two faces")
        directed = fcs[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        same_way = len(directed) - len(unique_rows(directed)[0])
        if same_way:
            problems.append(f"{same_way} edges run the same way in two faces (inconsistent winding)")
        if problems:
            return problems
    n_split = n if one_fan else _fans(fcs, partner, n)[1]
    if n_split != n:
        problems.append(f"{n_split - n} vertices join separate fans of faces")
    if len(fcs) == 0:
        return problems
    shell, volume, area, diagonal = _shells(pts, fcs) if shells is None else shells
    thin = np.abs(volume) <= THIN_SHELL * diagonal * area
    if thin.any():
        problems.append(f"{np.count_nonzero(thin)} shells enclose no volume (|volume| <= {THIN_SHELL:g} x area x "
                        "diagonal)")
    reps = _representatives(pts, fcs, shell)
    winding, down = _patch_windings(pts, fcs, np.zeros(len(fcs), np.int64), reps, np.full(len(reps), -1))
    if np.any(winding - down != 0):
        problems.append(f"{np.count_nonzero(winding - down != 0)} shells are inside out or inside another shell")
    canon = canonical_vertices(pts)
    curves = curves_of(pts, fcs, None, canon, query)
    ends = curves.point_keys[curves.segments]  # (S, 2, 3)
    ends_at_vertices = np.all(ends[:, :, 0] == VERTEX, axis=1)
    corners = canon[fcs[curves.pairs]]  # (S, 2, 3)
    shared = np.all(np.any(ends[:, :, None, None, 1] == corners[:, None], axis=3), axis=(1, 2))
    crossing = np.count_nonzero(~(ends_at_vertices & shared))
    if crossing:
        problems.append(f"{crossing} pairs of faces cross")
    overlaps = len(coplanar_overlaps(pts, fcs, curves))
    if overlaps:
        problems.append(f"{overlaps} pairs of faces overlap in a common plane")
    return problems


def _any_corner(flags: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces (F, 3) with a flagged vertex (``flags`` (V,) bool): (F,) bool."""
    corner = flags[faces]
    return corner[:, 0] | corner[:, 1] | corner[:, 2]


def _diagonal(points: np.ndarray) -> float:
    if len(points) == 0:
        return 0.0
    lo, hi = _box(points)
    return float(np.linalg.norm(hi - lo))


@njit(cache=True)
def _box(points):
    """Lowest and highest corner (3,) of the bounding box of ``points`` (V, 3), V > 0 (one pass; numpy's reduction
    along the first axis of an (V, 3) array is slower)."""
    lo = points[0].copy()
    hi = points[0].copy()
    for v in range(1, points.shape[0]):
        for a in range(3):
            lo[a] = min(lo[a], points[v, a])
            hi[a] = max(hi[a], points[v, a])
    return lo, hi


def _cross_rows(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Cross products of the rows of u and w (N, 3), as :func:`numpy.cross` computes them (without its axis
    handling, which costs more than the products on a few rows)."""
    out = np.empty(u.shape)
    out[:, 0] = u[:, 1] * w[:, 2] - u[:, 2] * w[:, 1]
    out[:, 1] = u[:, 2] * w[:, 0] - u[:, 0] * w[:, 2]
    out[:, 2] = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]
    return out


def _finalized(result: RepairResult) -> RepairResult:
    """``result`` made a closed, oriented 2-manifold by rule, or :class:`RepairError`.

    Where the kept surface touches itself (solids meeting at a vertex or
    along an edge) the vertices are split, one per fan of faces and the faces
    around an edge paired around their solids; shells that enclose no volume
    (below :data:`THIN_SHELL`) are dropped. Then :func:`mesh_problems` must
    find nothing.
    """
    points, faces = result.points, result.faces
    # faces of the input left whole were tested against each other when the curves were found: only pairs with
    # a piece of a cut face (it has a curve point) or a face at a split vertex are tested again
    changed = result.on_curve.copy()
    twins = halfedge_twins(faces, len(points)) if len(faces) else None
    split = _split_touching(points, faces, twins) if len(faces) else None
    if split is not None:
        points, faces, origin = split
        moved = origin != np.arange(len(origin))
        if len(origin) != len(result.points) or moved.any():
            twins = None  # the faces changed
        changed = changed[origin] | moved
        changed[origin[moved]] = True
        result = replace(result, points=points, faces=faces, source_vertex=result.source_vertex[origin],
                         on_curve=result.on_curve[origin])
    shells = None
    if len(faces):
        shells = shell, volume, area, diagonal = _shells(points, faces)
        keep = (np.abs(volume) > THIN_SHELL * diagonal * area)[shell]
        if not keep.all():
            shells = twins = None
            used = _used_vertices(faces[keep], len(points))
            new_index = np.full(len(points), -1, np.int64)
            new_index[used] = np.arange(len(used))
            lines = [new_index[line] for line in result.polylines]
            result = replace(result, points=points[used], faces=new_index[faces[keep]],
                             source_face=result.source_face[keep], source_vertex=result.source_vertex[used],
                             on_curve=result.on_curve[used], polylines=[line for line in lines if np.all(line >= 0)])
            changed = changed[used]
    problems = []
    if len(result.faces):  # empty: nothing left, which is a valid result
        problems = _problems(result.points, result.faces, _any_corner(changed, result.faces), shells, twins,
                             one_fan=split is not None and twins is not None)
    if problems:
        raise RepairError("the result would not be a closed, oriented 2-manifold without self-intersections: "
                          + "; ".join(problems))
    return result


# --- front ends --------------------------------------------------------------------------------------------------


def outward_parts(points, faces) -> np.ndarray:
    """The faces of a closed mesh oriented consistently and outward, part by part, for a repair or Boolean.

    Every edge-connected part is made consistent
    (:func:`~pverosion.kernels.mesh.orientation.orient_faces`) and turned to
    enclose a positive volume; then a part is turned back into a cavity wall
    when every one of its faces lies inside an odd number of the other parts
    (winding numbers by rays from every face). Parts that overlap, or lie
    inside another only partly, stay outward: overlapping parts merge in a
    repair instead of cutting holes into each other.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)

    Returns
    -------
    numpy.ndarray, shape (F, 3), int64
    """
    pts, fcs = as_triangle_mesh(points, faces)
    oriented = orient_faces(pts, fcs, mode="outward")
    fcs, part = oriented.faces, oriented.component
    tri = pts[fcs] - pts.min(axis=0)
    volume = np.bincount(part, np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])))
    fcs = np.where((volume < 0.0)[part, None], fcs[:, ::-1], fcs)
    if len(volume) > 1:
        winding, down = _patch_windings(pts, fcs, part, np.arange(len(fcs)), np.full(len(fcs), -1))
        odd = (winding - down) % 2 == 1  # the parts' own winding is 0 just in front of their faces
        cavity = np.bincount(part, odd, minlength=len(volume)) == np.bincount(part, minlength=len(volume))
        fcs = np.where(cavity[part, None], fcs[:, ::-1], fcs)
    return fcs


def _check_closed(faces: np.ndarray, n_vertices: int, what: str) -> None:
    if len(boundary_edges(faces, n_vertices)):
        raise InvalidMeshError(f"{what} must be closed: it has boundary edges (fill its holes first)")


def _corefine(pts, fcs, group, operation) -> RepairResult:
    """Cut the mesh along its intersection curves and keep the patches that bound the region of ``operation``
    (None: repair), each operand's region being where its winding number is at least 1: a patch stays when that
    region is on one side of it only, turned so that the region lies behind it."""
    canon = canonical_vertices(pts)
    curves = curves_of(pts, fcs, None, canon, coplanar_cuts=True)  # also where an operand meets itself
    overlaps = coplanar_overlaps(pts, fcs, curves)
    faces, source, point_id = _cut_faces(pts, fcs, canon, curves)
    all_points = np.concatenate([pts, curves.points])
    n_all = len(all_points)
    seg = np.sort(point_id[curves.segments], axis=1)
    cut_edges = np.unique(seg[:, 0] * n_all + seg[:, 1])
    patch = _patches(faces, n_all, cut_edges, len(overlaps) > 0)
    source_group = np.zeros(len(faces), np.int64) if group is None else np.asarray(group)[source]
    reps = _representatives(all_points, faces, patch)
    # winding numbers of A and B just in front of every patch; behind it, its own operand's is one more
    n_groups = 1 if group is None else 2
    own = source_group[reps]
    front = np.zeros((n_groups, len(reps)), np.int64)
    fcs_group = np.zeros(len(fcs), np.int64) if group is None else np.asarray(group)
    pair_group = fcs_group[curves.pairs]
    rows = []  # the patches whose winding number of operand k is cast, for every k
    for k in range(n_groups):
        # an operand's own winding number in front of its faces is 0 unless it meets itself (or it is a repair)
        if group is not None and not np.any((pair_group[:, 0] == k) & (pair_group[:, 1] == k)):
            rows.append(np.flatnonzero(own != k))
        else:
            rows.append(np.arange(len(reps)))
    # the rays of all operands at once: one grid of columns over the faces
    winding, down = _patch_windings(all_points, faces, source_group, reps[np.concatenate(rows)],
                                    np.repeat(np.arange(n_groups), [len(r) for r in rows]))
    cast = np.repeat(np.arange(n_groups), [len(r) for r in rows]), np.concatenate(rows)
    front[cast] = winding - (down & (own[cast[1]] == cast[0]))
    back = front + (np.arange(n_groups)[:, None] == own)
    lowest = np.ones(len(reps), bool)
    if len(overlaps):  # patches on coplanar overlaps: the winding numbers across every face lying there
        on_plane = np.isin(source[reps], overlaps)
        rows = np.flatnonzero(on_plane)
        front_c, back_c, shared, lowest_c = _coincident_windings(pts, fcs, fcs_group, overlaps, all_points, faces,
                                                                 source, source_group, reps[rows], n_groups)
        front[:, rows[shared]], back[:, rows[shared]] = front_c[:, shared], back_c[:, shared]
        lowest[rows] = lowest_c
    region = _REGION[operation]
    inside_front, inside_back = region(*(front >= 1)), region(*(back >= 1))
    stays, turns = (inside_front != inside_back) & lowest, inside_front
    keep, turn = stays[patch], turns[patch]
    faces = np.where(turn[:, None], faces[:, ::-1], faces)[keep]
    source = source[keep]
    used = _used_vertices(faces, n_all)
    new_index = np.full(n_all, -1, np.int64)
    new_index[used] = np.arange(len(used))
    on_curve = np.zeros(n_all, bool)
    on_curve[point_id] = True
    polylines = [new_index[point_id[line]] for line in trace_polylines(curves)]
    return RepairResult(points=all_points[used], faces=new_index[faces], source_face=source,
                        source_vertex=np.where(used < len(pts), used, -1),
                        on_curve=on_curve[used], curves=curves, polylines=polylines)


def _used_vertices(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """The vertices that some face uses, ascending (as ``np.unique(faces)``, without a sort)."""
    used = np.zeros(n_vertices, bool)
    used[faces.ravel()] = True
    return np.flatnonzero(used)


def _tolerance(points: np.ndarray, tolerance: float) -> float:
    if not (np.isfinite(tolerance) and tolerance >= 0.0):
        raise ValueError(f"tolerance must be a finite number >= 0; got {tolerance!r}")
    return float(tolerance) * _diagonal(points)


def _without_degenerate(pts, fcs, tol):
    """The pre-pass: the mesh without nearly degenerate faces, with the input vertex and face of every vertex and
    face."""
    if tol == 0.0:
        return pts, fcs, np.arange(len(pts)), np.arange(len(fcs))
    clean = remove_degenerate_faces(pts, fcs, needle_length=tol, cap_height=tol)
    return clean.points, clean.faces, clean.vertex_source, clean.face_source


def _renumbered(result: RepairResult, vertex_source: np.ndarray, face_source: np.ndarray) -> RepairResult:
    """``result`` with its sources taken one step further back (vertex_source (V,) may hold -1)."""
    source = result.source_vertex
    return replace(result, source_face=face_source[result.source_face],
                   source_vertex=np.where(source >= 0, vertex_source[np.maximum(source, 0)], -1))


def _improved(result: RepairResult, edge: float) -> RepairResult:
    """Needles collapsed and caps flipped or split, the curves kept; vertices of faces that would meet another
    face are locked and the improvement starts over (thrice at most, then the result stays as it was)."""
    locked = np.zeros(len(result.points), bool)
    for _ in range(3):
        clean = remove_degenerate_faces(result.points, result.faces, needle_length=IMPROVE_EDGE_RATIO * edge,
                                        max_angle=IMPROVE_MAX_ANGLE, polylines=result.polylines, locked=locked)
        meets = intersecting_faces(clean.points, clean.faces)
        if not meets.any():
            improved = replace(result, points=clean.points, faces=clean.faces, on_curve=clean.on_curve,
                               polylines=clean.polylines, source_vertex=clean.vertex_source,
                               source_face=clean.face_source)
            return _renumbered(improved, result.source_vertex, result.source_face)
        locked[result.faces[clean.face_source[meets]].ravel()] = True
    warnings.warn("the mesh improvement after the repair made faces meet; the repaired mesh is left as it was",
                  RuntimeWarning, stacklevel=3)
    return result


def _checked(result: RepairResult, edge: float | None) -> RepairResult:
    """:func:`_finalized` ``result``, improved first when ``edge`` (the input's average edge length) is given;
    should the improved mesh fail the checks, the result unimproved (with a warning)."""
    if edge is not None:
        improved = _improved(result, edge)
        if improved is not result:
            try:
                return _finalized(improved)
            except RepairError:
                warnings.warn("the mesh improvement after the repair broke the result's checks; the repaired mesh "
                              "is left as it was", RuntimeWarning, stacklevel=3)
    return _finalized(result)


def repair_intersections(points, faces, *, tolerance: float = REPAIR_TOLERANCE, improve: bool = False
                         ) -> RepairResult:
    """Remove the self-intersections of a closed mesh (and intersections between its closed parts).

    The result bounds the region where the winding number of the input is at
    least 1: parts of the surface that ended up inside the solid, or turned
    inside out, are cut away along the intersection curves, and the mesh may
    fall apart into several closed pieces.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        A closed mesh, oriented outward.
    tolerance : float, default: :data:`REPAIR_TOLERANCE`
        Pre-pass: nearly degenerate faces (an edge shorter than this, or a
        corner this close to the opposite edge, relative to the bounding-box
        diagonal) are removed first by edge collapse and edge flip. 0 skips
        the pre-pass (an exactly degenerate face on a curve then cannot be cut).
    improve : bool, default: False
        Improve the mesh afterwards: collapse the needles and flip or split
        the caps that cutting along the curves made (edges shorter than
        :data:`IMPROVE_EDGE_RATIO` times the input's average edge length,
        angles above :data:`IMPROVE_MAX_ANGLE`). Curve vertices stay where
        they are; no face may come to meet another.

    Returns
    -------
    RepairResult

    Raises
    ------
    InvalidMeshError
        If the mesh is not closed.
    ValueError
        For a negative or non-finite tolerance.
    RepairError
        If the result would not be a closed, oriented 2-manifold without
        self-intersections.
    """
    pts, fcs = as_triangle_mesh(points, faces)
    _check_closed(fcs, len(pts), "the mesh")
    clean_pts, clean_fcs, vertex_source, face_source = _without_degenerate(pts, fcs, _tolerance(pts, tolerance))
    result = _renumbered(_corefine(clean_pts, clean_fcs, None, None), vertex_source, face_source)
    return _checked(result, average_edge_length(pts, fcs) if improve else None)


def boolean_meshes(points_a, faces_a, points_b, faces_b, operation: str, *, tolerance: float = REPAIR_TOLERANCE,
                   improve: bool = False) -> RepairResult:
    """Union, intersection or difference of two closed meshes.

    Parameters
    ----------
    points_a, faces_a : array_like, shapes (Va, 3) and (Fa, 3)
        Operand A, closed and oriented outward.
    points_b, faces_b : array_like, shapes (Vb, 3) and (Fb, 3)
        Operand B, closed and oriented outward.
    operation : {"union", "intersection", "difference", "reverse_difference"}
        A ∪ B, A ∩ B, A ∖ B or B ∖ A.
    tolerance : float, default: :data:`REPAIR_TOLERANCE`
        Pre-pass on each operand (relative to that operand's bounding-box
        diagonal), see :func:`repair_intersections`.
    improve : bool, default: False
        Mesh improvement afterwards, see :func:`repair_intersections`.

    Returns
    -------
    RepairResult
        Faces of B are numbered after those of A in ``source_face``.

    Raises
    ------
    ValueError
        For an unknown operation, or a negative or non-finite tolerance.
    InvalidMeshError
        If an operand is not closed.
    RepairError
        If the result would not be a closed, oriented 2-manifold without
        self-intersections.
    """
    if operation not in OPERATIONS:
        raise ValueError(f"operation must be one of {OPERATIONS}; got {operation!r}")
    pa, fa = as_triangle_mesh(points_a, faces_a)
    pb, fb = as_triangle_mesh(points_b, faces_b)
    _check_closed(fa, len(pa), "mesh A")
    _check_closed(fb, len(pb), "mesh B")
    # each operand's own size: where the other one lies does not change which of its faces are degenerate
    ca = _without_degenerate(pa, fa, _tolerance(pa, tolerance))
    cb = _without_degenerate(pb, fb, _tolerance(pb, tolerance))
    pts = np.concatenate([ca[0], cb[0]])
    fcs = np.concatenate([ca[1], cb[1] + len(ca[0])])
    group = np.repeat([0, 1], [len(ca[1]), len(cb[1])])
    result = _renumbered(_corefine(pts, fcs, group, operation), np.concatenate([ca[2], cb[2] + len(pa)]),
                         np.concatenate([ca[3], cb[3] + len(fa)]))
    edge = average_edge_length(np.concatenate([pa, pb]), np.concatenate([fa, fb + len(pa)])) if improve else None
    return _checked(result, edge)
