"""Seed patterns for Voronoi shards (Mateos et al. §4.1, Figure 4): properties of every generator."""

import math
import time

import numpy as np
import pytest
import pyvista as pv
from scipy.spatial import ConvexHull, Voronoi, cKDTree

from pverosion.filters.base import polydata_triangles
from pverosion.kernels.shards.graph import build_shards
from pverosion.kernels.shards.seed_patterns import (
    hex_column_seeds,
    inside_mesh,
    jittered_grid_seeds,
    mesh_vertex_seeds,
    poisson_disc_seeds,
    slab_seeds,
    uniform_seeds,
)

BOX = (np.array([-1.0, -0.5, 0.0]), np.array([1.0, 0.5, 1.2]))

GENERATORS = {
    "uniform": lambda bounds, inside=None, seed=0: uniform_seeds(300, bounds=bounds, inside=inside, seed=seed),
    "jittered_grid": lambda bounds, inside=None, seed=0: jittered_grid_seeds(
        0.2, bounds=bounds, jitter=0.3, inside=inside, seed=seed),
    "hex_columns": lambda bounds, inside=None, seed=0: hex_column_seeds(
        0.2, bounds=bounds, jitter=0.2, layer_spacing=0.3, inside=inside, seed=seed),
    "slabs": lambda bounds, inside=None, seed=0: slab_seeds(
        [0.1, 0.25], bounds=bounds, spacing=0.2, tilt=25.0, jitter=0.2, inside=inside, seed=seed),
    "poisson_disc": lambda bounds, inside=None, seed=0: poisson_disc_seeds(
        0.12, bounds=bounds, radius_gradient=(0.03, 0.0, 0.02), inside=inside, seed=seed),
}


def _mesh(name):
    mesh = {"sphere": lambda: pv.Sphere(radius=0.9, theta_resolution=40, phi_resolution=40),
            "torus": lambda: pv.ParametricTorus(ringradius=0.8, crosssectionradius=0.3)}[name]()
    mesh = mesh.triangulate().clean()
    points, faces = polydata_triangles(mesh)
    return mesh, np.asarray(points, dtype=float), np.asarray(faces)


def _mesh_box(mesh):
    return np.array(mesh.bounds[::2]), np.array(mesh.bounds[1::2])


def _vtk_inside(mesh, pts):
    return pv.PolyData(pts).select_interior_points(mesh)["selected_points"].astype(bool)


# ----------------------------------------------------------------------------- common properties


@pytest.mark.parametrize("name", GENERATORS)
def test_reproducible_for_a_seed_and_different_for_another(name):
    gen = GENERATORS[name]
    a, b, c = gen(BOX, seed=7), gen(BOX, seed=7), gen(BOX, seed=8)
    assert a.dtype == np.float64 and a.ndim == 2 and a.shape[1] == 3 and len(a) > 10
    assert np.array_equal(a, b)
    assert a.shape != c.shape or not np.array_equal(a, c)
    # a Generator is accepted and gives the stream of its seed
    assert np.array_equal(gen(BOX, seed=np.random.default_rng(7)), a)


@pytest.mark.parametrize("name", GENERATORS)
def test_points_are_finite_distinct_and_in_the_bounds(name):
    pts = GENERATORS[name](BOX, seed=3)
    assert np.isfinite(pts).all()
    assert len(np.unique(pts, axis=0)) == len(pts)
    assert (pts >= BOX[0]).all() and (pts <= BOX[1]).all()


def test_inside_mesh_agrees_with_vtk_away_from_the_surface():
    mesh, points, faces = _mesh("torus")
    lo, hi = _mesh_box(mesh)
    q = np.random.default_rng(0).uniform(lo - 0.1, hi + 0.1, size=(20000, 3))
    ours = inside_mesh(points, faces)(q)
    distance = np.abs(pv.PolyData(q).compute_implicit_distance(mesh)["implicit_distance"])
    far = distance > 1e-6
    assert far.mean() > 0.99 and 0.1 < ours.mean() < 0.5
    assert np.array_equal(ours[far], _vtk_inside(mesh, q)[far])
    # non-finite points are outside rather than an error
    assert not inside_mesh(points, faces)(np.array([[np.nan, 0.0, 0.0]])).any()


