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
    surface = pv.read(tmp_path / "curvature.vtp")
    H = surface["mean_curvature"]
    assert H.max() > 0 > H.min()  # a rock with bumps and dents
    assert np.abs(surface["mean_curvature_normalized"]).max() == pytest.approx(1.0)
    assert (tmp_path / "curvature.png").stat().st_size > 10_000
