"""Colour coding of the papers and off-screen rendering helpers."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.colors import LinearSegmentedColormap

from pverosion.io import atomic_path

__all__ = ["CURVATURE_CMAP", "curvature_cmap", "render_scalars"]

CURVATURE_CMAP = "pverosion_curvature"
"""Name of the registered blue-green-red colour map (Skorkovská 2019, Figure 2)."""


def curvature_cmap() -> LinearSegmentedColormap:
    """The curvature colour map: blue for H < 0, green for H = 0, red for H > 0.

    It is registered with matplotlib (and so usable in PyVista) as
    ``"pverosion_curvature"`` when pverosion is imported. Use it with colour
    limits symmetric about zero so that green marks flat regions.
    """
    if CURVATURE_CMAP not in matplotlib.colormaps:
        cmap = LinearSegmentedColormap.from_list(CURVATURE_CMAP, [(0.0, 0.0, 1.0), (0.0, 0.8, 0.0), (1.0, 0.0, 0.0)])
        matplotlib.colormaps.register(cmap)
    return matplotlib.colormaps[CURVATURE_CMAP]


def render_scalars(
    mesh,
    path: str | os.PathLike,
    *,
    scalars: str = "mean_curvature",
    window_size: tuple[int, int] = (1024, 768),
    percentile: float = 98.0,
) -> Path:
    """Render ``mesh`` coloured by ``scalars`` with the curvature map, off-screen, to a PNG.

    Colour limits are symmetric about zero at the given percentile of
    ``|scalars|``, so zero is green and outliers do not wash out the rest.

    Parameters
    ----------
    mesh : pyvista.PolyData
    path : str or path-like
        PNG file to write (atomically).
    scalars : str, default: "mean_curvature"
    window_size : tuple of int, default: (1024, 768)
    percentile : float, default: 98.0

    Returns
    -------
    pathlib.Path
    """
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    values = np.asarray(mesh[scalars])
    limit = float(np.percentile(np.abs(values), percentile)) or 1.0
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
    plotter.add_mesh(mesh, scalars=scalars, cmap=curvature_cmap(), clim=(-limit, limit), smooth_shading=True)
    plotter.view_isometric()
    path = Path(path)
    with atomic_path(path) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()
    return path
