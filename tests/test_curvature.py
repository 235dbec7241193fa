import gc

import numpy as np
import pytest
import pyvista as pv
from conftest import assert_filter_equals_kernel, height_field, icosphere, one_and_all_threads

import pverosion
from pverosion.examples import load_cylinder, load_torus
from pverosion.kernels import InvalidMeshError, principal_curvatures
from pverosion.kernels._scatter import CHUNKS
from pverosion.kernels.curvature.operator import CurvatureOperator, CurvatureTracker


def test_sphere_mean_and_gaussian_curvature():
    r = 2.5
    s = icosphere(r, 6)
    assert s.n_points >= 40_000
    c = principal_curvatures(s.points, s.regular_faces)
    assert np.max(np.abs(c.mean - 1 / r)) <= 1e-3 / r
    assert np.max(np.abs(c.gaussian - 1 / r**2)) <= 1e-3 / r**2


def test_cylinder_mean_curvature_away_from_rims():
    r = 0.8
    cyl = load_cylinder(radius=r, height=4.0, n_around=128, n_along=64)
    c = principal_curvatures(cyl.points, cyl.regular_faces)
    inner = np.abs(cyl.points[:, 2]) < 1.5
    assert np.max(np.abs(c.mean[inner] - 1 / (2 * r))) <= 0.01 / (2 * r)
    assert np.max(np.abs(c.k2[inner])) <= 0.01 / r
    # k1 runs around the axis, k2 along it
    assert np.min(np.abs(c.direction2[inner, 2])) > 0.99


def test_torus_mean_curvature():
    R, r = 3.0, 1.0
    torus = load_torus(major_radius=R, minor_radius=r, n_major=300, n_minor=150)
    p = torus.points
    rho = np.hypot(p[:, 0], p[:, 1])
    cos_v = (rho - R) / r
    exact = (R + 2 * r * cos_v) / (2 * r * (R + r * cos_v))
    H = principal_curvatures(p, torus.regular_faces).mean
    assert np.max(np.abs(H - exact)) <= 0.01 * np.max(np.abs(exact))


def test_plane_has_zero_curvature():
    plane = height_field(lambda x, y: 0.0 * x, n=31)
    rng = np.random.default_rng(0)
    pts = plane.points.copy()
    pts[:, :2] += rng.uniform(-0.01, 0.01, size=(len(pts), 2))  # irregular triangles, still flat
    c = principal_curvatures(pts, plane.regular_faces)
    assert np.max(np.abs(c.mean)) < 1e-9
    assert np.max(np.abs(c.gaussian)) < 1e-9


def test_saddle_has_negative_gaussian_curvature():
    saddle = height_field(lambda x, y: 0.5 * (x**2 - y**2), n=61)
    c = principal_curvatures(saddle.points, saddle.regular_faces)
    centre = np.linalg.norm(saddle.points[:, :2], axis=1) < 0.5
    assert np.all(c.gaussian[centre] < 0)
    # at the origin k1 = -k2 = 1 for z = (x^2 - y^2) / 2
    origin = np.argmin(np.linalg.norm(saddle.points, axis=1))
    assert c.k1[origin] == pytest.approx(1.0, rel=0.02)
    assert c.k2[origin] == pytest.approx(-1.0, rel=0.02)