def test_inside_mesh_rejects_open_meshes():
    mesh = pv.Plane().triangulate()
    with pytest.raises(ValueError, match="closed"):
        inside_mesh(*polydata_triangles(mesh))


@pytest.mark.parametrize("mesh_name", ["sphere", "torus"])
@pytest.mark.parametrize("name", GENERATORS)
def test_points_stay_inside_a_closed_mesh(name, mesh_name):
    mesh, points, faces = _mesh(mesh_name)
    bounds = _mesh_box(mesh)
    pts = GENERATORS[name](bounds, inside=inside_mesh(points, faces), seed=1)
    assert len(pts) > 20
    assert _vtk_inside(mesh, pts).all()


@pytest.mark.parametrize("name", ["jittered_grid", "hex_columns", "slabs"])
def test_grid_patterns_culled_by_inside_are_the_unculled_points_inside(name):
    mesh, points, faces = _mesh("torus")
    bounds = _mesh_box(mesh)
    inside = inside_mesh(points, faces)
    full = GENERATORS[name](bounds, seed=4)
    assert np.array_equal(GENERATORS[name](bounds, inside=inside, seed=4), full[inside(full)])


# ----------------------------------------------------------------------------- uniform


def test_uniform_seeds_are_balanced_between_halves():
    n = 4000
    pts = uniform_seeds(n, bounds=BOX, seed=11)
    assert pts.shape == (n, 3)
    mid = 0.5 * (BOX[0] + BOX[1])
    for axis in range(3):  # Binomial(n, 1/2): 5 standard deviations
        assert abs((pts[:, axis] < mid[axis]).sum() - n / 2) < 5 * math.sqrt(n) / 2
    mesh, points, faces = _mesh("sphere")  # the sphere is symmetric about its centre
    pts = uniform_seeds(n, bounds=_mesh_box(mesh), inside=inside_mesh(points, faces), seed=12)
    assert pts.shape == (n, 3)
    for axis in range(3):
        assert abs((pts[:, axis] < 0.0).sum() - n / 2) < 5 * math.sqrt(n) / 2


def test_uniform_seeds_fail_clearly_when_the_region_is_empty():
    with pytest.raises(ValueError, match="inside accepted none"):
        uniform_seeds(10, bounds=BOX, inside=lambda p: np.zeros(len(p), dtype=bool))
    with pytest.raises(ValueError, match="shape"):
        uniform_seeds(10, bounds=BOX, inside=lambda p: np.ones(3, dtype=bool))


# ----------------------------------------------------------------------------- jittered grid


@pytest.mark.parametrize("jitter", [0.0, 0.1, 0.45])
def test_jittered_grid_points_stay_within_jitter_of_their_sites(jitter):
    spacing = np.array([0.25, 0.2, 0.3])
    lo, hi = np.zeros(3), np.array([2.0, 1.0, 1.2])  # multiples of the spacing: all sites are cell centres
    pts = jittered_grid_seeds(spacing, bounds=(lo, hi), jitter=jitter, seed=5)
    counts = np.round((hi - lo) / spacing).astype(int)
    assert len(pts) == counts.prod()  # nothing is jittered out of the box
    index = np.floor((pts - lo) / spacing).astype(int)  # |jitter| < spacing / 2: the cell of a point is its site's
    assert len(np.unique(index, axis=0)) == len(pts)
    offset = pts - (lo + (index + 0.5) * spacing)
    assert (np.abs(offset) <= jitter * spacing + 1e-12).all()
    if jitter == 0.0:
        assert (np.abs(offset) < 1e-12).all()
    else:  # the jitter uses its range: uniform on [-1, 1] per axis
        scaled = offset / (jitter * spacing)
        assert scaled.min() < -0.9 and scaled.max() > 0.9 and abs(scaled.mean()) < 0.1


