"""Intersection curves: exact classification, points on both faces, closed loops, the thesis' cuboid scene."""

from fractions import Fraction

import numpy as np
import pytest
import pyvista as pv

from pverosion.kernels import InvalidMeshError
from pverosion.kernels.exact.intersection import candidate_pairs, triangles_intersect
from pverosion.kernels.exact.intersection_curves import (
    EDGE_EDGE,
    EDGE_FACE,
    VERTEX,
    canonical_vertices,
    intersection_curves,
    trace_polylines,
)


def _two(a: pv.PolyData, b: pv.PolyData):
    points = np.vstack([a.points, b.points]).astype(float)
    faces = np.vstack([a.regular_faces, b.regular_faces + a.n_points])
    return points, faces, np.repeat([0, 1], [a.n_cells, b.n_cells])


def rotated_cuboids(n: int, degrees: float = 1.0):
    """The thesis' cuboids 2:2:2 and 4:1:1 (n cells per side), rotated together about x: the intersection
    runs along mesh edges."""
    a = pv.Box(bounds=(-1, 1, -1, 1, -1, 1), level=n - 1).triangulate()
    b = pv.Box(bounds=(-2, 2, -0.5, 0.5, -0.5, 0.5), level=n - 1).triangulate()
    rot = pv.transformations.axis_angle_rotation((1, 0, 0), degrees)[:3, :3]
    a.points = np.asarray(a.points, float) @ rot.T
    b.points = np.asarray(b.points, float) @ rot.T
    return _two(a, b)


def _distance_to_triangle(p, a, b, c):
    """Distance from p to triangle abc (brute force on a fine barycentric sampling is too coarse: exact)."""
    ab, ac, ap = b - a, c - a, p - a
    n = np.cross(ab, ac)
    n = n / np.linalg.norm(n)
    q = p - np.dot(ap, n) * n
    best = abs(np.dot(ap, n))
    inside = all(np.dot(np.cross(v1 - v0, q - v0), n) >= -1e-15 for v0, v1 in ((a, b), (b, c), (c, a)))
    if inside:
        return best
    dists = []
    for v0, v1 in ((a, b), (b, c), (c, a)):
        t = np.clip(np.dot(p - v0, v1 - v0) / np.dot(v1 - v0, v1 - v0), 0.0, 1.0)
        dists.append(np.linalg.norm(p - (v0 + t * (v1 - v0))))
    return min(dists)


def test_two_spheres_meet_in_one_closed_loop_on_both_faces():
    a = pv.Icosphere(radius=1.0, nsub=3)
    b = pv.Icosphere(radius=0.7, nsub=2).translate((0.9, 0.1, 0.05))
    points, faces, group = _two(a, b)
    curves = intersection_curves(points, faces, group=group)
    loops = trace_polylines(curves)
    assert len(loops) == 1 and loops[0][0] == loops[0][-1]
    assert len(loops[0]) - 1 == len(np.unique(np.sort(curves.segments, axis=1), axis=0))
    # every segment end lies on both faces of its pair
    for (f, g), (p, q) in zip(curves.pairs, curves.segments):
        for point in curves.points[[p, q]]:
            for face in (f, g):
                assert _distance_to_triangle(point, *points[faces[face]]) < 1e-12
    assert curves.case_table["impossible"] == 0
    # the pairs with a segment are the pairs that intersect (a float test agrees on this generic scene)
    candidates = candidate_pairs(points, faces, group=group)
    hit = {(int(f), int(g)) for f, g in candidates if triangles_intersect(points[faces[f]], points[faces[g]])}
    assert {tuple(map(int, pair)) for pair in curves.pairs} == hit


