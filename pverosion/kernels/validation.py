"""Validation of raw mesh arrays at the kernel boundary."""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["COORDINATE_STEP_FRACTION", "InvalidMeshError", "as_faces", "as_points", "as_triangle_mesh",
           "check_coordinate_precision", "check_proper_faces", "check_welded", "unique_rows"]

COORDINATE_STEP_FRACTION = 0.01
"""Largest rounding step of stored coordinates, as a fraction of the median edge length, taken without a warning.

A coordinate stored in a floating-point type is rounded to the nearest value of that type; near the largest
coordinate ``x`` these values are ``s = np.spacing(x)`` apart, so every coordinate may be off by ``s / 2``.
Curvature is the turn of the normals per unit length: a vertex off by ``d`` across an edge of length ``h``
tilts the normals there by about ``d / h``, and the curvature by about ``d / h**2``. Relative to the
curvature ``k`` that is ``(d / h) / (k h)``, where ``k h``, the angle between neighbouring normals, is a few
hundredths on a mesh that resolves its shape: a step of 1 % of the edge already moves the curvature by
a sizeable fraction of itself, and the error grows in proportion to the step. Weathering and hydraulic erosion
move the vertices by that curvature."""

_SAMPLED_FACES = 256
"""Faces, at least (and fewer than twice as many), whose edges give the median edge length of a larger mesh. Each
sampled face costs a few cache misses on a large mesh (its corners lie anywhere in the points), so the sample is
kept small: 512 edge lengths give the median edge within a few percent, far finer than the warning's margin."""


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


