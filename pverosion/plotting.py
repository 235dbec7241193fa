"""Colour coding of the papers and off-screen rendering helpers."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.colors import LinearSegmentedColormap

from pverosion.io import atomic_path

__all__ = [
    "CURVATURE_CMAP",
    "CURVATURE_COLOURS",
    "curvature_cmap",
    "plot_slices",
    "plot_statistics",
    "render_scalars",
    "render_strip",
    "save_figure",
    "scalar_style",
]

CURVATURE_CMAP = "pverosion_curvature"
"""Name of the registered blue-green-red colour map (Skorkovská 2019, Figure 2)."""

CURVATURE_COLOURS = ((0.0, 0.0, 1.0), (0.0, 0.8, 0.0), (1.0, 0.0, 0.0))
"""RGB colours of the curvature colour map at its low end, middle (H = 0) and high end."""


def curvature_cmap() -> LinearSegmentedColormap:
    """The curvature colour map: blue for H < 0, green for H = 0, red for H > 0.

    It is registered with matplotlib (and so usable in PyVista) as
    ``"pverosion_curvature"`` when :mod:`pverosion.plotting` is imported (which
    using ``pverosion.CURVATURE_CMAP`` does). Use it with colour
    limits symmetric about zero so that green marks flat regions.
    """
    if CURVATURE_CMAP not in matplotlib.colormaps:
        cmap = LinearSegmentedColormap.from_list(CURVATURE_CMAP, CURVATURE_COLOURS)
        matplotlib.colormaps.register(cmap)
    return matplotlib.colormaps[CURVATURE_CMAP]


def _offscreen_pyvista():
    """PyVista, set up to render without a display (EGL) when there is none."""
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    return pv


def _symmetric_limits(values, percentile: float) -> tuple[float, float]:
    """Colour limits ``(-L, L)`` with L the ``percentile`` of ``|values|``, so zero is the middle."""
    limit = float(np.percentile(np.abs(np.asarray(values)), percentile)) or 1.0
    return -limit, limit


def _colours(values, percentile: float, cmap: str | None) -> dict:
    """Colour map options: the curvature coding with symmetric limits, or ``cmap`` over the data range."""
    if cmap is None:
        return {"cmap": curvature_cmap(), "clim": _symmetric_limits(values, percentile)}
    return {"cmap": cmap}


CATEGORICAL_ARRAYS = ("material_id", "voxel_class", "shard_colour", "source_mesh", "contact")
"""Point or cell arrays that hold labels, coloured with a qualitative map and one colour per value."""

_SEQUENTIAL = {"hardness": "copper_r", "erosion_depth": "magma", "speed": "Blues", "sediment": "YlOrBr"}


def scalar_style(name: str, values, *, percentile: float = 98.0) -> dict:
    """``add_mesh`` colour options for the array ``name`` holding ``values``.

    Curvature arrays get the curvature colour map with limits symmetric about
    zero (see :func:`render_scalars`); label arrays (:data:`CATEGORICAL_ARRAYS`)
    a qualitative map with one colour per value; ``hardness`` the thesis'
    brown scale (dark is hard); other arrays a sequential map over their range.

    Parameters
    ----------
    name : str
    values : array_like, shape (N,) or (N, k)
        The array (vectors are coloured by their magnitude).
    percentile : float, default: 98.0
        Percentile of ``|values|`` used as the symmetric curvature limit.

    Returns
    -------
    dict
        ``cmap`` and ``clim`` (and for labels ``n_colors`` and ``annotations``, a label per value).
    """
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 2:
        values = np.linalg.norm(values, axis=1)
    if values.size == 0:
        return {"cmap": "viridis"}
    if "curvature" in name:
        return {"cmap": curvature_cmap(), "clim": _symmetric_limits(values, percentile)}
    lo, hi = float(values.min()), float(values.max())
    if name in CATEGORICAL_ARRAYS:
        n = int(round(hi - lo)) + 1  # one colour per integer label, each centred on its value
        labels = {float(v): str(int(v)) for v in np.arange(round(lo), round(hi) + 1)} if n <= 20 else None
        return {"cmap": "tab10" if n <= 10 else "tab20", "clim": (lo - 0.5, hi + 0.5), "n_colors": n,
                "annotations": labels}
    if hi <= lo:
        hi = lo + 1.0
    return {"cmap": _SEQUENTIAL.get(name, "viridis"), "clim": (lo, hi)}


def _save_screenshot(plotter, path: str | os.PathLike) -> Path:
    """Write the plotter's image to ``path`` atomically and close it."""
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            plotter.screenshot(str(tmp))
    finally:
        plotter.close()
    return path


