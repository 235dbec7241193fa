import numpy as np
import pytest

from pverosion.kernels import (
    normalize_curvature,
    normalize_shifted,
    normalize_symmetric,
)


def test_symmetric_keeps_zero_and_sign():
    h = np.array([-4.0, -1.0, 0.0, 2.0])
    out = normalize_symmetric(h)
    np.testing.assert_allclose(out, h / 4.0)
    assert out[2] == 0.0 and np.abs(out).max() == 1.0


def test_symmetric_leaves_fitting_range_unchanged():
    h = np.array([-0.3, 0.0, 0.5])
    np.testing.assert_array_equal(normalize_symmetric(h), h)


def test_shifted_maps_range_to_unit_interval():
    h = np.array([-2.0, 0.0, 6.0])
    np.testing.assert_allclose(normalize_shifted(h), [0.0, 0.25, 1.0])
    np.testing.assert_array_equal(normalize_shifted(np.full(4, 3.0)), 0.5)


def test_unknown_method_is_rejected():
    with pytest.raises(ValueError, match="normalization must be one of"):
        normalize_curvature(np.zeros(3), "log")


def test_symmetric_always_divides_and_is_scale_free():
    h = np.array([-0.3, 0.0, 0.5])
    np.testing.assert_allclose(normalize_symmetric(h, always=True), [-0.6, 0.0, 1.0])
    np.testing.assert_array_equal(normalize_symmetric(1e3 * h, always=True), normalize_symmetric(h, always=True))
    np.testing.assert_array_equal(normalize_symmetric(np.zeros(3), always=True), 0.0)


def test_statistics_over_a_mask_clip_the_rest():
    h = np.array([30.0, -0.5, 0.25, 0.5])  # a rim vertex's estimate first
    interior = np.array([False, True, True, True])
    np.testing.assert_allclose(normalize_symmetric(h, where=interior, always=True), [1.0, -1.0, 0.5, 1.0])
    np.testing.assert_allclose(normalize_shifted(h, where=interior), [1.0, 0.0, 0.75, 1.0])
    nothing = np.zeros(4, bool)  # a mask selecting nothing counts as all
    np.testing.assert_array_equal(normalize_shifted(h, where=nothing), normalize_shifted(h))
    with pytest.raises(ValueError, match="where must have the shape"):
        normalize_shifted(h, where=interior[:3])


@pytest.mark.parametrize("method", ["symmetric", "shifted"])
def test_the_curvature_stage_normalisations_are_the_same_in_any_units(method):
    """A unit sphere and one of radius 100 (H about 1 and 0.01): the same normalised array to rounding; the
    symmetric one used the paper's rule, which leaves values within <-1, 1> alone."""
    import pyvista as pv

    import pverosion

    sphere = pv.Icosphere(radius=1.0, nsub=3)
    big = sphere.scale(100.0, inplace=False)
    small_out = pverosion.curvature(sphere, normalization=method)["mean_curvature_normalized"]
    big_out = pverosion.curvature(big, normalization=method)["mean_curvature_normalized"]
    np.testing.assert_allclose(big_out, small_out, rtol=1e-5, atol=1e-6)
    assert np.abs(small_out).max() == pytest.approx(1.0)

