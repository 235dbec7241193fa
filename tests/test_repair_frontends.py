"""Repair and Boolean front ends: filters, function, accessor, CLI and ParaView plugin on procedural meshes.

Geometric checks, not golden numbers: closed outputs, volumes against manifold3d, curve vertices on both
input surfaces, every face a piece of the input face it names.
"""

import numpy as np
import pytest
import pyvista as pv
from test_paraview_plugin import plugin  # noqa: F401 - the stubbed ParaView plugin fixture
from vtkmodules.vtkFiltersSources import vtkSphereSource

import pverosion
from pverosion.cli import main
from pverosion.filters import ALL_FILTERS, BooleanOperation, RepairIntersections
from pverosion.kernels.exact.intersection_curves import CASES, IMPOSSIBLE_CASES
from pverosion.kernels.repair.mesh_repair import OPERATIONS

manifold3d = pytest.importorskip("manifold3d")

CENTRE_A, RADIUS_A = np.zeros(3), 1.0
CENTRE_B, RADIUS_B = np.array([0.9, 0.3, 0.2]), 0.8


@pytest.fixture(scope="module")
def sphere_a() -> pv.PolyData:
    return pv.Icosphere(radius=RADIUS_A, nsub=3, center=CENTRE_A)


@pytest.fixture(scope="module")
def sphere_b() -> pv.PolyData:
    return pv.Icosphere(radius=RADIUS_B, nsub=3, center=CENTRE_B)


def _manifold(mesh: pv.PolyData):
    return manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(mesh.points, np.float32),
                                               tri_verts=np.asarray(mesh.regular_faces, np.uint32)))


def _manifold_volume(a: pv.PolyData, b: pv.PolyData, operation: str) -> float:
    ma, mb = _manifold(a), _manifold(b)
    result = {"union": lambda: ma + mb, "intersection": lambda: ma ^ mb, "difference": lambda: ma - mb,
              "reverse_difference": lambda: mb - ma}[operation]()
    return result.volume()


