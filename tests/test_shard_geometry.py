"""Link polygons of shard graphs, the surface of a union of cells and the closed surface of every cell."""

import numba
import numpy as np
import pytest
import pyvista as pv
from scipy.spatial import ConvexHull

from pverosion.filters.base import polydata_triangles
from pverosion.kernels.shards import geometry as shard_geometry
from pverosion.kernels.shards.geometry import LinkMesh, cell_surfaces, cells_boundary, link_polygons
from pverosion.kernels.shards.graph import build_shards


def _l_block():
    """An L-shaped block: the outer surface of three unit cubes, closed and outward."""
    grid = pv.ImageData(dimensions=(3, 2, 3))  # 2 x 1 x 2 cells
    grid.cell_data["keep"] = np.array([1, 1, 1, 0])  # cells (x, z): (0, 0), (1, 0), (0, 1); x-fastest
    block = grid.threshold(0.5, scalars="keep").extract_surface(algorithm=None).triangulate()
    return block.subdivide(2, subfilter="linear")


MESHES = {
    "box": lambda: pv.Box(level=2),
    "sphere": lambda: pv.Sphere(theta_resolution=24, phi_resolution=24),
    "torus": lambda: pv.ParametricTorus(),
    "l_block": _l_block,
}


def _seeds_inside(mesh, n, seed):
    rng = np.random.default_rng(seed)
    lo, hi = np.array(mesh.bounds[::2]), np.array(mesh.bounds[1::2])
    cand = pv.PolyData(rng.uniform(lo, hi, (10 * n, 3)))
    inside = cand.select_interior_points(mesh)["selected_points"].astype(bool)
    return np.asarray(cand.points)[inside][:n]


def _shards(mesh, seeds):
    points, faces = polydata_triangles(mesh)
    return build_shards(seeds, points, faces)


@pytest.fixture(scope="module", params=list(MESHES))
def case(request):
    mesh = MESHES[request.param]().triangulate().clean()
    graph = _shards(mesh, _seeds_inside(mesh, 300, seed=1))
    return mesh, graph, link_polygons(graph)


def _signed_areas(points, triangles, normals):
    """Areas of the triangles projected on ``normals`` (one per triangle): negative when wound against them."""
    p = points[triangles]
    return 0.5 * np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), normals)


def _volume(points, triangles):
    """Enclosed volume by the divergence theorem."""
    p = points[triangles]
    return np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0


def _unbalanced_edges(triangles):
    """Directed edges a->b used a different number of times than b->a (0 for a closed, oriented surface)."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]).astype(np.int64)
    n = int(triangles.max()) + 1 if len(triangles) else 1
    forward, f_count = np.unique(edges[:, 0] * n + edges[:, 1], return_counts=True)
    backward, b_count = np.unique(edges[:, 1] * n + edges[:, 0], return_counts=True)
    both, f_pos, b_pos = np.intersect1d(forward, backward, return_indices=True)
    return (len(forward) - len(both)) + (len(backward) - len(both)) + int(np.count_nonzero(f_count[f_pos] != b_count[b_pos]))


def _boundary_loops(triangles):
    """Closed boundary loops (edges used once) of a triangulated polygon, as lists of vertex ids."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]).tolist()
    present = set(map(tuple, edges))
    after = {a: b for a, b in present if (b, a) not in present}
    loops, seen = [], set()
    for start in after:
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen:
            seen.add(v)
            loop.append(v)
            v = after[v]
        loops.append(loop)
    return loops


def _plane_coordinates(points, normal):
    e1 = np.cross(normal, np.eye(3)[np.argmin(np.abs(normal))])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return np.stack([points @ e1, points @ e2], axis=1)


def _shoelace(xy):
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# --- link polygons ----------------------------------------------------------------------------------------


