"""Interactive viewers of erosion results: time slider, scalar chooser, slices, layers, statistics chart, export.

:func:`view` opens a ``.pvd`` series, a ``.vtm``/``.vtp``/``.vti`` file, a
batch output folder or a dataset in a :class:`SeriesViewer`, a
:class:`pyvista.Plotter` that scripts can add to. Steps are read from disk
only when shown (a few are cached), so long series of large meshes scrub
without loading everything.
"""

from __future__ import annotations

import os
import sys
from collections import OrderedDict
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pyvista as pv

from pverosion.io import atomic_path, check_writable, read_dataset
from pverosion.plotting import _offscreen_pyvista, scalar_style

__all__ = ["SERIES_SUFFIXES", "Series", "SeriesViewer", "record_movie", "view"]

SERIES_SUFFIXES = (".pvd", ".vtm", ".vtp", ".vti", ".vtu")
"""What :class:`Series` opens besides folders: a ``.pvd`` collection or one XML VTK file."""

_PREFERRED_SCALARS = ("mean_curvature", "erosion_depth", "material_id", "hardness", "voxel_class", "speed")
_PREFERRED_STATISTICS = ("eroded_volume", "volume", "mean_abs_curvature", "particles", "area")
_VOLUME_MODES = ("slices", "threshold", "isosurface")


class Series:
    """The steps of a result, read lazily and cached.

    Parameters
    ----------
    source : str, path-like, pyvista.DataObject or sequence of pyvista.DataObject
        A ``.pvd`` collection (its steps and times), one ``.vtm``/``.vtp``/``.vti``/``.vtu``
        file (one step), a folder (its ``.pvd`` collection if it holds exactly
        one, else its VTK files in name order as steps 0, 1, ...), a dataset
        (one step) or a list of datasets (steps 0, 1, ...).
    cache : int, default: 8
        Number of steps kept in memory.

    Attributes
    ----------
    times : numpy.ndarray, shape (N,)
        Simulated time of every step.
    path : pathlib.Path or None
        The file or folder read (the ``.pvd`` of a folder holding one), None for datasets.
    files : list of pathlib.Path
        The file of every step (empty for datasets).
    """

    def __init__(self, source, *, cache: int = 8) -> None:
        if int(cache) < 1:
            raise ValueError(f"cache must be >= 1; got {cache!r}")
        self._cache: OrderedDict[int, pv.DataObject] = OrderedDict()
        self._size = int(cache)
        self.path: Path | None = None
        self.files: list[Path] = []
        self._data: list[pv.DataObject] = []
        if isinstance(source, (str, os.PathLike)):
            self._open(Path(source))
        elif isinstance(source, pv.DataObject) or hasattr(source, "GetClassName"):
            self._data = [pv.wrap(source)]
            self.times = np.zeros(1)
        elif isinstance(source, Sequence) and source and all(isinstance(d, pv.DataObject) for d in source):
            self._data = [pv.wrap(d) for d in source]
            self.times = np.arange(len(self._data), dtype=np.float64)
        else:
            raise TypeError(f"cannot view a {type(source).__name__}: give a path, a dataset or a list of datasets")

    def _open(self, path: Path) -> None:
        if not path.exists():
            raise FileNotFoundError(f"no such file or folder: {path}")
        self.path = path
        if path.is_dir():
            collections = sorted(path.glob("*.pvd"))
            if len(collections) == 1:
                return self._open(collections[0])
            files = sorted(p for p in path.iterdir() if p.suffix in SERIES_SUFFIXES[1:])
            if not files:
                found = f"{len(collections)} .pvd collections" if collections else "no VTK files"
                raise ValueError(f"{path} holds {found}; give one file")
            self.files = files
            self.times = np.arange(len(files), dtype=np.float64)
            return None
        if path.suffix == ".pvd":
            entries = pv.get_reader(path).datasets
            if not entries:
                raise ValueError(f"{path} lists no steps")
            self.files = [path.parent / e.path for e in entries]
            self.times = np.array([e.time for e in entries], dtype=np.float64)
            return None
        if path.suffix not in SERIES_SUFFIXES:
            raise ValueError(f"cannot view {path}: expected a folder or one of {', '.join(SERIES_SUFFIXES)}")
        self.files = [path]
        self.times = np.zeros(1)
        return None

    def __len__(self) -> int:
        return len(self.times)

    def __getitem__(self, step: int) -> pv.DataObject:
        step = int(step)
        if not 0 <= step < len(self):
            raise IndexError(f"step {step} out of range 0..{len(self) - 1}")
        if self._data:
            return self._data[step]
        if step in self._cache:
            self._cache.move_to_end(step)
            return self._cache[step]
        data = read_dataset(self.files[step])
        self._cache[step] = data
        while len(self._cache) > self._size:
            self._cache.popitem(last=False)
        return data

    @property
    def cached_steps(self) -> list[int]:
        """Steps held in memory now (least recently shown first)."""
        return list(range(len(self))) if self._data else list(self._cache)

    def statistics(self) -> dict[str, np.ndarray]:
        """Per-step statistics of the run: the 1-D numeric field arrays of the last step.

        Every stage stores one value per simulated step (step 0 first), so
        the last step's arrays hold the whole history; entry ``k`` belongs
        to simulated time ``k``.
        """
        stats = {}
        for _, data in _layers(self[len(self) - 1]):
            for name in data.field_data.keys():
                values = np.asarray(data.field_data[name])
                if values.ndim == 1 and values.size > 1 and np.issubdtype(values.dtype, np.number):
                    stats.setdefault(name, values.astype(np.float64))
        return stats


