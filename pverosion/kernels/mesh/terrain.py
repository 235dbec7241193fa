"""Closed triangle meshes of terrain blocks from height fields (DEMs)."""

from __future__ import annotations

import numpy as np

__all__ = ["height_field_solid"]


def height_field_solid(heights: np.ndarray, *, spacing=(1.0, 1.0), origin=(0.0, 0.0),
                       base: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The closed block under a height field: terrain on top, vertical sides, a flat bottom.

    Parameters
    ----------
    heights : (nx, ny) float
        Terrain height at ``origin + (i, j) * spacing``; nx, ny >= 2.
    spacing : float or (2,) float
        Sample spacing in x and y.
    origin : (2,) float
        Position of sample (0, 0).
    base : float, optional
        Height of the bottom (default: 5 % of the height range below the lowest point).

    Returns
    -------
    points : (nx * ny + 2 (nx + ny) - 3, 3) float64
    faces : (k, 3) int64
        Outward-oriented triangles of a closed 2-manifold.

    Raises
    ------
    ValueError
        Heights that are not a finite 2-D array of at least 2 x 2, a bad
        spacing, or a base not below every height.
    """
    h = np.asarray(heights, dtype=np.float64)
    if h.ndim != 2 or min(h.shape) < 2:
        raise ValueError(f"heights must be a 2-D array of at least 2 x 2 samples; got shape {h.shape}")
    if not np.isfinite(h).all():
        raise ValueError("heights contain NaN or infinite values")
    step = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (2,))
    if not (np.isfinite(step).all() and (step > 0).all()):
        raise ValueError(f"spacing must be positive; got {spacing!r}")
    span = float(h.max() - h.min())
    bottom = h.min() - 0.05 * max(span, float(step.max())) if base is None else float(base)
    if not bottom < h.min():
        raise ValueError(f"base ({bottom}) must lie below the lowest height ({h.min()})")
    nx, ny = h.shape
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    top = np.stack([origin[0] + ix * step[0], origin[1] + iy * step[1], h], axis=-1).reshape(-1, 3)
    vid = (ix * ny + iy)
    a, b, c, d = vid[:-1, :-1].ravel(), vid[1:, :-1].ravel(), vid[1:, 1:].ravel(), vid[:-1, 1:].ravel()
    faces = [np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)]  # counter-clockwise seen from above
    # the boundary ring of the top, counter-clockwise seen from above
    ring = np.concatenate([vid[:, 0], vid[-1, 1:], vid[-2::-1, -1], vid[0, -2:0:-1]])
    n = len(top)
    k = len(ring)
    lower = top[ring].copy()
    lower[:, 2] = bottom
    centre = np.array([[top[:, 0].mean(), top[:, 1].mean(), bottom]])
    points = np.concatenate([top, lower, centre])
    r0, r1 = ring, np.roll(ring, -1)
    l0 = n + np.arange(k)
    l1 = n + (np.arange(k) + 1) % k
    faces += [np.stack([r0, l0, l1], axis=1), np.stack([r0, l1, r1], axis=1)]  # sides, facing out
    faces.append(np.stack([np.full(k, n + k), l1, l0], axis=1))  # bottom fan, facing down
    return points, np.concatenate(faces).astype(np.int64)
