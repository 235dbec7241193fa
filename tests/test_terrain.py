"""Closed terrain blocks from height fields."""

import numpy as np
import pytest

from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.mesh.terrain import height_field_solid
from pverosion.kernels.mesh.topology import halfedge_twins


@pytest.mark.parametrize("shape, spacing", [((2, 2), 1.0), ((7, 4), (0.5, 0.25)), ((30, 45), (2.0, 3.0))])
def test_block_is_closed_and_encloses_the_volume_under_the_terrain(shape, spacing):
    rng = np.random.default_rng(len(shape))
    heights = rng.uniform(1.0, 3.0, shape)
    points, faces = height_field_solid(heights, spacing=spacing, origin=(10.0, -5.0), base=0.5)
    _, others = halfedge_twins(faces, len(points))
    assert (others == 1).all()  # closed 2-manifold
    # the top is piecewise linear on the triangles: volume = sum of prism volumes down to the base
    top = faces[(points[faces, 2] > 0.5).all(axis=1)]
    xy = points[top][:, :, :2]
    u, v = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    expected = float((area * (points[top, 2].mean(axis=1) - 0.5)).sum())
    assert signed_volume(points, faces) == pytest.approx(expected, rel=1e-12)
    sx, sy = np.broadcast_to(spacing, (2,))
    assert area.sum() == pytest.approx((shape[0] - 1) * sx * (shape[1] - 1) * sy, rel=1e-12)


@pytest.mark.parametrize("heights, kwargs, match", [
    (np.ones(5), {}, "2-D"),
    (np.full((3, 3), np.nan), {}, "NaN"),
    (np.ones((3, 3)), {"spacing": 0.0}, "spacing"),
    (np.ones((3, 3)), {"base": 2.0}, "base"),
])
def test_bad_height_fields_raise(heights, kwargs, match):
    with pytest.raises(ValueError, match=match):
        height_field_solid(heights, **kwargs)
