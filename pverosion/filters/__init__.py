"""VTK filters (VTKPythonAlgorithmBase subclasses) wrapping the kernels.

``ALL_FILTERS`` lists every stage; the CLI and the ParaView plugin are
generated from it, so a new stage is exposed by adding its class here (and to
:data:`pverosion._stages.STAGE_INDEX`, which lets the CLI list it without
importing it). The names load their module on first use, so importing one
filter module does not import (and compile) the others.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

_LAZY = {
    "ErosionFilter": "base",
    "Param": "base",
    "Curvature": "curvature",
    "HydraulicErosion": "hydraulic",
    "MaterialSampler": "materials",
    "MaterialsFromVolume": "materials",
    "BooleanOperation": "repair",
    "RepairIntersections": "repair",
    "FreezeThaw": "shards",
    "ShardGraph": "shards",
    "VoxelErosion": "voxel",
    "Weathering": "weathering",
}

_ALL_FILTERS = ("Curvature", "Weathering", "HydraulicErosion", "MaterialsFromVolume", "MaterialSampler",
                "VoxelErosion", "ShardGraph", "FreezeThaw", "RepairIntersections", "BooleanOperation")

__all__ = ["ALL_FILTERS", *sorted(_LAZY)]

if TYPE_CHECKING:
    from pverosion.filters.base import ErosionFilter, Param
    from pverosion.filters.curvature import Curvature
    from pverosion.filters.hydraulic import HydraulicErosion
    from pverosion.filters.materials import MaterialSampler, MaterialsFromVolume
    from pverosion.filters.repair import BooleanOperation, RepairIntersections
    from pverosion.filters.shards import FreezeThaw, ShardGraph
    from pverosion.filters.voxel import VoxelErosion
    from pverosion.filters.weathering import Weathering

    ALL_FILTERS: tuple[type[ErosionFilter], ...]


def __getattr__(name: str):
    if name == "ALL_FILTERS":
        value = tuple(__getattr__(cls) for cls in _ALL_FILTERS)
    elif name in _LAZY:
        value = getattr(import_module(f"pverosion.filters.{_LAZY[name]}"), name)
    else:
        raise AttributeError(f"module 'pverosion.filters' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
