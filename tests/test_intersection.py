import numpy as np
import pytest
from conftest import icosphere, touching_spheres

from pverosion.examples import load_torus
from pverosion.kernels.exact.intersection import (
    intersecting_faces,
    intersecting_pairs,
    spatial_order,
    triangles_intersect,
)

T = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


@pytest.mark.parametrize(
    ("other", "expected"),
    [
        ([[0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [0.3, 0.9, 0.0]], True),  # pierces T
        ([[0, 0, 1.0], [1, 0, 1.0], [0, 1, 1.0]], False),  # parallel, above
        ([[0.2, 0.2, 0.0], [2.0, 0.2, 0.0], [0.2, 2.0, 0.0]], True),  # coplanar, overlapping
        ([[2.0, 2.0, 0.0], [3.0, 2.0, 0.0], [2.0, 3.0, 0.0]], False),  # coplanar, apart
        ([[1.0, 0.0, 0.0], [2.0, 0.0, 1.0], [2.0, 1.0, -1.0]], True),  # touches T's corner
        ([[0.6, 0.6, -1.0], [0.6, 0.6, 1.0], [2.0, 2.0, 0.0]], False),  # passes beside the hypotenuse
    ],
)
def test_triangle_pairs(other, expected):
    assert triangles_intersect(T, np.array(other, dtype=float)) is expected
    assert triangles_intersect(np.array(other, dtype=float), T) is expected


def test_grid_agrees_with_brute_force_on_random_soups():
    rng = np.random.default_rng(7)
    for _ in range(3):
        n = 150
        centre = rng.random((n, 1, 3))
        points = (centre + 0.1 * rng.standard_normal((n, 3, 3))).reshape(-1, 3)
        faces = np.arange(3 * n).reshape(-1, 3)
        expected = np.zeros(n, bool)
        pairs = set()
        for i in range(n):
            for j in range(i + 1, n):
                if triangles_intersect(points[faces[i]], points[faces[j]]):
                    expected[i] = expected[j] = True
                    pairs.add((i, j))
        assert expected.any()
        assert np.array_equal(intersecting_faces(points, faces), expected)
        assert {tuple(p) for p in intersecting_pairs(points, faces)} == pairs


def test_faces_touching_where_distinct_vertices_coincide_meet_apart_and_are_adjacent_when_shared():
    above = [[0.0, 0.0, 0.0], [-1.0, 0.0, 1.0], [0.0, -1.0, 1.0]]  # its own corner on T's corner (0, 0, 0)
    piercing = [[0.2, 0.2, -1.0], [0.2, 0.2, 1.0], [0.3, 0.9, 0.0]]  # through T, away from that corner
    points = np.vstack([T, above, piercing])
    faces = np.arange(9).reshape(3, 3)
    assert intersecting_faces(points, faces).tolist() == [True, True, True]
    assert intersecting_faces(points, faces, coincident="shared").tolist() == [True, False, True]
    assert intersecting_faces(points, faces[:2], coincident="shared").tolist() == [False, False]
    only_above = np.array([False, True, False])
    assert intersecting_faces(points, faces, coincident="shared", query=only_above).tolist() == [False] * 3
    assert intersecting_faces(points, faces, query=only_above).tolist() == [True, True, False]
    with pytest.raises(ValueError, match="coincident must be"):
        intersecting_faces(points, faces, coincident="joined")


def test_a_repaired_pinch_touches_only_at_coincident_vertices():
    """Two spheres sharing a vertex: the repair splits it into two vertices at one position, where the faces of
    both still touch. That is what "shared" allows and "apart" counts."""
    import pverosion

    pinched, touch = touching_spheres()
    repaired = pverosion.repair(pinched)
    points, faces = np.asarray(repaired.points, dtype=float), repaired.regular_faces
    assert not intersecting_faces(points, faces, coincident="shared").any()
    touching = intersecting_faces(points, faces)
    at = np.flatnonzero((points == np.asarray(pinched.points[touch], dtype=float)).all(axis=1))
    assert len(at) == 2  # the split vertex
    assert touching.any() and np.isin(faces[touching], at).any(axis=1).all()  # every contact is at that point


def test_clean_closed_meshes_have_no_intersections():
    s = icosphere(1.0, 5)
    assert not intersecting_faces(s.points, s.regular_faces).any()
    torus = load_torus(n_major=120, n_minor=60)
    assert not intersecting_faces(torus.points, torus.regular_faces).any()


def test_pushed_vertex_is_detected_and_order_only_affects_speed():
    s = icosphere(1.0, 3)
    points = np.array(s.points)
    faces = s.regular_faces
    before = points.copy()
    points[0] = -1.5 * points[0]  # through the sphere: its fan now crosses the far side
    hits = intersecting_faces(points, faces)
    fan = (faces == 0).any(axis=1)
    assert hits[fan].any() and hits[~fan].any()
    stale = spatial_order(before, faces)
    assert np.array_equal(intersecting_faces(points, faces, order=stale), hits)
    assert np.array_equal(intersecting_faces(points, faces, query=fan), hits)
    assert not intersecting_faces(points, faces, query=~fan & ~hits).any()


def test_any_face_order_and_a_query_of_every_face_give_the_whole_check():
    s = icosphere(1.0, 3)
    points = np.array(s.points)
    faces = s.regular_faces
    points[0] = -1.5 * points[0]
    hits = intersecting_faces(points, faces)
    assert hits.any()
    rng = np.random.default_rng(3)
    for _ in range(3):
        order = rng.permutation(len(faces))
        assert np.array_equal(intersecting_faces(points, faces, order=order), hits)
    assert np.array_equal(intersecting_faces(points, faces, query=np.ones(len(faces), bool)), hits)


@pytest.mark.parametrize("bad", [-1, 10**6])
def test_order_with_an_index_out_of_range_is_refused(bad):
    s = icosphere(1.0, 2)
    order = np.arange(len(s.regular_faces))
    order[5] = bad
    with pytest.raises(ValueError, match="order"):
        intersecting_faces(s.points, s.regular_faces, order=order)


def test_a_local_query_finds_exactly_the_pairs_with_its_faces():
    # two overlapping spheres: intersecting pairs all along a circle
    a = icosphere(1.0, 3)
    b = icosphere(1.0, 3).translate((1.2, 0.1, 0.05))
    points = np.vstack([a.points, b.points])
    faces = np.vstack([a.regular_faces, b.regular_faces + a.n_points])
    pairs = intersecting_pairs(points, faces)
    assert len(pairs)
    centres = points[faces].mean(axis=1)
    for centre in ((0.6, 0.8, 0.0), (0.6, 0.0, 0.8), (-1.0, 0.0, 0.0), (2.2, 0.1, 0.0), (0.6, -0.5, -0.6)):
        query = np.linalg.norm(centres - centre, axis=1) < 0.5
        expected = np.zeros(len(faces), bool)
        for f, g in pairs:
            if query[f] or query[g]:
                expected[[f, g]] = True
        assert np.array_equal(intersecting_faces(points, faces, query=query), expected)
    assert not intersecting_faces(points, faces, query=np.zeros(len(faces), bool)).any()


def test_bunny_scan_does_not_self_intersect(bunny):
    assert not intersecting_faces(bunny.points, bunny.regular_faces).any()


def test_bad_input():
    with pytest.raises(ValueError, match="shape"):
        triangles_intersect(np.zeros((4, 3)), T)
    s = icosphere(1.0, 2)
    with pytest.raises(ValueError, match="query must have shape"):
        intersecting_faces(s.points, s.regular_faces, query=np.ones(3, bool))