def test_link_faces_have_the_graph_area_centroid_and_normal(case):
    mesh, graph, links = case
    assert isinstance(links, LinkMesh) and links.issues == 0
    assert links.points.dtype == np.float64 and links.triangles.dtype == np.int64
    assert np.all(np.diff(links.triangle_link) >= 0)
    assert np.array_equal(np.diff(links.link_start), np.bincount(links.triangle_link, minlength=graph.n_links))
    assert np.all(np.diff(links.link_start) > 0), "every link has triangles"
    outside = graph.exterior[links.triangle_link]
    p = links.points[links.triangles]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    # interior links are wound along link_normal, the pieces of exterior ones along the mesh's outward normal
    area = _signed_areas(links.points, links.triangles, graph.link_normal[links.triangle_link])
    assert np.all(area[~outside] >= -1e-9 * graph.link_area[links.triangle_link[~outside]])
    centre = p.mean(axis=1)
    nearest = mesh.find_closest_cell(centre[outside])
    facing = np.einsum("ij,ij->i", cross[outside], np.asarray(mesh.face_normals)[nearest])
    assert np.all(facing >= -1e-9 * graph.link_area[links.triangle_link[outside]])
    area[outside] = 0.5 * np.linalg.norm(cross[outside], axis=1)
    per_link = np.bincount(links.triangle_link, area, minlength=graph.n_links)
    scale = mesh.length**2
    np.testing.assert_allclose(per_link, graph.link_area, rtol=1e-9, atol=1e-15 * scale)
    moment = np.stack([np.bincount(links.triangle_link, area * centre[:, k], minlength=graph.n_links)
                       for k in range(3)], axis=1)
    np.testing.assert_allclose(moment / per_link[:, None], graph.link_centroid, rtol=0, atol=1e-9 * mesh.length)
    # an exterior link's area vector points along its normal
    vector = np.stack([np.bincount(links.triangle_link[outside], 0.5 * cross[outside, k], minlength=graph.n_links)
                       for k in range(3)], axis=1)[graph.exterior]
    np.testing.assert_allclose(vector / np.linalg.norm(vector, axis=1)[:, None], graph.link_normal[graph.exterior],
                               atol=1e-9)
    # the faces lie in their planes: interior links on the bisector, exterior ones on the mesh surface
    inner = links.triangles[~outside, 0]
    offset = np.einsum("ij,ij->i", links.points[inner] - graph.link_centroid[links.triangle_link[~outside]],
                       graph.link_normal[links.triangle_link[~outside]])
    assert np.abs(offset).max() < 1e-9 * mesh.length
    on_surface = pv.PolyData(links.points[np.unique(links.triangles[outside])]).compute_implicit_distance(mesh)
    assert np.abs(on_surface["implicit_distance"]).max() < 1e-9 * mesh.length


def test_torus_faces_cut_into_non_convex_pieces_still_match():
    mesh = pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4, u_res=48, v_res=24).triangulate().clean()
    graph = _shards(mesh, _seeds_inside(mesh, 30, seed=5))
    links = link_polygons(graph)
    non_convex = 0
    for k in np.flatnonzero(~graph.exterior):
        tri = links.triangles[links.link_start[k]:links.link_start[k + 1]]
        used = np.unique(tri)
        xy = _plane_coordinates(links.points[used], graph.link_normal[k])
        non_convex += ConvexHull(xy).volume > (1 + 1e-6) * graph.link_area[k]
    assert non_convex >= 3
    inner = ~graph.exterior[links.triangle_link]
    area = _signed_areas(links.points, links.triangles[inner], graph.link_normal[links.triangle_link[inner]])
    assert area.min() >= -1e-12
    per_link = np.bincount(links.triangle_link[inner], area, minlength=graph.n_links)
    np.testing.assert_allclose(per_link[~graph.exterior], graph.link_area[~graph.exterior], rtol=1e-9)


