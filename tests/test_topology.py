import numpy as np
import pytest
import pyvista as pv
import scipy.sparse as sp
from conftest import icosphere, one_and_all_threads, touching_spheres
from scipy.sparse.csgraph import connected_components

from pverosion.examples import load_cylinder
from pverosion.kernels import (
    boundary_edges,
    boundary_vertices,
    edge_topology,
    laplacian_vectors,
    locality_order,
    one_ring,
    uniform_laplacian,
    vertex_face_incidence,
)
from pverosion.kernels.mesh.topology import (
    halfedge_twins,
    locality_sorted,
    sorted_twins,
    vertex_fan_counts,
)


def test_closed_sphere_edges_follow_euler():
    s = icosphere(1.0, 3)
    f = s.regular_faces
    topo = edge_topology(f, s.n_points)
    assert len(topo.edges) == 3 * len(f) // 2
    assert s.n_points - len(topo.edges) + len(f) == 2
    assert np.all(topo.face_count == 2)
    assert topo.n_boundary_edges == 0
    assert np.all(topo.edges[:, 0] < topo.edges[:, 1])


def test_bunny_has_223_open_edges(bunny):
    f = bunny.regular_faces
    topo = edge_topology(f, bunny.n_points)
    assert topo.n_boundary_edges == 223
    rim = boundary_edges(f, bunny.n_points)
    assert len(rim) == 223
    # each rim edge runs in the direction of the one face that uses it
    face_edges = {(a, b) for tri in f.tolist() for a, b in zip(tri, tri[1:] + tri[:1])}
    assert all((a, b) in face_edges and (b, a) not in face_edges for a, b in rim.tolist())


def test_one_ring_matches_scipy_adjacency():
    s = icosphere(1.0, 2)
    f = s.regular_faces
    indptr, indices = one_ring(f, s.n_points)
    rows = f.ravel()
    cols = np.roll(f, -1, axis=1).ravel()
    ref = sp.coo_matrix((np.ones(2 * len(rows)), (np.r_[rows, cols], np.r_[cols, rows])), shape=(s.n_points,) * 2).tocsr()
    ref.sum_duplicates()
    ref.sort_indices()
    np.testing.assert_array_equal(indptr, ref.indptr)
    np.testing.assert_array_equal(indices, ref.indices)
    assert connected_components(ref)[0] == 1


def test_incidence_lists_every_corner_once():
    s = icosphere(1.0, 2)
    f = s.regular_faces
    indptr, face_ids, corners = vertex_face_incidence(f, s.n_points)
    assert indptr[-1] == f.size
    for v in (0, 5, s.n_points - 1):
        sl = slice(indptr[v], indptr[v + 1])
        np.testing.assert_array_equal(f[face_ids[sl], corners[sl]], v)
        assert set(face_ids[sl]) == set(np.flatnonzero((f == v).any(axis=1)))


def test_cylinder_boundary_is_its_two_rims():
    c = load_cylinder(n_around=32, n_along=10)
    mask = boundary_vertices(c.regular_faces, c.n_points)
    z = c.points[:, 2]
    np.testing.assert_array_equal(mask, np.isclose(np.abs(z), z.max()))


def test_uniform_laplacian_is_mean_of_neighbours_minus_vertex():
    s = icosphere(2.0, 2)
    f = s.regular_faces
    L = uniform_laplacian(f, s.n_points)
    np.testing.assert_allclose(np.asarray(L.sum(axis=1)).ravel(), 0.0, atol=1e-12)
    vec = laplacian_vectors(s.points, f)
    indptr, indices = one_ring(f, s.n_points)
    for i in (0, 17, 100):
        nbrs = indices[indptr[i]:indptr[i + 1]]
        np.testing.assert_allclose(vec[i], s.points[nbrs].mean(axis=0) - s.points[i], atol=1e-12)
    # on a sphere L points inward, along -normal
    radial = np.einsum("ij,ij->i", vec, s.points / 2.0)
    assert np.all(radial < 0)


def test_locality_order_sorts_faces_by_smallest_vertex():
    rng = np.random.default_rng(1)
    s = pv.Icosphere(nsub=3)
    f = s.regular_faces[rng.permutation(s.n_cells)].astype(np.int64)
    order = locality_order(f, s.n_points)
    assert np.array_equal(np.sort(order), np.arange(len(f)))
    lo = f[order].min(axis=1)
    assert np.all(np.diff(lo) >= 0)


def test_locality_sorted_is_the_order_and_the_gathered_faces():
    rng = np.random.default_rng(2)
    s = pv.Icosphere(nsub=3)
    f = s.regular_faces[rng.permutation(s.n_cells)].astype(np.int64)
    order, rows = locality_sorted(f, s.n_points)
    np.testing.assert_array_equal(order, locality_order(f, s.n_points))
    np.testing.assert_array_equal(rows, f[order])


def test_sorted_twins_equal_the_twins_of_the_sorted_faces():
    rng = np.random.default_rng(3)
    s = pv.Icosphere(nsub=2)
    # a scrambled closed surface, random faces with edges used by 3+ faces and duplicate faces, with and
    # without repeated vertices
    rand = rng.integers(0, 12, (300, 3))
    distinct = rand[(rand[:, 0] != rand[:, 1]) & (rand[:, 1] != rand[:, 2]) & (rand[:, 2] != rand[:, 0])]
    for f, n in ((s.regular_faces[rng.permutation(s.n_cells)].astype(np.int64), s.n_points),
                 (rand[:150], 12), (distinct, 12), (np.vstack([distinct[:40], distinct[:40, ::-1]]), 12)):
        order, rows, partner, others = sorted_twins(f, n)
        np.testing.assert_array_equal(order, locality_order(f, n))
        np.testing.assert_array_equal(rows, f[order])
        expected = halfedge_twins(rows, n)
        np.testing.assert_array_equal(partner, expected[0])
        np.testing.assert_array_equal(others, expected[1])
        via_incidence = halfedge_twins(rows, n, vertex_face_incidence(rows, n))
        np.testing.assert_array_equal(via_incidence[0], expected[0])
        np.testing.assert_array_equal(via_incidence[1], expected[1])


