"""Mateos et al.'s freeze–thaw scenes as FreezeThaw filter set-ups (Figures 14–17), shared by pipelines and benchmarks.

Each scene is a closed mesh plus the options of
:class:`pverosion.filters.FreezeThaw`; :data:`SCENES` maps a name to a
builder ``(small: bool) -> (mesh, options, steps)``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyvista as pv

from pverosion.kernels.mesh.terrain import height_field_solid

__all__ = ["SCENES", "basalt_wall", "cave_hill", "hill_cone", "slab_block", "terrain_ridge"]


def hill_cone(*, resolution: int = 48, radius: float = 1.0, height: float = 1.0) -> pv.PolyData:
    """A cone standing on z = 0, like the paper's Hill3D model (closed, outward triangles)."""
    cone = pv.Cone(center=(0.0, 0.0, 0.5 * height), direction=(0.0, 0.0, 1.0), height=height, radius=radius,
                   resolution=resolution, capping=True)
    return cone.triangulate().clean()


def _box(bounds) -> pv.PolyData:
    return pv.Box(bounds=bounds).triangulate().clean()


def cave_hill(small: bool = False):
    """Figure 14: the cone with core cells on its surface except a front window, so a cave is carved."""
    mesh = hill_cone()
    options = {"cells": 800 if small else 3000, "pattern": "grid", "jitter": 0.3, "core": "surface",
               "core_window": "0.32,0.32,0.3,0.3", "water_direction": "-1,-1,-0.6", "spread": 15.0,
               "paths_per_step": 2000 if small else 10000}
    return mesh, options, 8 if small else 12


def basalt_wall(small: bool = False):
    """Figure 15: a wall of jittered hexagonal columns (columnar basalt) with cross joints; the back row is core."""
    mesh = _box((-1.5, 1.5, -0.4, 0.4, 0.0, 1.6))
    options = {"cells": 120 if small else 300, "pattern": "hex", "jitter": 0.12, "layers": "0.4",
               "core_plane": "0,1,0,0.25", "water_direction": "0,0.5,-1", "spread": 10.0,
               "paths_per_step": 300 if small else 1000}
    return mesh, options, 10 if small else 20


def slab_block(small: bool = False):
    """Figure 16: a box cut into tilted slabs of varying thickness, water from the side and gravity upwards."""
    mesh = _box((0.0, 2.0, 0.0, 1.0, 0.0, 1.5))
    options = {"cells": 60 if small else 108, "pattern": "slabs", "layers": "0.15,0.3,0.2,0.35", "tilt": 20.0,
               "jitter": 0.0, "water_direction": "1,0,0", "spread": 30.0, "gravity": "0,0,1", "k_solid": 0.2,
               "k_air": 0.1, "k_res": 0.5, "paths_per_step": 500 if small else 2000}
    return mesh, options, 10 if small else 20


def terrain_ridge(path: str | Path, *, stride: int = 6) -> pv.PolyData:
    """Figure 17: the closed block under a DEM (e.g. ``SainteHelens.dem``), every ``stride``-th sample.

    Heights are scaled to the x-y extent's units as they come (metres for the St Helens DEM).
    """
    image = pv.read(str(path))
    dims = image.dimensions
    heights = np.asarray(image.active_scalars, dtype=np.float64).reshape(dims[:2], order="F")[::stride, ::stride]
    spacing = np.array(image.spacing[:2]) * stride
    points, faces = height_field_solid(heights, spacing=spacing, origin=image.origin[:2])
    return pv.PolyData.from_regular_faces(points, faces)


def ridge_scene(path: str | Path, small: bool = False):
    """Figure 17 set-up on a DEM block: jittered grid shards, near-vertical water, the bottom layer core."""
    mesh = terrain_ridge(path, stride=12 if small else 6)
    z = mesh.points[:, 2]
    floor = z.min() + 0.15 * (z.max() - z.min())
    options = {"cells": 1500 if small else 6000, "pattern": "grid", "jitter": 0.3, "core_plane": f"0,0,-1,{-floor}",
               "water_direction": "0.3,0,-1", "spread": 10.0, "paths_per_step": 2000 if small else 6000}
    return mesh, options, 10


SCENES = {"cave": cave_hill, "basalt": basalt_wall, "slabs": slab_block}
