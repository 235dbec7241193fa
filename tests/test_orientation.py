import numpy as np
import pytest
from conftest import height_field, icosphere

from pverosion.kernels import orient_faces, signed_volume, winding_number


def _scramble(faces, seed=0):
    rng = np.random.default_rng(seed)
    flip = rng.random(len(faces)) < 0.5
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, flip


def test_scrambled_sphere_becomes_consistent_and_outward():
    s = icosphere(1.0, 3)
    scrambled, flip = _scramble(s.regular_faces)
    o = orient_faces(s.points, scrambled)
    assert o.n_components == 1
    np.testing.assert_array_equal(o.flipped, flip)
    assert signed_volume(s.points, o.faces) > 0
    inward = orient_faces(s.points, scrambled, mode="inward")
    assert signed_volume(s.points, inward.faces) < 0
    kept = orient_faces(s.points, scrambled, mode="keep")
    np.testing.assert_array_equal(kept.faces, scrambled)
    with pytest.raises(ValueError, match="orientation must be one of"):
        orient_faces(s.points, scrambled, mode="up")


def test_bunny_scan_is_turned_outward(bunny):
    p, f = np.asarray(bunny.points, float), bunny.regular_faces
    assert signed_volume(p, f) < 0  # the file winds inward
    o = orient_faces(p, f)
    assert o.n_flipped == len(f)
    assert signed_volume(p, o.faces) > 0


def test_open_dome_faces_up_whatever_its_input_winding():
    dome = height_field(lambda x, y: 1.0 - 0.5 * (x**2 + y**2), n=21)
    for faces in (dome.regular_faces, dome.regular_faces[:, ::-1]):
        o = orient_faces(dome.points, faces)
        n = np.cross(*(dome.points[o.faces[:, k]] - dome.points[o.faces[:, 0]] for k in (1, 2)))
        assert np.all(n[:, 2] > 0)


def test_cavity_wall_points_into_the_cavity():
    outer, inner = icosphere(2.0, 2), icosphere(1.0, 2)
    p = np.vstack([outer.points, inner.points])
    f = np.vstack([outer.regular_faces, inner.regular_faces[:, ::-1] + outer.n_points])
    f, _ = _scramble(f, seed=3)
    o = orient_faces(p, f)
    n_outer = len(outer.regular_faces)
    assert signed_volume(p, o.faces[:n_outer]) > 0  # outer shell outward
    assert signed_volume(p, o.faces[n_outer:]) < 0  # cavity wall faces into the hole
    solid = signed_volume(outer.points, outer.regular_faces) - signed_volume(inner.points, inner.regular_faces)
    assert np.isclose(signed_volume(p, o.faces), solid, rtol=1e-9)


def test_winding_number_inside_and_outside():
    s = icosphere(1.0, 3)
    assert winding_number([0.1, 0.0, 0.2], s.points, s.regular_faces) == pytest.approx(1.0, abs=1e-9)
    assert winding_number([3.0, 0.0, 0.0], s.points, s.regular_faces) == pytest.approx(0.0, abs=1e-9)
