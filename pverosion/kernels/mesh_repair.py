"""Repair of intersecting triangle meshes and Boolean operations (Skorkovská's thesis, §10.2-10.3).

1. The intersection curves are found exactly
   (:func:`pverosion.kernels.intersection_curves.intersection_curves`).
2. Every face that an intersection segment lies on, or whose edge a curve
   point splits, is cut along its segments: its polygons are rebuilt and
   triangulated by ear clipping (:func:`pverosion.kernels.polygon_cut.cut_triangles`).
   The pieces on both sides of a curve share the curve's points, so the
   cut mesh is stitched along the curves by construction.
3. The curves divide the surface into patches (faces connected across edges
   that are not on a curve). Each patch lies wholly inside or outside every
   other part of the surface: its winding number is read once, by a ray from
   a point of its largest face.
4. Which patches stay depends on the operation. A repair keeps the boundary
   of the region of winding number >= 1: patches with winding number 0 just
   in front of them. A Boolean operation keeps, of each operand, the patches
   outside or inside the other, the thesis' temporary normals deciding
   which: a difference turns the subtracted operand's kept patches around.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pverosion.kernels.intersection_curves import (
    VERTEX,
    IntersectionCurves,
    canonical_vertices,
    intersection_curves,
    trace_polylines,
)
from pverosion.kernels.mesh_query import TriangleIndex, ray_winding
from pverosion.kernels.polygon_cut import cut_triangles
from pverosion.kernels.topology import boundary_edges
from pverosion.kernels.validation import InvalidMeshError, as_triangle_mesh

__all__ = ["OPERATIONS", "RepairResult", "boolean_meshes", "repair_intersections"]

OPERATIONS = ("union", "intersection", "difference", "reverse_difference")
"""Boolean operations: A ∪ B, A ∩ B, A ∖ B, B ∖ A."""

# per operation and operand: the winding number of the other operand a kept patch has, and whether it turns
_KEEP = {
    "union": ((0, False), (0, False)),
    "intersection": ((1, False), (1, False)),
    "difference": ((0, False), (1, True)),
    "reverse_difference": ((1, True), (0, False)),
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
    on_curve: np.ndarray
    curves: IntersectionCurves
    polylines: list


# --- cutting ---------------------------------------------------------------------------------------------------


def _edge_keys(canon: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Key a * V + b (a < b, canonical vertices) of every face edge k (from corner k to k + 1): (F, 3)."""
    a = canon[faces]
    b = np.roll(a, -1, axis=1)
    n = len(canon)
    return np.minimum(a, b) * n + np.maximum(a, b)


def _face_points(pts: np.ndarray, fcs: np.ndarray, canon: np.ndarray, curves: IntersectionCurves):
    """Every (face, curve point, location on the face) to cut with, sorted by face, and the face segments.

    The ends of each face's own segments, plus the curve points inside any
    edge of the face (also those a neighbour's segment put there), so that
    no cut leaves a T-junction.
    """
    seg_face = np.concatenate([curves.pairs[:, 0], curves.pairs[:, 1]])
    seg_points = np.concatenate([curves.segments, curves.segments])
    seg_loc = np.concatenate([curves.locations[:, :, 0], curves.locations[:, :, 1]])
    face = np.repeat(seg_face, 2)
    point = seg_points.ravel()
    loc = seg_loc.ravel()
    # curve points inside edges go to every face with that edge
    keys = _edge_keys(canon, fcs)
    on_edge = (loc >= 3) & (loc < 6)
    edge_key = keys[face[on_edge], loc[on_edge] - 3]
    flat = keys.ravel()
    order = np.argsort(flat, kind="stable")
    lo = np.searchsorted(flat[order], edge_key, side="left")
    hi = np.searchsorted(flat[order], edge_key, side="right")
    count = hi - lo
    rows = np.repeat(np.arange(len(edge_key)), count)
    slots = order[np.concatenate([np.arange(a, b) for a, b in zip(lo, hi)])] if len(rows) else np.zeros(0, np.int64)
    extra_face, extra_loc = slots // 3, 3 + slots % 3
    face = np.concatenate([face, extra_face])
    point = np.concatenate([point, point[on_edge][rows]])
    loc = np.concatenate([loc, extra_loc])
    table = np.unique(np.stack([face, point, loc], axis=1), axis=0)
    return table, seg_face, seg_points


def _project(pts: np.ndarray, tri: np.ndarray) -> tuple[int, bool]:
    """Axis to drop for a face (its normal's largest component) and whether the 2-D corners come out clockwise."""
    p0, p1, p2 = pts[tri]
    normal = np.cross(p1 - p0, p2 - p0)
    axis = int(np.argmax(np.abs(normal)))
    return axis, normal[axis] < 0.0


