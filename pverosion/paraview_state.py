"""ParaView scripts and state files that open a result with pverosion's colour coding and a time annotation."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from pverosion.io import atomic_path
from pverosion.plotting import curvature_cmap, scalar_style

__all__ = ["paraview_script", "write_paraview_state"]


def _lookup_table(name: str, values) -> tuple[list[float], bool]:
    """ParaView ``RGBPoints`` (value, r, g, b, ...) of the viewer's colour map for ``values``; whether it is labels."""
    import matplotlib

    style = scalar_style(name, values)
    cmap = style["cmap"] if not isinstance(style["cmap"], str) else matplotlib.colormaps[style["cmap"]]
    if cmap.name == curvature_cmap().name:
        stops = np.array([0.0, 0.5, 1.0])
    else:
        stops = np.linspace(0.0, 1.0, 9)
    lo, hi = style["clim"]
    points = []
    for x in stops:
        r, g, b, _ = cmap(float(x))
        points += [float(lo + x * (hi - lo)), float(r), float(g), float(b)]
    return points, "n_colors" in style


def paraview_script(series, data_path: str | os.PathLike, *, scalars: str | None = None) -> str:
    """Text of a ``pvpython`` script that opens ``data_path`` coloured like :func:`pverosion.view`.

    Parameters
    ----------
    series : pverosion.viewer.Series
        The result (its first step gives the arrays and the colour range).
    data_path : str or path-like
        The file ParaView opens (``.pvd``, ``.vtm``, ``.vtp``, ``.vti``); the
        script looks for it next to itself first, then at this absolute path.
    scalars : str, optional
        Array to colour by (default: the viewer's default choice).

    Returns
    -------
    str
    """
    from pverosion.viewer import _PREFERRED_SCALARS, _arrays, _layers

    layers = _layers(series[len(series) - 1])
    names = [n for _, layer in layers for n in _arrays(layer)]
    if scalars is None:
        scalars = next((n for n in _PREFERRED_SCALARS if n in names), names[0] if names else None)
    elif scalars not in names:
        raise ValueError(f"no array {scalars!r}; the data has {sorted(set(names))}")
    data_path = Path(data_path).resolve()
    lines = [
        f"# ParaView script: opens {data_path.name} coloured by {scalars} with pverosion's colour map.",
        "# Run: pvpython THIS.py [OUT.pvsm], or File > Load State... in ParaView.",
        "import os",
        "import sys",
        "",
        "from paraview.simple import *",
        "",
        f"path = {str(data_path)!r}",
        "if '__file__' in globals():",
        f"    near = os.path.join(os.path.dirname(os.path.abspath(__file__)), {data_path.name!r})",
        "    path = near if os.path.exists(near) else path",
        "source = OpenDataFile(path)",
        "view = GetActiveViewOrCreate('RenderView')",
        "display = Show(source, view)",
    ]
    if scalars is not None:
        layer = next(layer for _, layer in layers if scalars in _arrays(layer))
        association = "POINTS" if scalars in layer.point_data else "CELLS"
        values = layer.point_data[scalars] if association == "POINTS" else layer.cell_data[scalars]
        rgb, categorical = _lookup_table(scalars, values)
        lines += [
            f"ColorBy(display, ({association!r}, {scalars!r}))",
            f"lut = GetColorTransferFunction({scalars!r})",
            f"lut.RGBPoints = {rgb!r}",
            "lut.AutomaticRescaleRangeMode = 'Never'",
        ]
        if categorical:
            lines += ["lut.Discretize = 1", f"lut.NumberOfTableValues = {int(round(rgb[-4] - rgb[0]))}"]
        lines += ["display.SetScalarBarVisibility(view, True)"]
    lines += [
        "label = AnnotateTimeFilter(source)",
        "label.Format = 'step {time:g}' if '{' in label.Format else 'step %g'",
        "Show(label, view)",
        "view.ResetCamera()",
        "if len(sys.argv) > 1 and sys.argv[1].endswith('.pvsm'):",
        "    SaveState(sys.argv[1])  # no rendering: pvbatch may have no display",
        "else:",
        "    Render()",
        "",
    ]
    return "\n".join(lines)


def write_paraview_state(series, data_path: str | os.PathLike, out: str | os.PathLike, *,
                         scalars: str | None = None, pvpython: str | None = None) -> Path:
    """Write a ParaView Python script (``.py``) or state file (``.pvsm``) that opens ``data_path``.

    A ``.pvsm`` is made by running the script in ParaView's ``pvbatch`` (or
    ``pvpython``), which must be on ``PATH`` or given as ``pvpython``.

    Parameters
    ----------
    series : pverosion.viewer.Series
    data_path : str or path-like
        The file the state opens.
    out : str or path-like
        ``.py`` or ``.pvsm``; written atomically.
    scalars : str, optional
    pvpython : str, optional
        ParaView interpreter for ``.pvsm``.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        ``out`` is neither ``.py`` nor ``.pvsm``.
    RuntimeError
        No ParaView interpreter for a ``.pvsm``, or it failed.
    """
    out = Path(out)
    script = paraview_script(series, data_path, scalars=scalars)
    if out.suffix == ".py":
        with atomic_path(out) as tmp:
            tmp.write_text(script)
        return out
    if out.suffix != ".pvsm":
        raise ValueError(f"a ParaView state is a .py script or a .pvsm file; got {out}")
    exe = pvpython or shutil.which("pvbatch") or shutil.which("pvpython")
    if exe is None:
        raise RuntimeError("writing a .pvsm needs ParaView's pvbatch or pvpython on PATH; write a .py script instead")
    with tempfile.TemporaryDirectory() as folder, atomic_path(out) as tmp:
        runner = Path(folder) / "state.py"
        runner.write_text(script)
        done = subprocess.run([exe, str(runner), str(tmp)], capture_output=True, text=True, timeout=300,
                              stdin=subprocess.DEVNULL)
        if done.returncode != 0 or tmp.stat().st_size == 0:
            raise RuntimeError(f"{exe} could not write the state (exit {done.returncode}): {done.stderr[-2000:]}")
    return out
