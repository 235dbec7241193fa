import numpy as np
import pytest
import pyvista as pv
from conftest import assert_filter_equals_kernel, icosphere, one_and_all_threads

import pverosion
from pverosion.examples import load_torus
from pverosion.kernels.curvature.operator import CurvatureOperator, principal_curvatures
from pverosion.kernels.mesh.locality import (
    LOCAL_SPAN,
    MORTON_BITS,
    SMALL_SORT,
    locality_renumbering,
    morton_renumbering,
    poor_locality,
)
from pverosion.kernels.mesh.orientation import orient_faces
from pverosion.kernels.mesh.topology import locality_sorted


def _shuffled(points, faces, seed):
    """The mesh with its vertices renumbered at random: (points, faces, perm) with new vertex i = old perm[i]."""
    perm = np.random.default_rng(seed).permutation(len(points))
    rank = np.empty_like(perm)
    rank[perm] = np.arange(len(perm))
    return points[perm], rank[faces], perm


@pytest.fixture(scope="module")
def bumpy():
    """A sphere with bumps (no umbilics), 40962 vertices, vertices shuffled so that its locality is poor."""
    s = icosphere(1.0, 6)
    p = np.asarray(s.points)
    p = p * (1.0 + 0.05 * np.sin(3 * p[:, :1]) * np.cos(2 * p[:, 1:2]))
    return _shuffled(p, s.regular_faces.astype(np.int64), 11)


def _codes(points):
    lo, hi = points.min(axis=0), points.max(axis=0)
    q = np.clip(((points - lo) * ((1 << MORTON_BITS) - 1) / (hi - lo)).astype(np.int64), 0, (1 << MORTON_BITS) - 1)
    codes = np.zeros(len(points), np.int64)
    for bit in range(MORTON_BITS):
        for d in range(3):
            codes |= ((q[:, d] >> bit) & 1) << (3 * bit + d)
    return codes


def test_poor_locality_depends_on_the_face_set_only(bunny, bumpy):
    faces = bunny.regular_faces.astype(np.int64)
    assert not poor_locality(faces, bunny.n_points)  # a scan lists neighbours close together
    points, shuffled, _ = bumpy
    assert poor_locality(shuffled, len(points))
    rng = np.random.default_rng(2)
    rolled = np.roll(shuffled[rng.permutation(len(shuffled))], 1, axis=1)
    assert poor_locality(rolled, len(points))
    small = icosphere(1.0, 4)
    assert small.n_points <= LOCAL_SPAN
    assert not poor_locality(_shuffled(np.asarray(small.points), small.regular_faces, 3)[1], small.n_points)


def test_morton_renumbering_is_the_stable_order_of_the_cell_codes(bumpy):
    points = bumpy[0]
    ren = morton_renumbering(points)
    assert np.array_equal(ren.order, np.argsort(_codes(points), kind="stable"))
    assert np.array_equal(ren.rank[ren.order], np.arange(len(points)))
    faces = bumpy[1]
    assert np.array_equal(ren.to_local(points)[ren.faces(faces)], points[faces])
    assert np.array_equal(ren.to_caller(ren.to_local(points)), points)
    assert np.array_equal(ren.sorted_faces(faces), locality_sorted(ren.faces(faces), len(points))[1])
    assert np.median(np.ptp(ren.faces(faces), axis=1)) < np.median(np.ptp(faces, axis=1)) / 100


