"""Shared fixtures: procedural surfaces and the real scans of ../shared/data."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session")
def bunny() -> pv.PolyData:
    path = DATA / "bunny.ply"
    if not path.exists():
        pytest.skip(f"real data not found at {path}")
    return pv.read(path)


def icosphere(radius: float, nsub: int) -> pv.PolyData:
    """Icosphere with float64 points exactly on the sphere."""
    s = pv.Icosphere(radius=1.0, nsub=nsub)
    p = np.asarray(s.points, dtype=np.float64)
    p = radius * p / np.linalg.norm(p, axis=1, keepdims=True)
    return pv.PolyData.from_regular_faces(p, s.regular_faces)


def height_field(fn, *, n: int = 81, half: float = 1.0) -> pv.PolyData:
    """Triangulated graph z = fn(x, y) on a square grid."""
    x = np.linspace(-half, half, n)
    xx, yy = np.meshgrid(x, x, indexing="ij")
    grid = np.stack([xx, yy, fn(xx, yy)], axis=-1)
    from pverosion.examples import periodic_grid_surface

    return periodic_grid_surface(grid, wrap_u=False, wrap_v=False)
