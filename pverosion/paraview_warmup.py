"""Run every filter once on small inputs so that numba caches its compiled kernels.

``pverosion paraview setup`` runs ``pvpython -m pverosion.paraview_warmup``:
the first use of each filter then starts in seconds instead of compiling for
about a minute. Uses VTK sources only (the host's VTK), and prints one line
per filter.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkFiltersSources import vtkSphereSource
from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

__all__ = ["SMALL_OPTIONS", "small_inputs", "warm_up"]

SMALL_OPTIONS: dict[str, dict] = {
    "weather": {"iterations": 3},
    "hydraulic": {"iterations": 3, "emitter": "0,0,1.5,0,0,-1,0.2,40"},
    "materials": {"thresholds": "100,150"},
    "sample-materials": {},
    "voxel": {"iterations": 2},
    "shard-graph": {"cells": 20},
    "freeze-thaw": {"cells": 20, "iterations": 2, "paths_per_step": 10},
}
"""Options (by command name) that keep each filter's run small; the rest stay at their defaults."""


def _sphere(radius: float, centre=(0.0, 0.0, 0.0)):
    source = vtkSphereSource()
    source.SetRadius(radius)
    source.SetCenter(*centre)
    source.SetThetaResolution(24)
    source.SetPhiResolution(24)
    source.Update()
    return source.GetOutput()


def _wavelet(extent: int = 6) -> vtkImageData:
    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-extent, extent, -extent, extent, -extent, extent)
    source.Update()
    return source.GetOutput()


def small_inputs(command: str) -> tuple:
    """Small input data objects for the filter with CLI name ``command``.

    Spheres, overlapping spheres (Boolean), a wavelet image (materials), a
    voxel grid with a material floor and a water source (voxel erosion).
    """
    if command == "boolean":
        return _sphere(1.0), _sphere(1.0, (0.7, 0.1, 0.05))
    if command in ("materials", "sample-materials"):
        return (_wavelet(),)
    if command == "voxel":
        import numpy as np

        from pverosion.filters.voxel import voxel_grid

        amount = np.zeros((10, 8, 8))
        amount[:, :, :4] = 1.0
        source = np.zeros(amount.shape, bool)
        source[:2, :, 5:7] = True
        return (voxel_grid(amount, spacing=0.1, source=source),)
    return (_sphere(1.0),)


def warm_up() -> None:
    """Run every filter once on :func:`small_inputs` with :data:`SMALL_OPTIONS`.

    The material sampler reads the BSP tree the materials filter saved.
    """
    from pverosion.filters import ALL_FILTERS

    with tempfile.TemporaryDirectory() as tmp:
        tree = str(Path(tmp) / "tree.json")
        for cls in ALL_FILTERS:
            start = time.perf_counter()
            options = dict(SMALL_OPTIONS.get(cls.command_name(), {}))
            if cls.command_name() in ("materials", "sample-materials"):
                options["tree_file"] = tree
            cls(**options).run(*small_inputs(cls.command_name()))
            print(f"  {cls.command_name()}: ready ({time.perf_counter() - start:.0f} s)", flush=True)


if __name__ == "__main__":
    warm_up()