@pytest.mark.parametrize("n", [4, 8, 16, 32])
def test_rotated_cuboids_trace_two_exact_squares(n):
    points, faces, group = rotated_cuboids(n)
    curves = intersection_curves(points, faces, group=group)
    table = curves.case_table
    # the intersection runs along edges: exact predicates give only the cases 011, 111 and 112 (thesis §10.3)
    assert table["impossible"] == 0 and table["022"] == 0 and table["valid"] > 0
    assert table["011"] + table["111"] + table["112"] == table["valid"]
    loops = trace_polylines(curves)
    assert len(loops) == 2 and all(line[0] == line[-1] for line in loops)
    rot = pv.transformations.axis_angle_rotation((1, 0, 0), 1.0)[:3, :3]
    local = curves.points @ rot  # back to the cuboids' frame
    for line in loops:
        square = local[line]
        assert np.allclose(np.abs(square[:, 0]), 1.0, atol=1e-15)  # on a face of the 2:2:2 cuboid
        assert np.allclose(np.abs(square[:, 1:]).max(axis=1), 0.5, atol=1e-12)  # around the 4:1:1 cuboid
        assert len(line) - 1 == 4 * n  # one segment per edge of the 4:1:1 cuboid around the square
    # the boundary runs along edges: all its points are input vertices
    assert np.all(curves.point_keys[:, 0] == VERTEX)


def test_point_keys_name_vertices_edges_and_faces():
    # a triangle pierced by an edge through its interior, an edge crossing its edge, and a vertex on it
    points = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0],  # T in z = 0
                       [1, 1, -1], [1, 1, 1], [3, 3, 1],  # R: its edge 0-1 pierces T's interior
                       ], dtype=float)
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    curves = intersection_curves(points, faces)
    assert len(curves.segments) == 1
    kinds = sorted(curves.point_keys[:, 0].tolist())
    # R's edge 0-1 through T's interior; R's edge 2-0 crossing T's hypotenuse exactly at (2, 2, 0)
    assert kinds == [EDGE_FACE, EDGE_EDGE]
    assert {tuple(np.round(p, 12)) for p in curves.points} == {(1.0, 1.0, 0.0), (2.0, 2.0, 0.0)}
    points[5] = [3.0, 3.0, 3.0]  # now R's edge 2-0 crosses T's interior at (1.5, 1.5, 0)
    curves = intersection_curves(points, faces)
    assert sorted(curves.point_keys[:, 0].tolist()) == [EDGE_FACE, EDGE_FACE]
    assert {tuple(np.round(p, 12)) for p in curves.points} == {(1.0, 1.0, 0.0), (1.5, 1.5, 0.0)}
    # a vertex of R exactly on T's edge, and R's edge crossing T's edge: vertex and edge-edge points
    points = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [2, 0, 0], [2, 1, 1], [2, 1, -1]], dtype=float)
    curves = intersection_curves(points, [[0, 1, 2], [3, 4, 5]])
    # R's vertex 3 on T's edge 0-1, R's edge 4-5 through T's interior
    assert sorted(curves.point_keys[:, 0].tolist()) == [VERTEX, EDGE_FACE]
    assert curves.locations[0, :, 0].tolist() in ([3, 6], [6, 3])
    points[3:] = [[1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 0.0, 1.0]]  # R's edge 3-4 lies in T's plane
    curves = intersection_curves(points, [[0, 1, 2], [3, 4, 5]])
    # from R's vertex 3 inside T to where R's edge 3-4 crosses T's edge 0-1
    assert sorted(curves.point_keys[:, 0].tolist()) == [VERTEX, EDGE_EDGE]
    assert {tuple(np.round(p, 12)) for p in curves.points} == {(1.0, 1.0, 0.0), (1.0, 0.0, 0.0)}
    assert curves.case_table["impossible"] == 0


