"""pverosion: erosion simulation directly on triangle meshes and voxel fields.

Every process is a VTK filter (:mod:`pverosion.filters`) over array kernels
(:mod:`pverosion.kernels`), with front ends as functions (``pverosion.curvature``),
a PyVista accessor (``mesh.erosion.curvature()``), the ``pverosion`` command line,
and ParaView plugins.
"""

from pverosion.api import (
    boolean,
    curvature,
    freeze_thaw,
    hydraulic_erosion,
    materials_from_volume,
    repair,
    sample_materials,
    shard_graph,
    voxel_erosion,
    weather,
)
from pverosion.kernels.mesh_repair import CoplanarOverlapError
from pverosion.kernels.validation import InvalidMeshError
from pverosion.live import interactive
from pverosion.plotting import CURVATURE_CMAP, curvature_cmap
from pverosion.viewer import view

__version__ = "0.1.0"

curvature_cmap()  # register the colour map of the papers under CURVATURE_CMAP

__all__ = [
    "CURVATURE_CMAP",
    "CoplanarOverlapError",
    "InvalidMeshError",
    "__version__",
    "boolean",
    "curvature",
    "curvature_cmap",
    "freeze_thaw",
    "hydraulic_erosion",
    "interactive",
    "materials_from_volume",
    "repair",
    "sample_materials",
    "shard_graph",
    "view",
    "voxel_erosion",
    "weather",
]
