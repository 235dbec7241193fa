import numpy as np
import pytest

from pverosion.kernels._scratch import MIN_MAPPED_BYTES, scratch_arrays


@pytest.mark.parametrize("n", [10, MIN_MAPPED_BYTES // 128 + 7])  # heap-served and map-served
def test_scratch_arrays_are_zeroed_disjoint_aligned_and_writeable(n):
    specs = [((n, 3), np.float64), ((4, n, 4), np.float64), ((n,), np.int64), ((0, 3), np.float64)]
    arrays = scratch_arrays(*specs)
    for array, (shape, dtype) in zip(arrays, specs):
        assert array.shape == shape and array.dtype == dtype and array.flags.c_contiguous
        assert array.flags.writeable and not array.any()
        assert n < MIN_MAPPED_BYTES // 128 or array.ctypes.data % 64 == 0 or array.size == 0
    for k, array in enumerate(arrays[:3]):  # filling one array leaves the others zero
        array[...] = k + 1
    assert (arrays[0] == 1).all() and (arrays[1] == 2).all() and (arrays[2] == 3).all()