# ----------------------------------------------------------------------------- hexagonal columns


def test_hex_columns_neighbours_are_a_spacing_apart():
    bounds = (np.zeros(3), np.array([3.0, 2.5, 1.0]))
    s = 0.3
    exact = hex_column_seeds(s, bounds=bounds, jitter=0.0)
    assert np.allclose(exact[:, 2], 0.5)  # one seed per column, at mid-height
    d, _ = cKDTree(exact[:, :2]).query(exact[:, :2], k=7)
    assert np.allclose(d[:, 1], s)
    interior = ((exact[:, :2] > bounds[0][:2] + s) & (exact[:, :2] < bounds[1][:2] - s)).all(axis=1)
    assert interior.sum() > 20 and np.allclose(d[interior, 1:], s)  # six neighbours at the spacing
    jitter = 0.15
    pts = hex_column_seeds(s, bounds=bounds, jitter=jitter, seed=2)
    d, _ = cKDTree(pts[:, :2]).query(pts[:, :2], k=2)
    assert (d[:, 1] >= s * (1 - 2 * jitter) - 1e-12).all() and (d[:, 1] <= s * (1 + 2 * jitter) + 1e-12).all()
    assert abs(np.median(d[:, 1]) - s) < jitter * s


def test_hex_columns_along_another_axis_with_layers():
    bounds = (np.zeros(3), np.array([1.2, 2.0, 1.5]))
    pts = hex_column_seeds(0.25, bounds=bounds, axis=0, layer_spacing=0.4, jitter=0.1, seed=3)
    heights = np.unique(pts[:, 0])
    assert np.allclose(heights, [0.2, 0.6, 1.0])  # ceil(1.2 / 0.4) layers 0.4 apart, centred
    # every layer holds the same columns (same in-plane positions)
    layers = [pts[pts[:, 0] == h][:, 1:] for h in heights]
    assert all(np.array_equal(layer, layers[0]) for layer in layers)


@pytest.mark.parametrize("axis", [2, 0])
def test_hex_column_shards_are_full_height_prisms(axis):
    lo, hi = np.zeros(3), np.full(3, 2.0)
    hi[axis] = 1.0
    height = hi[axis] - lo[axis]
    s = 0.45
    seeds = hex_column_seeds(s, bounds=(lo, hi), axis=axis, jitter=0.2, seed=9)
    box = pv.Box((lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])).triangulate().clean()
    points, faces = polydata_triangles(box)
    graph = build_shards(seeds, points, faces)
    assert len(graph.volume) == len(seeds)
    assert graph.volume.sum() == pytest.approx(height * 4.0, rel=1e-9)
    interior = ~graph.exterior
    assert interior.any()
    assert np.abs(graph.link_normal[interior, axis]).max() < 1e-9  # faces between cells run along the columns
    # the cell of an interior column is its 2-D Voronoi polygon times the full height
    u, v = [a for a in range(3) if a != axis]
    plane = seeds[graph.cell_seed][:, [u, v]]
    vor = Voronoi(plane)
    checked = 0
    for cell, region_index in enumerate(vor.point_region):
        region = vor.regions[region_index]
        if -1 in region or len(region) == 0:
            continue
        poly = vor.vertices[region]
        if (poly < [lo[u], lo[v]]).any() or (poly > [hi[u], hi[v]]).any():
            continue
        assert graph.volume[cell] == pytest.approx(ConvexHull(poly).volume * height, rel=1e-9)
        checked += 1
    assert checked >= 5


# ----------------------------------------------------------------------------- slabs