def save_figure(fig, path: str | os.PathLike) -> Path:
    """Write a matplotlib figure to ``path`` as PNG atomically and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=100, format="png")
    finally:
        plt.close(fig)
    return path


def render_scalars(
    mesh,
    path: str | os.PathLike,
    *,
    scalars: str = "mean_curvature",
    window_size: tuple[int, int] = (1024, 768),
    percentile: float = 98.0,
    cmap: str | None = None,
) -> Path:
    """Render ``mesh`` coloured by ``scalars`` with the curvature map, off-screen, to a PNG.

    Colour limits are symmetric about zero at the given percentile of
    ``|scalars|``, so zero is green and outliers do not wash out the rest.
    With ``cmap``, that colour map spans the data range instead.

    Parameters
    ----------
    mesh : pyvista.PolyData
    path : str or path-like
        PNG file to write (atomically).
    scalars : str, default: "mean_curvature"
    window_size : tuple of int, default: (1024, 768)
    percentile : float, default: 98.0
    cmap : str, optional

    Returns
    -------
    pathlib.Path
    """
    pv = _offscreen_pyvista()
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
    plotter.add_mesh(mesh, scalars=scalars, smooth_shading=True, **_colours(mesh[scalars], percentile, cmap))
    plotter.view_isometric()
    return _save_screenshot(plotter, path)


def render_strip(
    rows: list[list],
    path: str | os.PathLike,
    *,
    labels: list[list[str]] | None = None,
    scalars: str = "mean_curvature",
    panel_size: tuple[int, int] = (360, 360),
    percentile: float = 98.0,
    cmap: str | None = None,
    particles: list[list] | None = None,
) -> Path:
    """Render a grid of meshes (one row per list) with the curvature colour map to one PNG.

    Each panel has colour limits symmetric about zero at the given
    percentile of its own ``|scalars|`` (curvature is scale-dependent), so
    green marks flat regions everywhere. All panels share one camera
    direction.

    Parameters
    ----------
    rows : list of list of pyvista.PolyData
    path : str or path-like
        PNG file to write (atomically).
    labels : list of list of str, optional
        Text in the corner of each panel.
    scalars : str, default: "mean_curvature"
    panel_size : tuple of int, default: (360, 360)
    percentile : float, default: 98.0
    cmap : str, optional
        Another colour map (e.g. ``"copper_r"`` for hardness, hard is dark),
        spanning each panel's data range instead of the curvature coding.
    particles : list of list of pyvista.PolyData or None, optional
        Point clouds (fluid particles) drawn as blue spheres over the panel
        at the same position; None or an empty cloud draws nothing.

    Returns
    -------
    pathlib.Path
    """
    pv = _offscreen_pyvista()
    n_rows, n_cols = len(rows), max(len(r) for r in rows)
    plotter = pv.Plotter(off_screen=True, shape=(n_rows, n_cols),
                         window_size=[panel_size[0] * n_cols, panel_size[1] * n_rows], border=False)
    for i, row in enumerate(rows):
        for j, mesh in enumerate(row):
            plotter.subplot(i, j)
            plotter.add_mesh(mesh, scalars=scalars, smooth_shading=True, show_scalar_bar=False,
                             **_colours(mesh[scalars], percentile, cmap))
            cloud = particles[i][j] if particles is not None else None
            if cloud is not None and cloud.n_points:
                plotter.add_mesh(cloud, color="#2f6fd6", render_points_as_spheres=True, point_size=4)
            if labels is not None:
                plotter.add_text(labels[i][j], font_size=10, position="upper_left")
            plotter.view_isometric()
    return _save_screenshot(plotter, path)


def plot_statistics(series: dict[str, dict[str, np.ndarray]], path: str | os.PathLike) -> Path:
    """Chart per-step statistics of one or more runs (one line per run) to a PNG.

    Parameters
    ----------
    series : dict
        Run label -> statistics as returned by
        :attr:`pverosion.kernels.weathering.model.WeatheringSolver.statistics`.
    path : str or path-like
        PNG file to write (atomically).

    Returns
    -------
    pathlib.Path
    """
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("volume", "volume"), ("area", "surface area"), ("mean_abs_curvature", "mean |H|"),
              ("max_abs_curvature", "max |H|"), ("eroded_volume", "eroded volume"), ("retries", "guard retries")]
    fig, axes = plt.subplots(2, 3, figsize=(12, 6), constrained_layout=True)
    for ax, (key, title) in zip(axes.ravel(), panels):
        for label, stats in series.items():
            ax.plot(np.arange(len(stats[key])), stats[key], label=label)
        ax.set_title(title)
        ax.set_xlabel("step")
    axes[0, 0].legend()
    return save_figure(fig, path)


def plot_slices(image, path: str | os.PathLike, *, scalars: str = "hardness", title: str = "") -> Path:
    """The three middle slices (x, y, z) of an image's point array as one PNG (Figures 11.11–11.18).

    Dark is hard and light is soft for ``hardness`` (the thesis' brown scale); other arrays
    use a qualitative map.

    Parameters
    ----------
    image : pyvista.ImageData
    path : str or path-like
        PNG file to write (atomically).
    scalars : str, default: "hardness"
    title : str, optional

    Returns
    -------
    pathlib.Path
    """
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nx, ny, nz = image.dimensions
    values = np.asarray(image.point_data[scalars]).reshape(nz, ny, nx).transpose(2, 1, 0)
    cmap = "copper_r" if scalars == "hardness" else "tab10"  # dark is hard, light is soft
    fig, axes = plt.subplots(1, 3, figsize=(12, 4), constrained_layout=True)
    cuts = (("x", values[nx // 2, :, :].T, "y", "z"), ("y", values[:, ny // 2, :].T, "x", "z"),
            ("z", values[:, :, nz // 2].T, "x", "y"))
    vmin, vmax = float(values.min()), float(values.max())
    for ax, (axis, cut, horizontal, vertical) in zip(axes, cuts):
        shown = ax.imshow(cut, origin="lower", cmap=cmap, vmin=vmin, vmax=vmax, interpolation="nearest")
        ax.set_title(f"{axis} = middle")
        ax.set_xlabel(horizontal)
        ax.set_ylabel(vertical)
    fig.colorbar(shown, ax=axes, shrink=0.8, label=scalars)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


curvature_cmap()  # register the colour map under CURVATURE_CMAP
