import subprocess
import sys

import numpy as np
import pytest
import pyvista as pv

import pverosion
import pverosion.examples
from pverosion.cli import main
from pverosion.filters import Curvature


def test_function_accessor_and_filter_agree():
    mesh = pv.Sphere(radius=2.0)
    a = pverosion.curvature(mesh, normalization="symmetric")
    b = mesh.erosion.curvature(normalization="symmetric")
    c = pv.wrap(Curvature(normalization="symmetric").run(mesh))
    for name in ("mean_curvature", "mean_curvature_normalized", "k1"):
        np.testing.assert_array_equal(a[name], b[name])
        np.testing.assert_array_equal(a[name], c[name])


def test_accessor_is_available_through_the_entry_point():
    code = "import pyvista as pv; print(round(float(pv.Sphere().erosion.curvature()['mean_curvature'].mean()), 1))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "2.0"


def test_cli_curvature_writes_vtp_and_screenshot(tmp_path, capsys):
    src = tmp_path / "rock.ply"
    pverosion.examples.load_rock(subdivisions=3).save(src)
    out, png = tmp_path / "out.vtp", tmp_path / "shot.png"
    assert main(["curvature", str(src), "-o", str(out), "--normalization", "shifted", "--screenshot", str(png)]) == 0
    result = pv.read(out)
    assert result["mean_curvature_normalized"].max() == pytest.approx(1.0)
    image = pv.read(png)
    rgb = np.asarray(image.point_data[image.array_names[0]])[:, :3].astype(int)
    # the rock shows the colour code: some strongly red and some green pixels
    assert np.any((rgb[:, 0] > 150) & (rgb[:, 1] < 80)) and np.any((rgb[:, 1] > 120) & (rgb[:, 0] < 80))


def test_cli_reports_bad_input(tmp_path, capsys):
    assert main(["curvature", str(tmp_path / "missing.ply"), "-o", str(tmp_path / "o.vtp")]) == 2
    assert "no such file" in capsys.readouterr().err
    pv.Plane().save(tmp_path / "quads.vtp")
    assert main(["curvature", str(tmp_path / "quads.vtp"), "-o", str(tmp_path / "o.vtp")]) == 2
    assert "triangulate" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["curvature", str(tmp_path / "quads.vtp"), "-o", "x.vtp", "--orientation", "up"])


def test_demo_writes_results(tmp_path):
    assert main(["demo", "-o", str(tmp_path)]) == 0
    reader = pv.get_reader(tmp_path / "cube_to_sphere.pvd")
    assert reader.time_values == [0.0, 30.0, 100.0, 200.0]
    reader.set_active_time_value(200.0)
    sphere = reader.read()[0]
    d = np.linalg.norm(sphere.points - sphere.points.mean(axis=0), axis=1)
    assert d.std() / d.mean() <= 0.02
    assert len(sphere.field_data["weathering_volume"]) == 201
    for name in ("cube_to_sphere.png", "cube_to_sphere_statistics.png"):
        assert (tmp_path / name).stat().st_size > 10_000


def test_cli_weather_series_and_errors(tmp_path, capsys):
    from pverosion.examples import load_cube

    load_cube(resolution=6).save(tmp_path / "cube.vtp")
    out = tmp_path / "w.vtp"
    args = ["weather", str(tmp_path / "cube.vtp"), "-o", str(out), "--iterations", "12", "--power", "2"]
    assert main([*args, "--save-every", "5", "--series", str(tmp_path / "run.pvd")]) == 0
    assert pv.get_reader(tmp_path / "run.pvd").time_values == [0.0, 5.0, 10.0, 12.0]
    final = pv.read(out)
    assert len(final.field_data["weathering_volume"]) == 13
    assert main([*args, "--series", str(tmp_path / "x.pvd")]) == 2
    assert "--series needs --save-every" in capsys.readouterr().err
    assert main([*args, "--save-every", "0"]) == 2


def test_cli_warning_gets_a_line_of_its_own_under_a_progress_bar(capsys):
    import re
    import warnings

    from tqdm import tqdm

    from pverosion.cli import warning_printer

    with warnings.catch_warnings(), tqdm(total=10, desc="steps", file=sys.stderr, mininterval=0) as bar:
        warnings.showwarning = warning_printer("pverosion weather")
        bar.update(3)
        warnings.warn("no water flows", UserWarning, stacklevel=1)
        bar.update(3)
    err = capsys.readouterr().err
    # the bar's text is cleared (carriage return) before the warning, which ends its own line
    assert re.search(r"\rpverosion weather: warning: no water flows\n", err), err
    assert "3/10" in err and "6/10" in err


def test_cli_reads_numbers_led_by_a_negative_one_as_a_value():
    """``--source-velocity -1,0,0`` is the vector, not an unknown option (argparse 3.11 took only ``-1``)."""
    from pverosion.cli import build_parser

    args = build_parser(stages={"voxel"}).parse_args(
        ["voxel", "in.vti", "-o", "out.vtm", "--source-velocity", "-1.5,0,-2e-1", "--iterations", "3"])
    assert args.source_velocity == "-1.5,0,-2e-1" and args.iterations == 3
    with pytest.raises(SystemExit):  # a real unknown option is still refused
        build_parser(stages={"voxel"}).parse_args(["voxel", "in.vti", "-o", "out.vtm", "--bogus"])