def test_principal_frame_is_orthonormal_and_tangent():
    s = icosphere(1.0, 3)
    s.points[:, 0] *= 1.7  # an ellipsoid, distinct principal curvatures
    c = principal_curvatures(s.points, s.regular_faces)
    assert np.all(c.k1 >= c.k2)
    for d in (c.direction1, c.direction2):
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-9)
        np.testing.assert_allclose(np.einsum("ij,ij->i", d, c.normals), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", c.direction1, c.direction2), 0.0, atol=1e-9)


def test_curvature_scales_inversely_with_size():
    s = icosphere(1.0, 3)
    s.points[:, 2] *= 0.6
    a = principal_curvatures(s.points, s.regular_faces)
    b = principal_curvatures(4.0 * s.points, s.regular_faces)
    np.testing.assert_allclose(b.mean, a.mean / 4.0, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("change", ["vertex_order", "face_order", "winding", "moved_1e5"])
def test_open_scan_curvature_does_not_depend_on_numbering_winding_or_place(change):
    """An open, bumpy patch of a sphere: renumbered vertices or faces and reversed winding change the values only
    by the rounding of the sums' order (default orientation="outward"); moved 1e5 units away, by the rounding of
    the coordinates there (1e-11 of the 1-unit model; the curvatures, up to 29, moved by 1e-8)."""
    sphere = icosphere(1.0, 4)
    rng = np.random.default_rng(2)
    points = np.asarray(sphere.points) * (1.0 + 0.02 * rng.standard_normal((sphere.n_points, 1)))
    faces = sphere.regular_faces[points[sphere.regular_faces][:, :, 2].min(axis=1) > -0.3]  # open at the bottom
    used = np.unique(faces)
    points, faces = points[used], np.searchsorted(used, faces)
    other_points, other_faces, back = points, faces, np.arange(len(points))
    if change == "vertex_order":
        back = rng.permutation(len(points))  # new vertex i is old vertex back[i]
        other_points, other_faces = points[back], np.argsort(back)[faces]
    elif change == "face_order":
        other_faces = faces[rng.permutation(len(faces))]
    elif change == "winding":
        other_faces = faces[:, ::-1]
    else:
        other_points = points + 1e5
    reference = pverosion.curvature(pv.PolyData.from_regular_faces(points, faces))
    other = pverosion.curvature(pv.PolyData.from_regular_faces(other_points, other_faces))
    atol = 1e-7 if change == "moved_1e5" else 1e-12
    for name in ("mean_curvature", "gaussian_curvature", "k1", "k2"):
        np.testing.assert_allclose(other[name], reference[name][back], rtol=0, atol=atol, err_msg=name)


def test_bunny_finite_and_convex_ears_positive(bunny):
    out = pverosion.curvature(bunny)
    for name in ("mean_curvature", "gaussian_curvature", "k1", "k2", "principal_direction_1"):
        assert np.all(np.isfinite(out[name])), name
    assert out.field_data["face_orientation"][0] == "outward"
    assert int(out.field_data["flipped_faces"][0]) == bunny.n_cells
    ears = out.points[:, 1] > 0.16  # the two ears stand above the head
    assert np.median(out["mean_curvature"][ears]) > 0
    assert np.mean(out["mean_curvature"][ears] > 0) > 0.7


def test_bunny_sign_agrees_with_vtk_curvatures(bunny):
    out = pverosion.curvature(bunny)
    ours = out["mean_curvature"]
    theirs = pv.PolyData(out.points.copy(), out.faces.copy()).curvature("mean")  # outward-oriented copy
    strong = (np.abs(ours) > 0.1 * np.percentile(np.abs(ours), 95)) & (
        np.abs(theirs) > 0.1 * np.percentile(np.abs(theirs), 95)
    )
    agree = np.sign(ours[strong]) == np.sign(theirs[strong])
    assert strong.sum() > 0.5 * bunny.n_points
    assert agree.mean() >= 0.9


def test_operator_reuses_connectivity_and_matches_one_shot():
    s = icosphere(1.0, 4)
    faces = s.regular_faces
    rng = np.random.default_rng(3)
    moved = s.points * (1.0 + 0.05 * rng.random((s.n_points, 1)))
    op = CurvatureOperator(faces, s.n_points)
    a, b = op(moved), principal_curvatures(moved, faces)
    assert np.array_equal(a.k1, b.k1) and np.array_equal(a.k2, b.k2)
    assert np.allclose(op(2.0 * s.points).mean, 0.5, rtol=1e-6)
    with pytest.raises(InvalidMeshError, match="shape"):
        op(s.points[:-1])


def test_result_is_independent_of_thread_count():
    s = icosphere(1.0, 4)
    p = s.points * (1.0 + 0.1 * np.random.default_rng(0).random((s.n_points, 1)))
    one, many = one_and_all_threads(lambda: principal_curvatures(p, s.regular_faces))
    assert np.array_equal(one.k1, many.k1) and np.array_equal(one.direction1, many.direction1)


def _fields(c):
    return (c.k1, c.k2, c.direction1, c.direction2, c.normals, c.point_areas)


def test_tracker_updates_equal_fresh_evaluations_and_the_operator():
    s = icosphere(1.0, 4)
    faces = s.regular_faces
    rng = np.random.default_rng(5)
    points = np.array(s.points, dtype=float)
    tracker = CurvatureTracker(faces, s.n_points)
    first = tracker(points)
    assert np.allclose(first.mean, 1.0, rtol=1e-3)
    for step in range(4):
        # a few points move (or, at the last step, all go back to the start)
        if step < 3:
            some = rng.choice(s.n_points, 25, replace=False)
            points[some] += 0.02 * rng.standard_normal((25, 3))
        else:
            points = np.array(s.points, dtype=float)
        update = tracker(points)
        fresh = CurvatureTracker(faces, s.n_points)(points)
        for a, b in zip(_fields(update), _fields(fresh)):
            assert np.array_equal(a, b)
        reference = CurvatureOperator(faces, s.n_points)(points)
        # (the principal directions of near-umbilic points amplify rounding: not compared)
        for name in ("k1", "k2", "normals", "point_areas"):
            a, b = getattr(update, name), getattr(reference, name)
            assert np.allclose(a, b, rtol=0.0, atol=1e-12 * max(1.0, np.abs(b).max()))
    assert not update.k1.flags.writeable
    with pytest.raises(InvalidMeshError, match="shape"):
        tracker(points[:-1])


def test_operator_from_sorted_faces_equals_the_one_built_from_any_order():
    s = icosphere(1.0, 3)
    rng = np.random.default_rng(4)
    faces = s.regular_faces[rng.permutation(s.n_cells)]
    moved = s.points * (1.0 + 0.05 * rng.random((s.n_points, 1)))
    ordered = faces[np.argsort(faces.min(axis=1), kind="stable")]
    a = CurvatureOperator.from_sorted(ordered, s.n_points)(moved)
    b = CurvatureOperator(faces, s.n_points)(moved)
    assert np.array_equal(a.k1, b.k1) and np.array_equal(a.direction2, b.direction2)


@pytest.mark.parametrize("order", ["sorted", "shuffled"])
def test_operator_on_faces_in_any_order_agrees_with_per_face_sums(order):
    """The operator adds into one accumulator whose rows the face chunks own, and adds the corners outside them
    afterwards: the normals and areas equal per-face sums made with numpy, and the results do not depend on
    the thread count."""
    s = icosphere(1.0, 4)
    rng = np.random.default_rng(8)
    p = np.asarray(s.points) * (1.0 + 0.05 * rng.random((s.n_points, 1)))
    faces = s.regular_faces.astype(np.int64)
    sort = np.argsort(faces.min(axis=1), kind="stable") if order == "sorted" else rng.permutation(len(faces))
    faces = faces[sort]
    op = CurvatureOperator.from_sorted(faces, len(p))
    result = op(p)
    owned = op._owned[0]
    chunk = np.arange(len(faces)) * CHUNKS // len(faces)  # the chunk of each face (chunk_range)
    inside = (faces >= owned.owners[chunk][:, None]) & (faces < owned.owners[chunk + 1][:, None])
    assert owned.n_outside == np.count_nonzero(~inside) and np.all(np.diff(owned.owners) >= 0)
    assert 0 < owned.n_outside < faces.size  # both ways of adding are taken
    a, b, e = (p[faces[:, k]] - p[faces[:, j]] for j, k in ((0, 1), (1, 2), (2, 0)))
    n = np.cross(a, b)
    la, lb, le = (np.einsum("ij,ij->i", x, x) for x in (a, b, e))
    total = np.zeros_like(p)
    for k, w in enumerate((1 / (la * le), 1 / (la * lb), 1 / (lb * le))):
        np.add.at(total, faces[:, k], w[:, None] * n)
    np.testing.assert_allclose(result.normals, total / np.linalg.norm(total, axis=1)[:, None], rtol=0, atol=1e-13)
    assert np.isclose(result.point_areas.sum(), 0.5 * np.linalg.norm(n, axis=1).sum(), rtol=1e-13)
    one, many = one_and_all_threads(lambda: CurvatureOperator.from_sorted(faces, len(p))(p))
    assert all(np.array_equal(x, y) for x, y in zip(_fields(one), _fields(many)))


@pytest.mark.parametrize("orientation", ["outward", "inward", "keep"])
def test_curvature_filter_equals_orientation_then_kernel(bunny, orientation):
    points, faces = np.asarray(bunny.points, float), bunny.regular_faces
    out = pverosion.curvature(bunny, orientation=orientation)
    gc.collect()  # the output's arrays share the kernel's memory: they must outlive the filter's temporaries
    _ = [np.full((bunny.n_points, 3), 7.0) for _ in range(8)]
    oriented = assert_filter_equals_kernel(out, points, faces, orientation)
    assert out.field_data["flipped_faces"][0] == oriented.n_flipped


@pytest.mark.parametrize(("nsub", "shuffle"), [(4, False), (6, True)])  # 2562 vertices: local; 40962 shuffled: not
def test_mean_curvature_operator_equals_the_full_estimate(nsub, shuffle):
    from pverosion.kernels.curvature.operator import MeanCurvatureOperator

    s = icosphere(1.0, nsub)
    p = np.asarray(s.points) * (1.0 + 0.05 * np.sin(3 * s.points[:, :1]) * np.cos(2 * s.points[:, 1:2]))
    faces = s.regular_faces.astype(np.int64)
    if shuffle:
        perm = np.random.default_rng(2).permutation(len(p))
        rank = np.empty_like(perm)
        rank[perm] = np.arange(len(perm))
        p, faces = p[perm], rank[faces]
    full = CurvatureOperator(faces, len(p))(p)
    mean_op = MeanCurvatureOperator(faces, len(p))
    mean = mean_op(p)
    assert (mean_op.renumbering is not None) == shuffle
    assert np.array_equal(mean.normals, full.normals) and np.array_equal(mean.point_areas, full.point_areas)
    assert np.allclose(mean.mean, full.mean, rtol=1e-12, atol=1e-12 * np.abs(full.mean).max())
    given = mean_op(p, normals=full.normals)
    assert np.array_equal(given.mean, mean.mean)
    one, many = one_and_all_threads(lambda: MeanCurvatureOperator(faces, len(p))(p))
    assert np.array_equal(one.mean, many.mean)


def test_a_mesh_with_edges_of_more_than_two_faces_is_warned_about(tmp_path, capsys):
    """A fin face on a sphere's edge shifts the curvature of its corners (H 0.38 instead of 1 at the fin's
    edge): the result is given, with a warning naming the cause, from every front end."""
    import warnings

    from pverosion.cli import main

    sphere = pv.Icosphere(radius=1.0, nsub=3)
    points, faces = np.asarray(sphere.points, np.float64), sphere.regular_faces
    a, b = faces[0, 0], faces[0, 1]
    tip = 0.5 * (points[a] + points[b]) * 1.5
    fin = pv.PolyData.from_regular_faces(np.vstack([points, tip]), np.vstack([faces, [[b, a, len(points)]]]))
    with pytest.warns(UserWarning, match="3 face sides lie on edges shared by more than two faces"):
        result = pverosion.curvature(fin)
    assert result.n_points == fin.n_points
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a closed manifold, and an open one, are not warned about
        pverosion.curvature(sphere)
        pverosion.curvature(sphere.remove_cells([0, 1, 2]))
    path = tmp_path / "fin.vtp"
    fin.save(path)
    assert main(["curvature", str(path), "-o", str(tmp_path / "out.vtp")]) == 0
    assert "warning: curvature: 3 face sides lie on edges shared by more than two faces" in capsys.readouterr().err
