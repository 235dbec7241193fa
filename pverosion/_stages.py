"""Index of the stages for the command line: name, help line and where the filter class lives.

The command line lists every stage in ``pverosion --help`` without importing
the filter modules (which load VTK and the numba kernels), and imports only the
filter of the stage that runs. ``tests/test_startup.py`` checks that this
index matches :data:`pverosion.filters.ALL_FILTERS`.
"""

from __future__ import annotations

from importlib import import_module
from typing import NamedTuple

__all__ = ["STAGE_INDEX", "Stage", "load_stage"]


class Stage(NamedTuple):
    """One entry of the index."""

    command: str
    """Subcommand (``ErosionFilter.command_name()``)."""
    label: str
    """Help line (the filter's ``LABEL``)."""
    target: str
    """``"module:Class"`` of the filter."""


STAGE_INDEX: tuple[Stage, ...] = (
    Stage("curvature", "Curvature (Rusinkiewicz)", "pverosion.filters.curvature:Curvature"),
    Stage("weather", "Weathering (curvature-driven)", "pverosion.filters.weathering:Weathering"),
    Stage("hydraulic", "Hydraulic erosion (particle fluid)", "pverosion.filters.hydraulic:HydraulicErosion"),
    Stage("materials", "Materials from volume (BSP)", "pverosion.filters.materials:MaterialsFromVolume"),
    Stage("sample-materials", "Material field sampling", "pverosion.filters.materials:MaterialSampler"),
    Stage("voxel", "Voxel hydraulic erosion", "pverosion.filters.voxel:VoxelErosion"),
    Stage("shard-graph", "Voronoi shards", "pverosion.filters.shards:ShardGraph"),
    Stage("shards", "Freeze-thaw weathering", "pverosion.filters.shards:FreezeThaw"),
    Stage("repair", "Repair self-intersections", "pverosion.filters.repair:RepairIntersections"),
    Stage("boolean", "Boolean operation", "pverosion.filters.repair:BooleanOperation"),
)
"""Every stage, in the order of :data:`pverosion.filters.ALL_FILTERS`."""


def load_stage(command: str) -> type:
    """Import and return the filter class of subcommand ``command``.

    Raises
    ------
    ValueError
        If ``command`` is not a stage.
    """
    for stage in STAGE_INDEX:
        if stage.command == command:
            module, name = stage.target.split(":")
            return getattr(import_module(module), name)
    raise ValueError(f"unknown stage {command!r}; stages: {', '.join(s.command for s in STAGE_INDEX)}")
