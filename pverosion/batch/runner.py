"""Run a scenario's jobs on Dask distributed (or serially), resumably.

The driving process expands the scenario, skips the jobs its output folder
already holds, submits the rest to a Dask cluster and records each result
in the manifest and results table as it arrives. Workers write only into
their job's own folder (see :mod:`pverosion.batch.job`). A worker that dies
mid-job has its job rescheduled on another worker by Dask (up to
``distributed.scheduler.allowed-failures`` times); a job that raises is
recorded as failed and the batch goes on.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from tqdm.auto import tqdm

from pverosion.batch.job import JOBS_FOLDER, TEMP_PREFIX, run_job, warm_up, write_json
from pverosion.batch.manifest import Manifest, collect_results, write_results
from pverosion.batch.scenario import Job, Scenario, ScenarioError, load_scenario, tomllib
from pverosion.io import atomic_path
from pverosion.limits import check_memory
from pverosion.warmup import warm_up as warm_stages

WORKER_BYTES = 150 << 20
"""Estimated memory of one local worker process before its first job (Python, NumPy, VTK, numba)."""

__all__ = ["BatchReport", "run_batch"]

_SPAWN_ENVIRON = "distributed.nanny.pre-spawn-environ"


@dataclass
class BatchReport:
    """What a call of :func:`run_batch` did.

    Attributes
    ----------
    root : pathlib.Path
        The batch output folder.
    rows : list of dict
        Result rows of the scenario's jobs that have run (now or before), in sweep order.
    ran : list of str
        Ids of the jobs run by this call.
    skipped : int
        Jobs already complete before this call.
    failed : int
        Jobs of the scenario whose last run failed.
    seconds_startup : float
        Cluster start-up and warm-up (0 for a serial run).
    seconds : float
        Wall time of the jobs themselves.
    workers : int
        Workers at the start (1 for a serial run).
    """

    root: Path
    rows: list[dict] = field(default_factory=list)
    ran: list[str] = field(default_factory=list)
    skipped: int = 0
    failed: int = 0
    seconds_startup: float = 0.0
    seconds: float = 0.0
    workers: int = 1


def run_batch(
    scenario: Scenario | str | os.PathLike,
    out: str | os.PathLike,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    serial: bool = False,
    client=None,
    threads_per_job: int | None = None,
    progress: bool = True,
    on_result: Callable[[dict, object], None] | None = None,
) -> BatchReport:
    """Run every job of ``scenario`` not yet complete in ``out``.

    Parameters
    ----------
    scenario : Scenario or path-like
        A parsed scenario or a TOML file (validated before anything runs).
    out : path-like
        Output folder: ``jobs/<folder>/`` per job, ``manifest.json``,
        ``results.json``, ``results.csv``, a copy of the scenario
        (``scenario.toml``) and the expanded jobs (``jobs.json``).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); its
        workers need pverosion installed and must see ``out`` at the same
        path (a shared file system).
    workers : int, optional
        Workers of the embedded ``LocalCluster`` (default: one per core).
    serial : bool, default: False
        Run the jobs one after another in this process, without Dask.
    client : distributed.Client, optional
        Use this client (and its cluster) instead of making one.
    threads_per_job : int, optional
        Numba threads per job (default: cores / workers on a local cluster,
        1 on a remote scheduler, all in a serial run).
    progress : bool, default: True
        Show a progress bar of finished jobs.
    on_result : callable, optional
        ``on_result(row, client)`` after each job's result is recorded
        (``client`` is None in a serial run).

    Returns
    -------
    BatchReport

    Raises
    ------
    ScenarioError
        If the scenario is invalid (before any job starts).
    ValueError
        If ``out`` is a file, or a folder that cannot be made (before any job starts).
    RuntimeError
        If another batch is running into ``out``, or the workers cannot see ``out``.
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario)
    if serial and (scheduler or client is not None or workers):
        raise ValueError("serial=True runs in this process; do not give scheduler, client or workers")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1; got {workers}")
    if workers is not None and scheduler is None and client is None:  # a local cluster starts one process each
        check_memory(workers * WORKER_BYTES, option="workers", what=f"a local cluster of {workers} worker processes")
    if threads_per_job is not None and threads_per_job < 1:
        raise ValueError(f"threads_per_job must be >= 1; got {threads_per_job}")
    root = Path(out).resolve()
    jobs = scenario.jobs
    with ExitStack() as stack:
        stack.enter_context(_exclusive(root))
        _prepare(root, scenario)
        manifest = Manifest(root)
        rows = collect_results(root, jobs)
        manifest.reconcile(jobs, rows)
        pending = [job for job in jobs if not manifest.done(job)]
        report = BatchReport(root=root, skipped=len(jobs) - len(pending))
        bar = stack.enter_context(tqdm(total=len(jobs), initial=report.skipped, desc=scenario.name, unit="job",
                                       disable=not progress))

        def finish(row: dict, active_client) -> None:
            manifest.record(row)
            rows[row["id"]] = row
            write_results(root, [rows[job.id] for job in jobs if job.id in rows])
            if not row.get("reused"):
                report.ran.append(row["id"])
            bar.update(1)
            if on_result is not None:
                on_result(row, active_client)

        if not pending:
            write_results(root, [rows[job.id] for job in jobs if job.id in rows])
        elif serial:
            start = time.perf_counter()
            for job in pending:
                finish(run_job(job, root, threads=threads_per_job), None)
            report.seconds = time.perf_counter() - start
        else:
            start = time.perf_counter()
            stages = sorted({stage["stage"] for job in pending for stage in job.stages})
            if client is None and scheduler is None:  # fill numba's cache once, stages in parallel processes
                warm_stages(stages, processes=workers)
            active = client if client is not None else stack.enter_context(
                _client(scheduler=scheduler, workers=workers))
            threads = threads_per_job or _default_threads(active, local=scheduler is None)
            _check_workers(active, root, stages)
            report.seconds_startup = time.perf_counter() - start
            report.workers = len(active.scheduler_info(n_workers=-1)["workers"])
            start = time.perf_counter()
            _run_on_dask(active, pending, root, threads, finish)
            report.seconds = time.perf_counter() - start
            _remove_leftovers(root)  # attempts cut short by a worker's death
        report.rows = [rows[job.id] for job in jobs if job.id in rows]
        report.failed = sum(row["status"] != "done" for row in report.rows)
    return report


