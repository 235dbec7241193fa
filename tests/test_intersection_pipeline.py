"""pipelines/intersection_scenes.py: the two-spheres and self-intersection scenes write their files and sane figures."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

from pverosion.scenes.intersection import two_spheres

SCRIPT = Path(__file__).resolve().parents[1] / "pipelines" / "intersection_scenes.py"


@pytest.fixture(scope="module")
def pipeline():
    spec = importlib.util.spec_from_file_location("intersection_scenes_pipeline", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(pipeline, monkeypatch, capsys, out: Path, scene: str) -> dict:
    monkeypatch.setattr(sys, "argv", ["intersection_scenes.py", "-o", str(out), "--scene", scene, "--quick"])
    pipeline.main()
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 1
    figures = json.loads(lines[0])
    assert figures["scene"] == scene
    for path in figures["files"]:
        assert Path(path).is_file() and Path(path).stat().st_size > 0
    assert {Path(p).name for p in figures["files"]} == {f"{scene}_input.vtp", f"{scene}_curves.vtp",
                                                         f"{scene}.vtp", f"{scene}.png"}
    cases = figures["cases"]
    assert cases["impossible"] == 0 and cases["valid"] > 0
    assert figures["closed"] and figures["open_edges"] == 0 and figures["loops"] >= 1
    return figures


def test_two_spheres(pipeline, monkeypatch, capsys, tmp_path):
    figures = run(pipeline, monkeypatch, capsys, tmp_path, "two_spheres")
    assert figures["loops"] == 1 and figures["pieces"] == 1
    assert max(figures["volumes_in"]) < figures["volume"] < sum(figures["volumes_in"])
    result = pv.read(tmp_path / "two_spheres.vtp")
    assert result.n_cells == figures["faces_out"] and result.n_open_edges == 0
    assert result["on_intersection"].any() and set(np.unique(result["source_mesh"])) == {0, 1}
    assert result.volume == pytest.approx(figures["volume"], rel=1e-9)
    source = pv.read(tmp_path / "two_spheres_input.vtp")
    assert source.n_cells == figures["faces"] and set(np.unique(source["source_mesh"])) == {0, 1}
    curves = pv.read(tmp_path / "two_spheres_curves.vtp")
    assert curves.n_lines == 1 and curves.n_points == figures["segments"]  # one closed loop
    manifold3d = pytest.importorskip("manifold3d")
    a, b = (manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(m.points, np.float32),
                                                 tri_verts=np.asarray(m.regular_faces, np.uint32)))
            for m in two_spheres())
    assert abs(figures["volume"] - (a + b).volume()) < 1e-3


def test_self_intersection(pipeline, monkeypatch, capsys, tmp_path):
    figures = run(pipeline, monkeypatch, capsys, tmp_path, "self_intersection")
    assert figures["objects"] == 1 and figures["pieces"] >= 1
    # the doubly covered region counts once: less than the input's signed volume, but not much less
    assert 0.9 * figures["volume_in"] < figures["volume"] < figures["volume_in"]
    result = pv.read(tmp_path / "self_intersection.vtp")
    assert result.n_cells == figures["faces_out"] and result.n_open_edges == 0