def test_twins_of_a_closed_surface_pair_up_opposite_half_edges():
    s = pv.Icosphere(nsub=2)
    f = s.regular_faces.astype(np.int64)
    partner, others = halfedge_twins(f, s.n_points)
    assert np.all(others == 1)
    h = np.arange(3 * len(f))
    np.testing.assert_array_equal(partner[partner], h)  # an involution
    start, end = f.ravel(), np.roll(f, -1, axis=1).ravel()
    np.testing.assert_array_equal(start[partner], end)  # the twin runs the other way
    np.testing.assert_array_equal(end[partner], start)


def test_sorted_twins_split_over_threads_equal_one_pass():
    rng = np.random.default_rng(5)
    s = pv.Icosphere(nsub=5)  # 20480 faces: several parts of the counting sort
    f = s.regular_faces[rng.permutation(s.n_cells)].astype(np.int64)
    one, many = one_and_all_threads(lambda: sorted_twins(f, s.n_points))
    for a, b in zip(one, many):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(many[0], locality_order(f, s.n_points))
    expected = halfedge_twins(many[1], s.n_points, vertex_face_incidence(many[1], s.n_points))
    np.testing.assert_array_equal(many[2], expected[0])
    np.testing.assert_array_equal(many[3], expected[1])


def _fans_by_brute_force(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Fans per vertex (V,): the faces around each vertex, linked when two share an edge at it, counted as graph
    components."""
    counts = np.zeros(n_vertices, np.int64)
    for v in range(n_vertices):
        around = np.flatnonzero((faces == v).any(axis=1))
        shared = np.array([[len(set(faces[f]) & set(faces[g]) - {v}) > 0 for g in around] for f in around])
        if len(around):
            counts[v] = connected_components(sp.csr_matrix(shared.reshape(len(around), len(around))))[0]
    return counts


def _tetrahedra_at_a_vertex(n: int) -> tuple[np.ndarray, int]:
    """Faces (4n, 3) of ``n`` closed tetrahedra that share only vertex 0, and the number of vertices."""
    tet = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return np.vstack([np.where(tet > 0, tet + 3 * k, 0) for k in range(n)]), 1 + 3 * n


def _fan_meshes() -> dict[str, tuple[np.ndarray, int]]:
    """Faces (F, 3) and number of vertices of meshes with and without non-manifold vertices."""
    sphere = icosphere(1.0, 2)
    f = sphere.regular_faces.astype(np.int64)
    cylinder = load_cylinder(n_around=16, n_along=6)
    plane = pv.Plane(i_resolution=6, j_resolution=6).triangulate()
    touching, touch = touching_spheres()
    t = touching.regular_faces.astype(np.int64)
    flipped = f.copy()
    flipped[::3] = flipped[::3, ::-1]  # an inconsistent winding joins the fans all the same
    return {
        "icosphere": (f, sphere.n_points),
        "icosphere and an unused vertex": (f, sphere.n_points + 1),
        "inconsistent winding": (flipped, sphere.n_points),
        "cylinder (two rims)": (cylinder.regular_faces, cylinder.n_points),
        "plane with a hole": (np.delete(plane.regular_faces, [30, 31], axis=0), plane.n_points),
        "touching spheres": (t, touching.n_points),
        "touching spheres, shuffled": (t[np.random.default_rng(0).permutation(len(t))], touching.n_points),
        "touching spheres, one open": (np.delete(t, np.flatnonzero((t == touch).any(axis=1))[0], axis=0),
                                       touching.n_points),
        "sheets meeting at a corner": (np.array([[0, 1, 2], [0, 3, 4], [0, 4, 5]]), 6),
        "three tetrahedra at a vertex": _tetrahedra_at_a_vertex(3),
        "edge of three faces": (np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]), 5),
    }


@pytest.mark.parametrize("name", list(_fan_meshes()))
def test_vertex_fan_counts_match_a_brute_force_count(name):
    faces, n = _fan_meshes()[name]
    kept = faces.copy()
    fans = vertex_fan_counts(faces, n)
    np.testing.assert_array_equal(fans, _fans_by_brute_force(faces, n))
    np.testing.assert_array_equal(vertex_fan_counts(faces, n, topology=edge_topology(faces, n)), fans)
    np.testing.assert_array_equal(faces, kept)


def test_boundary_vertices_have_one_open_fan_and_touching_surfaces_two():
    for name in ("cylinder (two rims)", "plane with a hole"):
        faces, n = _fan_meshes()[name]
        rim = boundary_vertices(faces, n)
        assert rim.sum() > 0
        np.testing.assert_array_equal(vertex_fan_counts(faces, n), np.ones(n))
    touching, touch = touching_spheres()
    expected = np.ones(touching.n_points, np.int64)
    expected[touch] = 2
    np.testing.assert_array_equal(vertex_fan_counts(touching.regular_faces, touching.n_points), expected)
    faces, n = _tetrahedra_at_a_vertex(3)
    assert vertex_fan_counts(faces, n).tolist() == [3] + [1] * (n - 1)
