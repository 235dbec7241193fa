"""Procedural example surfaces; no downloads, deterministic for a given seed."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pyvista as pv

__all__ = ["EXAMPLES", "data_path", "load_cube", "load_cylinder", "load_hand", "load_rock", "load_torus", "periodic_grid_surface"]


def data_path(name: str = "") -> Path:
    """Path of ``name`` in the folder of real scans (``bunny.ply``, ``SainteHelens.dem``, ``HeadMRVolume.mhd``).

    The folder is ``$PVEROSION_DATA`` when it is set, else ``shared/data`` beside the source
    checkout (``<checkout>/../shared/data``).  The path is returned whether or not it exists, so
    tests, pipelines, benchmarks and examples fall back to procedural stand-ins when it does not.

    Parameters
    ----------
    name : str, optional
        File name in the folder; empty for the folder itself.

    Returns
    -------
    pathlib.Path
    """
    folder = os.environ.get("PVEROSION_DATA")
    return (Path(folder) if folder else Path(__file__).resolve().parents[3] / "shared" / "data") / name


def _triangulate_grid(n_u: int, n_v: int, *, wrap_u: bool, wrap_v: bool) -> np.ndarray:
    """Triangles (F, 3) of an n_u x n_v vertex grid, vertex (i, j) at index i * n_v + j."""
    cells_u = n_u if wrap_u else n_u - 1
    cells_v = n_v if wrap_v else n_v - 1
    i, j = np.meshgrid(np.arange(cells_u), np.arange(cells_v), indexing="ij")
    i, j = i.ravel(), j.ravel()
    a = i * n_v + j
    b = ((i + 1) % n_u) * n_v + j
    c = ((i + 1) % n_u) * n_v + (j + 1) % n_v
    d = i * n_v + (j + 1) % n_v
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def periodic_grid_surface(points_grid: np.ndarray, *, wrap_u: bool, wrap_v: bool) -> pv.PolyData:
    """Triangulated surface through a grid of points.

    Parameters
    ----------
    points_grid : numpy.ndarray, shape (n_u, n_v, 3)
        Points; the (u, v) parameter directions of the grid.
    wrap_u, wrap_v : bool
        Whether the grid closes on itself along u or v (no seam, no duplicate points).

    Returns
    -------
    pyvista.PolyData
    """
    n_u, n_v, _ = points_grid.shape
    faces = _triangulate_grid(n_u, n_v, wrap_u=wrap_u, wrap_v=wrap_v)
    return pv.PolyData.from_regular_faces(points_grid.reshape(-1, 3), faces)


def load_torus(*, major_radius: float = 3.0, minor_radius: float = 1.0, n_major: int = 240,
               n_minor: int = 120) -> pv.PolyData:
    """Closed, outward-oriented torus around the z axis.

    Exact mean curvature at tube angle v: ``(R + 2 r cos v) / (2 r (R + r cos v))``.
    """
    u = np.linspace(0, 2 * np.pi, n_major, endpoint=False)
    v = np.linspace(0, 2 * np.pi, n_minor, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    ring = major_radius + minor_radius * np.cos(vv)
    grid = np.stack([ring * np.cos(uu), ring * np.sin(uu), minor_radius * np.sin(vv)], axis=-1)
    return periodic_grid_surface(grid, wrap_u=True, wrap_v=True)


def load_cylinder(*, radius: float = 1.0, height: float = 4.0, n_around: int = 128, n_along: int = 64) -> pv.PolyData:
    """Open cylinder (no caps) around the z axis, outward-oriented; H = 1 / (2 r)."""
    theta = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    z = np.linspace(-height / 2, height / 2, n_along)
    tt, zz = np.meshgrid(theta, z, indexing="ij")
    grid = np.stack([radius * np.cos(tt), radius * np.sin(tt), zz], axis=-1)
    return periodic_grid_surface(grid, wrap_u=True, wrap_v=False)


def load_rock(*, subdivisions: int = 5, n_bumps: int = 24, roughness: float = 0.25, seed: int = 0) -> pv.PolyData:
    """A boulder: a unit icosphere displaced radially by random smooth bumps and dents.

    Parameters
    ----------
    subdivisions : int, default: 5
        Icosphere subdivisions (10 * 4**subdivisions + 2 vertices).
    n_bumps : int, default: 24
        Number of Gaussian bumps (positive) and dents (negative).
    roughness : float, default: 0.25
        Largest bump height, relative to the radius.
    seed : int, default: 0
        Random seed; the same seed gives the same rock.

    Returns
    -------
    pyvista.PolyData
    """
    rng = np.random.default_rng(seed)
    sphere = pv.Icosphere(radius=1.0, nsub=subdivisions)
    points = np.asarray(sphere.points, dtype=np.float64)
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    centres = rng.normal(size=(n_bumps, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    heights = roughness * rng.uniform(-1.0, 1.0, n_bumps)
    widths = rng.uniform(0.2, 0.6, n_bumps)
    d2 = ((points[:, None, :] - centres[None]) ** 2).sum(-1)
    radius = 1.0 + (heights * np.exp(-d2 / widths**2)).sum(1)
    return pv.PolyData.from_regular_faces(points * radius[:, None], sphere.regular_faces)


def load_cube(*, resolution: int = 10, size: float = 2.0) -> pv.PolyData:
    """Closed cube centred at the origin, each face an evenly triangulated grid.

    Parameters
    ----------
    resolution : int, default: 10
        Grid cells along every cube edge (``6 * resolution**2 + 2`` vertices;
        602 for 10, the model of the paper's Figure 6).
    size : float, default: 2.0
        Edge length.

    Returns
    -------
    pyvista.PolyData
        Outward-oriented triangles.
    """
    if int(resolution) != resolution or resolution < 1:
        raise ValueError(f"resolution must be an integer >= 1; got {resolution!r}")
    n = int(resolution)
    t = np.linspace(-1.0, 1.0, n + 1)
    uu, vv = np.meshgrid(t, t, indexing="ij")
    grid_faces = _triangulate_grid(n + 1, n + 1, wrap_u=False, wrap_v=False)
    points, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.zeros((n + 1, n + 1, 3))
            # (u, v, outward) right-handed, so the grid's triangles face out
            u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
            if sign < 0:
                u_axis, v_axis = v_axis, u_axis
            p[..., axis] = sign
            p[..., u_axis] = uu
            p[..., v_axis] = vv
            faces.append(grid_faces + sum(len(q) for q in points))
            points.append(p.reshape(-1, 3))
    all_points = np.concatenate(points)
    unique, inverse = np.unique(np.round(all_points, 12), axis=0, return_inverse=True)
    cube_faces = inverse.ravel()[np.concatenate(faces)]
    return pv.PolyData.from_regular_faces(unique * (size / 2.0), cube_faces)


def load_hand(*, subdivisions: int = 5, finger_length: float = 0.9, finger_width: float = 0.18) -> pv.PolyData:
    """A "hand"-like closed surface: a flattened palm with five thin protruding fingers.

    Radial displacement of an icosphere by narrow lobes, so the surface stays a
    closed manifold; the finger tips are the most protruding, highly convex
    regions (the model of the paper's Figures 8–9).

    Parameters
    ----------
    subdivisions : int, default: 5
        Icosphere subdivisions.
    finger_length : float, default: 0.9
        Length of the fingers beyond the palm, relative to the palm radius.
    finger_width : float, default: 0.18
        Angular width (radians) of each finger.

    Returns
    -------
    pyvista.PolyData
    """
    sphere = pv.Icosphere(radius=1.0, nsub=subdivisions)
    points = np.asarray(sphere.points, dtype=np.float64)
    points /= np.linalg.norm(points, axis=1, keepdims=True)
    angles = np.deg2rad([-70.0, -35.0, 0.0, 30.0, 60.0])  # thumb to little finger, in the palm plane
    axes = np.stack([np.sin(angles), np.cos(angles), np.zeros_like(angles)], axis=1)
    lengths = finger_length * np.array([0.7, 1.0, 1.1, 1.0, 0.8])
    cosine = np.clip(points @ axes.T, -1.0, 1.0)
    lobes = lengths * np.exp(-((np.arccos(cosine) / finger_width) ** 2))
    radius = 1.0 + lobes.sum(axis=1)
    palm = np.array([1.0, 1.0, 0.45])  # flattened across the palm
    return pv.PolyData.from_regular_faces(points * radius[:, None] * palm, sphere.regular_faces)


EXAMPLES = {
    "cube": load_cube,
    "cylinder": load_cylinder,
    "hand": load_hand,
    "rock": load_rock,
    "torus": load_torus,
}
"""Procedural example surfaces by name (batch scenarios use these names)."""