def _expected_midplanes(thickness, base, below, above):
    """Mid-planes of layers cycling ``thickness`` upwards from ``base`` and backwards below it."""
    mids, b, k = [], base, 0
    while b < above:
        t = thickness[k % len(thickness)]
        mids.append(b + t / 2)
        b, k = b + t, k + 1
    b, k = base, -1
    while b > below:
        t = thickness[k % len(thickness)]
        mids.append(b - t / 2)
        b, k = b - t, k - 1
    return np.sort(mids)


def test_slabs_without_tilt_sit_on_the_layer_midplanes():
    thickness = [0.1, 0.3, 0.2]
    lo, hi = np.zeros(3), np.array([1.0, 0.8, 1.7])
    pts = slab_seeds(thickness, bounds=(lo, hi), spacing=(0.25, 0.2))
    mids = np.cumsum(np.resize(thickness, 8)) - np.resize(thickness, 8) / 2
    mids = mids[mids <= hi[2]]
    z = np.unique(np.round(pts[:, 2], 12))
    assert np.allclose(z, mids)
    for m in mids:  # every layer is the same 4 x 4 grid
        layer = pts[np.isclose(pts[:, 2], m)]
        assert np.allclose(np.unique(np.round(layer[:, 0], 12)), [0.125, 0.375, 0.625, 0.875])
        assert np.allclose(np.unique(np.round(layer[:, 1], 12)), [0.1, 0.3, 0.5, 0.7])
        assert len(layer) == 16
    # a scalar thickness: equal layers
    z = np.unique(np.round(slab_seeds(0.25, bounds=(lo, hi), spacing=0.2)[:, 2], 12))
    assert np.allclose(z, 0.125 + 0.25 * np.arange(7))


@pytest.mark.parametrize(("tilt", "tilt_axis", "jitter"), [(30.0, 0, 0.0), (-50.0, 1, 0.0), (15.0, 1, 0.3)])
def test_tilted_slabs_lie_on_the_rotated_midplanes(tilt, tilt_axis, jitter):
    thickness = [0.15, 0.05, 0.1]
    spacing = np.array([0.2, 0.15])
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([1.5, 1.0, 1.0])
    center = (lo + hi) / 2
    pts = slab_seeds(thickness, bounds=(lo, hi), spacing=spacing, tilt=tilt, tilt_axis=tilt_axis, jitter=jitter,
                     seed=1)
    t = math.radians(tilt)
    c, s = math.cos(t), math.sin(t)
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) if tilt_axis == 0 else np.array([[c, 0, s], [0, 1, 0],
                                                                                       [-s, 0, c]])
    local = center + (pts - center) @ rot  # back to the pattern frame
    half = 0.5 * np.linalg.norm(hi - lo)
    mids = _expected_midplanes(thickness, lo[2], center[2] - half, center[2] + half)
    # each seed's height along the rotated normal is one of the mid-planes
    gap = np.abs(local[:, 2][:, None] - mids[None, :]).min(axis=1)
    assert gap.max() < 1e-9
    assert len(np.unique(np.round(local[:, 2], 9))) > 12  # layers below the base are used too
    assert local[:, 2].min() < lo[2]
    # in-plane: the seed grid, centred on the box, moved at most jitter * spacing
    first = center[:2] - (np.ceil((hi - lo)[:2] / spacing) - 1) / 2 * spacing
    offset = (local[:, :2] - first) / spacing
    offset -= np.round(offset)
    assert (np.abs(offset) <= jitter + 1e-9).all()
    # the pattern still covers the whole box: no corner is left without seeds
    probes = np.random.default_rng(0).uniform(lo, hi, size=(20000, 3))
    probes = np.vstack([probes, lo + (hi - lo) * np.array([[i, j, k] for i in (0, 1) for j in (0, 1)
                                                           for k in (0, 1)])])
    d, _ = cKDTree(pts).query(probes)
    assert d.max() < np.sqrt(((1 + 2 * jitter) * spacing) @ ((1 + 2 * jitter) * spacing) + max(thickness) ** 2)


# ----------------------------------------------------------------------------- Poisson disc