def check_coordinate_precision(points: np.ndarray, faces: np.ndarray) -> None:
    """Warn when the storage type of the points rounds them coarsely against the mesh's edges.

    Points stored as float32 (or another float type coarser than float64) far from the origin are rounded
    in steps that may be a sizeable part of an edge, or longer (0.0625 at 1e6 units): the positions, and every
    result computed from them (curvature, erosion, voxels, cuts), are off before any computation, whatever precision
    follows. The faces taken at a regular stride through the face list, 256 to 511 of them (all faces of
    a smaller mesh), give both figures compared: the step at the largest ``|coordinate|`` of their corners
    over the three axes (an error in any one coordinate moves the point; points no face uses do not count)
    and the median length of the two edges from their first corners (the upper median of an even count). Edges of zero length, and faces
    naming points that do not exist, are left out. No pass over all points or faces; nothing at all for
    float64 points.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
        Vertex coordinates, in the type they are stored in (before any conversion to float64).
    faces : numpy.ndarray, shape (F, 3)
        Vertex indices of each triangle.

    Warns
    -----
    UserWarning
        If the step exceeds :data:`COORDINATE_STEP_FRACTION` of the median edge length; the message names
        the type, the step, the edge length and the remedies (the model exported again with float64 points,
        or moved near the origin). Non-finite coordinates are left to :func:`as_points` to refuse.
    """
    if not np.issubdtype(points.dtype, np.floating) or np.finfo(points.dtype).eps <= np.finfo(np.float64).eps:
        return
    if len(points) == 0 or len(faces) == 0:
        return
    sample = faces[:: max(1, len(faces) // _SAMPLED_FACES)]
    if not (sample.min() >= 0 and sample.max() < len(points)):
        sample = sample[((sample >= 0) & (sample < len(points))).all(axis=1)]
    stored = points[sample]  # (S, 3, 3), in the stored type
    if stored.size == 0:
        return
    largest = max(-stored.min(), stored.max())
    if not np.isfinite(largest):
        return
    step = float(np.spacing(largest))
    corners = stored.astype(np.float64)
    sides = corners[:, 1:] - corners[:, :1]  # the two edges from each sampled face's first corner
    squares = np.einsum("fkd,fkd->fk", sides, sides).ravel()
    squares = squares[squares > 0.0]
    if len(squares) == 0:
        return
    middle = len(squares) // 2  # the median (the upper one of an even count), from a partial sort of the squares
    edge = float(np.sqrt(np.partition(squares, middle)[middle]))
    if step <= COORDINATE_STEP_FRACTION * edge:
        return
    warnings.warn(
        f"the points are stored as {points.dtype}, whose values at the points' largest coordinate "
        f"({float(largest):.6g}) are {step:.3g} apart while the median edge is {edge:.3g} long (a rounding step "
        f"above {COORDINATE_STEP_FRACTION:.0%} of the edge length moves the points by a visible part of an edge, and "
        "every result made from them, curvature, erosion, voxels or cuts, with them): export "
        "the model again from its source with float64 points, or moved near the origin (and move the result "
        "back); moving the points after they were read does not undo the rounding", UserWarning, stacklevel=2)


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


def check_proper_faces(faces: np.ndarray) -> None:
    """``InvalidMeshError`` if a triangle uses a vertex twice or repeats another triangle's vertices.

    Stages that need a 2-manifold (or closed) surface call it first, so that
    such faces are named as what they are rather than reported as the
    boundary or non-manifold edges they make.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3)
        Triangles as vertex indices.

    Raises
    ------
    InvalidMeshError
        Naming how many faces are degenerate or duplicated, and the first ones.
    """
    faces = np.asarray(faces)
    repeated = np.flatnonzero((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2])
                              | (faces[:, 2] == faces[:, 0]))
    if len(repeated):
        raise InvalidMeshError(f"mesh has {len(repeated)} degenerate faces that use a vertex twice (first faces: "
                               f"{repeated[:5].tolist()}): remove them first (mesh.clean() drops them)")
    distinct, keys = unique_rows(np.sort(faces, axis=1))  # one integer per set of vertices
    if len(distinct) < len(faces):
        order = np.argsort(keys, kind="stable")
        copies = np.sort(order[1:][keys[order[1:]] == keys[order[:-1]]])  # each face after the first with its vertices
        raise InvalidMeshError(f"mesh has {len(copies)} faces that repeat the vertices of another face (first "
                               f"copies: {copies[:5].tolist()}): remove the duplicates first")


def check_welded(faces: np.ndarray, n_points: int) -> None:
    """``InvalidMeshError`` if the triangles share no vertex: a triangle soup whose coincident points were not merged.

    Such a mesh (an STL file read without merging its points, or a PLY or
    OBJ written from one) has only boundary edges, so every curvature is zero
    and nothing would move; the message names the cause and the fix instead.
    A single triangle is accepted. Only a mesh with at least three points
    per triangle can be one, so a welded mesh (about half a point per
    triangle) costs no pass over its faces.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3)
        Triangles as vertex indices.
    n_points : int
        Number of points of the mesh.

    Raises
    ------
    InvalidMeshError
        If there are two or more triangles and no vertex is used by two of them.
    """
    faces = np.asarray(faces)
    if len(faces) > 1 and n_points >= faces.size and len(np.unique(faces)) == faces.size:
        raise InvalidMeshError(f"no two of the mesh's {len(faces)} triangles share a vertex (an unwelded triangle "
                               "soup, as in an STL file): merge the coincident points first (mesh.clean())")


def unique_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted unique rows of an (N, K) integer array and the index of every input row among them (N,)."""
    if len(rows) == 0:
        return rows.copy(), np.zeros(0, np.int64)
    lo = rows.min(axis=0)
    span = rows.max(axis=0) - lo + 1
    if np.prod(span.astype(np.float64)) < 2.0**62:  # one sort of packed keys instead of a sort per column
        key = np.zeros(len(rows), np.int64)
        for k in range(rows.shape[1]):
            key = key * span[k] + (rows[:, k] - lo[k])
        _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
        return rows[first], inverse.reshape(-1)
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    new = np.r_[True, np.any(ordered[1:] != ordered[:-1], axis=1)]
    inverse = np.empty(len(rows), np.int64)
    inverse[order] = np.cumsum(new) - 1
    return ordered[new], inverse
