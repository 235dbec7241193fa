"""Spatial (Morton) vertex order, and the curvature filter computing large meshes in it."""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv

import pverosion
import pverosion.filters.curvature as curvature_filter
from pverosion.examples import load_torus
from pverosion.kernels import spatial_order

from conftest import icosphere


def test_spatial_order_is_a_permutation_and_sorts_a_line():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(5000, 3))
    order = spatial_order(points)
    assert order.dtype == np.int64 and np.array_equal(np.sort(order), np.arange(5000))
    line = np.column_stack([rng.random(1000), np.full(1000, 2.0), np.full(1000, -1.0)])
    assert np.array_equal(spatial_order(line), np.argsort(line[:, 0]))
    assert spatial_order(np.zeros((0, 3))).shape == (0,)
    assert np.array_equal(spatial_order(np.ones((4, 3))), np.arange(4))  # one cell: any order is fine; all kept


def test_spatial_order_ignores_units_and_position():
    points = np.random.default_rng(4).random((3000, 3))
    order = spatial_order(points)
    assert np.array_equal(spatial_order(points * 1e3 + 7.0), order)
    assert np.array_equal(spatial_order(points * 0.5**10 - 3.0), order)


def test_spatial_order_makes_neighbours_close():
    sphere = icosphere(1.0, 5)
    rng = np.random.default_rng(5)
    shuffle = rng.permutation(sphere.n_points)
    points, faces = sphere.points[shuffle], np.argsort(shuffle)[sphere.regular_faces]
    order = spatial_order(points)
    inverse = np.empty_like(order)
    inverse[order] = np.arange(len(order))
    spread = lambda f: np.median(f.max(axis=1) - f.min(axis=1))  # noqa: E731 - index span of a face
    assert spread(inverse[faces]) < 0.05 * spread(faces)


def _min_first(faces: np.ndarray) -> np.ndarray:
    """Each face rotated (keeping its cyclic order) to start at its smallest vertex."""
    k = np.argmin(faces, axis=1)
    return np.stack([faces[np.arange(len(faces)), (k + j) % 3] for j in range(3)], axis=1)


def test_curvature_filter_gives_the_same_result_in_spatial_order(monkeypatch):
    torus = load_torus(n_major=60, n_minor=24)  # no umbilics: the principal directions are defined
    rng = np.random.default_rng(6)
    shuffle = rng.permutation(torus.n_points)
    outward = np.argsort(shuffle)[torus.regular_faces]
    mesh = pv.PolyData.from_regular_faces(torus.points[shuffle], outward[:, ::-1])  # inward: the filter flips them
    monkeypatch.setattr(curvature_filter, "SPATIAL_ORDER_MIN_POINTS", 10**12)
    plain = pverosion.curvature(mesh, normalization="symmetric")
    monkeypatch.setattr(curvature_filter, "SPATIAL_ORDER_MIN_POINTS", 0)
    reordered = pverosion.curvature(mesh, normalization="symmetric")
    assert np.array_equal(reordered.regular_faces, plain.regular_faces)
    assert np.array_equal(_min_first(reordered.regular_faces), _min_first(outward))  # the same cyclic order
    np.testing.assert_array_equal(reordered.points, mesh.points)
    for name in plain.point_data:
        a, b = np.asarray(reordered.point_data[name]), np.asarray(plain.point_data[name])
        if name.startswith("principal_direction"):  # a direction is defined up to its sign
            np.testing.assert_allclose(np.abs(np.sum(a * b, axis=1)), 1.0, rtol=0, atol=1e-9)
        else:
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    assert int(reordered.field_data["flipped_faces"][0]) == mesh.n_cells
