import numpy as np
import pytest
import pyvista as pv

import pverosion
from pverosion.kernels import InvalidMeshError, as_triangle_mesh, principal_curvatures

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
