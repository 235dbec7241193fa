"""A second process that compiles some of a stage's kernels ahead of it while the stage runs on a cold cache.

numba compiles a kernel in the process that first calls it, one kernel after
another. On a cold cache (a fresh install) a stage's first run therefore
spends most of its time compiling on one core. When the stage compiles its
first kernel, :func:`start_helper` starts ``python -m pverosion._precompile
STAGE``: it compiles kernels the stage will need into the same numba cache,
chosen from their compile times so that each is ready before the stage gets
to it (:func:`helper_order`). The stage loads from the cache every kernel the
helper has finished by the time it gets there, and compiles the others.
There is no helper for a stage whose plan shows little to gain
(:func:`worth_a_helper`). When the stage is done, :func:`stop_helper` ends
the helper. Results do not change: the helper only fills the cache with the
code the stage would compile.

The kernels, argument types and compile seconds of each stage are listed, in
the order a run calls them, in ``compile_plan.json`` next to this module, written by
``python benchmarks/bench_cold_start.py --write-plan``. A kernel whose
argument types have changed since is compiled for nothing (the stage compiles
its own); one that no longer exists is skipped.

The command line starts helpers unless ``PVEROSION_PRECOMPILE`` is ``0``;
``PVEROSION_PRECOMPILE=1`` makes the Python API start them too. Only on POSIX
systems with several cores. Both processes save to the
cache under a file lock (:func:`lock_cache_saves`).
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path

__all__ = ["HELPER_DELAY_S", "MIN_SAVING_S", "PLAN_FILE", "compile_plan", "enabled", "helper_order",
           "helpers_allowed", "lock_cache_saves", "plan", "start_helper", "stop_helper", "worth_a_helper"]

PLAN_FILE = Path(__file__).with_name("compile_plan.json")
ENVIRONMENT = "PVEROSION_PRECOMPILE"
HELPER_DELAY_S = 2.0
"""Seconds from the stage's first compilation until the helper, a new process, starts compiling."""
MIN_SAVING_S = 4.0
"""Compile seconds a helper must save a stage (by the plan's figures) to be started."""
_allowed = False  # within helpers_allowed()


@cache
def _plans() -> dict[str, list[list]]:
    return json.loads(PLAN_FILE.read_text()) if PLAN_FILE.exists() else {}


def plan(stage: str) -> list[tuple[str, str, str, float]]:
    """The kernels of ``stage`` in the order a run compiles them: (module, function name, argument types, CPU
    seconds the compilation took when the plan was written)."""
    return [(module, name, signature, float(seconds)) for module, name, signature, seconds in _plans().get(stage, [])]


def _argument_types(text: str) -> tuple:
    """numba types from their ``repr`` tuple, e.g. ``"(Array(float64, 2, 'C', False, aligned=True), int64)"``."""
    from numba.core import types

    names = {**vars(types), "bool": types.boolean}
    return tuple(eval(text, {"__builtins__": {}}, names))  # the text comes from the package's own plan file


def _stage_seconds(seconds: list[float], taken: list[int], delay: float) -> float:
    """Compile seconds of the stage's process when the helper, starting ``delay`` s later, compiles the kernels
    ``taken`` (ascending) in that order: the stage loads those the helper has finished and compiles the rest."""
    ready, clock = {}, delay
    for k in taken:
        clock += seconds[k]
        ready[k] = clock
    clock = 0.0
    for k, cost in enumerate(seconds):
        if ready.get(k, float("inf")) > clock:
            clock += cost
    return clock


def _taken(seconds: list[float], delay: float) -> tuple[list[int], float]:
    """Greedily the kernels whose taking over shortens the stage's compilation most (:func:`_stage_seconds`),
    ascending, and the stage's compile seconds then."""
    taken: list[int] = []
    best = _stage_seconds(seconds, taken, delay)
    while True:
        trials = [(_stage_seconds(seconds, sorted([*taken, k]), delay), k)
                  for k in range(len(seconds)) if k not in taken]
        if not trials or min(trials)[0] >= best:
            return taken, best
        best, k = min(trials)
        taken = sorted([*taken, k])