@pytest.mark.parametrize("n", [SMALL_SORT - 1, SMALL_SORT])
def test_morton_order_is_the_same_with_short_and_long_digits(n):
    """Fewer than SMALL_SORT points are sorted in three passes of 10-bit digits, more in two of 15 bits: both give
    the stable order of the codes, clustered points (many in one cell) included."""
    rng = np.random.default_rng(n)
    points = np.concatenate([rng.normal(size=(n - n // 4, 3)), rng.normal(scale=1e-6, size=(n // 4, 3))])
    points = points[rng.permutation(n)]
    assert np.array_equal(morton_renumbering(points).order, np.argsort(_codes(points), kind="stable"))


def test_locality_renumbering_only_for_poor_locality(bunny, bumpy):
    assert locality_renumbering(np.asarray(bunny.points, float), bunny.regular_faces.astype(np.int64)) is None
    assert locality_renumbering(bumpy[0], bumpy[1]) is not None


def _fields(c):
    return {"k1": c.k1, "k2": c.k2, "normals": c.normals, "point_areas": c.point_areas, "direction1": c.direction1}


def test_curvature_follows_a_permutation_of_the_vertices(bumpy):
    points, faces, perm = bumpy
    rank = np.empty_like(perm)
    rank[perm] = np.arange(len(perm))
    original_points, original_faces = points[rank], perm[faces]  # the icosphere's own numbering
    op = CurvatureOperator(faces, len(points))
    shuffled = op(points)
    assert op.renumbering is not None
    reference = principal_curvatures(original_points, original_faces)
    for name, value in _fields(shuffled).items():
        expected = _fields(reference)[name][perm]
        if name == "direction1":  # defined up to sign, and amplifies rounding near umbilics: compared away from them
            apart = (shuffled.k1 - shuffled.k2) > 1e-3
            value = value[apart] * np.sign(np.sum(value[apart] * expected[apart], axis=1))[:, None]
            assert np.allclose(value, expected[apart], rtol=0.0, atol=1e-9), name
            continue
        assert np.allclose(value, expected, rtol=0.0, atol=1e-12 * np.abs(expected).max()), name
    strided = principal_curvatures(np.asfortranarray(points), faces)
    assert np.array_equal(strided.k1, shuffled.k1) and np.array_equal(strided.direction2, shuffled.direction2)


def test_renumbered_operator_keeps_its_numbering_and_takes_normals(bumpy):
    points, faces, _ = bumpy
    before = points.copy()
    op = CurvatureOperator(faces, len(points))
    first = op(points)
    order = op.renumbering.order
    moved = points * 1.01
    assert np.allclose(op(moved).mean, first.mean / 1.01, rtol=1e-12, atol=0.0)
    assert op.renumbering.order is order
    given = op(points, normals=first.normals)
    assert np.array_equal(given.k1, first.k1) and np.array_equal(given.normals, first.normals)
    assert np.array_equal(points, before)


def test_renumbered_curvature_is_independent_of_thread_count(bumpy):
    points, faces, _ = bumpy
    one, many = one_and_all_threads(lambda: principal_curvatures(points, faces))
    for name, value in _fields(one).items():
        assert np.array_equal(value, _fields(many)[name]), name


def test_shuffled_torus_mean_curvature():
    R, r = 3.0, 1.0
    torus = load_torus(major_radius=R, minor_radius=r, n_major=300, n_minor=150)
    points, faces, _ = _shuffled(np.asarray(torus.points, float), torus.regular_faces.astype(np.int64), 5)
    assert poor_locality(faces, len(points))
    rho = np.hypot(points[:, 0], points[:, 1])
    cos_v = (rho - R) / r
    exact = (R + 2 * r * cos_v) / (2 * r * (R + r * cos_v))
    mean = principal_curvatures(points, faces).mean
    assert np.max(np.abs(mean - exact)) <= 2e-3 * np.max(np.abs(exact))


@pytest.mark.parametrize("orientation", ["outward", "inward"])
def test_filter_equals_orientation_then_kernel_when_renumbered(bumpy, orientation):
    points, faces, _ = bumpy
    flipped = faces.copy()
    flipped[::3] = flipped[::3, ::-1]  # inconsistent input winding
    mesh = pv.PolyData.from_regular_faces(points, flipped)
    out = pverosion.curvature(mesh, orientation=orientation)
    assert_filter_equals_kernel(out, points, flipped, orientation)
    sign = 1.0 if orientation == "outward" else -1.0
    assert np.mean(sign * out["mean_curvature"]) > 0.5  # a bumpy unit sphere


def test_orientation_of_a_shuffled_mesh_follows_the_permutation(bumpy):
    points, faces, perm = bumpy
    rank = np.empty_like(perm)
    rank[perm] = np.arange(len(perm))
    flipped = faces.copy()
    flipped[1::4] = flipped[1::4, ::-1]
    shuffled = orient_faces(points, flipped)
    original = orient_faces(points[rank], perm[flipped])
    assert np.array_equal(shuffled.flipped, original.flipped)
    assert np.array_equal(perm[shuffled.faces], original.faces)


def test_operator_results_are_not_overwritten_by_later_calls(bumpy):
    points, faces, _ = bumpy
    op = CurvatureOperator(faces, len(points))
    first = op(points)
    kept = {name: value.copy() for name, value in _fields(first).items()}
    op(points * 1.5)
    op(points, normals=-first.normals)
    for name, value in _fields(first).items():
        assert np.array_equal(value, kept[name]), name


def test_renumbering_gathers_into_a_given_array_and_rejects_a_wrong_one(bumpy):
    points = bumpy[0]
    ren = morton_renumbering(points)
    out = np.full_like(points, np.nan)
    assert ren.to_local(points, out=out) is out
    assert np.array_equal(out, points[ren.order])
    with pytest.raises(ValueError, match="shape"):
        ren.to_local(points, out=np.empty((len(points), 2)))
    with pytest.raises(ValueError, match="C-contiguous"):
        ren.to_caller(points, out=np.empty((3, len(points))).T)