def _layers(data: pv.DataObject, prefix: str = "") -> list[tuple[str, pv.DataSet]]:
    """The non-empty datasets of ``data`` with a name each (block names joined by '/')."""
    if isinstance(data, pv.MultiBlock):
        out = []
        for k in range(data.n_blocks):
            block = data[k]
            if block is None:
                continue
            name = data.get_block_name(k) or f"block{k}"
            out += _layers(block, f"{prefix}{name}/")
        return out
    return [(prefix.rstrip("/") or "data", data)]


def _arrays(data: pv.DataSet) -> list[str]:
    names = list(data.point_data.keys()) + [n for n in data.cell_data.keys() if n not in data.point_data]
    return [n for n in names if not n.startswith("vtk")]


def _run_name(series: Series, panel: int) -> str:
    return series.path.stem if series.path is not None else f"run {panel + 1}"


def _is_cloud(data: pv.DataSet) -> bool:
    return isinstance(data, pv.PolyData) and data.n_points > 0 and data.n_cells in (0, data.n_verts)


class SeriesViewer(pv.Plotter):
    """A plotter showing a :class:`Series` one step at a time.

    Widgets: a step slider with play/pause, a scalar chooser (radio buttons
    along the left), layer toggles for MultiBlocks (right), three orthogonal
    slice widgets and a slices / threshold / isosurface switch for images,
    and a chart of the run's per-step statistics with a marker at the
    current step. Every widget calls a public method, so scripts and tests
    can drive the viewer the same way: :meth:`set_step`, :meth:`set_scalars`,
    :meth:`set_layer_visible`, :meth:`set_slice`, :meth:`set_volume_mode`.

    Parameters
    ----------
    series : Series
    scalars : str, optional
        Array to colour by; default: the first of ``mean_curvature``,
        ``erosion_depth``, ``material_id``, ``hardness``, ``voxel_class``,
        ``speed`` present, else the first array.
    step : int, default: 0
        Step shown first.
    compare : tuple of two int, optional
        Show these two steps side by side with linked cameras; the slider moves the second.
    other : Series, optional
        A second run shown beside the first at the same step (its last step
        when it is shorter), with linked cameras; the slider moves both.
    statistic : str, optional
        Field-data statistic charted; default: the first ``*eroded_volume``,
        ``*volume``, ... present. ``""`` hides the chart.
    widgets : bool, default: True
        Add the interactive widgets (off for movies and screenshots).
    **kwargs
        Passed to :class:`pyvista.Plotter` (``off_screen``, ``window_size``, ...).
    """

    def __init__(self, series: Series, *, scalars: str | None = None, step: int = 0,
                 compare: tuple[int, int] | None = None, other: Series | None = None,
                 statistic: str | None = None, widgets: bool = True, **kwargs) -> None:
        steps = [int(step)] if compare is None else [int(s) for s in compare]
        if compare is not None or other is not None:
            kwargs.setdefault("shape", (1, 2))
        kwargs.setdefault("window_size", (1024, 768))
        super().__init__(**kwargs)  # first: a plotter refused before it exists fails again when collected
        problem = ("compare two steps or two runs, not both" if compare is not None and other is not None else
                   f"compare takes two steps; got {compare!r}" if len(steps) != (1 if compare is None else 2) else "")
        for s in steps:
            if not problem and not 0 <= s < len(series):
                problem = f"{'compare ' if compare else ''}step {s} out of range 0..{len(series) - 1}"
        if problem:
            self.close()
            raise ValueError(problem)
        self.series = series
        self.other = other
        self.panel_series = [series] * len(steps) if other is None else [series, other]
        self.steps = steps if other is None else [steps[0], min(steps[0], len(other) - 1)]
        first = series[self.steps[0]]
        self.scalar_names: list[str] = []
        for _, data in _layers(first):
            self.scalar_names += [n for n in _arrays(data) if n not in self.scalar_names]
        if scalars is None:
            scalars = next((n for n in _PREFERRED_SCALARS if n in self.scalar_names),
                           self.scalar_names[0] if self.scalar_names else None)
        elif scalars not in self.scalar_names:
            raise ValueError(f"no array {scalars!r}; the data has {self.scalar_names}")
        self.scalars = scalars
        self.hidden: set[str] = set()
        self.volume_mode = "slices"
        self.volume_value: float | None = None
        self.slice_origin: np.ndarray | None = None
        self.slices: dict[str, pv.DataSet] = {}
        self.playing = False
        self._scalar_buttons: dict[str, object] = {}
        self._mode_buttons: dict[str, object] = {}
        self._slider = None
        self._labels: dict[int, object] = {}
        self._timer = None
        self._chart = None
        self._marker = None
        self._callbacks: list[Callable[[int], None]] = []
        self.stats = series.statistics()
        if statistic is None:
            statistic = next((s for want in _PREFERRED_STATISTICS for s in self.stats if s.endswith(want)), "")
        elif statistic and statistic not in self.stats:
            raise ValueError(f"no statistic {statistic!r}; the series has {sorted(self.stats)}")
        self.statistic = statistic
        for panel in range(len(self.steps)):
            self._draw(panel)
        if len(self.steps) > 1:
            self.link_views()
        self.view_isometric()
        if widgets:
            self._add_widgets()

    # -- what is shown ---------------------------------------------------------------------

    @property
    def step(self) -> int:
        """The step of :attr:`series` shown (the second panel's when comparing steps)."""
        return self.steps[0] if self.other is not None else self.steps[-1]

    @property
    def layer_names(self) -> list[str]:
        """Names of the datasets of the current step (block names for MultiBlocks, else ``"data"``)."""
        return [name for name, _ in _layers(self.series[self.step])]

    def current(self, layer: str | None = None) -> pv.DataSet:
        """The dataset of ``layer`` (default: the first) at the current step."""
        layers = dict(_layers(self.series[self.step]))
        if layer is None:
            return next(iter(layers.values()))
        if layer not in layers:
            raise KeyError(f"no layer {layer!r}; the step has {sorted(layers)}")
        return layers[layer]

    def _draw(self, panel: int) -> None:
        self.subplot(0, panel)
        step = self.steps[panel]
        series = self.panel_series[panel]
        data = series[step]
        for name, layer in _layers(data):
            actor_name = f"{panel}:{name}"
            if isinstance(layer, pv.ImageData):
                self._draw_image(panel, name, layer)
                continue
            if layer.n_points == 0:
                self.remove_actor(actor_name, render=False)
                continue
            options = self._colour_options(layer)
            if _is_cloud(layer):
                options.update(render_points_as_spheres=True, point_size=5)
                if "scalars" not in options:
                    options["color"] = "#2f6fd6"
            else:
                options.setdefault("color", "#d8d0c0")
                options["smooth_shading"] = True
            actor = self.add_mesh(layer, name=actor_name, reset_camera=False, render=False, **options)
            actor.SetVisibility(name not in self.hidden)
        label = f"step {step} / {len(series) - 1}   t = {series.times[step]:g}" if len(series) > 1 else ""
        if self.other is not None:
            label = f"{_run_name(series, panel)}: {label}"
        if panel not in self._labels:
            self._labels[panel] = self.add_text("", position="upper_left", font_size=10, name=f"{panel}:label")
        self._labels[panel].SetText(2, label)  # a new text actor would render the scene once more

    def _colour_options(self, layer: pv.DataSet) -> dict:
        name = self.scalars
        if name is None or name not in _arrays(layer):
            return {}
        values = layer.point_data[name] if name in layer.point_data else layer.cell_data[name]
        style = scalar_style(name, values)
        bar = {"title": name, "position_x": 0.3, "position_y": 0.02, "width": 0.34, "height": 0.06}
        if "n_colors" in style:
            bar["n_labels"] = 0  # the annotations name each label's colour
        return {"scalars": name, "scalar_bar_args": bar, **style}

    def _draw_image(self, panel: int, name: str, image: pv.ImageData) -> None:
        if self.slice_origin is None:
            self.slice_origin = np.array(image.center)
        options = self._colour_options(image)
        base = f"{panel}:{name}"
        for k, axis in enumerate("xyz"):
            # an image one layer thick across the axis is its own slice (a plane cut in its plane is empty)
            cut = image.cast_to_structured_grid() if image.dimensions[k] == 1 else \
                image.slice(normal=axis, origin=self.slice_origin)
            self.slices[axis] = cut
            if not cut.n_points:  # a 2-D image cut across a line it does not reach
                self.remove_actor(f"{base}:slice_{axis}", render=False)
                continue
            actor = self.add_mesh(cut, name=f"{base}:slice_{axis}", reset_camera=False, render=False,
                                  show_scalar_bar=axis == "x", lighting=False, **options)  # true colours
            actor.SetVisibility(self.volume_mode == "slices" and name not in self.hidden)
        if self.volume_mode == "slices" or not options:
            self.remove_actor(f"{base}:volume", render=False)
            return
        scalars = options["scalars"]
        if self.volume_value is None:
            lo, hi = image.get_data_range(scalars)
            self.volume_value = 0.5 * (lo + hi)
        if self.volume_mode == "threshold":
            shown = image.threshold(self.volume_value, scalars=scalars)
        else:
            shown = image.contour([self.volume_value], scalars=scalars)
        if shown.n_points:
            self.add_mesh(shown, name=f"{base}:volume", reset_camera=False, render=False, **options)
        else:
            self.remove_actor(f"{base}:volume", render=False)

    def set_step(self, step: int, *, render: bool = True) -> None:
        """Show ``step`` (in the second panel when comparing steps, in both runs when comparing runs).

        Steps are read from disk when they are not cached.
        """
        step = int(round(step))
        if not 0 <= step < len(self.series):
            raise ValueError(f"step {step} out of range 0..{len(self.series) - 1}")
        if self.other is not None:
            self.steps = [step, min(step, len(self.other) - 1)]
            self._draw(0)
        else:
            self.steps[-1] = step
        self._draw(len(self.steps) - 1)
        if self._slider is not None:
            self._slider.GetRepresentation().SetValue(step)
        self._update_marker()
        for callback in self._callbacks:
            callback(step)
        if render:
            self.render()

    def on_step(self, callback: Callable[[int], None]) -> None:
        """Call ``callback(step)`` whenever the shown step changes (links other views to this one)."""
        self._callbacks.append(callback)

    def set_scalars(self, name: str) -> None:
        """Colour every layer that has the array ``name`` by it (others keep a plain colour)."""
        if name not in self.scalar_names:
            raise ValueError(f"no array {name!r}; the data has {self.scalar_names}")
        self.scalars = name
        self.volume_value = None
        self.scalar_bars.clear()  # a new map, a new bar
        for panel in range(len(self.steps)):
            self._draw(panel)
        for other, button in self._scalar_buttons.items():
            button.GetRepresentation().SetState(int(other == name))
        self.render()

    def set_layer_visible(self, layer: str, visible: bool) -> None:
        """Show or hide a MultiBlock layer (a block name of :attr:`layer_names`)."""
        if layer not in self.layer_names:
            raise KeyError(f"no layer {layer!r}; the step has {self.layer_names}")
        (self.hidden.discard if visible else self.hidden.add)(layer)
        for panel in range(len(self.steps)):
            self._draw(panel)
        self.render()

    def set_slice(self, axis: str, origin) -> pv.DataSet:
        """Move the slice normal to ``axis`` ("x", "y" or "z") through ``origin``; return the new slice."""
        if axis not in ("x", "y", "z"):
            raise ValueError(f"axis must be 'x', 'y' or 'z'; got {axis!r}")
        if self.slice_origin is None:
            raise ValueError("the data holds no image to slice")
        k = "xyz".index(axis)
        self.slice_origin = self.slice_origin.copy()
        self.slice_origin[k] = float(np.asarray(origin, dtype=np.float64).reshape(-1)[k])
        for panel in range(len(self.steps)):
            self._draw(panel)
        self.render()
        return self.slices[axis]

    def set_volume_mode(self, mode: str, value: float | None = None) -> None:
        """Show images as three ``"slices"``, a ``"threshold"`` (cells above ``value``) or an ``"isosurface"``.

        ``value`` defaults to the middle of the colouring array's range.
        """
        if mode not in _VOLUME_MODES:
            raise ValueError(f"mode must be one of {_VOLUME_MODES}; got {mode!r}")
        self.volume_mode = mode
        self.volume_value = None if value is None else float(value)
        for other, button in self._mode_buttons.items():
            button.GetRepresentation().SetState(int(other == mode))
        for panel in range(len(self.steps)):
            self._draw(panel)
        self.render()

    # -- widgets ---------------------------------------------------------------------------

    def _add_widgets(self) -> None:
        self.subplot(0, len(self.steps) - 1)
        if len(self.series) > 1:
            self._slider = self.add_slider_widget(
                self.set_step, [0, len(self.series) - 1], value=self.step, title="step", fmt="%.0f",
                pointa=(0.35, 0.92), pointb=(0.95, 0.92), interaction_event="always")
            self.add_checkbox_button_widget(self.play, value=False, position=(10.0, 10.0), size=30)
            self.add_text("play", position=(45, 15), font_size=9, name="play_label")
        for k, name in enumerate(self.scalar_names[:12]):
            y = 60.0 + 32.0 * k

            def choose(state: bool, name=name) -> None:
                self.set_scalars(name)

            self._scalar_buttons[name] = self.add_checkbox_button_widget(
                choose, value=name == self.scalars, position=(10.0, y), size=24, color_on="orange")
            self.add_text(name, position=(40, int(y) + 4), font_size=8, name=f"scalar_label:{name}")
        if len(self.layer_names) > 1:
            width = self.window_size[0]
            for k, name in enumerate(self.layer_names):
                y = 60.0 + 32.0 * k

                def toggle(state: bool, name=name) -> None:
                    self.set_layer_visible(name, state)

                self.add_checkbox_button_widget(toggle, value=True, position=(width - 40.0, y), size=24)
                self.add_text(name, position=(width - 160, int(y) + 4), font_size=8, name=f"layer_label:{name}")
        if self.slice_origin is not None:
            for axis in "xyz":
                def moved(normal, origin, axis=axis) -> None:
                    self.set_slice(axis, origin)

                self.add_plane_widget(moved, normal=axis, origin=self.slice_origin, normal_rotation=False,
                                      outline_translation=False)

            top = 60.0 + 32.0 * min(len(self.scalar_names), 12)
            for k, mode in enumerate(("threshold", "isosurface")):
                def switch(state: bool, mode=mode) -> None:
                    self.set_volume_mode(mode if state else "slices")

                y = top + 32.0 * k
                self._mode_buttons[mode] = self.add_checkbox_button_widget(
                    switch, value=False, position=(10.0, y), size=24, color_on="green")
                self.add_text(mode, position=(40, int(y) + 4), font_size=8, name=f"mode_label:{mode}")
        if self.statistic:
            self._add_chart()

    def _add_chart(self) -> None:
        values = self.stats[self.statistic]
        chart = pv.Chart2D(size=(0.32, 0.28), loc=(0.66, 0.02), x_label="step", y_label=self.statistic)
        chart.line(np.arange(len(values)), values, color="black", width=2.0)
        self._marker = chart.line([0.0, 0.0], [0.0, 0.0], color="red", width=2.0)
        chart.background_color = (1.0, 1.0, 1.0, 0.6)
        self._chart = chart
        self.add_chart(chart)
        self._update_marker()

    def _update_marker(self) -> None:
        if self._marker is None:
            return
        values = self.stats[self.statistic]
        t = float(self.series.times[self.step])
        self._marker.update([t, t], [float(values.min()), float(values.max())])

    @property
    def marker_step(self) -> float | None:
        """Simulated step at which the statistics chart's marker stands (None without a chart)."""
        return None if self._marker is None else float(self._marker.x[0])

    def play(self, state: bool = True, *, interval: int = 200) -> None:
        """Start (``state=True``) or stop stepping through the series every ``interval`` ms, looping at the end."""
        self.playing = bool(state)
        if self.playing and self.iren is not None and not self.off_screen and not self._timer:
            self.iren.add_observer("TimerEvent", lambda *_: self.advance() if self.playing else None)
            self._timer = self.iren.create_timer(interval, repeating=True)

    def advance(self) -> int:
        """Show the next step (the first after the last); return it."""
        self.set_step((self.step + 1) % len(self.series))
        return self.step

    # -- export ----------------------------------------------------------------------------

    def save_screenshot(self, path: str | os.PathLike) -> Path:
        """Write the current view to a PNG atomically."""
        path = Path(path)
        with atomic_path(path) as tmp:
            self.screenshot(str(tmp))
        return path