def test_exact_plane_sides_against_fractions():
    # vertices placed exactly on, or one ulp off, another face's plane are classified exactly
    rng = np.random.default_rng(1)
    for _ in range(200):
        tri = rng.random((3, 3))
        w = rng.random(3)
        w /= w.sum()
        on_plane = (w[:, None] * tri).sum(axis=0)
        wiggle = np.nextafter(on_plane, on_plane + rng.choice([-1.0, 1.0], 3))
        for probe in (on_plane, wiggle):
            other = np.array([probe, probe + [0.5, 0.1, 0.7], probe + [-0.3, 0.6, -0.8]])
            points = np.vstack([tri, other])
            curves = intersection_curves(points, [[0, 1, 2], [3, 4, 5]])
            exact = [[Fraction(x) for x in row] for row in points]
            a, b, c, d = (exact[k] for k in (0, 1, 2, 3))
            ab = [b[i] - a[i] for i in range(3)]
            ac = [c[i] - a[i] for i in range(3)]
            n = [ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]]
            side = sum(n[i] * (d[i] - a[i]) for i in range(3))
            if side == 0:  # the vertex is a segment end or a touching point, named as the vertex itself
                assert curves.touching + len(curves.segments) >= 1
                if len(curves.segments):
                    assert any(k[0] == VERTEX and k[1] == 3 for k in curves.point_keys)
            assert curves.case_table["impossible"] == 0


def crossed_torus(n_around: int = 160, n_tube: int = 16, *, tube: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """A torus bent into a figure eight whose two halves pass through each other at the crossing (their centre
    lines 0.24 apart there, the tube 0.3 wide): a closed, immersed, self-intersecting tube with outward faces."""
    u = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    centre = np.stack([1.2 * np.sin(u), 0.9 * np.sin(2.0 * u), 0.12 * np.cos(u)], axis=1)
    tangent = np.stack([1.2 * np.cos(u), 1.8 * np.cos(2.0 * u), -0.12 * np.sin(u)], axis=1)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    normal = np.cross(tangent, [0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    binormal = np.cross(normal, tangent)
    v = np.linspace(0.0, 2.0 * np.pi, n_tube, endpoint=False)
    points = (centre[:, None] + tube * (np.cos(v)[None, :, None] * normal[:, None]
                                        + np.sin(v)[None, :, None] * binormal[:, None])).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_around), np.arange(n_tube), indexing="ij")
    a, b = i * n_tube + j, ((i + 1) % n_around) * n_tube + j
    c, d = ((i + 1) % n_around) * n_tube + (j + 1) % n_tube, i * n_tube + (j + 1) % n_tube
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return points, faces


def test_self_intersections_of_one_mesh_form_closed_loops():
    points, faces = crossed_torus()
    curves = intersection_curves(points, faces)
    loops = trace_polylines(curves)
    assert len(loops) >= 1 and all(line[0] == line[-1] for line in loops)
    assert curves.case_table["impossible"] == 0
    assert canonical_vertices(np.array([[0.0, 0, 0], [1, 0, 0], [0.0, 0, 0]])).tolist() == [0, 1, 0]


def test_canonical_vertices_are_the_lowest_index_of_every_position():
    # against a lexicographic sort of the rows; many repeated rows, and -0.0 beside 0.0 (one position)
    rng = np.random.default_rng(3)
    points = rng.integers(-2, 3, (5000, 3)).astype(float) * 0.25
    points[rng.random(5000) < 0.2, 1] *= -1.0  # zeros of either sign
    order = np.lexsort(points.T[::-1])
    ordered = points[order]
    new = np.r_[True, np.any(ordered[1:] != ordered[:-1], axis=1)]
    first = order[np.flatnonzero(new)]
    expected = np.empty(len(points), np.int64)
    expected[order] = first[np.cumsum(new) - 1]
    assert np.array_equal(canonical_vertices(points), expected)
    assert canonical_vertices(np.array([[0.0, -0.0, 1.0], [-0.0, 0.0, 1.0]])).tolist() == [0, 0]
    assert canonical_vertices(np.zeros((0, 3))).shape == (0,)


def test_bad_input_is_named():
    with pytest.raises(InvalidMeshError):
        intersection_curves(np.zeros((0, 3)), np.zeros((0, 3), int))
    with pytest.raises(ValueError, match="group"):
        intersection_curves(np.eye(3), [[0, 1, 2]], group=[0, 1])
