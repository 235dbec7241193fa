"""Overhanging vertices: height fields have none, caps and lower hemispheres do, grazing walls do not."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import height_field, icosphere

from pverosion.kernels.hydraulic.overhangs import overhanging_vertices
from pverosion.kernels.mesh.terrain import height_field_solid


def voxel_surface(occupied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward triangles of the boundary of a union of unit cubes (cell (i, j, k) spans [i, i+1] x ...)."""
    cells = np.pad(occupied, 1)
    dims = np.array(cells.shape) + 1
    faces = []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3  # e_b x e_c = e_a
        for step in (1, -1):
            neighbour = np.roll(cells, -step, axis=a)
            for cell in np.argwhere(cells & ~neighbour):
                corner = cell.copy()
                corner[a] += step > 0
                quad = [corner.copy() for _ in range(4)]
                quad[1][b] += 1
                quad[2][b] += 1
                quad[2][c] += 1
                quad[3][c] += 1
                if step < 0:
                    quad = quad[::-1]
                ids = [np.ravel_multi_index(q, dims) for q in quad]
                faces += [[ids[0], ids[1], ids[2]], [ids[0], ids[2], ids[3]]]
    faces = np.array(faces)
    used, inverse = np.unique(faces, return_inverse=True)
    points = np.stack(np.unravel_index(used, dims), axis=1).astype(float) - 1.0
    return points, inverse.reshape(-1, 3)


def test_height_field_surface_has_none():
    surface = height_field(lambda x, y: 0.3 * np.sin(3 * x) * np.cos(2 * y) + 0.1 * x)
    assert not overhanging_vertices(surface.points, surface.regular_faces).any()


def test_closed_block_flags_only_what_lies_under_its_top():
    x = np.linspace(0.0, 1.0, 12)
    heights = 0.3 + 0.1 * np.sin(6 * x)[:, None] * np.cos(4 * x)[None, :]
    points, faces = height_field_solid(heights, spacing=1.0 / 11)
    flagged = overhanging_vertices(points, faces)
    base = points[:, 2] == points[:, 2].min()
    # the sides are vertical walls (grazed, not flagged); only the bottom's centre lies under the terrain
    assert np.flatnonzero(flagged).tolist() == [len(points) - 1]
    assert not overhanging_vertices(points, faces, mask=~base).any()


def test_mushroom_flags_exactly_the_vertices_under_the_cap():
    occupied = np.zeros((6, 6, 5), bool)
    occupied[2:4, 2:4, :3] = True  # stem
    occupied[:, :, 3:] = True  # cap, 6 x 6 wide, from z = 3 to 5
    points, faces = voxel_surface(occupied)
    x, y, z = points.T
    under_cap = (x > 0) & (x < 6) & (y > 0) & (y < 6) & (z < 5)
    flagged = overhanging_vertices(points, faces)
    assert under_cap.sum() > 20
    np.testing.assert_array_equal(flagged, under_cap)
    # orientation does not matter
    np.testing.assert_array_equal(overhanging_vertices(points, faces[:, ::-1]), under_cap)


def test_sphere_lower_hemisphere_is_flagged_upper_is_not():
    sphere = icosphere(1.0, 4)
    z = sphere.points[:, 2]
    flagged = overhanging_vertices(sphere.points, sphere.regular_faces)
    assert flagged[z < -0.1].all()
    assert not flagged[z > 0.0].any()


def test_mask_restricts_the_tested_vertices():
    sphere = icosphere(1.0, 3)
    mask = sphere.points[:, 0] > 0.0
    everything = overhanging_vertices(sphere.points, sphere.regular_faces)
    masked = overhanging_vertices(sphere.points, sphere.regular_faces, mask=mask)
    np.testing.assert_array_equal(masked, everything & mask)


def test_bad_input():
    sphere = icosphere(1.0, 2)
    points, faces = sphere.points, sphere.regular_faces
    with pytest.raises(ValueError, match="points"):
        overhanging_vertices(points[:, :2], faces)
    with pytest.raises(ValueError, match="NaN"):
        overhanging_vertices(np.where(np.arange(len(points))[:, None] == 3, np.nan, points), faces)
    with pytest.raises(ValueError, match="vertex indices"):
        overhanging_vertices(points, faces + len(points))
    with pytest.raises(ValueError, match="mask"):
        overhanging_vertices(points, faces, mask=np.ones(len(points) - 1, bool))
    with pytest.raises(ValueError, match="mask"):
        overhanging_vertices(points, faces, mask=np.ones(len(points)))
