import numpy as np
import pytest
import pyvista as pv

import pverosion
from pverosion.kernels import InvalidMeshError, as_triangle_mesh, principal_curvatures
from pverosion.kernels.validation import check_coordinate_precision

TRI_P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
TRI_F = np.array([[0, 1, 2]])


@pytest.mark.parametrize(
    ("points", "faces", "match"),
    [
        (np.zeros((0, 3)), TRI_F, "no points"),
        (np.zeros((3, 2)), TRI_F, r"shape \(V, 3\)"),
        (np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]]), TRI_F, "NaN"),
        (TRI_P, np.array([[0, 1, 2, 0]]), "triangulate"),
        (TRI_P, np.zeros((0, 3), int), "no triangles"),
        (TRI_P, np.array([[0, 1, 3]]), "vertex indices"),
        (TRI_P, np.array([[0.0, 1.0, 2.0]]), "integer"),
    ],
)
def test_bad_arrays_raise_clear_errors(points, faces, match):
    with pytest.raises(InvalidMeshError, match=match):
        as_triangle_mesh(points, faces)
    with pytest.raises(InvalidMeshError, match=match):
        principal_curvatures(points, faces)


def test_filter_front_end_rejects_bad_meshes():
    with pytest.raises(InvalidMeshError, match="empty"):
        pverosion.curvature(pv.PolyData())
    with pytest.raises(InvalidMeshError, match="triangulate"):
        pverosion.curvature(pv.Plane())
    nan = pv.Sphere()
    nan.points[3] = np.nan
    with pytest.raises(InvalidMeshError, match="NaN"):
        pverosion.curvature(nan)
    with pytest.raises(TypeError, match="PolyData"):
        pverosion.curvature(pv.ImageData(dimensions=(3, 3, 3)))
    with pytest.raises(ValueError, match="orientation must be one of"):
        pverosion.curvature(pv.Sphere(), orientation="sideways")


def test_input_is_not_mutated(bunny):
    before_points = bunny.points.copy()
    before_faces = bunny.faces.copy()
    before_arrays = list(bunny.point_data.keys())
    out = pverosion.curvature(bunny, normalization="symmetric")
    assert "mean_curvature" in out.point_data
    np.testing.assert_array_equal(bunny.points, before_points)
    np.testing.assert_array_equal(bunny.faces, before_faces)
    assert list(bunny.point_data.keys()) == before_arrays


def _stored(mesh: pv.PolyData, offset: float, dtype) -> pv.PolyData:
    """A new mesh: ``mesh`` moved by ``offset`` along every axis, its points stored as ``dtype``."""
    points = (np.asarray(mesh.points, np.float64) + offset).astype(dtype)
    moved = pv.PolyData.from_regular_faces(points, mesh.regular_faces)
    assert moved.points.dtype == dtype
    return moved


def _small_sphere() -> pv.PolyData:
    """A closed sphere of the bunny scan's size (radius 0.08) with edges of 0.012, eight times the scan's."""
    return pv.Icosphere(radius=0.08, nsub=3)


@pytest.mark.parametrize("offset", [1e3, 1e6])
def test_float32_points_far_from_the_origin_are_warned_about(bunny, offset):
    """The bunny scan stored as float32 1000 units out is rounded in steps of 6.1e-5, 4 % of its median edge; a
    million units out in steps of 0.0625, longer than the edges: the warning names the type, the step and the
    remedy, and the result is given."""
    import re

    far = _stored(bunny, offset, np.float32)
    step = re.escape(f"{float(np.spacing(np.float32(offset))):.3g}")
    with pytest.warns(UserWarning, match=rf"stored as float32, .* are {step} apart while the median edge is "
                                         r".* long .*export the model again from its source with float64 "
                                         r"points.*does not undo the rounding"):
        out = pverosion.curvature(far)
    assert out.n_points == far.n_points


def test_float32_points_far_from_the_origin_are_warned_about_in_a_pipeline_and_on_the_command_line(
        bunny, tmp_path, capsys):
    """A PLY scan stored as float32 a million units out: a VTK pipeline from the file's reader warns, and the
    command line prints the warning on stderr, writes the result and exits with 0."""
    from vtkmodules.vtkCommonCore import VTK_FLOAT
    from vtkmodules.vtkIOPLY import vtkPLYReader

    from pverosion.cli import main
    from pverosion.filters.curvature import Curvature
    from pverosion.io import read_mesh

    path, out = tmp_path / "far.ply", tmp_path / "out.vtp"
    _stored(bunny, 1e6, np.float32).save(path)
    reader = vtkPLYReader()
    reader.SetFileName(str(path))
    alg = Curvature()
    alg.SetInputConnection(reader.GetOutputPort())
    with pytest.warns(UserWarning, match="stored as float32"):
        alg.Update()
    assert reader.GetOutput().GetPoints().GetDataType() == VTK_FLOAT
    assert alg.GetOutputDataObject(0).GetPointData().GetArray("mean_curvature") is not None
    assert main(["curvature", str(path), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "pverosion curvature: warning: the points are stored as float32" in err
    assert "0.0625 apart" in err
    assert read_mesh(out).n_points == bunny.n_points


@pytest.mark.parametrize("stage", ["weather", "repair", "shard_graph"])
def test_every_mesh_stage_warns_about_coarsely_stored_points(stage):
    """Weathering, repair and the shards take their points where curvature does: a float32 sphere 10,000 units
    out (steps of 9.8e-4, 8 % of its edges) is warned about by each."""
    options = {"weather": {"iterations": 1}, "repair": {}, "shard_graph": {"cells": 8}}[stage]
    with pytest.warns(UserWarning, match="stored as float32"):
        getattr(pverosion, stage)(_stored(_small_sphere(), 1e4, np.float32), **options)


@pytest.mark.parametrize(("make", "offset", "dtype"), [
    ("bunny", 1e6, np.float64),  # float64: steps of 1.2e-10 a million units out
    ("bunny", 0.0, np.float32),  # the scan as stored, near the origin: steps of 1.5e-8
    ("sphere", 1e3, np.float32),  # steps of 6.1e-5, 0.5 % of the edges
], ids=["float64-far", "float32-near", "float32-1e3-coarse-edges"])
def test_points_stored_finely_enough_are_not_warned_about(bunny, make, offset, dtype):
    import warnings

    mesh = _stored(bunny if make == "bunny" else _small_sphere(), offset, dtype)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        pverosion.curvature(mesh)


def test_a_far_point_no_face_uses_is_not_warned_about():
    """Only the points of the faces count: a float32 sphere near the origin with one unused point 10,000 units out
    (where float32 steps are 9.8e-4, 8 % of the sphere's edges) is stored finely enough where it matters."""
    import warnings

    sphere = _stored(_small_sphere(), 0.0, np.float32)
    stray = pv.PolyData.from_regular_faces(np.vstack([sphere.points, [[1e4, 0.0, 0.0]]]).astype(np.float32),
                                           sphere.regular_faces)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        check_coordinate_precision(np.asarray(stray.points), stray.regular_faces)


def test_coarsely_stored_points_with_nan_are_refused_without_a_warning():
    """Non-finite coordinates are refused as such; the precision check leaves them alone."""
    import warnings

    far = _stored(_small_sphere(), 1e6, np.float32)
    far.points[3] = np.nan
    with warnings.catch_warnings(), pytest.raises(InvalidMeshError, match="NaN"):
        warnings.simplefilter("error", UserWarning)
        pverosion.curvature(far)