def _check_disc_rule(pts, radii):
    pairs = cKDTree(pts).query_pairs(radii.max(), output_type="ndarray")
    d = np.linalg.norm(pts[pairs[:, 0]] - pts[pairs[:, 1]], axis=1)
    assert (d >= np.maximum(radii[pairs[:, 0]], radii[pairs[:, 1]])).all()


def test_poisson_disc_keeps_the_radius_and_fills_the_box():
    lo, hi = np.zeros(3), np.array([1.0, 1.0, 0.6])
    r = 0.06
    pts = poisson_disc_seeds(r, bounds=(lo, hi), seed=2)
    _check_disc_rule(pts, np.full(len(pts), r))
    # near-maximal: hardly any point of the box could still take a seed
    probes = np.random.default_rng(1).uniform(lo, hi, size=(50000, 3))
    d, _ = cKDTree(pts).query(probes)
    assert (d > r).mean() < 0.01 and d.max() < 2 * r


def test_poisson_disc_density_follows_the_radius_gradient():
    lo, hi = np.zeros(3), np.array([2.0, 1.0, 1.0])
    r0, g = 0.04, np.array([0.05, 0.0, 0.0])  # radius 0.04 at x = 0, 0.14 at x = 2
    pts = poisson_disc_seeds(r0, bounds=(lo, hi), radius_gradient=g, seed=3)
    radii = r0 + (pts - lo) @ g
    _check_disc_rule(pts, radii)
    counts = np.histogram(pts[:, 0], bins=4, range=(0.0, 2.0))[0]
    assert (np.diff(counts) < 0).all()  # fewer points where the radius is larger
    # density ~ 1 / r**3: the ratio of the outer quarters is close to that of their mean radii
    r_first, r_last = r0 + 0.25 * g[0], r0 + 1.75 * g[0]
    assert 0.5 < (counts[0] / counts[-1]) / (r_last / r_first) ** 3 < 2.0


def test_poisson_disc_with_a_radius_callable():
    lo, hi = -np.ones(3), np.ones(3)

    def radius(x):
        return 0.05 + 0.1 * np.linalg.norm(x, axis=1)

    pts = poisson_disc_seeds(radius, bounds=(lo, hi), seed=4)
    _check_disc_rule(pts, radius(pts))
    distance = np.linalg.norm(pts, axis=1)
    ball = 4 / 3 * math.pi * 0.5**3
    density_in, density_out = (distance < 0.5).sum() / ball, (distance >= 0.5).sum() / (8 - ball)
    assert density_in > 3 * density_out  # radius <= 0.1 inside the ball, >= 0.1 outside
    with pytest.raises(ValueError, match="radius callable"):
        poisson_disc_seeds(lambda x: x[:, 0], bounds=(lo, hi))


def test_poisson_disc_is_fast():
    poisson_disc_seeds(0.2, bounds=(np.zeros(3), np.ones(3)))  # compiled (or loaded from the cache)
    start = time.perf_counter()
    pts = poisson_disc_seeds(0.022, bounds=(np.zeros(3), np.ones(3)), radius_gradient=(0.02, 0.0, 0.0), seed=1)
    elapsed = time.perf_counter() - start
    assert len(pts) > 20000
    assert elapsed < 5.0


# ----------------------------------------------------------------------------- mesh vertices


def test_mesh_vertex_seeds_are_a_unique_subset():
    _, points, _ = _mesh("torus")
    doubled = np.vstack([points, points[:50]])  # repeated rows count once
    n_distinct = len(np.unique(doubled, axis=0))
    pts = mesh_vertex_seeds(doubled, count=100, seed=3)
    assert pts.shape == (100, 3)
    assert len(np.unique(pts, axis=0)) == 100
    rows = {tuple(p) for p in points}
    assert all(tuple(p) in rows for p in pts)
    index = np.array([np.flatnonzero((points == p).all(axis=1))[0] for p in pts])
    assert (np.diff(index) > 0).all()  # input order
    assert len(mesh_vertex_seeds(doubled, fraction=0.25, seed=3)) == round(0.25 * n_distinct)
    assert len(mesh_vertex_seeds(doubled)) == n_distinct
    assert np.array_equal(mesh_vertex_seeds(points, count=100, seed=3), pts)
    assert not np.array_equal(mesh_vertex_seeds(points, count=100, seed=4), pts)


