"""ShardGraph / FreezeThaw filters, the Python front ends, the accessor and ``pverosion shards``."""

import numpy as np
import pytest
import pyvista as pv

import pverosion
from pverosion.cli import main
from pverosion.filters import FreezeThaw
from pverosion.filters.shards import PATTERNS, pattern_seeds
from pverosion.kernels.shards.graph import build_shards
from pverosion.scenes.shards import hill_cone


@pytest.fixture(scope="module")
def cone():
    return hill_cone(resolution=24)


def _closed(mesh: pv.PolyData) -> bool:
    return mesh.n_open_edges == 0


def test_shard_graph_rebuilds_a_torus_from_closed_shards():
    torus = pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4).triangulate().clean()
    out = pverosion.shard_graph(torus, cells=150, seed=3)
    surface, shards, links = out["surface"], out["shards"], out["links"]
    assert _closed(surface) and surface.volume == pytest.approx(torus.volume, rel=1e-6)
    assert shards.volume == pytest.approx(torus.volume, rel=1e-6)
    n_cells = surface.field_data["shard_cells"][0]
    assert len(np.unique(shards["cell_id"])) == n_cells
    assert links["exterior"].sum() > 0 and set(np.unique(links["exterior"])) <= {0, 1}
    assert torus.n_points == pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4).triangulate().clean().n_points


def test_a_nested_shell_facing_outward_is_a_cavity():
    """A sphere inside a sphere, both wound outward, is a hollow ball: the shards keep the cavity empty."""
    outer = pv.Sphere(radius=1.0, theta_resolution=24, phi_resolution=24).triangulate().clean()
    inner = pv.Sphere(radius=0.5, theta_resolution=16, phi_resolution=16).triangulate().clean()
    hollow = outer + inner
    out = pverosion.shard_graph(hollow, cells=20, seed=1)
    expected = outer.volume - inner.volume
    assert out["surface"].volume == pytest.approx(expected, rel=1e-6)
    assert out["shards"].volume == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("winding", ["inward", "mixed"])
def test_shards_do_not_depend_on_the_winding(winding):
    """A closed mesh with inward or mixed winding is fractured as the same mesh turned outward."""
    torus = pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4).triangulate().clean()
    faces = torus.regular_faces
    turned = faces[:, ::-1].copy() if winding == "inward" else faces.copy()
    if winding == "mixed":
        turned[::3] = turned[::3, ::-1]
    other = pv.PolyData.from_regular_faces(torus.points, turned)
    before = other.copy(deep=True)
    reference, out = pverosion.shard_graph(torus, cells=40, seed=1), pverosion.shard_graph(other, cells=40, seed=1)
    assert out["surface"].volume == pytest.approx(torus.volume, rel=1e-6)
    for block in ("surface", "shards", "links"):
        assert out[block].n_cells == reference[block].n_cells
        np.testing.assert_allclose(np.sort(out[block].points, axis=0), np.sort(reference[block].points, axis=0),
                                   rtol=0, atol=1e-12)
    assert np.array_equal(other.faces, before.faces)  # the input keeps its winding


def _with_a_flat_face() -> pv.PolyData:
    """An icosphere whose face 10 has its third corner moved onto the middle of its first edge: a face of zero
    area in a closed mesh."""
    sphere = pv.Icosphere(nsub=3)
    points, faces = np.array(sphere.points, dtype=np.float64), sphere.regular_faces
    a, b, c = faces[10]
    points[c] = 0.5 * (points[a] + points[b])
    return pv.PolyData.from_regular_faces(points, faces)


def test_a_face_of_zero_area_is_refused_and_repair_makes_the_mesh_fracture_closed():
    """A face whose corners lie on a line bounds no piece of a cell: the shards would have a hole there (three
    open edges), so both stages refuse the mesh; the repaired mesh gives closed shards of the same volume."""
    flat = _with_a_flat_face()
    for call in (lambda m: pverosion.shard_graph(m, cells=50, seed=1),
                 lambda m: pverosion.freeze_thaw(m, cells=50, iterations=1, paths_per_step=5, seed=1)):
        with pytest.raises(pverosion.InvalidMeshError, match=r"1 faces of zero area.*\[10\].*pverosion repair"):
            call(flat)
    with pytest.raises(pverosion.InvalidMeshError, match="1 faces of zero area"):  # the kernel itself
        build_shards(np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 0.0]]), flat.points, flat.regular_faces)
    repaired = pverosion.repair(flat)
    out = pverosion.shard_graph(repaired, cells=50, seed=1)
    assert _closed(out["surface"]) and _closed(out["shards"])
    assert out["surface"].volume == pytest.approx(flat.volume, rel=1e-9)


@pytest.mark.parametrize("pattern", PATTERNS)
def test_every_seed_pattern_fills_the_cone(cone, pattern):
    from pverosion.filters.base import polydata_triangles
    from pverosion.kernels.shards.graph import build_shards

    points, faces = polydata_triangles(cone)
    seeds = pattern_seeds(points, faces, pattern=pattern, cells=200, seed=1)
    graph = build_shards(seeds, points, faces)
    assert graph.volume.sum() == pytest.approx(cone.volume, rel=1e-9)
    if pattern not in ("poisson", "vertices", "hex"):  # those set a spacing, not a count
        assert 0.5 * 200 <= graph.n_cells <= 2.0 * 200


