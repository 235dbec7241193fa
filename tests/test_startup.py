"""Start-up: lazy imports, the stage index, threads, the compile notice and ``pverosion warmup``."""

from __future__ import annotations

import importlib
import gc
import io
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pytest

import pverosion
from pverosion import _runtime
from pverosion._runtime import (
    ALLOCATOR_SETTINGS,
    POINTS_PER_THREAD,
    WORK_NOT_IN_POINTS,
    HEAP_KEPT_PER_POINT,
    configure_allocator,
    configure_environment,
    keep_heap_for,
    stage_run,
    threads_for,
)
from pverosion._stages import STAGE_INDEX, load_stage
from pverosion.cli import main
from pverosion.warmup import WARMUPS, warm_up

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "dask", "distributed", "matplotlib", "vtkmodules", "pyvista", "scipy")


def _loaded_after(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; which of HEAVY it loaded, and what it printed."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps({{m: m in sys.modules for m in {HEAVY!r}}}))"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    *printed, last = done.stdout.strip().splitlines()
    return {"loaded": {m for m, yes in json.loads(last).items() if yes}, "stdout": "\n".join(printed)}


def test_import_loads_no_kernels_dask_or_matplotlib():
    assert _loaded_after("import pverosion")["loaded"] == set()


def test_help_loads_no_kernels_and_lists_every_stage():
    run = _loaded_after("from pverosion.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass")
    assert run["loaded"] == set()
    for stage in STAGE_INDEX:
        assert f"{stage.command} " in run["stdout"] or f"{stage.command}\n" in run["stdout"]
    assert "warmup" in run["stdout"]


def test_one_stage_imports_only_its_filter():
    others = ("pverosion.filters.repair", "pverosion.kernels.exact.predicates")
    run = _loaded_after("from pverosion.cli import build_parser\nbuild_parser(stages={'curvature'})\nimport sys\n"
                        f"print(*(m in sys.modules for m in {others!r}))")
    assert run["stdout"] == "False False"
    assert "numba" in run["loaded"]


def test_every_public_name_resolves():
    for name in pverosion.__all__:
        assert getattr(pverosion, name) is not None
    assert set(pverosion.__all__) <= set(dir(pverosion))
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        pverosion.nonsense  # noqa: B018
    import pverosion.kernels as kernels

    for name in kernels.__all__:
        assert getattr(kernels, name).__module__.startswith("pverosion.kernels")
    with pytest.raises(AttributeError):
        kernels.nonsense  # noqa: B018


def test_colour_map_is_registered_on_use():
    import matplotlib

    assert pverosion.CURVATURE_CMAP in matplotlib.colormaps


def test_stage_index_matches_the_filters():
    from pverosion.filters import ALL_FILTERS

    assert [s.command for s in STAGE_INDEX] == [cls.command_name() for cls in ALL_FILTERS]
    for stage, cls in zip(STAGE_INDEX, ALL_FILTERS):
        assert load_stage(stage.command) is cls
        assert stage.label == cls.LABEL
    assert set(WARMUPS) == {s.command for s in STAGE_INDEX}
    with pytest.raises(ValueError, match="unknown stage 'erode'"):
        load_stage("erode")


def test_stage_help_still_has_the_stage_options(capsys):
    with pytest.raises(SystemExit):
        main(["curvature", "--help"])
    assert "--orientation" in capsys.readouterr().out


def test_cold_stage_starts_its_helper_before_parsing_and_help_starts_none(monkeypatch, tmp_path):
    from pverosion import _precompile

    calls = []

    def start(stage):
        calls.append((stage, _precompile._allowed))
        return None

    monkeypatch.setattr(_precompile, "start_helper_if_cold", start)
    with pytest.raises(SystemExit):
        main(["curvature", "--help"])
    with pytest.raises(SystemExit):
        main(["weather", "-h"])
    assert calls == []
    with pytest.raises(SystemExit):  # a bad option: the helper was asked for, then argparse stops the run
        main(["curvature", str(tmp_path / "in.ply"), "-o", str(tmp_path / "out.vtp"), "--no-such-option"])
    assert calls == [("curvature", True)]  # within helpers_allowed, before the arguments were parsed


def test_allocator_settings_leave_the_users_settings(monkeypatch):
    monkeypatch.setattr(_runtime, "_allocator", {})  # the fake mallopt below is not kept for later tests
    calls = []

    def mallopt(number, value):
        calls.append((number, value))
        return 1

    assert configure_allocator({"MALLOC_TRIM_THRESHOLD_": "0"}, mallopt) == {}
    assert configure_allocator({"PVEROSION_MALLOC_TUNING": "0"}, mallopt) == {}
    assert calls == []  # nothing touched
    assert configure_allocator({}, mallopt) == {name: value for name, (_, value) in ALLOCATOR_SETTINGS.items()}
    assert calls == list(ALLOCATOR_SETTINGS.values())
    refused = configure_allocator({}, lambda number, value: 0)  # mallopt reports failure: reported as not set
    assert refused == {}


def test_the_heap_kept_mapped_grows_with_the_largest_input_and_never_shrinks(monkeypatch):
    monkeypatch.setattr(_runtime, "_allocator", {})
    calls = []

    def mallopt(number, value):
        calls.append((number, value))
        return 1

    memory = 16 << 30
    assert keep_heap_for(800_000, memory=memory) == 0  # the allocator is not tuned: nothing is touched
    assert calls == []
    configure_allocator({}, mallopt)
    trim_number, base = ALLOCATOR_SETTINGS["M_TRIM_THRESHOLD"]
    assert keep_heap_for(36_000, memory=memory) == base  # a small input: the import's setting stays
    assert len(calls) == len(ALLOCATOR_SETTINGS)
    big = keep_heap_for(800_000, memory=memory)
    assert big == HEAP_KEPT_PER_POINT * 800_000 > base and calls[-1] == (trim_number, big)
    assert keep_heap_for(400_000, memory=memory) == big  # never lowered
    assert keep_heap_for(10**9, memory=memory) == memory // 8  # at most an eighth of the memory
    with stage_run("curvature", 10**9):  # every stage run asks for its input's points
        pass
    assert calls[-1] == (trim_number, max(memory, _runtime._physical_memory()) // 8)


@pytest.mark.skipif(not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc", reason="glibc only")
def test_allocator_settings_apply_on_glibc():
    assert configure_allocator({}) == {name: value for name, (_, value) in ALLOCATOR_SETTINGS.items()}


def test_environment_defaults_leave_the_users_settings():
    env = {"OMP_WAIT_POLICY": "ACTIVE"}
    added = configure_environment(env)
    assert env == {"OMP_WAIT_POLICY": "ACTIVE", "KMP_BLOCKTIME": "0"}
    assert added == {"KMP_BLOCKTIME": "0"}
    assert configure_environment(env) == {}
    assert os.environ["OMP_WAIT_POLICY"]  # set (by the import of pverosion, or by the user)


@pytest.mark.parametrize(("n_points", "available", "expected"), [
    (0, 4, 4), (1, 4, 1), (POINTS_PER_THREAD, 4, 1), (POINTS_PER_THREAD + 1, 4, 2),
    (3 * POINTS_PER_THREAD, 2, 2), (10**7, 1, 1),
])
def test_threads_for_small_inputs(n_points, available, expected):
    assert threads_for(n_points, available) == expected


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_stage_run_caps_threads_for_small_inputs_and_restores_them():
    before = numba.get_num_threads()
    with stage_run("test", 10, stream=io.StringIO()):
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == before
    with stage_run("test", 10**7, stream=io.StringIO()):
        assert numba.get_num_threads() == before
    for stage in WORK_NOT_IN_POINTS:  # many particles or cells on a small mesh: all threads
        with stage_run(stage, 10, stream=io.StringIO()):
            assert numba.get_num_threads() == before
    assert WORK_NOT_IN_POINTS <= {s.command for s in STAGE_INDEX}


def test_compile_notice_is_shown_once_when_kernels_compile():
    @numba.njit
    def triple(x):
        return 3 * x

    out = io.StringIO()
    with stage_run("test", stream=out):
        assert triple(2) == 6
        assert triple(5) == 15  # the same signature: no second notice
    text = out.getvalue()
    assert text.count("compiling kernels, once per install") == 1
    assert "pverosion test: compiled 1 functions in" in text
    quiet = io.StringIO()
    with stage_run("test", stream=quiet):
        assert triple(4) == 12
    assert quiet.getvalue() == ""
    assert not getattr(_runtime._state, "active", False)


def test_compilation_relaxes_the_garbage_collector_and_the_stage_restores_it():
    @numba.njit
    def quadruple(x):
        return 4 * x

    thresholds, frozen = gc.get_threshold(), gc.get_freeze_count()
    assert frozen == 0
    with stage_run("test", stream=io.StringIO()):
        assert gc.get_threshold() == thresholds  # nothing compiled yet
        assert quadruple(2) == 8
        assert gc.get_threshold() == _runtime.COMPILE_GC_THRESHOLD
        assert gc.get_freeze_count() > 0
    assert gc.get_threshold() == thresholds
    assert gc.get_freeze_count() == 0
    gc.freeze()  # an application that froze its own objects keeps them frozen, and its thresholds
    try:
        assert _runtime.relax_gc_for_compilation() is None
        assert gc.get_threshold() == thresholds
    finally:
        gc.unfreeze()


def test_warm_up_runs_the_chosen_stages(capsys):
    seconds = warm_up(["curvature", "curvature"], processes=1)
    assert list(seconds) == ["curvature"] and seconds["curvature"] > 0
    assert main(["warmup", "curvature", "--processes", "1"]) == 0
    assert "warmup curvature:" in capsys.readouterr().out
    with pytest.raises(ValueError, match="unknown stage"):
        warm_up(["erode"])
    with pytest.raises(ValueError, match="processes"):
        warm_up(["curvature"], processes=0)


def test_warm_up_in_parallel_processes():
    seconds = warm_up(["curvature", "materials"], processes=2)
    assert set(seconds) == {"curvature", "materials"}
    assert all(s > 0 for s in seconds.values())


def test_compile_plan_names_existing_kernels_with_parsable_types():
    from numba.core.dispatcher import Dispatcher

    from pverosion import _precompile

    plans = json.loads(_precompile.PLAN_FILE.read_text())
    assert {"curvature", "weather", "boolean"} <= set(plans) <= {s.command for s in STAGE_INDEX}
    for stage in plans:
        for module, name, signature, seconds in _precompile.plan(stage):
            assert seconds >= 0.0
            kernel = getattr(importlib.import_module(module), name)
            assert isinstance(kernel, Dispatcher), (module, name)
            types = _precompile._argument_types(signature)
            assert str(types) == signature and len(types) == kernel.py_func.__code__.co_argcount


def test_compile_plan_compiles_its_entries_and_skips_stale_ones(monkeypatch):
    from pverosion import _precompile

    entries = [["pverosion.kernels.exact.intersection", "_spread", "(int64,)", 0.1],
               ["pverosion.kernels.exact.intersection", "no_such_kernel", "(int64,)", 0.1],
               ["pverosion.kernels.exact.intersection", "_spread", "(NoSuchType,)", 0.1]]
    monkeypatch.setattr(_precompile, "_plans", lambda: {"test": entries})
    assert _precompile.compile_plan("test") == 1
    from pverosion.kernels.exact.intersection import _spread

    assert (numba.int64,) in _spread.signatures


@pytest.mark.parametrize("seed", range(5))
def test_helper_order_covers_the_plan_and_never_slows_the_stage(seed):
    from pverosion._precompile import _stage_seconds, helper_order

    seconds = list(np.random.default_rng(seed).exponential(1.0, size=20))
    order = helper_order(seconds, delay=1.0)
    assert sorted(order) == list(range(20))
    assert _stage_seconds(seconds, order, 1.0) <= _stage_seconds(seconds, [], 1.0) == pytest.approx(sum(seconds))
    # the stage waits for a kernel the helper is compiling, so the helper only ever shortens it
    assert all(_stage_seconds(seconds, order[:n], 1.0) <= sum(seconds) + 1e-9 for n in range(21))
    # one long kernel used last: the helper starts with it, and the stage only compiles the others
    assert helper_order([1.0, 1.0, 1.0, 1.0, 3.0], delay=0.5)[0] == 4
    assert _stage_seconds([1.0, 1.0, 1.0, 1.0, 3.0], [4], 0.5) == 4.0


def test_stage_and_helper_meet_in_the_middle():
    from pverosion._precompile import _stage_seconds, helper_order

    # equal kernels, no delay: each process compiles half, the last ones first in the helper
    assert helper_order([1.0] * 6, delay=0.0) == [5, 4, 3, 2, 1, 0]
    assert _stage_seconds([1.0] * 6, [5, 4, 3, 2, 1, 0], 0.0) == 3.0
    # the stage reaches the kernel the helper is compiling: it waits for it instead of compiling it too
    assert _stage_seconds([1.0, 1.0, 4.0], [2], 0.0) == 4.0


def test_a_helper_only_where_the_plan_shows_enough_to_gain(monkeypatch):
    from pverosion import _precompile

    entry = ["pverosion.kernels.exact.intersection", "_spread", "(int64,)"]
    plans = {"short": [[*entry, 0.5]] * 6, "long": [[*entry, 1.0]] * 14 + [[*entry, 10.0]]}
    monkeypatch.setattr(_precompile, "_plans", lambda: plans)
    assert not _precompile.worth_a_helper("short") and not _precompile.worth_a_helper("unknown")
    assert _precompile.worth_a_helper("long")


def test_helper_only_when_allowed(monkeypatch):
    from pverosion import _precompile

    monkeypatch.delenv("PVEROSION_PRECOMPILE", raising=False)
    assert not _precompile.enabled()
    with _precompile.helpers_allowed():
        assert _precompile.enabled() == (os.name == "posix" and (os.cpu_count() or 1) > 1)
        monkeypatch.setenv("PVEROSION_PRECOMPILE", "0")
        assert not _precompile.enabled() and _precompile.start_helper("curvature") is None
    assert not _precompile._allowed


@pytest.mark.skipif(os.name != "posix", reason="the cache lock uses flock")
def test_locked_cache_saves_keep_every_entry_under_concurrent_saves(tmp_path):
    """Threads saving different keys of one function's cache at once: every key loads its own data."""
    from concurrent.futures import ThreadPoolExecutor

    from numba.core.caching import IndexDataCacheFile

    from pverosion._precompile import lock_cache_saves

    lock_cache_saves()
    lock_cache_saves()  # once is enough; a second call changes nothing
    cache_file = IndexDataCacheFile(str(tmp_path), "kernel-1.py311", source_stamp=(1.0, 10))

    def save(worker):
        for i in range(25):
            cache_file.save((worker, i), f"{worker}:{i}")

    with ThreadPoolExecutor(4) as pool:
        list(pool.map(save, range(4)))
    assert all(cache_file.load((w, i)) == f"{w}:{i}" for w in range(4) for i in range(25))
    assert (tmp_path / "pverosion-cache.lock").exists()


def _claim_of(code_kernel: str, types: str) -> str:
    """Python source defining ``kernel``, ``types`` and ``claim`` (its claim file) in a fresh process."""
    return (f"from numba import types as nt\nfrom pverosion import _precompile\n{code_kernel}\n"
            f"types = {types}\nclaim = _precompile._claim_path(kernel, types)\n")


@pytest.mark.skipif(os.name != "posix", reason="the claims are for the POSIX compile helper")
@pytest.mark.parametrize("stage", [True, False])
def test_a_kernel_claimed_by_another_process_is_waited_for_and_loaded_not_compiled(tmp_path, stage):
    """The claimant compiles only after the waiter has started waiting; the waiter then loads its cache entry.
    The stage waits always, the helper (``stage`` False) when it holds no claim itself."""
    kernel = "from pverosion.kernels.exact.intersection import _spread as kernel"
    setup = _claim_of(kernel, "(nt.uint16,)")
    claimant = setup + ("_precompile.lock_cache_saves()\nassert _precompile._claim(claim)\nprint('claimed', flush=True)\n"
                        "import sys\nsys.stdin.readline()\nkernel.compile(types)\nclaim.unlink()\n")
    waiter = setup + (
        "import json\nfrom numba.core import event\ncompiled = []\n"
        "class Seen(event.Listener):\n"
        "    def on_start(self, ev): compiled.append(ev.data['dispatcher'].py_func.__name__)\n"
        "    def on_end(self, ev): pass\n"
        "event.register('numba:compile', Seen())\n_precompile.lock_cache_saves()\n"
        f"_precompile._share_compilations(wait={stage})\nprint('waiting', flush=True)\n"
        "kernel.compile(types)\nprint(json.dumps({'compiled': compiled, 'claim_left': claim.exists(),"
        " 'value': kernel(nt.uint16(3))}))\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    first = subprocess.Popen([sys.executable, "-c", claimant], env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)
    assert first.stdout.readline().strip() == "claimed"
    second = subprocess.Popen([sys.executable, "-c", waiter], env=env, stdout=subprocess.PIPE, text=True)
    assert second.stdout.readline().strip() == "waiting"
    first.communicate("go\n", timeout=120)  # the claimant compiles only now, while the waiter waits
    result = json.loads(second.communicate(timeout=120)[0].strip().splitlines()[-1])
    assert first.returncode == 0 and second.returncode == 0
    assert result == {"compiled": [], "claim_left": False, "value": 0b1001}


@pytest.mark.skipif(os.name != "posix", reason="the claims are for the POSIX compile helper")
def test_an_abandoned_claim_is_taken_over_and_a_live_one_is_respected(tmp_path, monkeypatch):
    from pverosion import _precompile
    from pverosion.kernels.exact.intersection import _spread

    claim = _precompile._claim_path(_spread, (numba.types.uint32,))
    assert claim is not None and claim.name.endswith(_precompile.CLAIM_SUFFIX)
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                           check=True)
    claim.write_text(ended.stdout.strip())  # a process that has ended mid-compilation
    try:
        assert _precompile._claimant_alive(claim) is False
        assert _precompile._claim(claim) and claim.read_text() == str(os.getpid())
        claim.write_text(str(os.getppid()))  # a live process
        assert _precompile._claimant_alive(claim) and not _precompile._claim(claim)
        # the helper skips a plan entry another live process has claimed
        entries = [["pverosion.kernels.exact.intersection", "_spread", "(uint32,)", 0.1]]
        monkeypatch.setattr(_precompile, "_plans", lambda: {"test": entries})
        assert _precompile.compile_plan("test") == 0 and (numba.types.uint32,) not in _spread.overloads
        claim.unlink()
        assert _precompile._claimant_alive(claim) is None
        assert _precompile.compile_plan("test") == 1 and not claim.exists()
        assert _precompile._claim_path(_spread, (numba.types.uint32,)) is None  # compiled here: nothing to claim
    finally:
        claim.unlink(missing_ok=True)


def test_no_second_helper_while_one_runs(monkeypatch):
    from pverosion import _precompile

    class Running:
        pid = -1

        def poll(self):
            return None

    monkeypatch.setenv("PVEROSION_PRECOMPILE", "1")
    monkeypatch.setattr(_precompile, "_helper", Running())
    assert _precompile.start_helper("curvature") is None


def test_a_cold_cache_is_told_from_the_first_kernel_of_the_plan(tmp_path, monkeypatch):
    from pverosion import _precompile
    from pverosion.kernels.exact.intersection import _spread

    _spread(np.int64(1))  # in the cache now
    monkeypatch.setattr(_precompile, "_plans", lambda: {
        "warm": [["pverosion.kernels.exact.intersection", "_spread", "(int64,)", 0.1]],
        "stale": [["pverosion.kernels.exact.intersection", "no_such_kernel", "(int64,)", 0.1]]})
    assert not _precompile._looks_cold("warm") and not _precompile._looks_cold("stale")
    assert not _precompile._looks_cold("unknown")
    probe = "from pverosion import _precompile\nprint(_precompile._looks_cold('curvature'))"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(tmp_path / "empty")}
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "True"