MOVIE_SUFFIXES = (".gif", ".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v")
"""Movie formats :func:`record_movie` writes (GIF with Pillow, the others with ffmpeg)."""

MAX_WINDOW = 16384
"""Largest window or image side in pixels (the render buffer limit of common OpenGL drivers)."""


def check_window_size(window_size) -> tuple[int, int]:
    """``window_size`` as two ints, or ``ValueError`` unless both are pixel counts in 1..:data:`MAX_WINDOW`.

    Checked before a window exists: a zero or negative size rendered an empty
    image and a huge one ended the process in ``std::bad_alloc``.
    """
    size = tuple(window_size)
    if len(size) != 2 or not all(isinstance(v, (int, np.integer)) and 1 <= v <= MAX_WINDOW for v in size):
        raise ValueError(f"window size must be two pixel counts W H in 1..{MAX_WINDOW}; got {size}")
    return int(size[0]), int(size[1])


def check_movie_options(path: str | os.PathLike, fps: float) -> None:
    """``ValueError`` for a movie file that is not a movie format, or a frame rate it cannot hold."""
    suffix = Path(path).suffix.lower()
    if suffix not in MOVIE_SUFFIXES:
        raise ValueError(f"a movie is written as {', '.join(MOVIE_SUFFIXES)}; got {os.fspath(path)!r}")
    if not (isinstance(fps, (int, float, np.integer, np.floating)) and 0 < fps < float("inf")):
        raise ValueError(f"fps must be > 0 and finite; got {fps!r}")
    if suffix == ".gif" and fps > 100:
        raise ValueError(f"a GIF's frame delays are in 1/100 s: fps must be <= 100; got {fps!r}")


