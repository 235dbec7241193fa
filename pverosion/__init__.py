"""pverosion: erosion simulation directly on triangle meshes and voxel fields.

Every process is a VTK filter (:mod:`pverosion.filters`) over array kernels
(:mod:`pverosion.kernels`), with front ends as functions (``pverosion.curvature``),
a PyVista accessor (``mesh.erosion.curvature()``), the ``pverosion`` command line,
and ParaView plugins.

Importing the package is cheap: the front ends, and with them VTK, numba and
matplotlib, load on first use of a name below.
"""

from __future__ import annotations

import sys
from importlib import import_module
from typing import TYPE_CHECKING

from pverosion._moved import install as _install_moved_modules
from pverosion._runtime import configure_allocator, configure_environment

configure_environment()  # before numba starts its threads
configure_allocator()  # scratch arrays stay mapped between kernel calls
_install_moved_modules()  # old module paths of the flat layout keep working, with a DeprecationWarning

__version__ = "0.1.0"

_LAZY = {
    "boolean": "pverosion.api",
    "curvature": "pverosion.api",
    "freeze_thaw": "pverosion.api",
    "hydraulic_erosion": "pverosion.api",
    "materials_from_volume": "pverosion.api",
    "repair": "pverosion.api",
    "sample_materials": "pverosion.api",
    "shard_graph": "pverosion.api",
    "voxel_erosion": "pverosion.api",
    "weather": "pverosion.api",
    "CoplanarOverlapError": "pverosion.kernels.repair.mesh_repair",
    "RepairError": "pverosion.kernels.repair.mesh_repair",
    "InvalidMeshError": "pverosion.kernels.validation",
    "CURVATURE_CMAP": "pverosion.plotting",  # importing pverosion.plotting registers the colour map
    "curvature_cmap": "pverosion.plotting",
    "interactive": "pverosion.live",
    "view": "pverosion.viewer",
}

__all__ = ["__version__", *sorted(_LAZY, key=str.lower)]

if TYPE_CHECKING:
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
    from pverosion.kernels.repair.mesh_repair import CoplanarOverlapError, RepairError
    from pverosion.kernels.validation import InvalidMeshError
    from pverosion.live import interactive
    from pverosion.plotting import CURVATURE_CMAP, curvature_cmap
    from pverosion.viewer import view


def _in_paraview() -> bool:
    """True inside pvpython, pvbatch or ParaView's Python shell."""
    return sys.modules.get("paraview") is not None or type(sys.stdout).__name__ == "vtkPythonStdStreamCaptureHelper"


def _import_keeping_host_window(module: str):
    """Import ``module``; inside ParaView, keep the host's VTK output window.

    Importing PyVista replaces VTK's output window to send VTK's messages to Python's logging; in
    ParaView, Python's own output and ParaView's errors go through that window, so the host's stays.
    """
    if not _in_paraview():
        return import_module(module)
    from vtkmodules.vtkCommonCore import vtkOutputWindow

    host_window = vtkOutputWindow.GetInstance()
    try:
        return import_module(module)
    finally:
        vtkOutputWindow.SetInstance(host_window)


if _in_paraview():  # the plugin's filter modules import PyVista: do it here, under the guard
    _import_keeping_host_window("pyvista")


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'pverosion' has no attribute {name!r}")
    value = getattr(_import_keeping_host_window(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
