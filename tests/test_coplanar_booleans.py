"""Booleans and repairs of solids whose faces overlap in a common plane: boxes sharing faces, a model on a ground
slab, a mesh and its mirror image. Every result is checked by mesh_problems and manifold3d, and its volume against
the exact value and manifold3d's."""

import numpy as np
import pytest
import pyvista as pv
from test_repair_guarantees import _box, _join, assert_two_manifold

from pverosion.kernels.exact.intersection_curves import coplanar_overlaps, intersection_curves
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.repair.mesh_repair import OPERATIONS, boolean_meshes, mesh_problems, repair_intersections

manifold3d = pytest.importorskip("manifold3d")


def _solid(points, faces):
    return manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(points, np.float32),
                                               tri_verts=np.asarray(faces, np.uint32)))


def _reference(a, b, operation):
    ma, mb = _solid(*a), _solid(*b)
    return {"union": lambda: ma + mb, "intersection": lambda: ma ^ mb, "difference": lambda: ma - mb,
            "reverse_difference": lambda: mb - ma}[operation]().volume()


def _overlapping(a, b):
    """Whether faces of a and b overlap in a common plane (the inputs are meant to)."""
    points, faces = _join(a, b)
    curves = intersection_curves(points, faces, group=np.repeat([0, 1], [len(a[1]), len(b[1])]))
    return len(coplanar_overlaps(points, faces, curves)) > 0


def _checked(a, b, operation, expected):
    """The Boolean: clean, with the exact volume ``expected`` and manifold3d's (inputs float32-exact)."""
    result = boolean_meshes(*a, *b, operation)
    volume = signed_volume(result.points, result.faces) if len(result.faces) else 0.0
    if len(result.faces):
        assert_two_manifold(result.points, result.faces)
    assert volume == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert volume == pytest.approx(_reference(a, b, operation), rel=1e-6, abs=1e-9)
    return result


UNIT = _box((0, 0, 0), (1, 1, 1))


@pytest.mark.parametrize("level", [0, 2])
def test_boxes_sharing_a_whole_face(level):
    above = _box((0, 0, 1), (1, 1, 2), level=level)
    assert _overlapping(UNIT, above)
    union = _checked(UNIT, above, "union", 2.0)
    # no face is left between the two boxes: nothing lies inside the plane z = 1 but the rim
    tri = union.points[union.faces]
    inside = np.all(tri[:, :, 2] == 1.0, axis=1) & np.all((tri[:, :, :2] > 0.0) & (tri[:, :, :2] < 1.0), axis=(1, 2))
    assert not inside.any()
    assert _checked(UNIT, above, "intersection", 0.0).faces.size == 0
    difference = _checked(UNIT, above, "difference", 1.0)
    assert np.allclose(difference.points.min(axis=0), 0.0) and np.allclose(difference.points.max(axis=0), 1.0)
    _checked(UNIT, above, "reverse_difference", 1.0)


@pytest.mark.parametrize("operation", OPERATIONS)
def test_boxes_sharing_part_of_a_face(operation):
    above = _box((0.5, 0.25, 1), (1.5, 1.5, 2), level=1)
    overlap_area = 0.5 * 0.75
    assert _overlapping(UNIT, above)
    volume_b = 1.0 * 1.25
    expected = {"union": 1.0 + volume_b, "intersection": 0.0, "difference": 1.0, "reverse_difference": volume_b}
    result = _checked(UNIT, above, operation, expected[operation])
    if operation == "union":  # the shared part of the plane z = 1 is inside the union: no face lies on it
        tri = result.points[result.faces]
        centre = tri.mean(axis=1)
        on_shared = (centre[:, 2] == 1.0) & (centre[:, 0] > 0.5) & (centre[:, 0] < 1.0)
        on_shared &= (centre[:, 1] > 0.25) & (centre[:, 1] < 1.0)
        assert not on_shared.any()
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        flat = np.all(tri[:, :, 2] == 1.0, axis=1)
        # A's top and B's bottom without the overlap, once each
        assert area[flat].sum() == pytest.approx(1.0 + 1.25 - 2 * overlap_area, rel=1e-12)


@pytest.mark.parametrize("operation", OPERATIONS)
def test_boxes_overlapping_with_flush_sides(operation):
    """Four sides of each box lie in the planes of the other's, facing the same way."""
    other = _box((0.5, 0, 0), (1.5, 1, 1), level=1)
    assert _overlapping(UNIT, other)
    expected = {"union": 1.5, "intersection": 0.5, "difference": 0.5, "reverse_difference": 0.5}
    _checked(UNIT, other, operation, expected[operation])


@pytest.mark.parametrize("operation", OPERATIONS)
def test_identical_boxes(operation):
    other = _box((0, 0, 0), (1, 1, 1), level=1)
    expected = {"union": 1.0, "intersection": 1.0, "difference": 0.0, "reverse_difference": 0.0}
    _checked(UNIT, other, operation, expected[operation])


def test_grid_of_unit_boxes_repairs_to_their_union():
    """A soup of 2 x 2 x 2 unit boxes side by side, as one mesh: the repair is one closed box of volume 8, with no
    face left inside."""
    boxes = [_box((i, j, k), (i + 1, j + 1, k + 1), level=(i + j + k) % 2) for i in range(2) for j in range(2)
             for k in range(2)]
    points, faces = _join(*boxes)
    result = repair_intersections(points, faces)
    assert_two_manifold(result.points, result.faces)
    assert signed_volume(result.points, result.faces) == pytest.approx(8.0, rel=1e-12)
    centre = result.points[result.faces].mean(axis=1)
    assert np.all(np.any((centre == 0.0) | (centre == 2.0), axis=1))  # every face on the outside


