"""Index of the stages for the command line: name, help line and where the filter class lives.

The command line lists every stage in ``pverosion --help`` without importing
the filter modules (which load VTK and the numba kernels), and imports only the
filter of the stage that runs. ``tests/test_startup.py`` checks that this
index matches :data:`pverosion.filters.ALL_FILTERS`.
"""

from __future__ import annotations

import warnings
from importlib import import_module
from typing import NamedTuple

__all__ = ["DEPRECATED_COMMANDS", "STAGE_INDEX", "Stage", "load_stage", "resolve_command"]


class Stage(NamedTuple):
    """One entry of the index."""

    command: str
    """Subcommand (``ErosionFilter.command_name()``)."""
    label: str
    """Help line (the filter's ``LABEL``)."""
    target: str
    """``"module:Class"`` of the filter."""
    function: str
    """Public function of :mod:`pverosion.api` running the filter."""
    accessor: str
    """Method of the ``dataset.erosion`` accessor: the command with ``_`` for ``-`` ("" when the stage's input is
    not a dataset)."""


STAGE_INDEX: tuple[Stage, ...] = (
    Stage("curvature", "Curvature (Rusinkiewicz)", "pverosion.filters.curvature:Curvature",
          "curvature", "curvature"),
    Stage("weather", "Weathering (curvature-driven)", "pverosion.filters.weathering:Weathering",
          "weather", "weather"),
    Stage("hydraulic", "Hydraulic erosion (particle fluid)", "pverosion.filters.hydraulic:HydraulicErosion",
          "hydraulic_erosion", "hydraulic"),
    Stage("materials", "Materials from volume (BSP)", "pverosion.filters.materials:MaterialsFromVolume",
          "materials_from_volume", "materials"),
    Stage("sample-materials", "Material field sampling", "pverosion.filters.materials:MaterialSampler",
          "sample_materials", ""),
    Stage("voxel", "Voxel hydraulic erosion", "pverosion.filters.voxel:VoxelErosion",
          "voxel_erosion", "voxel"),
    Stage("shard-graph", "Voronoi shards", "pverosion.filters.shards:ShardGraph",
          "shard_graph", "shard_graph"),
    Stage("freeze-thaw", "Freeze-thaw weathering", "pverosion.filters.shards:FreezeThaw",
          "freeze_thaw", "freeze_thaw"),
    Stage("repair", "Repair self-intersections", "pverosion.filters.repair:RepairIntersections",
          "repair", "repair"),
    Stage("boolean", "Boolean operation", "pverosion.filters.repair:BooleanOperation",
          "boolean", "boolean"),
)
"""Every stage, in the order of :data:`pverosion.filters.ALL_FILTERS`."""


DEPRECATED_COMMANDS: dict[str, str] = {"shards": "freeze-thaw"}
"""Old stage names still accepted (with a ``DeprecationWarning``) by the CLI, batch scenarios and warm-up.

``shards`` named the freeze-thaw stage on the command line while
``mesh.erosion.shards`` built the shard graph; every front end now says
``freeze-thaw`` / ``freeze_thaw`` and ``shard-graph`` / ``shard_graph``.
"""


def resolve_command(command: str, *, stacklevel: int = 2) -> str:
    """``command``, or the current name of a deprecated stage name (warning ``DeprecationWarning``)."""
    new = DEPRECATED_COMMANDS.get(command)
    if new is None:
        return command
    warnings.warn(f"stage {command!r} is deprecated; use {new!r}", DeprecationWarning, stacklevel=stacklevel + 1)
    return new


def load_stage(command: str) -> type:
    """Import and return the filter class of subcommand ``command`` (deprecated names accepted).

    Raises
    ------
    ValueError
        If ``command`` is not a stage.
    """
    command = resolve_command(command)
    for stage in STAGE_INDEX:
        if stage.command == command:
            module, name = stage.target.split(":")
            return getattr(import_module(module), name)
    raise ValueError(f"unknown stage {command!r}; stages: {', '.join(s.command for s in STAGE_INDEX)}")
