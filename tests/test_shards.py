"""Shard generation: Voronoi cells clipped to closed meshes, convex or not, and their link graphs."""

import numba
import numpy as np
import pytest
import pyvista as pv

from pverosion.kernels.shards.graph import build_shards


def _mesh(mesh):
    mesh = mesh.triangulate().clean()
    return np.asarray(mesh.points, dtype=float), mesh.regular_faces, mesh


def _l_block():
    """An L-shaped block: the outer surface of three unit cubes, closed and outward."""
    grid = pv.ImageData(dimensions=(3, 2, 3))  # 2 x 1 x 2 cells
    keep = np.array([1, 1, 1, 0])  # cells (x, z): (0, 0), (1, 0), (0, 1); x-fastest
    grid.cell_data["keep"] = keep
    block = grid.threshold(0.5, scalars="keep").extract_surface(algorithm=None).triangulate()
    return block.subdivide(2, subfilter="linear").clean()


def _seeds_inside(mesh, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = np.array(mesh.bounds[::2]), np.array(mesh.bounds[1::2])
    cand = pv.PolyData(rng.uniform(lo, hi, (8 * n, 3)))
    inside = cand.select_interior_points(mesh)["selected_points"].astype(bool)
    return np.asarray(cand.points)[inside][:n]


@pytest.mark.parametrize("name", ["box", "sphere", "torus", "l_block"])
def test_cells_fill_the_mesh_volume_and_stay_inside(name):
    mesh = {
        "box": lambda: pv.Box(level=2),
        "sphere": lambda: pv.Sphere(theta_resolution=24, phi_resolution=24),
        "torus": lambda: pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4, u_res=48, v_res=24),
        "l_block": _l_block,
    }[name]()
    points, faces, mesh = _mesh(mesh)
    seeds = _seeds_inside(mesh, 300, seed=1)
    graph = build_shards(seeds, points, faces)
    assert graph.volume.min() > 0.0
    assert graph.volume.sum() == pytest.approx(mesh.volume, rel=5e-3)
    # the cells were cut exactly, so the volumes add up far better than the acceptance asks
    assert graph.volume.sum() == pytest.approx(mesh.volume, rel=1e-9)
    # no cell outside the mesh: the faces between cells lie inside it (VTK's test, independent of ours)
    interior = ~graph.exterior
    centroids = pv.PolyData(graph.link_centroid[interior])
    inside = centroids.select_interior_points(mesh)["selected_points"].astype(bool)
    assert inside.mean() > 0.99
    # exterior links are surface patches: flat ones lie on the surface, curved ones near it, within their cell
    distance = np.abs(pv.PolyData(graph.link_centroid[graph.exterior]).compute_implicit_distance(mesh)[
        "implicit_distance"])
    normals = np.asarray(mesh.face_normals)[graph.surface_triangle]
    link = np.repeat(np.arange(graph.n_links), np.diff(graph.surface_start))
    bend = np.zeros(graph.n_links)
    np.maximum.at(bend, link, np.linalg.norm(normals - graph.link_normal[link], axis=1))
    flat = bend[graph.exterior] < 1e-9
    assert flat.any() if name in ("box", "l_block") else True
    assert distance[flat].max(initial=0.0) < 1e-6 * mesh.length
    spacing = (mesh.volume / graph.n_cells) ** (1 / 3)
    assert distance.max() < 0.5 * spacing
    # the exterior area is the mesh's surface area
    assert graph.link_area[graph.exterior].sum() == pytest.approx(mesh.area, rel=1e-9)


def test_the_torus_hole_separates_cells_on_opposite_sides():
    points, faces, mesh = _mesh(pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.3, u_res=48, v_res=24))
    # two seeds facing each other across the hole: their Voronoi cells meet only in the hole, outside the mesh
    seeds = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    graph = build_shards(seeds, points, faces)
    assert graph.n_cells == 4
    pairs = {tuple(sorted(c)) for c in graph.link_cells[~graph.exterior]}
    assert (0, 1) not in pairs and (2, 3) not in pairs
    assert pairs == {(0, 2), (0, 3), (1, 2), (1, 3)}
    assert graph.volume.sum() == pytest.approx(mesh.volume, rel=1e-9)