def _cut_faces(pts, fcs, canon, curves):
    """Cut the faces touched by the curves; returns the output faces (canonical / curve-point ids), their
    source faces, and the vertex id of every curve point."""
    n_vertices = len(pts)
    keys = curves.point_keys
    point_id = np.where(keys[:, 0] == VERTEX, keys[:, 1], n_vertices + np.arange(len(keys)))
    table, seg_face, seg_points = _face_points(pts, fcs, canon, curves)
    cut = np.unique(table[:, 0])
    whole = np.ones(len(fcs), bool)
    whole[cut] = False
    kept = np.flatnonzero(whole)
    out_faces = [canon[fcs[kept]]]
    out_source = [kept]
    if len(cut) == 0:
        return np.concatenate(out_faces), np.concatenate(out_source), point_id
    # local points of every cut face: its 3 corners, then its curve points that are not corners
    xy, location, param, point_start = [], [], [], [0]
    segs, seg_start = [], [0]
    rows_start = np.searchsorted(table[:, 0], cut)
    rows_stop = np.searchsorted(table[:, 0], cut, side="right")
    seg_order = np.argsort(seg_face, kind="stable")
    s_start = np.searchsorted(seg_face[seg_order], cut)
    s_stop = np.searchsorted(seg_face[seg_order], cut, side="right")
    local_ids = []
    for i, f in enumerate(cut):
        tri = fcs[f]
        rows = table[rows_start[i]:rows_stop[i]]
        others = rows[rows[:, 2] >= 3]
        axis, flip = _project(pts, tri)
        cols = [(axis + 1) % 3, (axis + 2) % 3]
        if flip:
            cols = cols[::-1]
        corner_xyz = pts[tri]
        xyz = np.concatenate([corner_xyz, curves.points[others[:, 1]]])
        xy.append(xyz[:, cols])
        location.append(np.concatenate([[0, 1, 2], others[:, 2]]))
        t = np.zeros(len(xyz))
        edge = (others[:, 2] >= 3) & (others[:, 2] < 6)
        if edge.any():
            k = others[edge, 2] - 3
            a, b = corner_xyz[k], corner_xyz[(k + 1) % 3]
            d = b - a
            t[3:][edge] = np.einsum("ij,ij->i", xyz[3:][edge] - a, d) / np.einsum("ij,ij->i", d, d)
        param.append(t)
        point_start.append(point_start[-1] + len(xyz))
        # curve point -> local index (corners by their location)
        local = {int(p): 3 + j for j, p in enumerate(others[:, 1])}
        for p, loc in rows[rows[:, 2] < 3][:, 1:]:
            local[int(p)] = int(loc)
        face_segs = seg_points[seg_order[s_start[i]:s_stop[i]]]
        segs.append(np.array([[local[int(a)], local[int(b)]] for a, b in face_segs], dtype=np.int64).reshape(-1, 2))
        seg_start.append(seg_start[-1] + len(face_segs))
        ids = np.concatenate([canon[tri], point_id[others[:, 1]]])
        local_ids.append(ids)
    triangles, _, tri_start = cut_triangles(np.concatenate(xy), np.concatenate(location).astype(np.int64),
                                            np.concatenate(param), np.asarray(point_start, np.int64),
                                            np.concatenate(segs), np.asarray(seg_start, np.int64))
    for i, f in enumerate(cut):
        local = triangles[tri_start[i]:tri_start[i + 1]]
        if len(local) == 0:
            raise RuntimeError(f"face {f} could not be cut along its intersection segments")
        out_faces.append(local_ids[i][local])
        out_source.append(np.full(len(local), f))
    return np.concatenate(out_faces), np.concatenate(out_source), point_id


# --- patches and their winding numbers ---------------------------------------------------------------------------


def _patches(faces: np.ndarray, n_vertices: int, cut_edges: np.ndarray) -> np.ndarray:
    """Patch of every face (F,): faces connected across edges that are not intersection edges."""
    a = faces
    b = np.roll(faces, -1, axis=1)
    key = (np.minimum(a, b) * n_vertices + np.maximum(a, b)).ravel()
    owner = np.repeat(np.arange(len(faces)), 3)
    free = ~np.isin(key, cut_edges)
    key, owner = key[free], owner[free]
    order = np.argsort(key, kind="stable")
    key, owner = key[order], owner[order]
    same = key[1:] == key[:-1]
    graph = coo_matrix((np.ones(int(same.sum())), (owner[:-1][same], owner[1:][same])),
                       shape=(len(faces), len(faces)))
    return connected_components(graph, directed=False)[1]


class _Rays:
    """Winding numbers by rays along x, y or z over one mesh (an index per axis, built when first needed)."""

    def __init__(self, points: np.ndarray, faces: np.ndarray, group: np.ndarray) -> None:
        self.points, self.faces, self.group = points, faces, group
        self._index: dict[int, TriangleIndex] = {}

    def winding(self, p: np.ndarray, axis: int, skip: int, group: int) -> int:
        """Winding number at ``p`` along +axis, leaving out face ``skip``, of the faces of ``group`` (< 0: all)."""
        perm = [(axis + 1) % 3, (axis + 2) % 3, axis]  # cyclic: the faces keep their orientation
        if axis not in self._index:
            self._index[axis] = TriangleIndex.build(self.points[:, perm], self.faces)
        ix = self._index[axis]
        return int(ray_winding(p[perm], ix.points, ix.faces, ix.lo, ix.size, ix.dims, ix.start2, ix.items2, skip,
                               self.group, group))


