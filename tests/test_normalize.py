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
