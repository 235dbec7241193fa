"""The series viewer driven off-screen: slider, scalar chooser, slices, layers, chart, comparison, export, CLI."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
from conftest import run_pvbatch

from pverosion.examples import load_cube
from pverosion.filters.weathering import Weathering
from pverosion.io import TimeSeriesWriter
from pverosion.viewer import Series, record_movie, view

ROOT = Path(__file__).resolve().parents[1]
STEPS = 30


@pytest.fixture(scope="module")
def series_path(tmp_path_factory) -> Path:
    """A weathering run of a cube saved at every step 0..29 (30 steps)."""
    path = tmp_path_factory.mktemp("series") / "cube.pvd"
    with TimeSeriesWriter(path) as series:
        Weathering(iterations=STEPS - 1).step_through(load_cube(resolution=6), list(range(STEPS)),
                                                     on_output=lambda t, r: series.write(r, time=t))
    return path


def _image(viewer) -> np.ndarray:
    viewer.render()
    return np.asarray(viewer.screenshot(return_img=True), dtype=np.int16)


def _widgets(viewer):
    return getattr(viewer, "widgets", viewer)  # PyVista >= 0.49 groups them; older versions keep them on the plotter


def _shown(viewer, name: str = "data", panel: int = 0) -> pv.DataSet:
    """What the panel's actor ``name`` draws: its mapper's input, brought up to date as a render would."""
    mapper = viewer.renderers[panel].actors[f"{panel}:{name}"].mapper
    if mapper.GetInputAlgorithm() is not None:
        mapper.GetInputAlgorithm().Update()
    return pv.wrap(mapper.GetInput())


def test_series_reads_steps_lazily(series_path):
    series = Series(series_path, cache=3)
    assert len(series) == STEPS
    np.testing.assert_array_equal(series.times, np.arange(STEPS))
    assert series.cached_steps == []
    for step in (4, 7, 9, 12):
        series[step]
    assert series.cached_steps == [7, 9, 12]
    assert Series(series_path.parent).path == series_path  # a folder holding one collection
    with pytest.raises(IndexError):
        series[STEPS]
    notes = series_path.parent / "notes.txt"
    notes.write_text("")
    with pytest.raises(ValueError, match="cannot view"):
        Series(notes)
    with pytest.raises(FileNotFoundError):
        Series(series_path.parent / "missing.pvd")


def test_slider_moves_through_steps_and_matches_files(series_path):
    viewer = view(series_path, off_screen=True, window_size=(400, 300))
    try:
        slider = _widgets(viewer).slider_widgets[0]
        images = {}
        for step in (3, 17, 29):
            slider.GetRepresentation().SetValue(step)
            slider.InvokeEvent("InteractionEvent")  # what dragging the slider does
            assert viewer.step == step
            on_disk = pv.read(viewer.series.files[step])
            shown = _shown(viewer)
            np.testing.assert_array_equal(shown.points, on_disk.points)
            np.testing.assert_array_equal(shown["mean_curvature"], on_disk["mean_curvature"])
            assert viewer.marker_step == step  # the statistics chart follows
            images[step] = _image(viewer)
        assert np.abs(images[3] - images[29]).max() > 50  # the render changes from step to step
        assert len(viewer.series.cached_steps) <= 8
        stats = pv.read(viewer.series.files[-1]).field_data["weathering_eroded_volume"]
        assert viewer.statistic == "weathering_eroded_volume"
        np.testing.assert_array_equal(next(iter(viewer._chart.plots("line"))).y, stats)  # the run's whole history
        # the step's render matches a viewer opened on that step's file alone, without widgets
        alone = view(pv.read(viewer.series.files[17]), off_screen=True, window_size=(400, 300), widgets=False)
        other = view(series_path, step=17, off_screen=True, window_size=(400, 300), widgets=False)
        try:
            below_label = slice(40, None)  # the step labels differ ("step 0 / 0" and "step 17 / 29")
            assert np.abs(_image(alone)[below_label] - _image(other)[below_label]).max() <= 2
        finally:
            alone.close()
            other.close()
    finally:
        viewer.close()


def test_curvature_uses_the_colour_map_with_symmetric_limits(series_path):
    viewer = view(series_path, step=5, off_screen=True, window_size=(300, 300))
    try:
        mapper = viewer.actors["0:data"].mapper
        lo, hi = mapper.scalar_range
        assert lo == -hi and hi > 0
        h = pv.read(viewer.series.files[5])["mean_curvature"]
        assert hi == pytest.approx(np.percentile(np.abs(h), 98.0))
        lut = mapper.lookup_table
        for value, colour in ((lo, (0.0, 0.0, 1.0)), (0.0, (0.0, 0.8, 0.0)), (hi, (1.0, 0.0, 0.0))):
            np.testing.assert_allclose(np.asarray(lut.map_value(value)[:3]), colour, atol=0.02)
    finally:
        viewer.close()


def test_scalar_chooser_button_recolours(series_path):
    viewer = view(series_path, step=10, off_screen=True, window_size=(300, 300))
    try:
        assert viewer.scalar_names[:1] == ["mean_curvature"]
        button = viewer._scalar_buttons["erosion_depth"]
        button.GetRepresentation().SetState(1)
        button.InvokeEvent("StateChangedEvent")  # a click on the button
        assert viewer.scalars == "erosion_depth"
        assert viewer.actors["0:data"].mapper.array_name == "erosion_depth"
        assert viewer._scalar_buttons["mean_curvature"].GetRepresentation().GetState() == 0
        depth = pv.read(viewer.series.files[10])["erosion_depth"]
        assert viewer.actors["0:data"].mapper.scalar_range == pytest.approx((depth.min(), depth.max()))
        with pytest.raises(ValueError, match="no array"):
            viewer.set_scalars("nope")
    finally:
        viewer.close()


def _labelled_image() -> pv.ImageData:
    """10 x 8 x 6 points; value i + 10 j + 100 k at point (i, j, k), material_id = k // 2."""
    image = pv.ImageData(dimensions=(10, 8, 6), spacing=(0.5, 0.25, 1.0), origin=(1.0, -2.0, 0.0))
    i, j, k = np.meshgrid(np.arange(10), np.arange(8), np.arange(6), indexing="ij")
    image.point_data["value"] = (i + 10 * j + 100 * k).ravel(order="F").astype(np.float64)
    image.point_data["material_id"] = (k // 2).ravel(order="F").astype(np.int32)
    return image


def test_slice_widgets_give_the_slice_values():
    image = _labelled_image()
    viewer = view(image, scalars="value", off_screen=True, window_size=(300, 300))
    try:
        widgets = dict(zip("xyz", _widgets(viewer).plane_widgets))
        for axis, index in (("x", 3), ("y", 5), ("z", 4)):
            k = "xyz".index(axis)
            origin = list(image.center)
            origin[k] = image.origin[k] + index * image.spacing[k]
            widgets[axis].SetOrigin(origin)
            widgets[axis].InvokeEvent("EndInteractionEvent")  # the user let go of the plane
            cut = viewer.slices[axis]
            coords = (np.asarray(cut.points) - image.origin) / image.spacing
            assert np.allclose(coords[:, k], index)
            expected = coords[:, 0] + 10 * coords[:, 1] + 100 * coords[:, 2]
            np.testing.assert_allclose(cut["value"], expected, atol=1e-9)
            assert cut.n_points == np.prod([n for m, n in enumerate(image.dimensions) if m != k])
        button = viewer._mode_buttons["threshold"]
        button.GetRepresentation().SetState(1)
        button.InvokeEvent("StateChangedEvent")  # a click on the threshold button
        assert viewer.volume_mode == "threshold"
        middle = viewer.volume_value
        assert middle == pytest.approx(0.5 * (image["value"].min() + image["value"].max()))
        viewer.set_volume_mode("threshold", 250.0)
        shown = viewer.actors["0:data:volume"].mapper.dataset
        assert shown.n_cells > 0 and shown["value"].min() >= 250.0 - 111  # whole cells with a point above
        viewer.set_volume_mode("isosurface", 250.0)
        iso = viewer.actors["0:data:volume"].mapper.dataset
        np.testing.assert_allclose(iso["value"], 250.0, atol=1e-9)
        assert not viewer.actors["0:data:slice_x"].GetVisibility()
        assert viewer._mode_buttons["isosurface"].GetRepresentation().GetState() == 1
        assert viewer._mode_buttons["threshold"].GetRepresentation().GetState() == 0
        with pytest.raises(ValueError, match="mode"):
            viewer.set_volume_mode("volume")
    finally:
        viewer.close()


def test_material_id_is_categorical():
    viewer = view(_labelled_image(), scalars="material_id", off_screen=True, window_size=(300, 300))
    try:
        mapper = viewer.actors["0:data:slice_x"].mapper
        assert mapper.scalar_range == pytest.approx((-0.5, 2.5))
        assert mapper.lookup_table.n_values == 3  # one colour per material
    finally:
        viewer.close()


def test_multiblock_layers_toggle():
    mesh = pv.Sphere()
    mesh["mean_curvature"] = np.ones(mesh.n_points)
    blocks = pv.MultiBlock({"mesh": mesh, "particles": pv.PolyData(np.random.default_rng(0).random((50, 3)))})
    viewer = view(blocks, off_screen=True, window_size=(300, 300))
    try:
        assert viewer.layer_names == ["mesh", "particles"]
        particles = viewer.actors["0:particles"]
        assert particles.GetVisibility()
        before = _image(viewer)
        viewer.set_layer_visible("particles", False)
        assert not viewer.actors["0:particles"].GetVisibility() and viewer.actors["0:mesh"].GetVisibility()
        assert np.abs(_image(viewer) - before).max() > 50
        with pytest.raises(KeyError):
            viewer.set_layer_visible("water", True)
    finally:
        viewer.close()


def test_compare_two_steps_with_linked_cameras(series_path):
    viewer = view(series_path, compare=(0, 29), off_screen=True, window_size=(600, 300))
    try:
        first, second = _shown(viewer, panel=0), _shown(viewer, panel=1)
        np.testing.assert_array_equal(first.points, pv.read(viewer.series.files[0]).points)
        np.testing.assert_array_equal(second.points, pv.read(viewer.series.files[29]).points)
        assert viewer.renderers[0].camera is viewer.renderers[1].camera
        with pytest.raises(ValueError, match="compare"):
            view(series_path, compare=(0, STEPS), off_screen=True)
    finally:
        viewer.close()


def _frames(path: Path) -> list[np.ndarray]:
    iio = pytest.importorskip("imageio.v3")
    return [frame.astype(int) for frame in iio.imiter(path)]


def test_cli_movie_has_one_frame_per_step(series_path, tmp_path):
    pytest.importorskip("imageio_ffmpeg", reason="mp4 needs the view extra (imageio-ffmpeg)")
    out = tmp_path / "cube.mp4"
    done = _cli(series_path, "--movie", out, "--fps", 12, "--window-size", 240, 160)
    assert done.returncode == 0, done.stderr
    frames = _frames(out)
    assert len(frames) == STEPS
    assert frames[0].shape[:2] == (160, 240)
    assert np.abs(frames[0] - frames[-1]).max() > 50


def test_gif_orbits_the_camera(series_path, tmp_path):
    viewer = view(series_path, off_screen=True, widgets=False, window_size=(240, 160))
    try:
        azimuth = viewer.camera.azimuth
        out = record_movie(viewer, tmp_path / "cube.gif", fps=10, orbit=True, steps=[0] * 4)  # one step, turning
        assert viewer.camera.azimuth == pytest.approx(azimuth + 3 * 90.0)
    finally:
        viewer.close()
    frames = _frames(out)
    assert len(frames) == 4
    assert np.abs(frames[0] - frames[1]).max() > 50  # the view turned, the data did not change


def _cli(*args, cwd=None):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYVISTA_OFF_SCREEN": "true"}
    return subprocess.run([sys.executable, "-m", "pverosion", "view", *map(str, args)], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=600)


@pytest.mark.parametrize("damage", ["truncated", "empty"])
def test_cli_refuses_to_picture_a_damaged_or_empty_file(tmp_path, damage):
    """A cut .vtp reads as an empty dataset with only VTK's printout: the view says so and writes no picture."""
    path = tmp_path / "step.vtp"
    if damage == "truncated":
        pv.Sphere().save(path)
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    else:
        pv.PolyData().save(path)
    done = _cli(path, "--screenshot", tmp_path / "shot.png")
    assert done.returncode == 2, done.stderr
    assert "step.vtp holds no points" in done.stderr.strip().splitlines()[-1]
    assert not (tmp_path / "shot.png").exists()


def test_cli_checks_the_picture_path_before_reading(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    done = _cli(tmp_path / "missing.vtp", "--screenshot", tmp_path / "file" / "shot.png")
    assert done.returncode == 2, done.stderr
    assert "--screenshot" in done.stderr and "is not a folder" in done.stderr


@pytest.mark.parametrize("options, message", [
    (["--screenshot", "shot.png", "--window-size", "0", "0"], "window size must be two pixel counts"),
    (["--screenshot", "shot.png", "--window-size", "100000", "100000"], "window size must be two pixel counts"),
    (["--movie", "shot.txt"], "a movie is written as .gif"),
    (["--movie", "shot.gif", "--fps", "1e9"], "fps must be <= 100"),
    (["--movie", "shot.gif", "--fps", "inf"], "fps must be > 0 and finite"),
    (["--web", "99999"], "a port is a number in 0..65535"),
    (["--live", "weather", "--screenshot", "shot.png"], "--screenshot does not apply to it"),
    (["--live", "weather", "--movie", "shot.gif", "--scalars", "k1"], "--movie, --scalars do not apply to it"),
    (["--web", "8766", "--screenshot", "shot.png"], "--web serves the viewer until stopped"),
], ids=["window-zero", "window-huge", "movie-txt", "gif-fps-huge", "fps-inf", "port", "live-screenshot",
        "live-movie", "web-and-screenshot"])
def test_cli_refuses_bad_picture_options_before_rendering(series_path, tmp_path, monkeypatch, capsys, options,
                                                           message):
    """An empty image, a std::bad_alloc abort, a TIFF-writer error or an OverflowError became named refusals."""
    from pverosion.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["view", str(series_path), *options]) == 2
    assert message in capsys.readouterr().err
    assert not any(tmp_path.glob("shot*"))
    with pytest.raises(ValueError, match="window size"):
        view(series_path, off_screen=True, window_size=(-10, 100))


def test_a_refused_comparison_leaves_no_half_made_plotter(series_path, tmp_path, monkeypatch, capsys):
    """Comparing two steps and two runs at once was refused before the plotter existed, and collecting it printed
    an ignored AttributeError traceback."""
    import gc
    import sys

    from pverosion.cli import main

    unraisable = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    assert main(["view", str(series_path), "--compare", "0,1", "--compare-run", str(series_path),
                 "--screenshot", str(tmp_path / "c.png")]) == 2
    gc.collect()
    assert "compare two steps or two runs, not both" in capsys.readouterr().err and unraisable == []


def test_cli_web_on_a_taken_port_says_so_before_serving(series_path, capsys):
    """The command printed "serving http://..." and then failed on the bind."""
    import socket

    from pverosion.cli import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["view", str(series_path), "--web", str(port)]) == 2
    captured = capsys.readouterr()
    assert f"port {port} on 127.0.0.1 is taken" in captured.err and "serving" not in captured.out