def view(data, *, scalars: str | None = None, step: int = 0, compare: tuple[int, int] | None = None,
         other=None, statistic: str | None = None, widgets: bool = True, off_screen: bool | None = None,
         window_size: tuple[int, int] = (1024, 768)) -> SeriesViewer:
    """Open an erosion result in an interactive viewer.

    Parameters
    ----------
    data : str, path-like, pyvista.DataObject, sequence of pyvista.DataObject or Series
        A ``.pvd`` time series, a ``.vtm``/``.vtp``/``.vti`` file, a batch
        output folder, a dataset or a list of datasets (see :class:`Series`).
    other : same kinds as ``data``, optional
        A second run to show beside the first (see :class:`SeriesViewer`).
    scalars, step, compare, statistic, widgets
        See :class:`SeriesViewer`.
    off_screen : bool, optional
        Render without a window (default: PyVista's setting, e.g. ``PYVISTA_OFF_SCREEN``).
    window_size : tuple of int, default: (1024, 768)

    Returns
    -------
    SeriesViewer
        The :class:`pyvista.Plotter`; call ``.show()`` to interact, or add to it first.

    Examples
    --------
    >>> import pverosion
    >>> from pverosion.examples import load_cube
    >>> steps = [pverosion.weather(load_cube(resolution=6), iterations=n) for n in (0, 5, 10)]
    >>> plotter = pverosion.view(steps, off_screen=True)
    >>> plotter.set_step(2)
    >>> plotter.step, plotter.scalars
    (2, 'mean_curvature')
    >>> plotter.close()
    """
    window_size = check_window_size(window_size)
    if off_screen or (off_screen is None and pv.OFF_SCREEN):
        _offscreen_pyvista()
        off_screen = True
    series = data if isinstance(data, Series) else Series(data)
    if other is not None and not isinstance(other, Series):
        other = Series(other)
    return SeriesViewer(series, scalars=scalars, step=step, compare=compare, other=other, statistic=statistic,
                        widgets=widgets, off_screen=off_screen, window_size=list(window_size))


