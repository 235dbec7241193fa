"""Repair and Booleans: closed, manifold, oriented, intersection-free output; volumes against manifold3d, the
exact cuboid volumes and the winding-number region of a self-intersecting tube."""

from fractions import Fraction

import numpy as np
import pytest
import pyvista as pv
from conftest import winding_numbers
from test_intersection_curves import crossed_torus, rotated_cuboids

from pverosion.kernels import InvalidMeshError
from pverosion.kernels.exact.intersection import candidate_pairs, triangles_intersect
from pverosion.kernels.exact.intersection_curves import intersection_curves
from pverosion.kernels.mesh.orientation import winding_number
from pverosion.kernels.repair.mesh_repair import OPERATIONS, boolean_meshes, repair_intersections

manifold3d = pytest.importorskip("manifold3d")


def _volume(points, faces):
    p = points[faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def _sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def _det(a, b, c, d):
    """Exact orientation of d against the plane through a, b, c (rational arithmetic)."""
    u, v, w = _sub(b, a), _sub(c, a), _sub(d, a)
    value = (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
             + u[2] * (v[0] * w[1] - v[1] * w[0]))
    return (value > 0) - (value < 0)


def _det2(a, b, c):
    value = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return (value > 0) - (value < 0)


def _segment_meets_triangle_2d(a, b, t):
    """Closed 2-D segment ab and closed triangle t meet (exact)."""
    def inside(p):
        s = [_det2(t[i], t[(i + 1) % 3], p) for i in range(3)]
        return all(x >= 0 for x in s) or all(x <= 0 for x in s)

    def cross(p, q, r, s):
        d1, d2, d3, d4 = _det2(p, q, r), _det2(p, q, s), _det2(r, s, p), _det2(r, s, q)
        if d1 * d2 < 0 and d3 * d4 < 0:
            return True
        def on(p, q, r):
            return all(min(p[i], q[i]) <= r[i] <= max(p[i], q[i]) for i in range(2))
        return (d1 == 0 and on(p, q, r)) or (d2 == 0 and on(p, q, s)) or (d3 == 0 and on(r, s, p)) or (
            d4 == 0 and on(r, s, q))

    return inside(a) or inside(b) or any(cross(a, b, t[i], t[(i + 1) % 3]) for i in range(3))


def _edge_meets_triangle(a, b, t):
    """Closed segment ab meets closed triangle t (exact, rational)."""
    sa, sb = _det(*t, a), _det(*t, b)
    if sa * sb > 0:
        return False
    if sa == 0 and sb == 0:  # in the triangle's plane: drop the axis of the largest normal component
        u, v = _sub(t[1], t[0]), _sub(t[2], t[0])
        normal = [abs(u[1] * v[2] - u[2] * v[1]), abs(u[2] * v[0] - u[0] * v[2]), abs(u[0] * v[1] - u[1] * v[0])]
        axis = normal.index(max(normal))
        keep = [i for i in range(3) if i != axis]
        return _segment_meets_triangle_2d([a[i] for i in keep], [b[i] for i in keep],
                                          [[p[i] for i in keep] for p in t])
    s = [_det(t[i], t[(i + 1) % 3], a, b) for i in range(3)]
    return all(x >= 0 for x in s) or all(x <= 0 for x in s)


def exact_touching_pairs(points, faces):
    """Pairs of faces without a shared vertex that meet, decided in exact rational arithmetic (independent of
    the package's predicates and detector) for the pairs a floating-point test with a tolerance flags."""
    found = []
    for f, g in candidate_pairs(points, faces):
        if set(faces[f]) & set(faces[g]):
            continue  # neighbours at a vertex (folds there are intersection_curves' segments)
        if not triangles_intersect(points[faces[f]], points[faces[g]]):
            continue
        p = [[Fraction(x) for x in points[v]] for v in faces[f]]
        q = [[Fraction(x) for x in points[v]] for v in faces[g]]
        if any(_edge_meets_triangle(p[i], p[(i + 1) % 3], q) for i in range(3)) or any(
                _edge_meets_triangle(q[i], q[(i + 1) % 3], p) for i in range(3)):
            found.append((int(f), int(g)))
    return found


def assert_clean(points, faces):
    """Closed, manifold, consistently oriented, without self-intersections (two independent checks)."""
    assert len(faces) > 0
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    # every directed edge once and its reverse once: closed, manifold (2 faces per edge) and oriented
    keys = directed[:, 0] * len(points) + directed[:, 1]
    reverse = directed[:, 1] * len(points) + directed[:, 0]
    assert len(np.unique(keys)) == len(keys)
    assert np.array_equal(np.sort(keys), np.sort(reverse))
    curves = intersection_curves(points, faces)
    assert len(curves.segments) == 0 and curves.touching == 0
    assert exact_touching_pairs(points, faces) == []
    mesh = manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(points, np.float32),
                                               tri_verts=np.asarray(faces, np.uint32)))
    assert mesh.status() == manifold3d.Error.NoError


def _manifold(mesh: pv.PolyData):
    return manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(mesh.points, np.float32),
                                               tri_verts=np.asarray(mesh.regular_faces, np.uint32)))


def _reference(a: pv.PolyData, b: pv.PolyData, operation: str) -> float:
    ma, mb = _manifold(a), _manifold(b)
    result = {"union": ma + mb, "intersection": ma ^ mb, "difference": ma - mb, "reverse_difference": mb - ma}
    return result[operation].volume()