def helper_order(seconds: list[float], *, delay: float = HELPER_DELAY_S) -> list[int]:
    """The order in which the helper compiles the kernels of a plan (indices into ``seconds``).

    The kernels of :func:`_taken`, in the stage's order of use; then the
    others, last used first, in case the stage runs slower than the plan's
    figures.
    """
    taken, _ = _taken(seconds, delay)
    return taken + [k for k in reversed(range(len(seconds))) if k not in taken]


def worth_a_helper(stage: str) -> bool:
    """Whether the helper would save the stage at least :data:`MIN_SAVING_S` of compilation by the plan's figures
    (starting a process costs CPU time too, which a busy machine does not have to spare)."""
    seconds = [entry[3] for entry in plan(stage)]
    return sum(seconds) - _taken(seconds, HELPER_DELAY_S)[1] >= MIN_SAVING_S


def compile_plan(stage: str) -> int:
    """Compile (or load from the cache) the kernels of ``stage``'s plan in :func:`helper_order`; returns how many
    it compiled or loaded.

    Entries whose module or function no longer exists, or that fail to compile
    for the recorded types, are skipped: the stage itself compiles what it needs.
    """
    done = 0
    entries = plan(stage)
    for k in helper_order([entry[3] for entry in entries]):
        module, name, signature, _ = entries[k]
        try:
            kernel = getattr(importlib.import_module(module), name)
            kernel.compile(_argument_types(signature))
        except Exception:  # noqa: BLE001, S112 - a stale entry only costs the stage its own compilation
            continue
        done += 1
    return done


def lock_cache_saves() -> None:
    """Make numba's cache saves in this process exclusive among the processes that call this.

    numba saves a kernel by reading the index of its function's cache, adding an
    entry with a free data file number, and writing the index and the data
    file. Two processes saving different signatures of one function at once
    could pick the same number, and the index could then name the other
    signature's code. A save here holds an exclusive ``flock`` on a lock file
    beside the index, so the read, the update and both writes happen as one.
    """
    import fcntl

    from numba.core import caching

    save = caching.IndexDataCacheFile.save
    if getattr(save, "locked", False):
        return

    def locked_save(self, key, data):
        with open(os.path.join(self._cache_path, "pverosion-cache.lock"), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                save(self, key, data)
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    locked_save.locked = True
    caching.IndexDataCacheFile.save = locked_save


@contextmanager
def helpers_allowed() -> Iterator[None]:
    """Within this context (the command line's), stages start compile helpers unless ``PVEROSION_PRECOMPILE=0``."""
    global _allowed
    before, _allowed = _allowed, True
    try:
        yield
    finally:
        _allowed = before


def enabled() -> bool:
    """Whether a stage starts a compile helper: ``PVEROSION_PRECOMPILE=1``, or unset within
    :func:`helpers_allowed`; on POSIX systems with several cores only."""
    setting = os.environ.get(ENVIRONMENT, "1" if _allowed else "0")
    return setting == "1" and os.name == "posix" and (os.cpu_count() or 1) > 1


def start_helper(stage: str) -> subprocess.Popen | None:
    """Start the helper process for ``stage`` if :func:`enabled`; None if not started."""
    if not enabled() or not worth_a_helper(stage):
        return None
    lock_cache_saves()
    package_parent = str(Path(__file__).resolve().parents[1])
    path = os.environ.get("PYTHONPATH", "")
    env = {**os.environ, ENVIRONMENT: "0", "PYTHONPATH": os.pathsep.join(p for p in (package_parent, path) if p)}
    return subprocess.Popen([sys.executable, "-m", "pverosion._precompile", stage], env=env,
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def stop_helper(helper: subprocess.Popen | None) -> None:
    """End ``helper`` (numba writes each cache file whole, so stopping it mid-kernel leaves no partial entry)."""
    if helper is None or helper.poll() is not None:
        return
    helper.terminate()
    try:
        helper.wait(timeout=5.0)
    except subprocess.TimeoutExpired:
        helper.kill()
        helper.wait()


if __name__ == "__main__":
    lock_cache_saves()
    compile_plan(sys.argv[1])
