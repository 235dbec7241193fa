"""Run one batch job into its own folder, atomically.

A job builds its input, runs its stages in order and writes everything into
a temporary folder next to its final one, then renames the folder into
place: a job folder is either complete or absent. The folder holds

- ``final.<format>``: the last stage's output;
- ``<stage>.pvd`` and ``<stage>/``: saved steps of time-dependent stages
  (``outputs.save_every``);
- ``final.png`` when ``outputs.screenshot`` is set;
- ``job.json`` (the job's full description), ``result.json`` (its figures)
  and ``log.txt``.

A job that raises is kept as ``<folder>.failed`` with its log and error, so a
later run retries it (with a fixed input file, as a new job of the same index,
whose success removes the failure's folder); :func:`run_job` never raises for a
failing stage.
"""

from __future__ import annotations

import json
import logging
import os
import platform
import shutil
import tempfile
import time
import traceback
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyvista as pv

from pverosion.batch.scenario import IMAGE_SUFFIXES, STAGES, Job
from pverosion.filters.base import output_times
from pverosion.io import TimeSeriesWriter, atomic_path, read_image, read_mesh, write_atomic

__all__ = ["RESULT_FILE", "job_figures", "read_result", "run_job", "warm_up", "write_json"]

RESULT_FILE = "result.json"
JOBS_FOLDER = "jobs"
TEMP_PREFIX = ".tmp-"


def write_json(data: Any, path: str | os.PathLike) -> None:
    """Write ``data`` as indented JSON to ``path`` through a temporary file and a rename."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, sort_keys=False, default=_plain) + "\n", encoding="utf-8")


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot write {type(value).__name__} to JSON")


def read_result(folder: str | os.PathLike) -> dict | None:
    """The result a completed job folder holds, or None if it has none."""
    path = Path(folder) / RESULT_FILE
    if not path.is_file():
        return None
    return json.loads(path.read_text(encoding="utf-8"))


def _on_dask_worker() -> bool:
    """Whether this runs in a Dask worker (not in the caller's process, as a serial batch does)."""
    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):
        return False
    return True


def run_job(job: Job, root: str | os.PathLike, *, threads: int | None = None) -> dict:
    """Run ``job`` into ``root/jobs/<job.folder>`` and return its result row.

    Running a job whose folder is already complete does nothing and returns
    the stored result (with ``reused`` true), so a job retried after its
    worker died, or run twice, is written exactly once. Warnings the stages
    give (a coarsely stored input, say) go to the job's log and to the
    ``warnings`` column, every time, where a worker's stderr would show each
    message once per process at most.

    Parameters
    ----------
    job : Job
    root : path-like
        The batch output folder.
    threads : int, optional
        Numba threads for this job (default: leave the process setting).

    Returns
    -------
    dict
        ``id``, ``index``, ``label``, ``folder``, ``status`` ("done" or
        "failed"), ``error``, ``warnings`` (their messages, joined by " | "),
        ``seconds``, ``worker``, the swept values and the figures of
        :func:`job_figures`.
    """
    jobs = Path(root) / JOBS_FOLDER
    final = jobs / job.folder
    stored = read_result(final)
    if stored is not None:
        return {**stored, "reused": True}
    jobs.mkdir(parents=True, exist_ok=True)
    if _on_dask_worker():  # the other programs running are mostly this batch's other workers
        from pverosion.kernels._threads import adapt_to_load

        adapt_to_load(False)
    if threads is not None:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    tmp = Path(tempfile.mkdtemp(prefix=f"{TEMP_PREFIX}{job.folder}-", dir=jobs))
    log, handler = _job_logger(job, tmp / "log.txt")
    row = {"id": job.id, "index": job.index, "label": job.label, "folder": job.folder, **job.swept,
           "status": "done", "error": "", "warnings": "", "worker": f"{platform.node()}:{os.getpid()}"}
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            write_json(job.to_dict(), tmp / "job.json")
            row.update(_execute(job, tmp, log))
        except Exception as exc:  # noqa: BLE001 - a failing job is recorded, the batch goes on
            row["status"] = "failed"
            row["error"] = f"{type(exc).__name__}: {exc}"
            log.error("job failed:\n%s", traceback.format_exc())
    messages = list(dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught))
    for message in messages:
        log.warning("%s", message)
    row["warnings"] = " | ".join(messages)
    row["seconds"] = time.perf_counter() - start
    log.info("%s in %.3f s", row["status"], row["seconds"])
    log.removeHandler(handler)
    handler.close()
    write_json(row, tmp / RESULT_FILE)
    if row["status"] == "failed":
        target = jobs / f"{job.folder}.failed"
        shutil.rmtree(target, ignore_errors=True)
        os.replace(tmp, target)
        return row
    try:
        os.rename(tmp, final)
    except OSError:  # another attempt of the same job finished first: keep its folder
        shutil.rmtree(tmp, ignore_errors=True)
        stored = read_result(final)
        if stored is None:
            raise
        return {**stored, "reused": True}
    for failed in jobs.glob(f"{job.index:04d}-*.failed"):  # this job's failure, or its own with an older input
        shutil.rmtree(failed, ignore_errors=True)
    return row