# ----------------------------------------------------------------------------- bad inputs


@pytest.mark.parametrize(("call", "match"), [
    (lambda: uniform_seeds(0, bounds=BOX), "n must"),
    (lambda: uniform_seeds(5, bounds=(np.ones(3), np.zeros(3))), "lo < hi"),
    (lambda: uniform_seeds(5, bounds=(np.zeros(2), np.ones(2))), "bounds"),
    (lambda: uniform_seeds(5, bounds=(np.zeros(3), [1.0, np.nan, 1.0])), "bounds must be finite"),
    (lambda: uniform_seeds(5, bounds=BOX, inside="sphere"), "inside must"),
    (lambda: jittered_grid_seeds(0.0, bounds=BOX), "spacing"),
    (lambda: jittered_grid_seeds([0.1, 0.1], bounds=BOX), "spacing"),
    (lambda: jittered_grid_seeds(np.nan, bounds=BOX), "spacing"),
    (lambda: jittered_grid_seeds(0.1, bounds=BOX, jitter=0.5), "jitter"),
    (lambda: jittered_grid_seeds(0.1, bounds=BOX, jitter=-0.1), "jitter"),
    (lambda: jittered_grid_seeds(1e-4, bounds=BOX), "spacing"),
    (lambda: hex_column_seeds(-1.0, bounds=BOX), "spacing"),
    (lambda: hex_column_seeds(0.1, bounds=BOX, axis=3), "axis"),
    (lambda: hex_column_seeds(0.1, bounds=BOX, layer_spacing=0.0), "layer_spacing"),
    (lambda: slab_seeds(0.0, bounds=BOX, spacing=0.1), "layer_thickness"),
    (lambda: slab_seeds([], bounds=BOX, spacing=0.1), "layer_thickness"),
    (lambda: slab_seeds([0.1, -0.2], bounds=BOX, spacing=0.1), "layer_thickness"),
    (lambda: slab_seeds(0.1, bounds=BOX, spacing=(0.1, 0.1, 0.1)), "spacing"),
    (lambda: slab_seeds(0.1, bounds=BOX, spacing=0.1, tilt_axis=2), "tilt_axis"),
    (lambda: slab_seeds(0.1, bounds=BOX, spacing=0.1, tilt=np.inf), "tilt"),
    (lambda: poisson_disc_seeds(0.0, bounds=BOX), "radius"),
    (lambda: poisson_disc_seeds(0.1, bounds=BOX, radius_gradient=(-1.0, 0.0, 0.0)), "stay positive"),
    (lambda: poisson_disc_seeds(0.1, bounds=BOX, radius_gradient=(1.0, 0.0)), "radius_gradient"),
    (lambda: poisson_disc_seeds(0.1, bounds=BOX, attempts=0), "attempts"),
    (lambda: poisson_disc_seeds(1e-4, bounds=BOX), "radius"),
    (lambda: poisson_disc_seeds(0.1, bounds=BOX, inside=lambda p: np.zeros(len(p), bool)), "inside accepted none"),
    (lambda: mesh_vertex_seeds(np.zeros((4, 2))), "points"),
    (lambda: mesh_vertex_seeds(np.array([[0.0, 0.0, np.nan]])), "NaN"),
    (lambda: mesh_vertex_seeds(np.eye(3), count=4), "count"),
    (lambda: mesh_vertex_seeds(np.eye(3), fraction=0.0), "fraction"),
    (lambda: mesh_vertex_seeds(np.eye(3), fraction=0.5, count=2), "either fraction or count"),
])
def test_bad_inputs_raise_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()