@pytest.mark.parametrize("axis", [0, 2])
def test_torus_section_with_a_hole_or_in_two_pieces(axis):
    # two seeds in the hole of the torus: their bisector plane meets the ring in an annulus (z = 0) or, across
    # the hole (x = 0), in two separate discs
    mesh = pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4, u_res=48, v_res=24).triangulate().clean()
    seeds = np.zeros((2, 3))
    seeds[:, axis] = [0.1, -0.1]
    graph = _shards(mesh, seeds)
    links = link_polygons(graph)
    (k,) = np.flatnonzero(~graph.exterior)
    tri = links.triangles[links.link_start[k]:links.link_start[k + 1]]
    loops = _boundary_loops(tri)
    assert len(loops) == 2
    signs = sorted(np.sign(_shoelace(_plane_coordinates(links.points[loop], graph.link_normal[k]))) for loop in loops)
    assert signs == ([-1.0, 1.0] if axis == 2 else [1.0, 1.0])  # a hole runs the other way round
    # independent of the shards: the closed lines of VTK's section of the mesh by the same plane
    normal = np.eye(3)[axis]
    section = mesh.slice(normal=normal, origin=(0, 0, 0)).strip(join=True, max_length=100000)
    section_points, lines, pos, areas = np.asarray(section.points, dtype=float), section.lines, 0, []
    while pos < len(lines):
        ids = lines[pos + 1:pos + 1 + lines[pos]]
        pos += 1 + lines[pos]
        areas.append(abs(_shoelace(_plane_coordinates(section_points[ids], normal))))
    assert len(areas) == 2
    expected = max(areas) - min(areas) if axis == 2 else sum(areas)
    area = _signed_areas(links.points, tri, np.broadcast_to(graph.link_normal[k], tri.shape)).sum()
    assert area == pytest.approx(graph.link_area[k], rel=1e-12)
    assert area == pytest.approx(expected, rel=1e-6)


def test_same_polygons_for_any_thread_count():
    mesh = pv.ParametricTorus(ringradius=1.0, crosssectionradius=0.4, u_res=32, v_res=16).triangulate().clean()
    graph = _shards(mesh, _seeds_inside(mesh, 1200, seed=7))  # several batches
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = link_polygons(graph)
    finally:
        numba.set_num_threads(threads)
    two = link_polygons(graph)
    for name in ("points", "triangles", "triangle_link", "link_start"):
        assert np.array_equal(getattr(one, name), getattr(two, name)), name


def test_cells_that_overflow_their_slots_are_redone_with_more_room(monkeypatch):
    mesh = pv.Sphere(theta_resolution=24, phi_resolution=24).triangulate().clean()
    graph = _shards(mesh, _seeds_inside(mesh, 200, seed=4))
    roomy = link_polygons(graph)
    monkeypatch.setattr(shard_geometry, "_CAP_POINTS", 8)
    monkeypatch.setattr(shard_geometry, "_CAP_TRIANGLES", 8)
    tight = link_polygons(graph)
    assert len(tight.triangles) == len(roomy.triangles) and len(tight.points) == len(roomy.points)
    assert np.array_equal(tight.link_start, roomy.link_start)
    for links in (roomy, tight):
        p = links.points[links.triangles]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        np.testing.assert_allclose(np.bincount(links.triangle_link, area, minlength=graph.n_links), graph.link_area,
                                   rtol=1e-9)


# --- surfaces ---------------------------------------------------------------------------------------------


def test_boundary_of_all_cells_is_the_closed_mesh(case):
    mesh, graph, links = case
    points, triangles, triangle_link, flipped = cells_boundary(graph, np.ones(graph.n_cells, bool), links=links)
    assert np.all(graph.exterior[triangle_link]) and not flipped.any()
    assert _unbalanced_edges(triangles) == 0
    assert len(np.unique(triangles)) == len(points)
    volume = _volume(points, triangles)
    assert volume == pytest.approx(mesh.volume, rel=1e-9)
    assert volume == pytest.approx(graph.volume.sum(), rel=1e-9)


def test_boundary_of_some_cells_encloses_their_volume(case):
    _, graph, links = case
    rng = np.random.default_rng(2)
    for fraction in (0.5, 0.1):
        mask = rng.random(graph.n_cells) < fraction
        points, triangles, triangle_link, flipped = cells_boundary(graph, mask, links=links)
        assert _unbalanced_edges(triangles) == 0
        assert _volume(points, triangles) == pytest.approx(graph.volume[mask].sum(), rel=1e-9)
        # one side in the union, the other not; flipped where the union is on the link's second side
        first, second = graph.link_cells[triangle_link].T
        in_second = np.where(second >= 0, mask[np.maximum(second, 0)], False)
        assert np.array_equal(mask[first] != in_second, np.ones(len(triangle_link), bool))
        assert np.array_equal(flipped, in_second)
        # the complement shares the interior part of the surface, wound the other way
        _, _, other_link, other_flipped = cells_boundary(graph, ~mask, links=links)
        inner = ~graph.exterior
        shared = np.unique(triangle_link[inner[triangle_link]])
        assert np.array_equal(shared, np.unique(other_link[inner[other_link]]))
        side, other_side = np.zeros(graph.n_links, bool), np.zeros(graph.n_links, bool)
        side[triangle_link], other_side[other_link] = flipped, other_flipped
        assert np.all(side[shared] != other_side[shared])
    points, triangles, triangle_link, flipped = cells_boundary(graph, np.zeros(graph.n_cells, bool), links=links)
    assert points.shape == (0, 3) and triangles.shape == (0, 3) and len(triangle_link) == len(flipped) == 0