def _run_on_dask(client, pending: list[Job], root: Path, threads: int, finish: Callable) -> None:
    from distributed import as_completed

    futures = {client.submit(run_job, job, str(root), threads=threads, pure=False): job for job in pending}
    try:
        for future in as_completed(futures):
            job = futures[future]
            try:
                row = future.result()
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker after repeated worker deaths
                row = {"id": job.id, "index": job.index, "label": job.label, "folder": job.folder, **job.swept,
                       "status": "failed", "error": f"{type(exc).__name__}: {exc}"}
            finish(row, client)
    finally:
        client.cancel(list(futures))


@contextmanager
def _client(*, scheduler: str | None, workers: int | None):
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        with Client(scheduler) as client:
            yield client
        return
    import dask

    n = workers or os.cpu_count() or 1
    # Dask sets MALLOC_TRIM_THRESHOLD_ in its workers, which also pins glibc's mmap threshold: every
    # array above 128 KiB is then mapped and unmapped afresh, which slows array-heavy jobs (bench_batch.py).
    with dask.config.set({f"{_SPAWN_ENVIRON}.MALLOC_TRIM_THRESHOLD_": None}), \
            LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                         silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client


def _default_threads(client, *, local: bool) -> int:
    if not local:
        return 1
    n_workers = max(len(client.scheduler_info(n_workers=-1)["workers"]), 1)
    return max(1, (os.cpu_count() or 1) // n_workers)


def _check_workers(client, root: Path, stages: list[str]) -> None:
    """Fail early unless every worker sees the output folder; load the kernels on every worker."""
    seen = client.run(os.path.isdir, str(root))
    blind = [worker for worker, ok in seen.items() if not ok]
    if blind:
        raise RuntimeError(f"workers {', '.join(blind)} cannot see the output folder {root}: "
                           "batch outputs need a file system shared by the driver and every worker")
    warm = [client.submit(warm_up, stages, workers=[worker], allow_other_workers=False, pure=False) for worker in seen]
    client.gather(warm)


def _remove_leftovers(root: Path) -> None:
    """Remove the temporary folders of job attempts that were interrupted (their jobs ran again)."""
    for stale in (root / JOBS_FOLDER).glob(f"{TEMP_PREFIX}*"):
        shutil.rmtree(stale, ignore_errors=True)


def _prepare(root: Path, scenario: Scenario) -> None:
    """Create the output folders, remove leftovers of interrupted jobs, keep the scenario and job list.

    Raises
    ------
    ScenarioError
        If ``root`` holds the results of a different scenario (its content,
        comments and layout aside): one folder, one scenario.
    """
    kept = root / "scenario.toml"
    if kept.is_file():
        try:
            same = tomllib.loads(kept.read_text(encoding="utf-8")) == tomllib.loads(scenario.text)
        except tomllib.TOMLDecodeError:
            same = False
        if not same:
            raise ScenarioError(f"{root} holds the results of another scenario ({kept}); give this one another "
                                "output folder, or remove that one")
    (root / JOBS_FOLDER).mkdir(parents=True, exist_ok=True)
    _remove_leftovers(root)
    with atomic_path(root / "scenario.toml") as tmp:
        tmp.write_text(scenario.text, encoding="utf-8")
    write_json([job.to_dict() for job in scenario.jobs], root / "jobs.json")


@contextmanager
def _exclusive(root: Path):
    """Hold an exclusive lock on ``root/.batch.lock`` (released when the process ends, however it ends)."""
    if root.exists() and not root.is_dir():
        raise ValueError(f"batch output folder {root}: is a file; give a folder")
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"batch output folder {root}: cannot be made ({exc.strerror or exc})") from None
    try:
        import fcntl
    except ImportError:  # not on POSIX: no lock
        yield
        return
    with open(root / ".batch.lock", "w") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise RuntimeError(f"another batch is running into {root}") from None
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