def record_movie(viewer: SeriesViewer, path: str | os.PathLike, *, fps: float = 10.0, orbit: bool = False,
                 steps: Sequence[int] | None = None) -> Path:
    """Render every step of the viewer's series into a movie, one frame per step.

    Parameters
    ----------
    viewer : SeriesViewer
    path : str or path-like
        ``.gif`` (Pillow) or ``.mp4`` and other ffmpeg formats (needs ``imageio-ffmpeg``:
        ``pip install "pverosion[view]"``); written atomically.
    fps : float, default: 10
    orbit : bool, default: False
        Turn the camera once around the scene's vertical axis over the movie.
    steps : sequence of int, optional
        Steps to render (default: all).

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    check_movie_options(path, fps)
    steps = list(range(len(viewer.series))) if steps is None else [int(s) for s in steps]
    if path.suffix.lower() != ".gif":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError as exc:
            raise RuntimeError(f"writing {path.suffix} movies needs imageio-ffmpeg: "
                               "pip install 'pverosion[view]' (or write a .gif)") from exc
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".gif":
            viewer.open_gif(str(tmp), fps=fps)
        else:
            viewer.open_movie(str(tmp), framerate=fps, macro_block_size=1)
        try:
            for k, step in enumerate(steps):
                viewer.set_step(step, render=False)
                if orbit and k:
                    viewer.camera.azimuth = viewer.camera.azimuth + 360.0 / len(steps)
                viewer.write_frame()
        finally:
            viewer.mwriter.close()
            viewer.mwriter = None
            viewer._gif_filename = None  # nothing is left open (PyVista's gallery scraper would move the file)
    return path



# -- command line ----------------------------------------------------------------------------


def _steps(text: str) -> tuple[int, int]:
    import argparse

    parts = text.split(",")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"expected two steps I,J; got {text!r}")
    return int(parts[0]), int(parts[1])


def _gravity(text: str) -> tuple[float, ...]:
    import argparse

    from pverosion.filters.materials import parse_numbers

    try:
        return tuple(parse_numbers(text, "gravity", count=3))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_view_command(sub) -> None:
    """Register ``pverosion view PATH`` on the command line's subparsers ``sub``."""
    from pverosion.live import STAGES

    cmd = sub.add_parser("view", help="look at a result: time slider, slices, statistics; export movies",
                         description="Open a .pvd series, .vtm/.vtp/.vti file or batch output folder in an "
                         "interactive viewer, or export it (--movie, --screenshot, --paraview-state) without a "
                         "window. With --live, PATH is a surface to erode interactively.")
    cmd.add_argument("path", type=Path, help="series (.pvd), file (.vtm, .vtp, .vti, .vtu) or folder")
    cmd.add_argument("--scalars", help="array to colour by (default: mean_curvature, erosion_depth, ... present)")
    cmd.add_argument("--step", type=int, default=None, help="step shown first / in a screenshot (default: 0, "
                     "the last for --screenshot)")
    cmd.add_argument("--compare", type=_steps, metavar="I,J", help="two steps side by side with linked cameras")
    cmd.add_argument("--compare-run", type=Path, metavar="OTHER", help="a second run beside the first, same steps")
    cmd.add_argument("--statistic", help="field-data statistic to chart ('' hides the chart)")
    cmd.add_argument("--movie", type=Path, metavar="OUT.mp4|OUT.gif", help="render every step into a movie")
    cmd.add_argument("--fps", type=float, default=10.0, help="movie frames per second (default: 10)")
    cmd.add_argument("--orbit", action="store_true", help="turn the camera once around the model over the movie")
    cmd.add_argument("--screenshot", type=Path, metavar="OUT.png", help="render one step to a PNG")
    cmd.add_argument("--paraview-state", type=Path, metavar="OUT.py|OUT.pvsm",
                     help="write a ParaView script or state that opens PATH with the same colour coding")
    cmd.add_argument("--live", choices=STAGES, help="erode the surface PATH interactively (right-click to place water "
                     "or to brush weathering)")
    cmd.add_argument("--gravity", type=_gravity, default=(0.0, 0.0, -9.81), metavar="GX,GY,GZ",
                     help="--live hydraulic: gravity (default: 0,0,-9.81; 0,-9.81,0 for a model whose up is +y)")
    cmd.add_argument("--web", type=int, metavar="PORT", help="serve the viewer as a web page on 127.0.0.1:PORT "
                     "(needs pverosion[view])")
    cmd.add_argument("--window-size", type=int, nargs=2, default=(1024, 768), metavar=("W", "H"))


