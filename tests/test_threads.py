"""Parallel loops on index ranges (:mod:`pverosion.kernels._threads`): every item once, whatever the threads."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path

import numba
import numpy as np
import pytest
import pyvista as pv
from numba import njit

from pverosion.kernels._scatter import CHUNKS, chunk_range
from pverosion.kernels import _threads
from pverosion.kernels.curvature.operator import principal_curvatures
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


@pytest.fixture
def default_threads(monkeypatch):
    """numba's default thread count in this thread, ``NUMBA_NUM_THREADS`` unset, adaptation on."""
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    before, adapting = numba.get_num_threads(), _threads._adapt[0]  # a batch job run in this process turns it off
    numba.set_num_threads(numba.config.NUMBA_DEFAULT_NUM_THREADS)
    _threads.adapt_to_load(True)
    yield numba.config.NUMBA_DEFAULT_NUM_THREADS
    numba.set_num_threads(before)
    _threads.adapt_to_load(adapting)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS != numba.config.NUMBA_DEFAULT_NUM_THREADS,
                    reason="NUMBA_NUM_THREADS sets the pool size")
def test_other_running_programs_add_threads_only_to_the_default_count(default_threads, monkeypatch):
    n = default_threads
    monkeypatch.setattr(_threads, "other_running", lambda: 0)
    assert _threads._threads() == n
    monkeypatch.setattr(_threads, "other_running", lambda: 1)
    assert _threads._threads() == n + min(n, 2)
    monkeypatch.setattr(_threads, "other_running", lambda: 50)
    assert _threads._threads() == 2 * n  # never more than twice the count
    _threads.adapt_to_load(False)
    assert _threads._threads() == n
    _threads.adapt_to_load(True)
    monkeypatch.setenv("NUMBA_NUM_THREADS", str(n))  # a count the user chose is kept
    assert _threads._threads() == n
    monkeypatch.delenv("NUMBA_NUM_THREADS")
    if n > 1:
        numba.set_num_threads(n - 1)  # as are a lowered count and a stage's cap
        assert _threads._threads() == n - 1


@pytest.mark.skipif(not Path("/proc/loadavg").exists(), reason="reads /proc/loadavg (Linux)")
def test_a_spinning_program_is_seen_as_running(monkeypatch):
    monkeypatch.setattr(_threads, "LOAD_CHECK_S", 0.0)
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.3)
        _threads.other_running()
        assert _threads.other_running() >= 1
    finally:
        spinner.kill()
        spinner.wait()


def test_results_do_not_depend_on_threads_added_for_a_busy_machine(default_threads, monkeypatch):
    sphere = pv.Icosphere(nsub=5, radius=2.0)
    points, faces = np.asarray(sphere.points, np.float64), sphere.regular_faces
    values = np.random.default_rng(5).standard_normal(50_001) * 1e6
    runs = []
    for busy in (0, 3):
        monkeypatch.setattr(_threads, "other_running", lambda busy=busy: busy)
        partial = np.zeros(CHUNKS)
        for_chunks(_chunk_sum, len(values), values, partial)
        visits = np.zeros(100_003, np.int64)
        for_ranges(_count_visits, len(visits), visits)
        assert np.all(visits == 1)
        runs.append((partial, principal_curvatures(points, faces)))
    (sums0, curv0), (sums1, curv1) = runs
    assert np.array_equal(sums0, sums1)
    for name in ("k1", "k2", "direction1", "direction2", "normals", "point_areas"):
        assert np.array_equal(getattr(curv0, name), getattr(curv1, name))
