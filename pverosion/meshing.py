"""Planar meshing on the front-end side (VTK, matplotlib): constrained triangulation, lattices, hole filling.

Used by the scenes (terrain plans, scan preparation), by the hydraulic filter's ``fill_holes``
option and by tests that close the holes of real scans.
"""

from __future__ import annotations

import numpy as np
import pyvista as pv
from matplotlib.path import Path as Polygon
from scipy import sparse
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from pverosion.kernels.mesh.topology import edge_topology
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["fill_holes", "points_clear_of", "resample", "triangular_lattice", "triangulate"]


def resample(curve: np.ndarray, spacing: float) -> np.ndarray:
    """Points evenly spaced by arc length (about ``spacing`` apart) along a polyline (n, 2), ends kept."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
    s = np.linspace(0.0, arc[-1], max(1, round(arc[-1] / spacing)) + 1)
    return np.stack([np.interp(s, arc, curve[:, 0]), np.interp(s, arc, curve[:, 1])], axis=1)


def triangular_lattice(lo, hi, spacing: float) -> np.ndarray:
    """Triangular lattice of points with edge ``spacing`` covering the box [lo, hi] (2-D)."""
    rows = np.arange(lo[1], hi[1] + spacing, spacing * np.sqrt(3.0) / 2.0)
    cols = np.arange(lo[0] - spacing, hi[0] + spacing, spacing)
    x = cols[None, :] + 0.5 * spacing * (np.arange(len(rows)) % 2)[:, None]
    return np.stack([x, np.broadcast_to(rows[:, None], x.shape)], axis=-1).reshape(-1, 2)


def points_clear_of(points: np.ndarray, curves: list[np.ndarray], distance: float) -> np.ndarray:
    """Mask of the points (n, 2) farther than ``distance`` from every polyline in ``curves``."""
    dense = np.vstack([resample(c, 0.05 * distance) for c in curves])
    return cKDTree(dense).query(points)[0] > distance


def triangulate(points: np.ndarray, constraints: np.ndarray) -> np.ndarray:
    """Counter-clockwise constrained Delaunay triangles (m, 3) of ``points`` (n, 2) over their convex hull.

    Every constraint edge (k, 2) is an edge of the result (VTK's
    vtkDelaunay2D, which recovers the edges by flipping).

    Raises
    ------
    RuntimeError
        A point left out (merged with a close one) or a constraint edge missing.
    """
    n = len(points)
    lines = np.hstack([np.full((len(constraints), 1), 2), constraints]).ravel()
    flat = np.column_stack([points, np.zeros(n)])
    cloud = pv.PolyData(flat).delaunay_2d(edge_source=pv.PolyData(flat, lines=lines))
    tri = cloud.regular_faces.astype(np.int64)
    if cloud.n_points != n or len(np.unique(tri)) != n:
        raise RuntimeError("the planar triangulation left points out")
    p = points[tri]
    cross = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])
    tri[cross < 0] = tri[cross < 0][:, ::-1]
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    wanted = np.sort(constraints, axis=1)
    if not np.isin(wanted[:, 0] * n + wanted[:, 1], edges[:, 0] * n + edges[:, 1]).all():
        raise RuntimeError("the planar triangulation misses a constraint edge")
    return tri


def _boundary_loops(faces: np.ndarray, n_points: int) -> list[np.ndarray]:
    """Boundary loops of a triangle mesh, each the vertices in the order of its boundary half-edges.

    Raises
    ------
    ValueError
        A vertex on more than one boundary loop (the holes cannot be told apart).
    """
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = edges[:, 0] * n_points + edges[:, 1]
    open_edges = edges[~np.isin(key, edges[:, 1] * n_points + edges[:, 0])]
    if len(np.unique(open_edges[:, 0])) != len(open_edges):
        raise ValueError("the mesh has a vertex on several hole rims; repair it before filling the holes")
    after = dict(zip(open_edges[:, 0].tolist(), open_edges[:, 1].tolist()))
    loops = []
    while after:
        v, loop = next(iter(after)), []
        while v in after:
            loop.append(v)
            v = after.pop(v)
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def _hole_patch(rim: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles over a hole's rim (k, 3) given in boundary order: new inner points (n, 3) and faces (m, 3)
    indexing rim points first, then the new ones; oriented to match the faces round the hole.

    The rim is projected on its best-fitting plane, filled with a triangular
    lattice at the rim's mean edge length and triangulated (constrained
    Delaunay); the
    new points then sit at the average of their neighbours (a membrane, solved exactly).
    A rim lying in a coordinate plane gets a patch exactly in that plane.

    Raises
    ------
    ValueError
        A rim that is not a simple polygon in its plane, or one the
        triangulation fails on.
    """
    k = len(rim)
    if k < 3:
        raise ValueError(f"a hole's rim must have at least 3 edges; got {k}")
    centre = rim.mean(axis=0)
    axes = np.linalg.svd(rim - centre)[2]
    flat = (rim - centre) @ axes[:2].T
    closed = np.vstack([flat, flat[:1]])
    a, b = closed[:-1], closed[1:]
    d = b - a
    cross = d[:, None, 0] * (a[None, :, 1] - a[:, None, 1]) - d[:, None, 1] * (a[None, :, 0] - a[:, None, 0])
    cross2 = d[:, None, 0] * (b[None, :, 1] - a[:, None, 1]) - d[:, None, 1] * (b[None, :, 0] - a[:, None, 0])
    straddle = (cross * cross2 < 0) & (cross.T * cross2.T < 0)
    if straddle.any():
        raise ValueError(f"a hole's rim of {k} edges is not a simple polygon in its plane; it cannot be filled")
    spacing = float(np.linalg.norm(d, axis=1).mean())
    lattice = triangular_lattice(flat.min(axis=0), flat.max(axis=0), spacing)
    polygon = Polygon(closed)
    lattice = lattice[polygon.contains_points(lattice)]
    if len(lattice):
        lattice = lattice[points_clear_of(lattice, [closed], 0.6 * spacing)]
    ring = np.stack([np.arange(k), (np.arange(k) + 1) % k], axis=1)
    try:
        tri = triangulate(np.vstack([flat, lattice]), ring)
    except RuntimeError as error:
        raise ValueError(f"a hole's rim of {k} edges cannot be triangulated: {error}") from None
    tri = tri[polygon.contains_points(np.vstack([flat, lattice])[tri].mean(axis=1))]
    inner = centre + lattice @ axes[:2]
    if len(inner):
        inner = _membrane(rim, tri, len(inner))
    in_plane = np.ptp(rim, axis=0) == 0.0  # a rim in a coordinate plane: keep the patch exactly in it
    inner[:, in_plane] = rim[0, in_plane]
    # the faces round the hole run a -> b along the rim; the patch must run b -> a
    forward = (((tri[:, 0] == 0) & (tri[:, 1] == 1)) | ((tri[:, 1] == 0) & (tri[:, 2] == 1))
               | ((tri[:, 2] == 0) & (tri[:, 0] == 1)))
    return inner, tri[:, ::-1] if forward.any() else tri


