"""A second process that compiles some of a stage's kernels ahead of it while the stage runs on a cold cache.

numba compiles a kernel in the process that first calls it, one kernel after
another. On a cold cache (a fresh install) a stage's first run therefore
spends most of its time compiling on one core. When the stage compiles its
first kernel (the command line: before it imports the stage, when the cache
looks cold), :func:`start_helper` starts ``python -m pverosion._precompile
STAGE``: it compiles the stage's kernels into the same numba cache, those the
stage needs last first (:func:`helper_order`), while the stage compiles from
the first. Each process claims a kernel before compiling it
(:func:`shared_compilation`): the helper skips what the stage has claimed,
the stage waits for what the helper has claimed and then loads it from the
cache, so no kernel is compiled twice and the two meet in the middle. There
is no helper for a stage whose plan shows little to gain
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

import hashlib
import importlib
import importlib.util
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path

__all__ = ["CLAIM_SUFFIX", "HELPER_DELAY_S", "MIN_SAVING_S", "PLAN_FILE", "POLL_S",
           "WAIT_LIMIT_S", "compile_plan", "early_helper", "enabled", "helper_order", "helpers_allowed",
           "lock_cache_saves", "plan", "shared_compilation", "start_helper", "start_helper_if_cold",
           "stop_helper", "worth_a_helper"]

PLAN_FILE = Path(__file__).with_name("compile_plan.json")
ENVIRONMENT = "PVEROSION_PRECOMPILE"
HELPER_DELAY_S = 0.0
"""Seconds from the stage's first compilation until the helper, a new process, starts compiling: none, as the
command line starts the helper before it imports the stage (:func:`early_helper`), and the helper is compiling by
the time the stage reads its input."""
MIN_SAVING_S = 2.0
"""Compile seconds a helper must save a stage (by the plan's figures) to be started."""
WAIT_LIMIT_S = 90.0
"""Longest wait for another process's compilation of a kernel (:func:`shared_compilation`); a claim older than
this is taken as abandoned."""
POLL_S = 0.02
"""Seconds between two looks at a claim being waited for."""
CLAIM_SUFFIX = ".pverosion-compiling"
_allowed = False  # within helpers_allowed()
_helper: subprocess.Popen | None = None  # the helper this process started, until stop_helper
_waits = False  # shared_compilation waits for kernels another process has claimed
_holding: set[Path] = set()  # the claims this process holds


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


def _stage_seconds(seconds: list[float], order: list[int], delay: float) -> float:
    """Compile seconds of the stage's process when the helper, starting ``delay`` s later, takes the kernels in
    ``order``: the helper skips a kernel the stage has started, the stage waits for one the helper has started
    (:func:`shared_compilation`), loads those the helper has finished and compiles the others."""
    stage_clock, helper_clock, next_up = 0.0, delay, 0
    ready: dict[int, float] = {}  # kernel -> when the helper has it in the cache
    started: set[int] = set()
    for k, cost in enumerate(seconds):
        while next_up < len(order) and helper_clock <= stage_clock:  # the helper's starts until the stage gets to k
            j, next_up = order[next_up], next_up + 1
            if j not in started:
                started.add(j)
                helper_clock += seconds[j]
                ready[j] = helper_clock
        if k in ready:
            stage_clock = max(stage_clock, ready[k])
        else:
            started.add(k)
            stage_clock += cost
    return stage_clock


@cache
def _best_order(seconds: tuple[float, ...], delay: float) -> tuple[tuple[int, ...], float]:
    """:func:`helper_order` and the stage's compile seconds then."""
    order = list(reversed(range(len(seconds))))
    best = _stage_seconds(list(seconds), order, delay)
    for _ in range(len(seconds)):
        trials = [(_stage_seconds(list(seconds), [k, *(j for j in order if j != k)], delay), k) for k in order[1:]]
        if not trials or min(trials)[0] >= best - 1e-9:
            break
        best, k = min(trials)
        order = [k, *(j for j in order if j != k)]
    return tuple(order), best


def helper_order(seconds: list[float], *, delay: float = HELPER_DELAY_S) -> list[int]:
    """The order in which the helper compiles the kernels of a plan (indices into ``seconds``).

    The kernels the stage needs last come first, so that the stage, compiling
    from the first, and the helper meet in the middle; then, one at a time, the
    kernel whose move to the front shortens the stage's compilation most
    (:func:`_stage_seconds`), while one does.
    """
    return list(_best_order(tuple(seconds), delay)[0])


def worth_a_helper(stage: str) -> bool:
    """Whether the helper would save the stage at least :data:`MIN_SAVING_S` of compilation by the plan's figures
    (starting a process costs CPU time too, which a busy machine does not have to spare)."""
    seconds = [entry[3] for entry in plan(stage)]
    return sum(seconds) - _best_order(tuple(seconds), HELPER_DELAY_S)[1] >= MIN_SAVING_S


def compile_plan(stage: str) -> int:
    """Compile (or load from the cache) the kernels of ``stage``'s plan in :func:`helper_order`; returns how many
    it compiled or loaded.

    A kernel another process has claimed (:func:`shared_compilation`) is
    skipped: that process is compiling it. Entries whose module or function no
    longer exists, or that fail to compile for the recorded types, are skipped
    too: the stage itself compiles what it needs.
    """
    done = 0
    entries = plan(stage)
    for k in helper_order([entry[3] for entry in entries]):
        module, name, signature, _ = entries[k]
        try:
            kernel = getattr(importlib.import_module(module), name)
            types = _argument_types(signature)
        except Exception:  # noqa: BLE001, S112 - a stale entry only costs the stage its own compilation
            continue
        claim = _claim_path(kernel, types)
        if claim is not None and not _claim(claim):
            continue
        try:
            kernel.compile(types)
            done += 1
        except Exception:  # noqa: BLE001, S112 - as above
            continue
        finally:
            if claim is not None:
                _release(claim)
    return done


def _claim_path(dispatcher, types: tuple) -> Path | None:
    """The claim file of one signature of a cached pverosion kernel (beside its cache index); None for other
    functions, those without a file cache, and signatures this process has already."""
    folder = getattr(dispatcher._cache, "_cache_path", None)  # numba's NullCache has none
    function = dispatcher.py_func
    if folder is None or not function.__module__.startswith("pverosion.") or tuple(types) in dispatcher.overloads:
        return None
    key = f"{function.__module__}.{function.__qualname__}{tuple(types)}"
    return Path(folder) / f"{function.__name__}-{hashlib.sha1(key.encode()).hexdigest()[:20]}{CLAIM_SUFFIX}"


def _claimant_alive(claim: Path) -> bool | None:
    """Whether the process named in ``claim`` still runs and the claim is recent; None if there is no claim."""
    try:
        text = claim.read_text()
        age = time.time() - claim.stat().st_mtime
    except FileNotFoundError:
        return None
    if age > WAIT_LIMIT_S:
        return False
    if not text.strip():
        return True  # just created, the number not written yet
    try:
        pid = int(text)
    except ValueError:
        return False  # not a claim this module wrote
    if _helper is not None and pid == _helper.pid:
        return _helper.poll() is None  # an ended child is a zombie until polled: os.kill would still find it
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _claim(claim: Path) -> bool:
    """Create ``claim`` with this process's number; False if another live process holds it (an abandoned one is
    replaced)."""
    for _ in range(2):
        try:
            descriptor = os.open(claim, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if _claimant_alive(claim) is not False:
                return False
            claim.unlink(missing_ok=True)  # abandoned: its process ended mid-compilation
            continue
        except OSError:
            return False  # a read-only cache: nothing to share
        with os.fdopen(descriptor, "w") as file:
            file.write(str(os.getpid()))
        _holding.add(claim)
        return True
    return False


def _release(claim: Path) -> None:
    """Remove a claim this process holds."""
    _holding.discard(claim)
    claim.unlink(missing_ok=True)


def _wait_for(claim: Path) -> None:
    """Return once ``claim`` is gone or abandoned, or after :data:`WAIT_LIMIT_S`."""
    deadline = time.monotonic() + WAIT_LIMIT_S
    while _claimant_alive(claim) and time.monotonic() < deadline:
        time.sleep(POLL_S)


def shared_compilation(original):
    """``numba.core.dispatcher.Dispatcher.compile`` that shares compilations with the other processes on the cache.

    Before compiling a signature of a cached pverosion kernel, the process
    claims it with a file beside the kernel's cache index
    (:data:`CLAIM_SUFFIX`, created exclusively, holding the process number).
    If another live process holds the claim, this one waits until the claim is
    removed (the other has saved the kernel to the cache, or failed), then
    compiles as numba does: loading the kernel from the cache, found by
    numba's own index for exactly these argument types, or compiling it if
    the cache has no entry. A claim whose process has ended or older than
    :data:`WAIT_LIMIT_S` is abandoned; the wait never exceeds
    :data:`WAIT_LIMIT_S`. The helper waits only while it holds no claim (a
    kernel compiled when its module is imported), and :func:`compile_plan`
    skips what is claimed: a process waited for never waits itself, so two
    processes never wait for each other.
    """

    def compile(self, sig):
        from numba.core import sigutils

        claim = _claim_path(self, sigutils.normalize_signature(sig)[0])
        if claim is None:
            return original(self, sig)
        mine = _claim(claim)
        if not mine and claim not in _holding:
            if _waits or not _holding:
                _wait_for(claim)
            mine = _claim(claim)  # gone, or abandoned: compile (or load what the other saved)
        try:
            return original(self, sig)
        finally:
            if mine:
                _release(claim)

    compile.original = original
    return compile


def _share_compilations(*, wait: bool) -> None:
    """Install :func:`shared_compilation` in this process; ``wait``: for kernels another process has claimed."""
    global _waits
    from numba.core.dispatcher import Dispatcher

    _waits = wait
    if not hasattr(Dispatcher.compile, "original"):
        Dispatcher.compile = shared_compilation(Dispatcher.compile)


def _stop_sharing() -> None:
    """Undo :func:`_share_compilations`."""
    from numba.core.dispatcher import Dispatcher

    Dispatcher.compile = getattr(Dispatcher.compile, "original", Dispatcher.compile)


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
    """Start the helper process for ``stage`` if :func:`enabled`; None if not started. While it runs, this
    process shares its compilations with it (:func:`shared_compilation`)."""
    global _helper
    if _helper is not None or not enabled() or not worth_a_helper(stage):  # one at a time
        return None
    lock_cache_saves()
    package_parent = str(Path(__file__).resolve().parents[1])
    path = os.environ.get("PYTHONPATH", "")
    env = {**os.environ, ENVIRONMENT: "0", "PYTHONPATH": os.pathsep.join(p for p in (package_parent, path) if p)}
    _helper = subprocess.Popen([sys.executable, "-m", "pverosion._precompile", stage], env=env,
                               stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _share_compilations(wait=True)
    return _helper


def _cache_folder_probe() -> None:
    """A function numba's cache locators are asked about, in place of a kernel (:func:`_looks_cold`)."""


def _looks_cold(stage: str) -> bool:
    """Whether the cache has no entry for the first kernel of ``stage``'s plan (then it has none for the others
    either, after a fresh install); False when that cannot be told.

    The kernel's module is not imported: a module whose kernels have explicit
    signatures compiles them on import. Its cache folder is the one numba's
    locators give for the module's file, and the kernel's index is named
    ``<module file stem>.<kernel name>-<line>.py<version>.nbi``.
    """
    entries = plan(stage)
    if not entries:
        return False
    module, name, _, _ = entries[0]
    try:
        from numba.core.caching import CompileResultCacheImpl

        source = importlib.util.find_spec(module).origin
        if f"def {name}(" not in Path(source).read_text():
            return False  # a stale plan
        locators = (cls.from_function(_cache_folder_probe, source) for cls in CompileResultCacheImpl._locator_classes)
        folder = Path(next(locator for locator in locators if locator is not None).get_cache_path())
    except Exception:  # noqa: BLE001 - an unusual install: no early helper, the first compilation starts one
        return False
    return not any(folder.glob(f"{Path(source).stem}.{name}-*.nbi"))


def start_helper_if_cold(stage: str) -> subprocess.Popen | None:
    """:func:`start_helper` now, before the stage reads its input, if the cache looks cold (:func:`_looks_cold`):
    the helper is then ready sooner than when started by the stage's first compilation. The caller stops it
    (:func:`stop_helper`)."""
    if not enabled() or not worth_a_helper(stage) or not _looks_cold(stage):
        return None
    return start_helper(stage)


@contextmanager
def early_helper(stage: str) -> Iterator[None]:
    """Within this context, the helper of :func:`start_helper_if_cold`, stopped on leaving."""
    helper = start_helper_if_cold(stage)
    try:
        yield
    finally:
        stop_helper(helper)


def stop_helper(helper: subprocess.Popen | None) -> None:
    """End ``helper`` (numba writes each cache file whole, so stopping it mid-kernel leaves no partial entry; its
    claim is abandoned, see :func:`shared_compilation`)."""
    global _helper
    if helper is None:
        return
    if helper is _helper:
        _stop_sharing()
        _helper = None
    if helper.poll() is not None:
        return
    helper.terminate()
    try:
        helper.wait(timeout=5.0)
    except subprocess.TimeoutExpired:
        helper.kill()
        helper.wait()


if __name__ == "__main__":
    from pverosion._runtime import relax_gc_for_compilation

    relax_gc_for_compilation()  # this process only compiles
    lock_cache_saves()
    _share_compilations(wait=False)
    compile_plan(sys.argv[1])
