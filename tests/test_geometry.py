import numpy as np
import pyvista as pv
from conftest import icosphere

from pverosion.kernels import (
    average_edge_length,
    corner_areas,
    face_normals,
    point_areas,
    signed_volume,
    vertex_normals,
)


def test_corner_areas_partition_face_and_surface_area():
    rng = np.random.default_rng(1)
    s = icosphere(1.5, 3)
    p = s.points + rng.normal(scale=0.02, size=s.points.shape)  # includes obtuse triangles
    f = s.regular_faces
    _, area = face_normals(p, f)
    np.testing.assert_allclose(corner_areas(p, f).sum(axis=1), area, rtol=1e-12)
    assert np.all(corner_areas(p, f) >= 0)
    np.testing.assert_allclose(point_areas(p, f).sum(), pv.PolyData.from_regular_faces(p, f).area, rtol=1e-9)


def test_vertex_normals_on_sphere_are_radial():
    s = icosphere(3.0, 4)
    radial = s.points / 3.0
    for weighting in ("area", "max"):
        n = vertex_normals(s.points, s.regular_faces, weighting=weighting)
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-12)
        assert np.einsum("ij,ij->i", n, radial).min() > 0.9999
    # Max's weights are exact for points on a sphere
    n = vertex_normals(s.points, s.regular_faces, weighting="max")
    np.testing.assert_allclose(n, radial, atol=1e-9)


def test_signed_volume_and_edge_length():
    s = icosphere(2.0, 5)
    f = s.regular_faces
    assert abs(signed_volume(s.points, f) - 4 / 3 * np.pi * 8) < 0.002 * 4 / 3 * np.pi * 8
    assert signed_volume(s.points, f[:, ::-1]) < 0
    # an icosphere edge subtends about 63.4 / 2**nsub degrees
    expected = 2.0 * np.deg2rad(63.43 / 32)
    assert abs(average_edge_length(s.points, f) - expected) < 0.1 * expected
