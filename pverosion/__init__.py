"""pverosion: erosion simulation directly on triangle meshes and voxel fields.

Every process is a VTK filter (:mod:`pverosion.filters`) over array kernels
(:mod:`pverosion.kernels`), with front ends as functions (``pverosion.curvature``),
a PyVista accessor (``mesh.erosion.curvature()``), the ``pverosion`` command line,
and ParaView plugins.
"""

import sys as _sys

from vtkmodules.vtkCommonCore import vtkOutputWindow

# Importing PyVista replaces VTK's output window to send VTK's messages to Python's logging module. In
# pvpython, pvbatch and ParaView's Python shell, Python's own output and ParaView's errors go through that
# window, so the replacement would silence them: there, keep the host's window.
_host_window = vtkOutputWindow.GetInstance()
_keep_host_window = "paraview" in _sys.modules or type(_sys.stdout).__name__ == "vtkPythonStdStreamCaptureHelper"

from pverosion.api import (  # noqa: E402
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
from pverosion.kernels.mesh_repair import CoplanarOverlapError  # noqa: E402
from pverosion.kernels.validation import InvalidMeshError  # noqa: E402
from pverosion.plotting import CURVATURE_CMAP, curvature_cmap  # noqa: E402

if _keep_host_window:
    vtkOutputWindow.SetInstance(_host_window)
del _host_window, _keep_host_window

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
    "materials_from_volume",
    "repair",
    "sample_materials",
    "shard_graph",
    "voxel_erosion",
    "weather",
]