def test_graphs_are_consistent():
    points, faces, mesh = _mesh(pv.Sphere(theta_resolution=20, phi_resolution=20))
    graph = build_shards(_seeds_inside(mesh, 200, seed=3), points, faces)
    # links graph: symmetric, no self loops, neighbours are near each other
    rows = np.repeat(np.arange(graph.n_links), np.diff(graph.link_start))
    cols = graph.link_neighbours
    assert np.all(rows != cols)
    edges = set(zip(rows.tolist(), cols.tolist()))
    assert all((b, a) in edges for a, b in edges)
    spacing = (mesh.volume / graph.n_cells) ** (1 / 3)
    assert np.linalg.norm(graph.link_centroid[rows] - graph.link_centroid[cols], axis=1).max() < 3 * spacing
    # every link has neighbours; cells graph lists each interior link under both of its cells
    assert np.all(np.diff(graph.link_start) > 0)
    for c in range(graph.n_cells):
        for link in graph.cell_links[graph.cell_start[c]:graph.cell_start[c + 1]]:
            assert c in graph.link_cells[link]
    # interior links join nearby seeds only
    a, b = graph.link_cells[~graph.exterior].T
    assert np.all(np.linalg.norm(graph.seeds[a] - graph.seeds[b], axis=1) < 4 * spacing)
    # normals point from the first cell to the second
    d = graph.seeds[b] - graph.seeds[a]
    assert np.all(np.einsum("ij,ij->i", d, graph.link_normal[~graph.exterior]) > 0)


def test_seeds_outside_the_mesh_only_get_what_reaches_inside():
    points, faces, _ = _mesh(pv.Box(level=1))
    grid = np.stack(np.meshgrid(*[np.linspace(-1.4, 1.4, 8)] * 3, indexing="ij"), -1).reshape(-1, 3)
    seeds = grid + np.random.default_rng(0).normal(scale=0.01, size=grid.shape)
    graph = build_shards(seeds, points, faces)
    assert graph.volume.sum() == pytest.approx(8.0, rel=1e-9)
    # every seed inside the box keeps a cell; only seeds outside it can lose theirs
    inside = np.flatnonzero(np.abs(seeds).max(axis=1) < 1.0)
    assert np.all(np.isin(inside, graph.cell_seed))
    dropped = np.setdiff1d(np.arange(len(seeds)), graph.cell_seed)
    assert len(dropped) > 0 and np.all(np.abs(seeds[dropped]).max(axis=1) > 1.0)


def test_same_seeds_same_graph_for_any_thread_count():
    points, faces, mesh = _mesh(pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4, u_res=32, v_res=16))
    seeds = _seeds_inside(mesh, 400, seed=7)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = build_shards(seeds, points, faces)
    finally:
        numba.set_num_threads(threads)
    two = build_shards(seeds, points, faces)
    for name in ("volume", "link_cells", "link_area", "link_centroid", "link_normal", "link_start",
                 "link_neighbours", "cell_start", "cell_links"):
        assert np.array_equal(getattr(one, name), getattr(two, name)), name


def test_bad_input_is_named():
    points, faces, _ = _mesh(pv.Box())
    with pytest.raises(ValueError, match="shape"):
        build_shards(np.zeros((4, 2)), points, faces)
    with pytest.raises(ValueError, match="NaN"):
        build_shards(np.array([[0.0, 0.0, np.nan]]), points, faces)
    with pytest.raises(ValueError, match="distinct"):
        build_shards(np.zeros((2, 3)), points, faces)
    with pytest.raises(ValueError, match="closed"):
        build_shards(np.zeros((1, 3)), points, faces[:-1])
    with pytest.raises(ValueError, match="empty"):
        build_shards(np.zeros((1, 3)), np.zeros((0, 3)), np.zeros((0, 3), int))