def _signed_volume(mesh: pv.PolyData) -> float:
    p = np.asarray(mesh.points, np.float64)[mesh.regular_faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def _distance(points: np.ndarray, surface: pv.PolyData) -> np.ndarray:
    """Unsigned distance of every point to the triangles of ``surface``."""
    return np.abs(pv.PolyData(np.asarray(points, np.float64)).compute_implicit_distance(surface)["implicit_distance"])


def _inner_radius(mesh: pv.PolyData, centre: np.ndarray) -> float:
    """Smallest distance from ``centre`` to a face plane: the mesh lies between it and the circumradius."""
    p = np.asarray(mesh.points, np.float64)[mesh.regular_faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return float(np.abs(np.einsum("ij,ij->i", p[:, 0] - centre, n)).min())


def _snapshot(mesh: pv.PolyData) -> dict:
    return {"points": np.array(mesh.points), "faces": np.array(mesh.faces),
            **{f"p:{k}": np.array(mesh.point_data[k]) for k in mesh.point_data},
            **{f"c:{k}": np.array(mesh.cell_data[k]) for k in mesh.cell_data}}


def _assert_same(x: pv.PolyData, y: pv.PolyData) -> None:
    np.testing.assert_array_equal(x.points, y.points)
    np.testing.assert_array_equal(x.regular_faces, y.regular_faces)
    for data_x, data_y in ((x.point_data, y.point_data), (x.cell_data, y.cell_data), (x.field_data, y.field_data)):
        assert set(data_x.keys()) == set(data_y.keys())
        for key in data_x:
            np.testing.assert_array_equal(data_x[key], data_y[key])


@pytest.mark.parametrize("operation", OPERATIONS)
def test_boolean_is_closed_with_manifold3d_volume(sphere_a, sphere_b, operation):
    out = pverosion.boolean(sphere_a, sphere_b, operation)
    assert out.n_cells > 0 and out.n_open_edges == 0 and out.is_manifold
    expected = _manifold_volume(sphere_a, sphere_b, operation)
    assert _signed_volume(out) == pytest.approx(expected, rel=1e-3)
    assert int(out.field_data["intersection_loops"][0]) == 1


def test_repair_merges_overlapping_parts_and_drops_a_nested_one(sphere_a, sphere_b):
    two = sphere_a + sphere_b
    out = pverosion.repair(two)
    assert out.n_open_edges == 0 and out.is_manifold
    assert _signed_volume(out) == pytest.approx(_manifold_volume(sphere_a, sphere_b, "union"), rel=1e-3)
    assert int(out.field_data["intersection_loops"][0]) == 1
    # a small sphere wholly inside, its winding kept: winding number 2 there, so its surface goes and nothing is
    # cut (by default it would be taken for a cavity wall and turned)
    nested = sphere_a + pv.Icosphere(radius=0.3, nsub=2, center=(0.1, 0.0, 0.0))
    kept = pverosion.repair(nested, orientation="keep")
    assert kept.n_cells == sphere_a.n_cells and int(kept.field_data["intersection_loops"][0]) == 0
    np.testing.assert_array_equal(np.sort(kept["source_face"]), np.arange(sphere_a.n_cells))
    assert not kept["on_intersection"].any()


def test_on_intersection_marks_exactly_the_curve_vertices(sphere_a, sphere_b):
    out = pverosion.boolean(sphere_a, sphere_b, "union")
    marked = out["on_intersection"].astype(bool)
    assert out["on_intersection"].dtype == np.int8 and marked.sum() > 10
    points = np.asarray(out.points, np.float64)
    curve, rest = points[marked], points[~marked]
    # on both triangle meshes (to rounding), so on both spheres within their chord error
    assert _distance(curve, sphere_a).max() < 1e-9 and _distance(curve, sphere_b).max() < 1e-9
    for centre, radius, sphere in ((CENTRE_A, RADIUS_A, sphere_a), (CENTRE_B, RADIUS_B, sphere_b)):
        r = np.linalg.norm(curve - centre, axis=1)
        assert r.max() <= radius + 1e-9 and r.min() >= _inner_radius(sphere, centre) - 1e-9
    # every other vertex is an input vertex of one sphere and off the other sphere's surface
    inputs = np.concatenate([sphere_a.points, sphere_b.points]).astype(np.float64)
    assert {tuple(p) for p in rest} <= {tuple(p) for p in inputs}
    assert np.minimum(_distance(rest, sphere_a), _distance(rest, sphere_b)).max() < 1e-12  # on one ...
    assert np.maximum(_distance(rest, sphere_a), _distance(rest, sphere_b)).min() > 1e-6  # ... not both


@pytest.mark.parametrize("operation", ["union", "difference"])
def test_source_mesh_and_source_face_name_the_input_face(sphere_a, sphere_b, operation):
    out = pverosion.boolean(sphere_a, sphere_b, operation)
    source_mesh, source_face = out["source_mesh"], out["source_face"]
    assert source_mesh.dtype == np.int8 and source_face.dtype == np.int64
    assert set(np.unique(source_mesh).tolist()) == {0, 1}
    centroids = np.asarray(out.cell_centers().points, np.float64)
    for k, (sphere, other) in enumerate(((sphere_a, sphere_b), (sphere_b, sphere_a))):
        mine = source_mesh == k
        assert source_face[mine].max() < sphere.n_cells
        assert _distance(centroids[mine], sphere).max() < 1e-9
        assert _distance(centroids[mine], other).min() > 1e-6
        # in the plane of, and inside, the very face it names
        p = np.asarray(sphere.points, np.float64)[sphere.regular_faces[source_face[mine]]]
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        assert np.abs(np.einsum("ij,ij->i", centroids[mine] - p[:, 0], n)).max() < 1e-12
        for i in range(3):
            edge = np.cross(n, p[:, (i + 1) % 3] - p[:, i])
            assert np.einsum("ij,ij->i", centroids[mine] - p[:, i], edge).min() > -1e-12


def test_case_table_in_field_data(sphere_a, sphere_b):
    for out in (pverosion.boolean(sphere_a, sphere_b, "intersection"), pverosion.repair(sphere_a + sphere_b)):
        fd = out.field_data
        assert list(fd["intersection_case_names"]) == list(CASES)
        cases = fd["intersection_cases"]
        assert cases.dtype == np.int64 and cases.shape == (len(CASES),) and cases.sum() > 0
        impossible = [CASES.index(name) for name in IMPOSSIBLE_CASES]
        assert not cases[impossible].any() and int(fd["intersection_impossible_cases"][0]) == 0
        assert int(fd["intersection_valid_cases"][0]) == cases.sum() - cases[CASES.index("000")]
        # both faces of every intersecting pair are classified
        assert cases.sum() >= 2 * int(fd["intersection_segments"][0]) > 0


def test_function_accessor_filter_and_cli_agree(tmp_path, sphere_a, sphere_b, capsys):
    for operation in ("union", "reverse_difference"):
        a = pverosion.boolean(sphere_a, sphere_b, operation)
        b = sphere_a.erosion.boolean(sphere_b, operation=operation)
        c = pv.wrap(BooleanOperation(operation=operation).run(sphere_a, sphere_b))
        _assert_same(a, b)
        _assert_same(a, c)
    sphere_a.save(tmp_path / "a.vtp")
    sphere_b.save(tmp_path / "b.ply")
    out, png = tmp_path / "union.vtp", tmp_path / "union.png"
    assert main(["boolean", str(tmp_path / "a.vtp"), str(tmp_path / "b.ply"), "--operation", "union",
                 "-o", str(out), "--screenshot", str(png)]) == 0
    _assert_same(pv.read(out), pverosion.boolean(pv.read(tmp_path / "a.vtp"), pv.read(tmp_path / "b.ply")))
    assert png.stat().st_size > 10_000
    two = sphere_a + sphere_b
    two.save(tmp_path / "two.vtp")
    assert main(["repair", str(tmp_path / "two.vtp"), "-o", str(tmp_path / "repaired.vtp")]) == 0
    repaired = pverosion.repair(pv.read(tmp_path / "two.vtp"))
    _assert_same(pv.read(tmp_path / "repaired.vtp"), repaired)
    _assert_same(two.erosion.repair(), repaired)
    _assert_same(pv.wrap(RepairIntersections().run(two)), repaired)
    assert "boolean:" in capsys.readouterr().out
    # atomic writes leave only the finished files
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.vtp", "b.ply", "repaired.vtp", "two.vtp", "union.png",
                                                         "union.vtp"]


def test_improve_and_tolerance_reach_the_kernel_from_every_front_end(tmp_path, sphere_a, sphere_b):
    plain = pverosion.boolean(sphere_a, sphere_b, "difference")
    better = pverosion.boolean(sphere_a, sphere_b, "difference", improve=True)
    assert better.n_open_edges == 0 and better.n_cells < plain.n_cells
    assert better.volume == pytest.approx(_manifold_volume(sphere_a, sphere_b, "difference"), rel=1e-3)
    _assert_same(sphere_a.erosion.boolean(sphere_b, "difference", improve=True), better)
    sphere_a.save(tmp_path / "a.vtp")
    sphere_b.save(tmp_path / "b.vtp")
    assert main(["boolean", str(tmp_path / "a.vtp"), str(tmp_path / "b.vtp"), "--operation", "difference",
                 "--improve", "--tolerance", "1e-8", "-o", str(tmp_path / "out.vtp")]) == 0
    _assert_same(pv.read(tmp_path / "out.vtp"),
                 pverosion.boolean(sphere_a, sphere_b, "difference", improve=True, tolerance=1e-8))
    two = sphere_a + sphere_b
    repaired = two.erosion.repair(improve=True)
    assert repaired.n_open_edges == 0 and repaired.n_cells < pverosion.repair(two).n_cells
    with pytest.raises(ValueError, match="tolerance"):
        pverosion.repair(two, tolerance=-1.0)


def test_inputs_are_not_modified(sphere_a, sphere_b):
    a, b = sphere_a.copy(), sphere_b.copy()
    a.cell_data["tag"] = np.arange(a.n_cells, dtype=np.int32)
    a.point_data["height"] = a.points[:, 2].copy()
    before = (_snapshot(a), _snapshot(b))
    pverosion.boolean(a, b, "difference")
    a.erosion.boolean(b, operation="intersection")
    pverosion.repair(a)
    for mesh, snap in zip((a, b), before):
        after = _snapshot(mesh)
        assert after.keys() == snap.keys()
        for key, value in snap.items():
            np.testing.assert_array_equal(after[key], value)


def test_cell_arrays_are_carried_to_the_pieces(sphere_a, sphere_b):
    a, b = sphere_a.copy(), sphere_b.copy()
    a.cell_data["tag"] = np.arange(a.n_cells, dtype=np.int32)
    b.cell_data["tag"] = 10_000 + np.arange(b.n_cells, dtype=np.int32)
    a.cell_data["only_a"] = np.ones(a.n_cells)
    out = pverosion.boolean(a, b, "union")
    expected = np.where(out["source_mesh"] == 1, 10_000, 0) + out["source_face"]
    np.testing.assert_array_equal(out["tag"], expected)
    assert "only_a" not in out.cell_data  # B has no such array
    np.testing.assert_array_equal(pverosion.repair(a)["tag"], np.arange(a.n_cells))


def test_empty_result_and_vtk_pipeline(sphere_a):
    far = pv.Icosphere(radius=0.5, nsub=2, center=(5.0, 0.0, 0.0))
    empty = pverosion.boolean(sphere_a, far, "intersection")
    assert empty.n_cells == 0 and int(empty.field_data["intersection_loops"][0]) == 0
    assert pverosion.boolean(sphere_a, far, "union").n_cells == sphere_a.n_cells + far.n_cells
    # two sources connected to the two ports of a plain VTK pipeline
    sources = []
    for x in (0.0, 0.5):
        src = vtkSphereSource()
        src.SetCenter(x, 0.0, 0.0)
        src.SetThetaResolution(24)
        src.SetPhiResolution(24)
        sources.append(src)
    alg = BooleanOperation()
    alg.SetOperation("intersection")
    alg.SetInputConnection(0, sources[0].GetOutputPort())
    alg.SetInputConnection(1, sources[1].GetOutputPort())
    alg.Update()
    out = pv.wrap(alg.GetOutputDataObject(0))
    assert out.n_cells > 0 and out.n_open_edges == 0
    assert out.bounds[0] == pytest.approx(0.0, abs=0.01) and out.bounds[1] == pytest.approx(0.5, abs=0.01)  # the lens


def test_errors_are_clear(sphere_a, sphere_b, tmp_path, capsys):
    open_sphere = sphere_a.remove_cells([0])
    with pytest.raises(pverosion.InvalidMeshError, match="mesh B must be closed"):
        pverosion.boolean(sphere_a, open_sphere)
    with pytest.raises(pverosion.InvalidMeshError, match="the mesh must be closed"):
        pverosion.repair(open_sphere)
    with pytest.raises(ValueError, match="operation must be one of"):
        pverosion.boolean(sphere_a, sphere_b, "xor")
    with pytest.raises(ValueError, match="operation must be one of"):
        sphere_a.erosion.boolean(sphere_b, operation="xor")
    with pytest.raises(TypeError, match="takes 2 input"):
        BooleanOperation().run(sphere_a)
    with pytest.raises(TypeError, match="takes 1 input"):
        RepairIntersections().run(sphere_a, sphere_b)
    with pytest.raises(TypeError, match="PolyData"):
        pverosion.boolean(sphere_a, sphere_b.cast_to_unstructured_grid())
    with pytest.raises(pverosion.InvalidMeshError, match="mesh A: .*triangulate"):
        pverosion.boolean(pv.Box(), sphere_b)
    inward = pv.PolyData.from_regular_faces(sphere_a.points, sphere_a.regular_faces[:, ::-1])
    with pytest.raises(pverosion.InvalidMeshError, match="inward"):
        pverosion.repair(inward, orientation="keep")
    assert pverosion.repair(inward).n_cells == sphere_a.n_cells  # orientation="outward" by default
    # the command line: exit status 2 and the message
    sphere_a.save(tmp_path / "a.vtp")
    open_sphere.save(tmp_path / "open.vtp")
    assert main(["boolean", str(tmp_path / "a.vtp"), str(tmp_path / "open.vtp"), "-o", str(tmp_path / "o.vtp")]) == 2
    assert "mesh B must be closed" in capsys.readouterr().err
    assert main(["repair", str(tmp_path / "open.vtp"), "-o", str(tmp_path / "o.vtp")]) == 2
    assert "must be closed" in capsys.readouterr().err
    assert not (tmp_path / "o.vtp").exists()
    with pytest.raises(SystemExit):
        main(["boolean", str(tmp_path / "a.vtp"), str(tmp_path / "a.vtp"), "--operation", "xor", "-o", "x.vtp"])
    with pytest.raises(SystemExit):
        main(["boolean", str(tmp_path / "a.vtp"), "-o", "x.vtp"])


def test_paraview_proxies_have_two_ports_and_the_operation(plugin, sphere_a, sphere_b):  # noqa: F811
    assert RepairIntersections in ALL_FILTERS and BooleanOperation in ALL_FILTERS
    repair_proxy = plugin.PVErosionRepairIntersections
    assert [kw["port_index"] for kw in repair_proxy._stub_inputs] == [0]
    proxy = plugin.PVErosionBooleanOperation
    assert issubclass(proxy, BooleanOperation)
    assert [(kw["name"], kw["port_index"]) for kw in proxy._stub_inputs] == [("InputA", 0), ("InputB", 1)]
    assert proxy._stub_datatypes == [["vtkPolyData"], ["vtkPolyData"]]
    assert hasattr(proxy, "SetPVOperation") and hasattr(proxy, "SetPVOrientation")
    alg = proxy()
    assert alg.GetNumberOfInputPorts() == 2
    alg.SetPVOperation(OPERATIONS.index("difference"))  # as ParaView sets an enumeration: by index
    assert alg.GetOperation() == "difference"
    alg.SetInputDataObject(0, sphere_a)
    alg.SetInputDataObject(1, sphere_b)
    alg.Update()
    out = pv.wrap(alg.GetOutputDataObject(0))
    assert out.n_open_edges == 0
    assert _signed_volume(out) == pytest.approx(_manifold_volume(sphere_a, sphere_b, "difference"), rel=1e-3)


@pytest.mark.parametrize("shift", [10.0, 1e6])
def test_an_operand_far_away_does_not_change_the_other(shift):
    """The nearly-degenerate pre-pass of a Boolean is relative to each operand's own size: a small sphere's
    faces all stay whether the other operand lies beside it or a million units away."""
    small = pv.Icosphere(radius=1e-3, nsub=2)
    points = np.asarray(small.points, np.float64)
    far = pv.PolyData.from_regular_faces(points + [shift, 0.0, 0.0], small.regular_faces)
    union = pverosion.boolean(pv.PolyData.from_regular_faces(points, small.regular_faces), far)
    assert union.n_cells == 2 * small.n_cells
    near = union.extract_cells(np.flatnonzero(union.cell_data["source_mesh"] == 0))
    np.testing.assert_array_equal(np.sort(near.points, axis=0), np.sort(points, axis=0))


def test_repair_keeps_a_small_part_far_from_the_rest():
    """A shell is judged empty against its own size: a small closed part a million units from a large one stays."""
    small, large = pv.Icosphere(radius=1e-3, nsub=2), pv.Icosphere(radius=1.0, nsub=2)
    points = np.vstack([np.asarray(large.points, np.float64), np.asarray(small.points, np.float64) + [1e6, 0.0, 0.0]])
    faces = np.vstack([large.regular_faces, small.regular_faces + large.n_points])
    out = pverosion.repair(pv.PolyData.from_regular_faces(points, faces))
    assert out.n_cells == len(faces)
    assert out.volume == pytest.approx(large.volume + small.volume, rel=1e-9)


@pytest.mark.parametrize("operation", ["repair", *OPERATIONS])
def test_a_model_far_from_the_origin_gives_the_same_result_moved(sphere_a, sphere_b, operation):
    """The outward check measures the enclosed volume about the model, not about the origin: two 2 mm balls
    100 km from the origin (where a volume summed about the origin cancels to noise of either sign) give the
    result of the balls at the origin, moved: the same faces, vertices within the rounding of the coordinates."""
    shift = np.array([1e5, 1e5, 1e5])
    small = [pv.PolyData.from_regular_faces(np.asarray(m.points, np.float64) * 1e-3, m.regular_faces)
             for m in (sphere_a, sphere_b)]
    moved = [pv.PolyData.from_regular_faces(np.asarray(m.points) + shift, m.regular_faces) for m in small]

    def run(a, b):
        if operation == "repair":
            both = pv.PolyData.from_regular_faces(np.vstack([a.points, b.points]),
                                                  np.vstack([a.regular_faces, b.regular_faces + a.n_points]))
            return pverosion.repair(both)
        return pverosion.boolean(a, b, operation)

    near, far = run(*small), run(*moved)
    np.testing.assert_array_equal(far.regular_faces, near.regular_faces)
    np.testing.assert_allclose(np.asarray(far.points) - shift, near.points, rtol=0.0, atol=1e-9)


def test_the_command_line_reports_the_output_size_and_an_empty_result(sphere_a, tmp_path, capsys):
    """The summary line gives the input's and the output's sizes: an empty Boolean (exit 0, as it is a valid
    result) is said to be empty instead of showing only the input's size."""
    far = pv.Icosphere(radius=0.5, nsub=2, center=(5.0, 0.0, 0.0))
    a, b = tmp_path / "a.vtp", tmp_path / "b.vtp"
    sphere_a.save(a)
    far.save(b)
    n_in = (sphere_a.n_points + far.n_points, sphere_a.n_cells + far.n_cells)
    assert main(["boolean", str(a), str(b), "--operation", "intersection", "-o", str(tmp_path / "i.vtp")]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert f"{n_in[0]} points, {n_in[1]} cells -> 0 points, 0 cells" in line and "the result is empty" in line
    assert main(["boolean", str(a), str(b), "--operation", "union", "-o", str(tmp_path / "u.vtp")]) == 0
    union = pv.read(tmp_path / "u.vtp")
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert f"-> {union.n_points} points, {union.n_cells} cells in" in line and "empty" not in line