def _check_view_options(args) -> None:
    """``ValueError`` for options that the chosen mode would leave unused, and for a window without a display."""
    exports = [flag for flag, value in (("--movie", args.movie), ("--screenshot", args.screenshot),
                                        ("--paraview-state", args.paraview_state)) if value is not None]
    if args.live:
        unused = exports + [flag for flag, value in (
            ("--web", args.web), ("--scalars", args.scalars), ("--step", args.step), ("--compare", args.compare),
            ("--compare-run", args.compare_run), ("--statistic", args.statistic)) if value is not None]
        if unused:
            raise ValueError(f"--live opens an interactive window on the surface; {', '.join(unused)} "
                             f"{'does' if len(unused) == 1 else 'do'} not apply to it")
    elif args.web is not None and exports:
        raise ValueError(f"--web serves the viewer until stopped and is not combined with {', '.join(exports)}: "
                         "run the exports first, then --web")
    window = args.live or (args.web is None and not exports)
    if window and sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                            or os.environ.get("WAYLAND_DISPLAY")):
        raise ValueError("no display to open a window on (DISPLAY is not set): export with --screenshot, --movie "
                         "or --paraview-state, serve the viewer with --web PORT, or run under xvfb-run")


def run_view(args) -> int:
    """Run ``pverosion view`` from parsed arguments; return the exit status."""
    _check_view_options(args)
    if args.live:
        from pverosion.io import read_mesh
        from pverosion.live import interactive

        session = interactive(read_mesh(args.path), stage=args.live, window_size=check_window_size(args.window_size),
                              **({"gravity": args.gravity} if args.live == "hydraulic" else {}))
        session.start()
        session.plotter.show()
        session.stop()
        return 0
    check_window_size(args.window_size)
    if args.movie is not None:
        check_movie_options(args.movie, args.fps)
    if args.web is not None and not 0 <= args.web <= 65535:
        raise ValueError(f"--web: a port is a number in 0..65535; got {args.web}")
    for out, flag in ((args.movie, "--movie"), (args.screenshot, "--screenshot"), (args.paraview_state,
                                                                                  "--paraview-state")):
        if out is not None:
            check_writable(out, flag)  # before anything is read or rendered
    series = Series(args.path)
    exporting = args.movie or args.screenshot or args.paraview_state
    if args.paraview_state:
        from pverosion.paraview_state import write_paraview_state

        data = series.path if series.path.is_file() else series.files[-1]
        print(f"paraview state -> {write_paraview_state(series, data, args.paraview_state, scalars=args.scalars)}")
    options = {"scalars": args.scalars, "compare": args.compare, "other": args.compare_run,
               "statistic": args.statistic, "window_size": tuple(args.window_size)}
    for out in (args.movie, args.screenshot):
        if out is None:
            continue
        step = args.step if args.step is not None else (0 if out is args.movie else len(series) - 1)
        viewer = view(series, step=step, widgets=False, off_screen=True, **options)
        try:
            if out is args.movie:
                record_movie(viewer, out, fps=args.fps, orbit=args.orbit)
                print(f"movie: {len(series)} frames -> {out}")
            else:
                viewer.save_screenshot(out)
                print(f"screenshot -> {out}")
        finally:
            viewer.close()
    if args.web is not None and not exporting:
        from pverosion.web import serve

        serve(view(series, step=args.step or 0, widgets=False, off_screen=True, **options), port=args.web)
    elif not exporting:
        view(series, step=args.step or 0, **options).show()
    return 0
