"""Consistent, outward face orientation for closed meshes and open scans.

Faces are first made consistent inside each edge-connected component by
propagating across manifold edges (edges shared by exactly two faces). Each
component is then turned outward by the sign of its enclosed volume, where
the holes of open scans are virtually closed by a cone from every boundary
loop to that loop's centroid. A component that lies inside another one (the
wall of a cavity) is turned the other way, decided by the generalised
winding number, so that normals always point out of the solid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pverosion.kernels.topology import boundary_edges, edge_topology

__all__ = ["ORIENTATIONS", "Orientation", "orient_faces", "winding_number"]

ORIENTATIONS = ("outward", "inward", "keep")
"""Accepted values of the ``orientation`` option."""


@dataclass(frozen=True)
class Orientation:
    """Result of :func:`orient_faces`.

    Attributes
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
        Faces in the chosen orientation.
    flipped : numpy.ndarray, shape (F,), bool
        Faces whose vertex order was reversed relative to the input.
    component : numpy.ndarray, shape (F,), int64
        Edge-connected component of each face.
    mode : str
        The orientation that was asked for.
    """

    faces: np.ndarray
    flipped: np.ndarray
    component: np.ndarray
    mode: str

    @property
    def n_flipped(self) -> int:
        """Number of faces whose order was reversed."""
        return int(np.count_nonzero(self.flipped))

    @property
    def n_components(self) -> int:
        """Number of edge-connected components."""
        return int(self.component.max()) + 1 if self.component.size else 0


@njit(cache=True, error_model="numpy")
def _propagate(faces, halfedge_edge, face_count):
    n_faces = faces.shape[0]
    n_edges = face_count.shape[0]
    he = halfedge_edge.ravel()
    first = np.full(n_edges, -1, np.int64)
    partner = np.full(3 * n_faces, -1, np.int64)
    for h in range(3 * n_faces):
        e = he[h]
        if e < 0 or face_count[e] != 2:
            continue
        if first[e] < 0:
            first[e] = h
        else:
            partner[h] = first[e]
            partner[first[e]] = h
    flip = np.zeros(n_faces, np.bool_)
    comp = np.full(n_faces, -1, np.int64)
    stack = np.empty(n_faces, np.int64)
    n_comp = 0
    for seed in range(n_faces):
        if comp[seed] >= 0:
            continue
        comp[seed] = n_comp
        top = 0
        stack[top] = seed
        top += 1
        while top > 0:
            top -= 1
            f = stack[top]
            for k in range(3):
                p = partner[3 * f + k]
                if p < 0:
                    continue
                g = p // 3
                if comp[g] >= 0:
                    continue
                same_direction = faces[f, k] == faces[g, p - 3 * g]
                comp[g] = n_comp
                flip[g] = flip[f] ^ same_direction
                stack[top] = g
                top += 1
        n_comp += 1
    return flip, comp


@njit(cache=True, error_model="numpy")
def _winding(point, points, faces):
    total = 0.0
    for f in range(faces.shape[0]):
        a = points[faces[f, 0]] - point
        b = points[faces[f, 1]] - point
        c = points[faces[f, 2]] - point
        la = np.sqrt(a @ a)
        lb = np.sqrt(b @ b)
        lc = np.sqrt(c @ c)
        det = a @ np.cross(b, c)
        den = la * lb * lc + (a @ b) * lc + (a @ c) * lb + (b @ c) * la
        total += 2.0 * np.arctan2(det, den)
    return total / (4.0 * np.pi)


def winding_number(point, points: np.ndarray, faces: np.ndarray) -> float:
    """Generalised winding number of a triangle mesh around a point.

    Parameters
    ----------
    point : array_like, shape (3,)
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)

    Returns
    -------
    float
        About 1 inside a closed outward-oriented mesh, 0 outside, fractional
        near the holes of an open one.
    """
    return float(_winding(np.asarray(point, dtype=np.float64), points, faces))


def _closed_volumes(points, faces, component, n_comp, topology):
    """Signed volume of every component with its holes closed by cones."""
    origin = points.mean(axis=0)
    p0, p1, p2 = (points[faces[:, k]] - origin for k in range(3))
    dets = np.einsum("ij,ij->i", p0, np.cross(p1, p2))
    volume = np.bincount(component, weights=dets, minlength=n_comp)
    n_vertices = len(points)
    rim = boundary_edges(faces, n_vertices, topology)
    if len(rim):
        graph = coo_matrix((np.ones(len(rim)), (rim[:, 0], rim[:, 1])), shape=(n_vertices, n_vertices))
        _, loop_of_vertex = connected_components(graph, directed=False)
        _, loop = np.unique(loop_of_vertex[rim[:, 0]], return_inverse=True)
        n_loops = int(loop.max()) + 1
        counts = np.bincount(loop, minlength=n_loops)[:, None]
        apex = np.stack(
            [np.bincount(loop, weights=points[rim[:, 0], d], minlength=n_loops) for d in range(3)], axis=1
        ) / counts
        a, b, c = points[rim[:, 1]] - origin, points[rim[:, 0]] - origin, apex[loop] - origin
        cone = np.einsum("ij,ij->i", a, np.cross(b, c))
        # the component of each rim edge: that of a face using its first vertex on the rim
        face_of_vertex = np.full(n_vertices, -1, np.int64)
        face_of_vertex[faces.ravel()] = np.repeat(np.arange(len(faces)), 3)
        volume += np.bincount(component[face_of_vertex[rim[:, 0]]], weights=cone, minlength=n_comp)
    return volume / 6.0


def orient_faces(points: np.ndarray, faces: np.ndarray, *, mode: str = "outward") -> Orientation:
    """Orient faces consistently, with normals pointing out of (or into) the solid.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
    mode : {"outward", "inward", "keep"}
        ``"outward"`` makes convex regions have positive mean curvature;
        ``"inward"`` is its mirror; ``"keep"`` returns the faces unchanged.

    Returns
    -------
    Orientation

    Notes
    -----
    A component whose closed volume is negligible (a flat or symmetric open
    sheet) keeps the orientation of its first face. Non-orientable
    components (a Möbius strip) keep whatever the propagation reached.
    """
    if mode not in ORIENTATIONS:
        raise ValueError(f"orientation must be one of {ORIENTATIONS}; got {mode!r}")
    n_vertices = len(points)
    topo = edge_topology(faces, n_vertices)
    flip, component = _propagate(faces, topo.halfedge_edge, topo.face_count)
    n_comp = int(component.max()) + 1
    if mode == "keep":
        return Orientation(faces, np.zeros(len(faces), bool), component, mode)

    oriented = _apply(faces, flip)
    volume = _closed_volumes(points, oriented, component, n_comp, topo)
    extent = np.ptp(points, axis=0).max()
    decided = np.abs(volume) > 1e-9 * extent**3
    turn = decided & (volume < 0)
    if n_comp > 1:
        turn ^= _cavity_walls(points, _apply(oriented, turn[component]), component, n_comp, decided)
    if mode == "inward":
        turn ^= decided
    flip ^= turn[component]
    return Orientation(_apply(faces, flip), flip, component, mode)


def _apply(faces, flip):
    out = faces.copy()
    out[flip, 1], out[flip, 2] = faces[flip, 2], faces[flip, 1]
    return out


def _cavity_walls(points, outward, component, n_comp, decided):
    """Components nested inside an odd number of other solids (cavity walls)."""
    order = np.argsort(component, kind="stable")
    bounds = np.searchsorted(component[order], np.arange(n_comp + 1))
    comp_faces = [outward[order[bounds[c] : bounds[c + 1]]] for c in range(n_comp)]
    lo = np.array([points[f].reshape(-1, 3).min(axis=0) for f in comp_faces])
    hi = np.array([points[f].reshape(-1, 3).max(axis=0) for f in comp_faces])
    walls = np.zeros(n_comp, bool)
    for c in np.flatnonzero(decided):
        probe = points[comp_faces[c][0, 0]]
        depth = 0
        for d in np.flatnonzero(decided):
            if d != c and np.all(probe >= lo[d]) and np.all(probe <= hi[d]):
                depth += round(winding_number(probe, points, comp_faces[d]))
        walls[c] = depth % 2 == 1
    return walls