def _job_logger(job: Job, path: Path) -> tuple[logging.Logger, logging.Handler]:
    log = logging.getLogger(f"pverosion.batch.job.{job.id[:16]}")
    log.setLevel(logging.INFO)
    log.propagate = False
    handler = logging.FileHandler(path, encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    log.addHandler(handler)
    log.info("job %d (%s) %s on %s pid %d", job.index, job.id[:10], job.label or "(no sweep)", platform.node(),
             os.getpid())
    return log, handler


def _load_input(spec: dict) -> pv.DataSet:
    if "file" in spec:
        path = spec["file"]
        return read_image(path) if path.lower().endswith(IMAGE_SUFFIXES) else read_mesh(path)
    from pverosion.examples import EXAMPLES

    return EXAMPLES[spec["example"]](**spec["options"])


def _execute(job: Job, folder: Path, log: logging.Logger) -> dict:
    data = _load_input(job.input)
    log.info("input: %s with %d points, %d cells", type(data).__name__, data.n_points, data.n_cells)
    source = data
    figures: dict[str, Any] = {}
    for spec in job.stages:
        cls = STAGES[spec["stage"]]
        options = dict(spec["options"])
        for p in cls.PARAMS:
            if p.path == "output" and options.get(p.name):
                options[p.name] = str(folder / options[p.name])
        alg = cls(**options)
        log.info("stage %s (%s) %s", spec["name"], spec["stage"], json.dumps(spec["options"], sort_keys=True))
        start = time.perf_counter()
        if cls.TIME_DEPENDENT:
            data = _run_time_stage(alg, data, spec["name"], job.outputs["save_every"], folder, log)
        else:
            data = pv.wrap(alg.run(data))
        figures[f"seconds_{spec['name']}"] = time.perf_counter() - start
        log.info("stage %s done in %.3f s", spec["name"], figures[f"seconds_{spec['name']}"])
    out = write_atomic(data, folder / f"final.{job.outputs['format']}")
    log.info("wrote %s", out.name)
    if job.outputs["screenshot"]:
        from pverosion.plotting import plot_slices, render_scalars

        shot = folder / "final.png"
        if isinstance(data, pv.ImageData):
            plot_slices(data, shot)
        else:  # every surface stage outputs mean_curvature
            render_scalars(data, shot)
        log.info("wrote %s", shot.name)
    figures.update(job_figures(source, data))
    log.info("figures %s", json.dumps(figures, default=_plain))
    return figures


def _run_time_stage(alg, data, name: str, save_every: int, folder: Path, log: logging.Logger):
    n = alg.get_option("iterations")
    series = TimeSeriesWriter(folder / f"{name}.pvd") if save_every else None
    logged = [-1]

    def progress(t: float) -> None:
        tenth = int(10 * t / max(n, 1))
        if tenth > logged[0]:
            logged[0] = tenth
            log.info("stage %s: step %d of %d", name, int(t), n)

    def save(t: float, result) -> None:
        if series is not None:
            series.write(result, time=t)

    result = alg.step_through(data, output_times(n, save_every), on_output=save, on_progress=progress)
    return pv.wrap(result)


def job_figures(before: pv.DataSet, after: pv.DataSet) -> dict[str, float]:
    """Figures of a job's result row.

    Parameters
    ----------
    before, after : pyvista.DataSet
        The job's input and final output.

    Returns
    -------
    dict
        ``points``, ``cells`` (of ``after``); for triangle surfaces also
        ``volume_before``, ``volume``, ``volume_change`` (relative),
        ``area_before``, ``area`` and mean-curvature statistics
        ``mean_curvature_mean``, ``mean_curvature_abs_mean``,
        ``mean_curvature_abs_max`` (recomputed on the output, outward);
        ``retries``, ``frozen_vertices`` and ``collapses`` when a weathering
        stage reported them. For a MultiBlock, those of its surface: block
        ``surface`` (voxel erosion, shards, freeze-thaw) or ``mesh``
        (hydraulic erosion); with a voxel ``state`` block, its size instead and
        ``mass_error``.
    """
    from pverosion.api import curvature

    if isinstance(after, pv.MultiBlock):
        names = after.keys()
        figures = job_figures(before, after["surface" if "surface" in names else "mesh"])
        if "state" in names:  # voxel erosion: the state's size
            state = after["state"]
            figures.update(points=int(state.n_points), cells=int(state.n_cells))
            if "mass_error" in state.field_data:
                figures["mass_error"] = float(state.field_data["mass_error"][0])
        return figures
    figures: dict[str, float] = {"points": int(after.n_points), "cells": int(after.n_cells)}
    if isinstance(after, pv.PolyData) and isinstance(before, pv.PolyData) and after.is_all_triangles:
        figures["volume_before"] = float(before.volume)
        figures["volume"] = float(after.volume)
        figures["volume_change"] = (figures["volume"] - figures["volume_before"]) / abs(figures["volume_before"]) \
            if figures["volume_before"] else float("nan")
        figures["area_before"] = float(before.area)
        figures["area"] = float(after.area)
        h = np.asarray(curvature(after)["mean_curvature"])
        figures["mean_curvature_mean"] = float(h.mean())
        figures["mean_curvature_abs_mean"] = float(np.abs(h).mean())
        figures["mean_curvature_abs_max"] = float(np.abs(h).max())
    for name, key in (("retries", "retries"), ("frozen_vertices", "frozen_vertices"),
                      ("weathering_collapses", "collapses")):
        if name in after.field_data:
            figures[key] = int(np.sum(after.field_data[name]))
    return figures


def warm_up(stages: Sequence[str] = ("weather",)) -> str:
    """Load the compiled kernels of ``stages`` in this process (tiny runs); returns the worker's name.

    Batch runs call this on every worker at start-up, so the first job of a
    worker is not charged with loading numba's cache.
    """
    from pverosion.warmup import warm_up as warm_stages

    warm_stages(stages, processes=1)
    return f"{platform.node()}:{os.getpid()}"
