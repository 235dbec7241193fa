"""Validation of raw mesh arrays at the kernel boundary."""

from __future__ import annotations

import numpy as np

__all__ = ["InvalidMeshError", "as_triangle_mesh"]


class InvalidMeshError(ValueError):
    """Raised when a mesh cannot be processed (empty, NaN points, non-triangles, bad shapes)."""


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
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InvalidMeshError(f"points must have shape (V, 3); got {pts.shape}")
    if pts.shape[0] == 0:
        raise InvalidMeshError("mesh is empty: it has no points")
    if not np.issubdtype(pts.dtype, np.number):
        raise InvalidMeshError(f"points must be numeric; got dtype {pts.dtype}")
    pts = np.ascontiguousarray(pts, dtype=np.float64)
    finite = np.isfinite(pts).all(axis=1)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise InvalidMeshError(
            f"points contain NaN or infinite coordinates at {bad.size} vertices "
            f"(first indices: {bad[:5].tolist()})"
        )

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
    if lo < 0 or hi >= pts.shape[0]:
        raise InvalidMeshError(
            f"faces reference vertex indices in [{lo}, {hi}] but the mesh has {pts.shape[0]} points"
        )
    return pts, fcs