def test_freeze_thaw_erodes_keeps_core_and_stays_closed(cone):
    alg = FreezeThaw(iterations=4, paths_per_step=2500, cells=200, core="surface", core_window="0,-0.45,0.3,0.35",
                     water_direction="0,1,-0.3", seed=2)
    first = pv.wrap(alg.run_time(cone, 0))
    last = pv.wrap(alg.run_time(cone, 4))
    core_before = np.unique(first["shards"]["cell_id"][first["shards"]["core"] == 1])
    core_after = np.unique(last["shards"]["cell_id"][last["shards"]["core"] == 1])
    np.testing.assert_array_equal(core_before, core_after)
    surface = last["surface"]
    field = surface.field_data
    assert field["shard_paths"][0] == 10000 and field["shard_breaks"][0] > 0
    assert field["shard_solid_cells"][0] < field["shard_cells"][0]  # shards came off through the window
    assert _closed(surface)
    assert surface.volume == pytest.approx(last["shards"].volume, rel=1e-9)
    assert surface.volume < cone.volume
    paths = last["paths"]
    assert paths.n_lines > 0 and (np.asarray(paths["water"]) <= 1.0).all()


def test_time_steps_continue_and_rerun_bit_for_bit(cone):
    options = {"iterations": 3, "paths_per_step": 800, "cells": 150, "seed": 5}
    stepped = FreezeThaw(**options)
    result = pv.wrap(stepped.step_through(cone, [0, 1, 2, 3]))
    fresh = pv.wrap(FreezeThaw(**options).run(cone))
    for name in ("surface", "links"):
        assert result[name].points.tobytes() == fresh[name].points.tobytes()
        assert np.asarray(result[name]["link_life"]).tobytes() == np.asarray(fresh[name]["link_life"]).tobytes()
    again = pv.wrap(stepped.run_time(cone, 3))  # cached: same
    assert np.asarray(again["links"]["link_life"]).tobytes() == np.asarray(fresh["links"]["link_life"]).tobytes()


def test_front_ends_take_resistance_fields_and_core_functions(cone):
    image = pv.ImageData(dimensions=(8, 8, 8), spacing=(0.3, 0.3, 0.15), origin=(-1.05, -1.05, 0.0))
    image.point_data["rho"] = np.full(image.n_points, 1.0)
    options = {"iterations": 1, "paths_per_step": 2000, "cells": 120, "seed": 1, "shards": False, "record_paths": False}
    soft = pverosion.freeze_thaw(cone, **options)
    hard = pverosion.freeze_thaw(cone, resistance=image, **options)
    # resistance absorbs more water per link: more damage where the paths go, so more breaks in total
    assert hard["surface"].field_data["shard_breaks"][0] != soft["surface"].field_data["shard_breaks"][0]
    kept = cone.erosion.freeze_thaw(core=lambda seeds: np.ones(len(seeds), bool), **options)
    assert kept["surface"].field_data["shard_solid_cells"][0] == kept["surface"].field_data["shard_cells"][0]
    assert not {"shards", "paths"} & set(kept.keys())
    assert cone.erosion.shard_graph(cells=50)["surface"].n_cells > 0


def test_bad_inputs_raise_clear_errors(cone):
    open_mesh = pv.Sphere().clip("z")
    with pytest.raises(ValueError, match="closed"):
        pverosion.shard_graph(open_mesh.triangulate(), cells=20)
    with pytest.raises(ValueError, match="core_window"):
        FreezeThaw(core_window="1,2", cells=20).run(cone)
    with pytest.raises(ValueError, match="pattern"):
        FreezeThaw(pattern="spiral")
    with pytest.raises(TypeError, match="resistance"):
        FreezeThaw().SetResistanceField("granite")
    with pytest.raises(ValueError, match="paths"):
        pverosion.freeze_thaw(cone, paths_per_step=0)


def test_cli_writes_the_result_and_the_series(tmp_path, cone, capsys):
    src = tmp_path / "cone.vtp"
    cone.save(src)
    code = main(["freeze-thaw", str(src), "-o", str(tmp_path / "out.vtm"), "--cells", "80", "--iterations", "2",
                 "--paths-per-step", "300", "--save-every", "1", "--screenshot", str(tmp_path / "shot.png")])
    assert code == 0
    out = pv.read(tmp_path / "out.vtm")
    assert set(out.keys()) >= {"surface", "shards", "links", "paths"}
    assert pv.get_reader(tmp_path / "out.pvd").time_values == [0.0, 1.0, 2.0]
    assert (tmp_path / "shot.png").stat().st_size > 0
    assert main(["freeze-thaw", str(src), "-o", str(tmp_path / "bad.vtm"), "--water-direction", "0,0"]) == 2
    assert "--water-direction" in capsys.readouterr().err
