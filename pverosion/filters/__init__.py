"""VTK filters (VTKPythonAlgorithmBase subclasses) wrapping the kernels.

``ALL_FILTERS`` lists every stage; the CLI and the ParaView plugin are
generated from it, so a new stage is exposed by adding its class here.
"""

from pverosion.filters.base import ErosionFilter, Param
from pverosion.filters.curvature import Curvature
from pverosion.filters.hydraulic import HydraulicErosion
from pverosion.filters.materials import MaterialSampler, MaterialsFromVolume
from pverosion.filters.repair import BooleanOperation, RepairIntersections
from pverosion.filters.shards import FreezeThaw, ShardGraph
from pverosion.filters.voxel import VoxelErosion
from pverosion.filters.weathering import Weathering

ALL_FILTERS: tuple[type[ErosionFilter], ...] = (Curvature, Weathering, HydraulicErosion, MaterialsFromVolume,
                                                MaterialSampler, VoxelErosion, ShardGraph, FreezeThaw,
                                                RepairIntersections, BooleanOperation)

__all__ = [
    "ALL_FILTERS",
    "BooleanOperation",
    "Curvature",
    "ErosionFilter",
    "FreezeThaw",
    "HydraulicErosion",
    "MaterialSampler",
    "MaterialsFromVolume",
    "Param",
    "RepairIntersections",
    "ShardGraph",
    "VoxelErosion",
    "Weathering",
]
