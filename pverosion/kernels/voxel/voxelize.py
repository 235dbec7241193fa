"""Voxel material grids from closed triangle meshes and from height fields.

Grids are (nx, ny, nz) arrays of material amount in [0, 1] sampled at the
cell centres ``origin + (i, j, k) * spacing``.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from pverosion.kernels._jit import njit
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["height_field_amount", "voxelize_mesh"]


@njit(cache=True, parallel=True, error_model="numpy")
def _column_parity(points, faces, origin, spacing, dims):
    """Inside mask by crossings of a vertical ray through every column (even-odd rule)."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    inside = np.zeros((nx, ny, nz), np.bool_)
    n_faces = faces.shape[0]
    # rays pass a hair off the cell centres, so they miss the edges and vertices of grid-aligned meshes
    dx, dy = 1.1e-7 * np.sqrt(2.0) * spacing[0], 1.3e-7 * np.sqrt(3.0) * spacing[1]
    for i in prange(nx):
        x = origin[0] + i * spacing[0] + dx
        hits = np.empty(n_faces)
        for j in range(ny):
            y = origin[1] + j * spacing[1] + dy
            n_hits = 0
            for f in range(n_faces):
                a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
                ax, ay = points[a, 0], points[a, 1]
                bx, by = points[b, 0], points[b, 1]
                cx, cy = points[c, 0], points[c, 1]
                if x < min(ax, bx, cx) or x > max(ax, bx, cx) or y < min(ay, by, cy) or y > max(ay, by, cy):
                    continue
                det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
                if det == 0.0:
                    continue
                l1 = ((x - ax) * (cy - ay) - (cx - ax) * (y - ay)) / det
                l2 = ((bx - ax) * (y - ay) - (x - ax) * (by - ay)) / det
                l0 = 1.0 - l1 - l2
                if l0 < 0.0 or l1 < 0.0 or l2 < 0.0:
                    continue
                hits[n_hits] = l0 * points[a, 2] + l1 * points[b, 2] + l2 * points[c, 2]
                n_hits += 1
            if n_hits < 2:
                continue
            z_hits = np.sort(hits[:n_hits])
            for k in range(nz):
                z = origin[2] + k * spacing[2]
                crossings = 0
                for h in range(n_hits):
                    if z_hits[h] < z:
                        crossings += 1
                inside[i, j, k] = crossings % 2 == 1
    return inside


def voxelize_mesh(points: np.ndarray, faces: np.ndarray, *, origin, spacing, dims) -> np.ndarray:
    """Cells whose centre lies inside a closed triangle mesh.

    Each column of cell centres is crossed by a vertical ray; a centre is
    inside when an odd number of surface crossings lie below it.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
        A closed surface (any orientation).
    origin : (3,) float
        Centre of cell (0, 0, 0).
    spacing : (3,) float
        Cell size along x, y, z.
    dims : (3,) int
        Cells along x, y, z.

    Returns
    -------
    numpy.ndarray of bool, shape dims
    """
    points, faces = as_triangle_mesh(points, faces)
    origin = np.asarray(origin, dtype=np.float64).reshape(3)
    spacing = np.asarray(spacing, dtype=np.float64).reshape(3)
    dims = np.asarray(dims, dtype=np.int64).reshape(3)
    if np.any(spacing <= 0) or np.any(dims < 1):
        raise ValueError(f"spacing must be > 0 and dims >= 1; got {spacing.tolist()} and {dims.tolist()}")
    return _column_parity(points, faces, origin, spacing, dims)


def height_field_amount(heights: np.ndarray, *, z0: float, dz: float, nz: int) -> np.ndarray:
    """Material amount of a terrain: full below the height, the fraction below it in the surface cell.

    Parameters
    ----------
    heights : numpy.ndarray, shape (nx, ny)
        Terrain height at each column.
    z0 : float
        Centre of the lowest cell layer.
    dz : float
        Layer thickness.
    nz : int
        Number of layers.

    Returns
    -------
    numpy.ndarray, shape (nx, ny, nz)
        In [0, 1]: the fraction of each cell below the terrain.
    """
    heights = np.asarray(heights, dtype=np.float64)
    if heights.ndim != 2:
        raise ValueError(f"heights must be a 2-D array (nx, ny); got shape {heights.shape}")
    if not np.all(np.isfinite(heights)):
        raise ValueError("heights contain NaN or infinite values")
    if not dz > 0 or nz < 1:
        raise ValueError(f"dz must be > 0 and nz >= 1; got {dz!r}, {nz!r}")
    bottoms = z0 - 0.5 * dz + dz * np.arange(nz)
    return np.clip((heights[:, :, None] - bottoms[None, None, :]) / dz, 0.0, 1.0)
