"""Parallel loops on index ranges (:mod:`pverosion.kernels._threads`): every item once, whatever the threads."""

from __future__ import annotations

import threading

import numba
import numpy as np
import pytest
from numba import njit

from pverosion.kernels._scatter import CHUNKS, chunk_range
from pverosion.kernels._threads import MIN_ITEMS_PER_RANGE, for_chunks, for_ranges


@njit(nogil=True)
def _count_visits(visits, start, stop):
    for i in range(start, stop):
        visits[i] += 1


@njit(nogil=True)
def _chunk_sum(values, partial, c):
    start, stop = chunk_range(values.shape[0], c)
    for i in range(start, stop):
        partial[c] += values[i]


@pytest.fixture(params=[1, numba.config.NUMBA_NUM_THREADS])
def threads(request):
    before = numba.get_num_threads()
    numba.set_num_threads(request.param)
    yield request.param
    numba.set_num_threads(before)


@pytest.mark.parametrize("n_items", [0, 1, MIN_ITEMS_PER_RANGE - 1, 3 * MIN_ITEMS_PER_RANGE + 7, 100_003])
def test_ranges_visit_every_item_once(threads, n_items):
    visits = np.zeros(n_items, np.int64)
    for_ranges(_count_visits, n_items, visits)
    assert np.all(visits == 1)


def test_chunk_sums_do_not_depend_on_the_thread_count():
    values = np.random.default_rng(3).standard_normal(50_001) * 1e6
    sums = []
    before = numba.get_num_threads()
    try:
        for n in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(n)
            partial = np.zeros(CHUNKS)
            for_chunks(_chunk_sum, len(values), values, partial)
            sums.append(partial)
    finally:
        numba.set_num_threads(before)
    expected = [values[slice(*chunk_range(len(values), c))].sum() for c in range(CHUNKS)]
    np.testing.assert_allclose(sums[0], expected, rtol=1e-9)
    for other in sums[1:]:
        assert np.array_equal(other, sums[0])


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_ranges_run_in_several_threads_when_allowed():
    seen = set()
    both = threading.Barrier(2, timeout=30)  # broken (an error) unless a second thread runs the other range

    def record(start, stop):
        seen.add(threading.get_ident())
        both.wait()

    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        for_ranges(record, 2 * MIN_ITEMS_PER_RANGE)
    finally:
        numba.set_num_threads(before)
    assert len(seen) == 2


def test_an_error_in_a_range_reaches_the_caller():
    def fail(start, stop):
        if start > 0:
            raise ValueError("bad range")

    before = numba.get_num_threads()
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    try:
        if numba.get_num_threads() < 2:
            pytest.skip("needs two numba threads")
        with pytest.raises(ValueError, match="bad range"):
            for_ranges(fail, 4 * MIN_ITEMS_PER_RANGE)
    finally:
        numba.set_num_threads(before)


def test_loops_after_an_error_still_visit_every_item_once():
    def fail(start, stop):
        raise ValueError("bad range")

    before = numba.get_num_threads()
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    try:
        for _ in range(3):
            with pytest.raises(ValueError, match="bad range"):
                for_ranges(fail, 8 * MIN_ITEMS_PER_RANGE)
            visits = np.zeros(8 * MIN_ITEMS_PER_RANGE + 5, np.int64)
            for_ranges(_count_visits, len(visits), visits)
            assert np.all(visits == 1)
    finally:
        numba.set_num_threads(before)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_an_interrupt_in_a_pool_thread_reaches_the_caller():
    caller = threading.get_ident()
    both = threading.Barrier(2, timeout=30)  # the pool thread takes the second range

    def interrupt_elsewhere(start, stop):
        both.wait()
        if threading.get_ident() != caller:
            raise KeyboardInterrupt

    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        with pytest.raises(KeyboardInterrupt):
            for_ranges(interrupt_elsewhere, 2 * MIN_ITEMS_PER_RANGE)
    finally:
        numba.set_num_threads(before)
