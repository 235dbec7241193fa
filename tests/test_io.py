import re

import numpy as np
import pytest
import pyvista as pv

from pverosion.io import TimeSeriesWriter, read_mesh, write_atomic


def test_time_series_round_trips_through_pyvista_reader(tmp_path):
    path = tmp_path / "run.pvd"
    with TimeSeriesWriter(path) as series:
        for step in range(3):
            series.write(pv.Sphere(radius=1.0 + step), time=0.5 * step)
    reader = pv.get_reader(path)
    assert reader.time_values == [0.0, 0.5, 1.0]
    reader.set_active_time_value(1.0)
    mesh = reader.read()[0]
    assert np.max(np.linalg.norm(mesh.points, axis=1)) == pytest.approx(3.0, rel=1e-6)
    assert not list(tmp_path.rglob(".*"))  # no temporary files left behind


def test_time_series_index_is_valid_after_each_step(tmp_path):
    series = TimeSeriesWriter(tmp_path / "steps.pvd")
    series.write(pv.Sphere(), time=0)
    assert pv.get_reader(tmp_path / "steps.pvd").number_time_points == 1
    series.write(pv.ImageData(dimensions=(2, 2, 2)), time=1)
    assert pv.get_reader(tmp_path / "steps.pvd").number_time_points == 2
    with pytest.raises(ValueError, match="increase"):
        series.write(pv.Sphere(), time=1)
    with pytest.raises(ValueError, match=".pvd"):
        TimeSeriesWriter(tmp_path / "x.vtp")


def test_atomic_write_keeps_old_file_on_failure(tmp_path):
    target = tmp_path / "mesh.vtp"
    write_atomic(pv.Sphere(), target)
    before = target.read_bytes()
    with pytest.raises(Exception):
        write_atomic(object(), target)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["mesh.vtp"]


@pytest.mark.parametrize("ext", [".stl", ".ply", ".obj"])
def test_a_surface_only_format_warns_about_the_arrays_it_drops_on_the_command_line_too(tmp_path, capsys, ext):
    """STL, PLY and OBJ keep the surface, not the curvature arrays: the result is written (exit 0) and the
    warning names the arrays lost and .vtp; a .vtp result keeps them all without a word."""
    import warnings

    from pverosion.cli import main

    sphere = pv.Icosphere(nsub=2)
    sphere.save(tmp_path / "sphere.vtp")
    assert main(["curvature", str(tmp_path / "sphere.vtp"), "-o", str(tmp_path / f"out{ext}")]) == 0
    err = capsys.readouterr().err
    assert re.search(rf"out{re.escape(ext)}: a {re.escape(ext)} file keeps the surface only; its \d+ arrays "
                     r"\(mean_curvature, .* and \d+ more\) are not written: write \.vtp", err), err
    assert pv.read(tmp_path / f"out{ext}").n_points == sphere.n_points
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["curvature", str(tmp_path / "sphere.vtp"), "-o", str(tmp_path / "out.vtp")]) == 0
        write_atomic(pv.Icosphere(nsub=1), tmp_path / f"plain{ext}")  # no arrays: nothing lost
    assert "mean_curvature" in pv.read(tmp_path / "out.vtp").point_data


def test_read_mesh_formats_and_errors(tmp_path):
    sphere = pv.Sphere()
    for ext in (".ply", ".stl", ".obj", ".vtp", ".vtk"):
        sphere.save(tmp_path / f"s{ext}")
        assert read_mesh(tmp_path / f"s{ext}").n_cells == sphere.n_cells
    sphere.cast_to_unstructured_grid().save(tmp_path / "grid.vtu")
    assert isinstance(read_mesh(tmp_path / "grid.vtu"), pv.PolyData)
    with pytest.raises(FileNotFoundError):
        read_mesh(tmp_path / "missing.ply")
    with pytest.raises(IsADirectoryError, match="is a folder, not a file"):
        read_mesh(tmp_path)


def test_read_mesh_takes_the_one_surface_block_of_a_result(tmp_path):
    """A voxel result's grid and isosurface were merged into one 'mesh' of quads and triangles."""
    state = pv.ImageData(dimensions=(3, 3, 3))
    surface = pv.Sphere()
    pv.MultiBlock({"state": state, "surface": surface}).save(tmp_path / "voxel.vtm")
    mesh = read_mesh(tmp_path / "voxel.vtm")
    assert mesh.n_points == surface.n_points and mesh.n_cells == surface.n_cells
    particles = pv.PolyData(np.random.default_rng(0).random((5, 3)))  # vertices only: not a surface
    pv.MultiBlock({"mesh": surface, "particles": particles}).save(tmp_path / "fluid.vtm")
    assert read_mesh(tmp_path / "fluid.vtm").n_points == surface.n_points
    pv.MultiBlock({"a": surface, "b": pv.Cube().triangulate()}).save(tmp_path / "two.vtm")
    with pytest.raises(ValueError, match=r"2 blocks: a \(PolyData\), b \(PolyData\); more than one holds a surface"):
        read_mesh(tmp_path / "two.vtm")


@pytest.mark.parametrize(("attribute", "value"), [("Origin", "nan 0 0"), ("Spacing", "1 inf 1"),
                                                   ("Direction", "1 0 0 0 nan 0 0 0 1"), ("Origin", "0 zero 0")])
def test_an_image_with_a_grid_that_is_not_finite_is_refused(tmp_path, attribute, value):
    from pverosion.io import read_image

    grid = pv.ImageData(dimensions=(4, 3, 2), origin=(5.0, 6.0, 7.0), spacing=(0.5, 0.25, 2.0))
    grid["density"] = np.arange(grid.n_points, dtype=float)
    good = tmp_path / "good.vti"
    grid.save(good)
    read = read_image(good)
    assert read.origin == grid.origin and read.spacing == grid.spacing
    text = good.read_bytes()
    tag_end = text.index(b">", text.index(b"<ImageData"))
    head = text[:tag_end].decode()
    start = head.index(f'{attribute}="') + len(attribute) + 2
    bad = tmp_path / "bad.vti"
    bad.write_bytes((head[:start] + value + head[head.index('"', start):]).encode() + text[tag_end:])
    with pytest.raises(ValueError, match=f"{attribute} '{value}' is not"):
        read_image(bad)


def test_a_series_written_again_keeps_only_its_own_steps(tmp_path):
    """A shorter run into the name of an earlier series left the earlier steps in its folder: a viewer of the
    folder showed both runs mixed. The earlier steps go once the new index replaces the old."""
    path = tmp_path / "run.pvd"
    with TimeSeriesWriter(path) as series:
        for step in range(4):
            series.write(pv.Sphere(radius=1 + step), time=step)
        series.write(pv.MultiBlock({"a": pv.Sphere()}), time=9)  # a step with a blocks folder
    assert len(list((tmp_path / "run").iterdir())) == 6
    with TimeSeriesWriter(path) as series:
        series.write(pv.Cube(), time=0)
        assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["run_000000.vtp"]  # an interrupted rerun
        series.write(pv.Cube(), time=1)
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["run_000000.vtp", "run_000001.vtp"]
    reader = pv.get_reader(path)
    assert reader.time_values == [0.0, 1.0]
    reader.set_active_time_value(1.0)
    assert reader.read()[0].n_cells == pv.Cube().n_cells