def test_every_cell_surface_is_closed_around_its_volume(case):
    _, graph, links = case
    cells = np.random.default_rng(3).permutation(graph.n_cells)[:120]
    points, triangles, triangle_cell = cell_surfaces(graph, cells, links=links)
    assert points.dtype == np.float64 and triangles.dtype == np.int64 and triangle_cell.dtype == np.int64
    # grouped in the order asked for
    firsts = triangle_cell[np.r_[0, np.flatnonzero(np.diff(triangle_cell)) + 1]]
    assert np.array_equal(firsts, cells)
    owners = np.full(len(points), -1)
    for c in cells:
        tri = triangles[triangle_cell == c]
        assert _unbalanced_edges(tri) == 0
        assert _volume(points, tri) == pytest.approx(graph.volume[c], rel=1e-9)
        assert np.all(owners[tri] == -1), "every cell has points of its own"
        owners[tri] = c
    assert np.all(owners >= 0)


# --- input checks -----------------------------------------------------------------------------------------


def test_bad_input_is_named():
    mesh = pv.Box(level=1).triangulate().clean()
    graph = _shards(mesh, np.random.default_rng(0).uniform(-0.9, 0.9, (20, 3)))
    links = link_polygons(graph)
    n = graph.n_cells
    with pytest.raises(ValueError, match="mask"):
        cells_boundary(graph, np.ones(n - 1, bool), links=links)
    with pytest.raises(ValueError, match="bool"):
        cells_boundary(graph, np.ones(n, int), links=links)
    with pytest.raises(ValueError, match="range|\\["):
        cell_surfaces(graph, [0, n], links=links)
    with pytest.raises(ValueError, match="range|\\["):
        cell_surfaces(graph, [-1], links=links)
    with pytest.raises(ValueError, match="distinct"):
        cell_surfaces(graph, [1, 1], links=links)
    with pytest.raises(ValueError, match="indices"):
        cell_surfaces(graph, [0.5], links=links)
    with pytest.raises(ValueError, match="indices"):
        cell_surfaces(graph, [[0, 1]], links=links)
    other = _shards(mesh, np.random.default_rng(1).uniform(-0.9, 0.9, (30, 3)))
    with pytest.raises(ValueError, match="LinkMesh"):
        cells_boundary(other, np.ones(other.n_cells, bool), links=links)
    with pytest.raises(ValueError, match="tolerance"):
        link_polygons(graph, tolerance=0.0)
    # without links= they are computed
    points, triangles, _ = cell_surfaces(graph, [0])
    assert _volume(points, triangles) == pytest.approx(graph.volume[0], rel=1e-9)


def test_polygons_of_a_model_far_from_the_origin_match_its_links():
    """Points computed from the cells' planes carry the rounding of their coordinates: a 20 cm torus 100 km from
    the origin is triangulated as at the origin, every link's polygons summing to its area (the merge tolerance
    had been 1e-9 of the box alone, finer than that rounding, and loops stayed open)."""
    mesh = pv.ParametricTorus(ringradius=0.1, crosssectionradius=0.04, u_res=32, v_res=16).triangulate().clean()
    seeds = _seeds_inside(mesh, 150, seed=3)
    shift = np.full(3, 1e5)
    points, faces = polydata_triangles(mesh)
    for offset in (np.zeros(3), shift):
        graph = build_shards(seeds + offset, np.asarray(points, np.float64) + offset, faces)
        links = link_polygons(graph)
        p = links.points - offset
        t = links.triangles
        area = 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
        per_link = np.bincount(links.triangle_link, area, minlength=graph.n_links)
        assert links.issues == 0
        np.testing.assert_allclose(per_link, graph.link_area, rtol=0.0, atol=1e-6 * graph.link_area.max())