def test_cli_window_without_a_display_is_refused(series_path, monkeypatch, capsys):
    """Without a display VTK printed X server errors and the command exited 0 having shown nothing."""
    from pverosion.cli import main

    monkeypatch.setattr("sys.platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(series_path)]) == 2
    assert "no display to open a window on" in capsys.readouterr().err


def test_cli_screenshot_and_paraview_script(series_path, tmp_path):
    done = _cli(series_path, "--screenshot", tmp_path / "last.png", "--paraview-state", tmp_path / "open.py",
                "--window-size", 320, 240)
    assert done.returncode == 0, done.stderr
    image = pv.read(tmp_path / "last.png")
    assert image.dimensions[:2] == (320, 240)
    script = (tmp_path / "open.py").read_text()
    assert str(series_path.resolve()) in script and "'mean_curvature'" in script
    bad = _cli(series_path, "--compare", "1,99", "--screenshot", tmp_path / "x.png")
    assert bad.returncode == 2 and "out of range" in bad.stderr


_LOAD_STATE = """
import sys

import numpy as np
from paraview.simple import GetActiveView, GetColorTransferFunction, GetSources, LoadState, Render, SaveScreenshot
from vtkmodules.numpy_interface import dataset_adapter as dsa
from vtkmodules.vtkIOImage import vtkPNGReader

LoadState(sys.argv[1])
readers = [s for s in GetSources().values() if s.GetXMLName() == "PVDReader"]
print("FILE", readers[0].FileName)
print("STEPS", len(readers[0].TimestepValues))
print("RGB", " ".join(map(repr, GetColorTransferFunction("mean_curvature").RGBPoints)))
Render()
SaveScreenshot(sys.argv[2], GetActiveView(), ImageResolution=[320, 240])
png = vtkPNGReader()
png.SetFileName(sys.argv[2])
png.Update()
print("SPREAD", np.asarray(dsa.WrapDataObject(png.GetOutput()).PointData[0]).std(axis=0).max())
"""


@pytest.mark.skipif(shutil.which("pvbatch") is None, reason="ParaView's pvbatch is not installed")
def test_paraview_state_opens_in_paraview(series_path, tmp_path):
    from pverosion.paraview_state import write_paraview_state

    state = write_paraview_state(Series(series_path), series_path, tmp_path / "cube.pvsm")
    loader = tmp_path / "load.py"
    loader.write_text(_LOAD_STATE)
    done = run_pvbatch([shutil.which("pvbatch"), str(loader), str(state), str(tmp_path / "shot.png")],
                       screen="640x480x24", timeout=600, cwd=tmp_path)
    assert done.returncode == 0, (done.stdout + done.stderr)[-4000:]
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines() if line.split(" ", 1)[0].isupper())
    assert Path(lines["FILE"]) == series_path.resolve()  # ParaView reopens the series with all its steps
    assert int(lines["STEPS"]) == STEPS
    h = pv.read(Series(series_path).files[-1])["mean_curvature"]
    limit = np.percentile(np.abs(h), 98.0)
    rgb = np.array(lines["RGB"].split(), dtype=float).reshape(-1, 4)
    # the viewer's colour map: blue, green, red at the symmetric limits of the last step's curvature
    np.testing.assert_allclose(rgb[:, 0], [-limit, 0.0, limit], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(rgb[:, 1:], [[0, 0, 1], [0, 0.8, 0], [1, 0, 0]], atol=0.01)
    assert float(lines["SPREAD"]) > 10  # the state renders the mesh, not a blank view


def test_readme_screenshot(series_path, tmp_path):
    """The README's picture: the viewer on a weathering run, midway, with its widgets and chart."""
    viewer = view(series_path, step=15, off_screen=True, window_size=(640, 420))
    try:
        out = viewer.save_screenshot(tmp_path / "viewer.png")
    finally:
        viewer.close()
    pixels = np.asarray(pv.read(out).active_scalars)
    assert len(np.unique(pixels, axis=0)) > 100  # a picture, not a blank window
    if os.environ.get("PVEROSION_WRITE_DOCS"):
        target = ROOT / "docs" / "_static" / "viewer.png"
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(out, target)
    assert out.stat().st_size < 200_000


def test_compare_two_runs_moves_both(series_path):
    other = [pv.read(f).translate((0.5, 0.0, 0.0)) for f in Series(series_path).files[:10]]  # a shorter run
    viewer = view(series_path, other=other, off_screen=True, window_size=(600, 300))
    try:
        viewer.set_step(6)
        np.testing.assert_array_equal(_shown(viewer, panel=0).points, pv.read(viewer.series.files[6]).points)
        np.testing.assert_array_equal(_shown(viewer, panel=1).points, other[6].points)
        viewer.set_step(20)  # past the other run's end: it stays at its last step
        assert viewer.steps == [20, 9]
        np.testing.assert_array_equal(_shown(viewer, panel=1).points, other[9].points)
        assert viewer.renderers[0].camera is viewer.renderers[1].camera
    finally:
        viewer.close()


def test_play_advances_and_wraps(series_path):
    viewer = view(series_path, step=STEPS - 2, off_screen=True, window_size=(200, 200))
    try:
        assert viewer.advance() == STEPS - 1
        assert viewer.advance() == 0
    finally:
        viewer.close()


@pytest.mark.parametrize("dims", [(6, 5, 1), (1, 6, 5), (1, 1, 1)], ids=["dem", "x-slab", "one-voxel"])
def test_an_image_one_layer_thick_is_its_own_slice(dims):
    """A DEM read as a (nx, ny, 1) image failed to show: the slice in its own plane was empty."""
    image = pv.ImageData(dimensions=dims)
    image["elevation"] = np.arange(image.n_points, dtype=float)
    plotter = view(image, off_screen=True, window_size=(120, 100))
    try:
        flat = "xyz"[dims.index(1)]
        assert plotter.slices[flat].n_points == image.n_points
        assert np.array_equal(plotter.slices[flat]["elevation"], image["elevation"])
        assert plotter.screenshot(return_img=True).shape[:2] == (100, 120)
    finally:
        plotter.close()