def test_row_of_boxes_unioned_one_by_one():
    row = UNIT
    for i in range(1, 4):
        result = _checked(row, _box((i, 0, 0), (i + 1, 1, 1), level=i % 2), "union", i + 1.0)
        row = (result.points, result.faces)


def test_three_coincident_copies_repair_to_one():
    points, faces = _join(UNIT, _box((0, 0, 0), (1, 1, 1), level=1), UNIT)
    result = repair_intersections(points, faces)
    assert_two_manifold(result.points, result.faces)
    assert signed_volume(result.points, result.faces) == pytest.approx(1.0, rel=1e-12)
    tri = result.points[result.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    assert area == pytest.approx(6.0, rel=1e-12)  # one copy of the surface


@pytest.mark.parametrize("level", [0, 1])
def test_box_on_a_ground_slab(level):
    slab = _box((-1, -1, -0.5), (2, 2, 0), level=level)
    box = _box((0.25, 0.25, 0), (0.75, 0.75, 1))
    slab_volume = 3.0 * 3.0 * 0.5
    _checked(box, slab, "union", slab_volume + 0.25)
    _checked(box, slab, "intersection", 0.0)
    _checked(box, slab, "difference", 0.25)
    _checked(slab, box, "difference", slab_volume)


def _dome():
    """An icosphere cut flat at z = 0 (the upper half), float32-exact: a model with a flat bottom."""
    sphere = pv.Icosphere(radius=1.0, nsub=3)
    cut = boolean_meshes(sphere.points, sphere.regular_faces, *_box((-2, -2, 0), (2, 2, 2)), "intersection")
    points = cut.points.astype(np.float32).astype(np.float64)
    assert np.count_nonzero(points[:, 2] == 0.0) >= 3
    return points, cut.faces


def test_model_on_a_ground_slab():
    dome = _dome()
    dome_volume = signed_volume(*dome)
    slab = _box((-1.5, -1.5, -0.25), (1.5, 1.5, 0))
    assert _overlapping(dome, slab)
    _checked(dome, slab, "union", dome_volume + 9.0 * 0.25)
    _checked(dome, slab, "difference", dome_volume)
    _checked(slab, dome, "difference", 9.0 * 0.25)
    _checked(dome, slab, "intersection", 0.0)
    # a slab smaller than the model's base: the base sticks out over the slab's rim
    small = _box((-0.5, -0.25, -0.25), (0.5, 0.25, 0))
    _checked(dome, small, "union", dome_volume + 0.25 * 0.5)


def test_mesh_and_its_mirror_image_across_its_flat_face():
    points, faces = _dome()
    mirrored = (points * [1.0, 1.0, -1.0], faces[:, ::-1].copy())
    volume = signed_volume(points, faces)
    union = _checked((points, faces), mirrored, "union", 2.0 * volume)
    assert np.all(union.points[union.faces].mean(axis=1)[:, 2] != 0.0)  # the flat faces are gone
    _checked((points, faces), mirrored, "intersection", 0.0)
    _checked((points, faces), mirrored, "difference", volume)
    # the same two halves as one mesh, repaired
    joined = _join((points, faces), mirrored)
    result = repair_intersections(*joined)
    assert_two_manifold(result.points, result.faces)
    assert signed_volume(result.points, result.faces) == pytest.approx(2.0 * volume, rel=1e-12)


def test_coplanar_segments_are_the_edges_inside_the_other_face():
    """Two triangles in z = 0 overlapping in the triangle (1, 1), (3, 1), (1, 3): the cut segments are the parts of
    their edges inside each other, which bound that triangle, with ends at a vertex or where two edges cross."""
    from pverosion.kernels.exact.intersection_curves import EDGE_EDGE, VERTEX, canonical_vertices, curves_of

    points = np.array([[0.0, 0, 0], [4, 0, 0], [0, 4, 0], [1, 1, 0], [5, 1, 0], [1, 5, 0]])
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    plain = curves_of(points, faces, None, canonical_vertices(points))
    assert len(plain.segments) == 0 and plain.coplanar.tolist() == [[0, 1]]
    curves = curves_of(points, faces, None, canonical_vertices(points), coplanar_cuts=True)
    ends = {frozenset(map(tuple, curves.points[s].round(12).tolist())) for s in curves.segments}
    corners = [(1.0, 1.0, 0.0), (3.0, 1.0, 0.0), (1.0, 3.0, 0.0)]
    assert ends == {frozenset([corners[0], corners[1]]), frozenset([corners[1], corners[2]]),
                    frozenset([corners[2], corners[0]])}
    assert sorted(curves.point_keys[:, 0].tolist()) == [VERTEX, EDGE_EDGE, EDGE_EDGE]


def test_a_scan_cut_flat_on_a_ground_slab(closed_bunny):
    """The bunny scan (holes filled) cut flat near its bottom, float32-exact, resting with that cut on a slab: the
    union is clean and its volume is the sum of the two (and manifold3d's)."""
    points, faces = closed_bunny
    lo, hi = points.min(axis=0) - 0.01, points.max(axis=0) + 0.01
    lo[1] = points[:, 1].min() + 0.1 * np.ptp(points[:, 1])
    upper = _box(lo, hi)
    cut = boolean_meshes(points, faces, *upper, "intersection")
    plane = upper[0][:, 1].min()
    model = (cut.points.astype(np.float32).astype(np.float64), cut.faces)
    assert np.count_nonzero(model[0][:, 1] == plane) > 100 and mesh_problems(*model) == []
    slab_lo, slab_hi = lo - 0.01, hi + 0.01
    slab_hi[1], slab_lo[1] = plane, plane - 0.02
    slab = _box(slab_lo, slab_hi, level=2)
    assert _overlapping(model, slab)
    _checked(model, slab, "union", signed_volume(*model) + signed_volume(*slab))