def _membrane(rim: np.ndarray, tri: np.ndarray, n: int) -> np.ndarray:
    """Inner points of a patch, each exactly at the mean of its one-ring (solved, not iterated).

    Parameters
    ----------
    rim : numpy.ndarray, shape (k, 3)
        The fixed rim points, vertices ``0 .. k-1`` of ``tri``.
    tri : numpy.ndarray, shape (m, 3)
        Consistently oriented patch triangles over the rim and the ``n`` inner vertices ``k .. k+n-1``.
    n : int

    Returns
    -------
    numpy.ndarray, shape (n, 3)
        The solution of the uniform Laplace equation with the rim fixed: the
        Laplacian of every inner point is zero up to rounding, so it gives no
        direction wherever the model sits (an iterated relaxation leaves a
        residual above the rounding of a model far from the origin).
    """
    k = len(rim)
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])  # each inner ring edge once
    edges = edges[edges[:, 0] >= k]
    row, col = edges[:, 0] - k, edges[:, 1]
    inside = col >= k
    system = (sparse.diags(np.bincount(row, minlength=n).astype(np.float64))
              - sparse.csr_matrix((np.ones(int(inside.sum())), (row[inside], col[inside] - k)), shape=(n, n)))
    rhs = np.zeros((n, 3))
    np.add.at(rhs, row[~inside], rim[col[~inside]])
    return np.asarray(spsolve(system.tocsc(), rhs)).reshape(n, 3)


def _canonical_rim(points: np.ndarray, loop: np.ndarray) -> tuple[np.ndarray, bool]:
    """A hole's rim in an order that depends on its points only, and whether it runs against the boundary.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    loop : numpy.ndarray, shape (k,), int
        The rim's vertices in boundary order, from any of them.

    Returns
    -------
    loop : numpy.ndarray, shape (k,), int
        The rim from its lexicographically smallest point, towards the
        smaller of that point's two rim neighbours: the patch is the same
        whatever the numbering of the vertices and faces and their winding.
    backward : bool
        True when that order runs against the boundary order.
    """
    rim = points[loop]
    first = int(np.lexsort(rim.T[::-1])[0])
    loop = np.roll(loop, -first)
    after, before = points[loop[1]], points[loop[-1]]
    backward = bool(tuple(before) < tuple(after))
    return (np.concatenate([loop[:1], loop[:0:-1]]) if backward else loop), backward


def fill_holes(points, faces) -> tuple[np.ndarray, np.ndarray]:
    """Close every hole of a triangle mesh with a patch of about its rim's edge length.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        Consistently oriented triangles; edges used by more than two faces
        are not allowed.

    Returns
    -------
    points : numpy.ndarray, shape (V + n, 3)
        The input points, then the patches' inner points.
    faces : numpy.ndarray, shape (F + m, 3)

    Raises
    ------
    ValueError
        A non-manifold edge or vertex on a rim, or a hole that is not a
        simple polygon when projected on its plane.
    """
    pts, fcs = as_triangle_mesh(points, faces)
    if edge_topology(fcs, len(pts)).n_nonmanifold_edges:
        raise ValueError("the mesh has edges shared by more than two faces; repair it before filling the holes")
    new_points, new_faces = [pts], [fcs]
    count = len(pts)
    for loop in _boundary_loops(fcs, len(pts)):
        loop, backward = _canonical_rim(pts, loop)
        inner, tri = _hole_patch(pts[loop])
        index = np.concatenate([loop, count + np.arange(len(inner))])
        new_points.append(inner)
        new_faces.append(index[tri[:, ::-1] if backward else tri])
        count += len(inner)
    return np.vstack(new_points), np.vstack(new_faces)
