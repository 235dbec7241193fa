"""Validation of raw mesh arrays at the kernel boundary."""

from __future__ import annotations

import numpy as np

__all__ = ["InvalidMeshError", "as_faces", "as_points", "as_triangle_mesh"]


class InvalidMeshError(ValueError):
    """Raised when a mesh cannot be processed (empty, NaN points, non-triangles, bad shapes)."""


def as_points(points) -> np.ndarray:
    """Check vertex coordinates and return them as a contiguous ``float64`` array.

    Parameters
    ----------
    points : array_like, shape (V, 3)

    Returns
    -------
    numpy.ndarray, shape (V, 3), float64

    Raises
    ------
    InvalidMeshError
        If the array is empty, has the wrong shape, is not numeric or holds
        NaN or infinite coordinates.
    """
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InvalidMeshError(f"points must have shape (V, 3); got {pts.shape}")
    if pts.shape[0] == 0:
        raise InvalidMeshError("mesh is empty: it has no points")
    if not np.issubdtype(pts.dtype, np.number):
        raise InvalidMeshError(f"points must be numeric; got dtype {pts.dtype}")
    pts = np.ascontiguousarray(pts, dtype=np.float64)
    if not np.isfinite(pts).all():
        bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
        raise InvalidMeshError(
            f"points contain NaN or infinite coordinates at {bad.size} vertices "
            f"(first indices: {bad[:5].tolist()})"
        )
    return pts


def as_faces(faces, n_vertices: int) -> np.ndarray:
    """Check triangle indices and return them as a contiguous ``int64`` array.

    Parameters
    ----------
    faces : array_like, shape (F, 3)
        Vertex indices of each triangle.
    n_vertices : int
        Number of mesh vertices V; indices must lie in ``[0, V)``.

    Returns
    -------
    numpy.ndarray, shape (F, 3), int64

    Raises
    ------
    InvalidMeshError
        If there are no faces, faces that are not triangles, non-integer
        indices or indices outside ``[0, V)``.
    """
    fcs = np.asarray(faces)
    if fcs.ndim != 2 or fcs.shape[1] != 3:
        hint = ""
        if fcs.ndim == 2 and fcs.shape[1] > 3:
            hint = " (polygons with more than 3 vertices: triangulate the mesh first)"
        raise InvalidMeshError(f"faces must have shape (F, 3){hint}; got {fcs.shape}")
    if fcs.shape[0] == 0:
        raise InvalidMeshError("mesh has no triangles")
    if not np.issubdtype(fcs.dtype, np.integer):
        raise InvalidMeshError(f"faces must hold integer vertex indices; got dtype {fcs.dtype}")
    fcs = np.ascontiguousarray(fcs, dtype=np.int64)
    lo, hi = int(fcs.min()), int(fcs.max())
    if lo < 0 or hi >= n_vertices:
        raise InvalidMeshError(
            f"faces reference vertex indices in [{lo}, {hi}] but the mesh has {n_vertices} points"
        )
    return fcs


def as_triangle_mesh(points, faces) -> tuple[np.ndarray, np.ndarray]:
    """Check a triangle mesh and return contiguous ``float64``/``int64`` copies-or-views.

    Parameters
    ----------
    points : array_like, shape (V, 3)
        Vertex coordinates.
    faces : array_like, shape (F, 3)
        Vertex indices of each triangle.

    Returns
    -------
    points : numpy.ndarray, shape (V, 3), float64
    faces : numpy.ndarray, shape (F, 3), int64

    Raises
    ------
    InvalidMeshError
        If the mesh is empty, has non-finite coordinates, faces that are not
        triangles, or indices outside ``[0, V)``.
    """
    pts = as_points(points)
    return pts, as_faces(faces, pts.shape[0])