def _select(points, faces, source_group, patch, keep_rule) -> tuple[np.ndarray, np.ndarray]:
    """Whether each face stays (F,) and whether it turns (F,), decided once per patch by ``keep_rule``."""
    tri = points[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(normal, axis=1)
    rays = _Rays(points, faces, source_group)
    keep = np.zeros(len(faces), bool)
    turn = np.zeros(len(faces), bool)
    order = np.lexsort((-area, patch))
    first = order[np.r_[True, patch[order][1:] != patch[order][:-1]]]  # largest face of every patch
    for f in first:
        axis = int(np.argmax(np.abs(normal[f])))
        centre = tri[f].mean(axis=0)
        stays, turns = keep_rule(rays, f, centre, axis, normal[f, axis] < 0.0)
        members = patch == patch[f]
        keep[members] = stays
        turn[members] = turns
    return keep, turn


# --- front ends --------------------------------------------------------------------------------------------------


def _check_closed(faces: np.ndarray, n_vertices: int, what: str) -> None:
    if len(boundary_edges(faces, n_vertices)):
        raise InvalidMeshError(f"{what} must be closed: it has boundary edges (fill its holes first)")


def _corefine(pts, fcs, group, keep_rule) -> RepairResult:
    curves = intersection_curves(pts, fcs, group=group)
    canon = canonical_vertices(pts)
    faces, source, point_id = _cut_faces(pts, fcs, canon, curves)
    all_points = np.concatenate([pts, curves.points])
    n_all = len(all_points)
    seg = np.sort(point_id[curves.segments], axis=1)
    cut_edges = np.unique(seg[:, 0] * n_all + seg[:, 1])
    patch = _patches(faces, n_all, cut_edges)
    source_group = np.zeros(len(faces), np.int64) if group is None else np.asarray(group)[source]
    keep, turn = _select(all_points, faces, source_group, patch, keep_rule)
    faces = np.where(turn[:, None], faces[:, ::-1], faces)[keep]
    source = source[keep]
    used = np.unique(faces)
    new_index = np.full(n_all, -1, np.int64)
    new_index[used] = np.arange(len(used))
    on_curve = np.zeros(n_all, bool)
    on_curve[point_id] = True
    polylines = [new_index[point_id[line]] for line in trace_polylines(curves)]
    return RepairResult(points=all_points[used], faces=new_index[faces], source_face=source,
                        on_curve=on_curve[used], curves=curves, polylines=polylines)


def repair_intersections(points, faces) -> RepairResult:
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

    Returns
    -------
    RepairResult

    Raises
    ------
    InvalidMeshError
        If the mesh is not closed.
    """
    pts, fcs = as_triangle_mesh(points, faces)
    _check_closed(fcs, len(pts), "the mesh")

    def front_is_outside(rays, f, centre, axis, faces_down):
        w_front = rays.winding(centre, axis, f, -1) - int(faces_down)
        return w_front == 0, False

    return _corefine(pts, fcs, None, front_is_outside)


def boolean_meshes(points_a, faces_a, points_b, faces_b, operation: str) -> RepairResult:
    """Union, intersection or difference of two closed meshes.

    Parameters
    ----------
    points_a, faces_a : array_like, shapes (Va, 3) and (Fa, 3)
        Operand A, closed and oriented outward.
    points_b, faces_b : array_like, shapes (Vb, 3) and (Fb, 3)
        Operand B, closed and oriented outward.
    operation : {"union", "intersection", "difference", "reverse_difference"}
        A ∪ B, A ∩ B, A ∖ B or B ∖ A.

    Returns
    -------
    RepairResult
        Faces of B are numbered after those of A in ``source_face``.

    Raises
    ------
    ValueError
        For an unknown operation.
    InvalidMeshError
        If an operand is not closed.
    """
    if operation not in OPERATIONS:
        raise ValueError(f"operation must be one of {OPERATIONS}; got {operation!r}")
    pa, fa = as_triangle_mesh(points_a, faces_a)
    pb, fb = as_triangle_mesh(points_b, faces_b)
    _check_closed(fa, len(pa), "mesh A")
    _check_closed(fb, len(pb), "mesh B")
    pts = np.concatenate([pa, pb])
    fcs = np.concatenate([fa, fb + len(pa)])
    group = np.repeat([0, 1], [len(fa), len(fb)])
    rule = _KEEP[operation]

    def other_winding(rays, f, centre, axis, faces_down):
        own = int(rays.group[f])
        target, turns = rule[own]
        return rays.winding(centre, axis, f, 1 - own) == target, turns

    return _corefine(pts, fcs, group, other_winding)