SCENES = {
    "spheres": (pv.Icosphere(radius=1.0, nsub=4), pv.Icosphere(radius=0.7, nsub=3).translate((0.8, 0.15, 0.1))),
    "cube_sphere": (pv.Box(bounds=(-0.8, 0.8, -0.8, 0.8, -0.8, 0.8), level=6).triangulate(),
                    pv.Icosphere(radius=1.0, nsub=4).translate((0.05, 0.03, 0.02))),
}


@pytest.mark.parametrize("scene", sorted(SCENES))
@pytest.mark.parametrize("operation", OPERATIONS)
def test_boolean_is_clean_and_matches_manifold3d(scene, operation):
    a, b = SCENES[scene]
    result = boolean_meshes(a.points, a.regular_faces, b.points, b.regular_faces, operation)
    assert_clean(result.points, result.faces)
    assert _volume(result.points, result.faces) == pytest.approx(_reference(a, b, operation), rel=1e-3)
    assert result.on_curve.any() and result.curves.case_table["impossible"] == 0


@pytest.mark.parametrize("n", [4, 8, 16])
def test_rotated_cuboids_give_the_exact_volumes(n):
    points, faces, group = rotated_cuboids(n)
    na = int(np.count_nonzero(group == 0))
    va = int(faces[:na].max()) + 1
    a_points, a_faces = points[:va], faces[:na]
    b_points, b_faces = points[va:], faces[na:] - va
    exact = {"union": 10.0, "intersection": 2.0, "difference": 6.0, "reverse_difference": 2.0}
    for operation, volume in exact.items():
        result = boolean_meshes(a_points, a_faces, b_points, b_faces, operation)
        assert_clean(result.points, result.faces)
        assert _volume(result.points, result.faces) == pytest.approx(volume, rel=1e-9)
        assert result.curves.case_table["impossible"] == 0


def test_self_intersecting_tube_is_repaired_to_its_winding_region():
    points, faces = crossed_torus()
    result = repair_intersections(points, faces)
    assert_clean(result.points, result.faces)
    # the tube covers space twice only where its halves cross: sample the winding number there
    lo, hi = np.array([-0.32, -0.32, -0.12]), np.array([0.32, 0.32, 0.12])
    shape = (32, 32, 12)
    axes = [np.linspace(a, b, k, endpoint=False) + (b - a) / (2 * k) for a, b, k in zip(lo, hi, shape)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    w_input = winding_numbers(grid, points, faces)
    w_output = winding_numbers(grid, result.points, result.faces)
    assert np.allclose(w_input[:5], [winding_number(p, points, faces) for p in grid[:5]])
    assert np.array_equal(np.round(w_input) >= 1, np.round(w_output) >= 1)  # the same region...
    assert np.all(np.abs(w_output - (np.round(w_input) >= 1)) < 1e-6)  # ...covered once
    # its volume: the input's minus what the input covers twice
    twice = np.count_nonzero(np.round(w_input) >= 2) * np.prod((hi - lo) / shape)
    assert twice > 0.0
    assert _volume(result.points, result.faces) == pytest.approx(_volume(points, faces) - twice, rel=5e-3)


def test_bad_input_is_named():
    box = pv.Box().triangulate()
    with pytest.raises(ValueError, match="operation"):
        boolean_meshes(box.points, box.regular_faces, box.points, box.regular_faces, "xor")
    open_box = box.regular_faces[1:]
    with pytest.raises(InvalidMeshError, match="closed"):
        boolean_meshes(box.points, open_box, box.points, box.regular_faces, "union")
    with pytest.raises(InvalidMeshError, match="closed"):
        repair_intersections(box.points, open_box)


def test_coplanar_overlaps_are_cut_and_coplanar_neighbours_are_not():
    box = pv.Box(bounds=(0, 1, 0, 1, 0, 1), level=3).triangulate().clean()
    points, faces = np.asarray(box.points, float), box.regular_faces
    # one box alone: faces of a side lie in one plane and their boxes meet, but an edge line separates every two
    # of them there, so none is even reported as coplanar
    alone = repair_intersections(points, faces)
    assert len(alone.curves.coplanar) == 0
    assert _volume(alone.points, alone.faces) == pytest.approx(1.0, rel=1e-12)
    # a second box sharing the planes z = 0 and z = 1 overlaps the first one's top and bottom faces there: the
    # overlapping faces are cut along each other's edges, and one copy of the shared pieces stays
    other = pv.Box(bounds=(0.5, 1.5, 0.2, 0.8, 0, 1), level=2).triangulate().clean()
    x0, x1, y0, y1 = (float(v) for v in other.bounds[:4])  # float32 coordinates
    for operation, expected in (("union", 1.0 + (x1 - 1.0) * (y1 - y0)), ("difference", 1.0 - (1.0 - x0) * (y1 - y0)),
                                ("intersection", (1.0 - x0) * (y1 - y0))):
        result = boolean_meshes(points, faces, other.points, other.regular_faces, operation)
        assert_clean(result.points, result.faces)
        assert _volume(result.points, result.faces) == pytest.approx(expected, rel=1e-12)
    # lifted off the planes a little, it is cut as usual
    lifted = other.translate((0.0, 0.0, 1e-3))
    result = boolean_meshes(points, faces, lifted.points, lifted.regular_faces, "union")
    assert_clean(result.points, result.faces)
    x0, x1, y0, y1, z0, z1 = (float(v) for v in lifted.bounds)  # float32 coordinates
    expected = 1.0 + (x1 - 1.0) * (y1 - y0) * (z1 - z0) + (1.0 - x0) * (y1 - y0) * (z1 - 1.0)
    assert _volume(result.points, result.faces) == pytest.approx(expected, rel=1e-9)
