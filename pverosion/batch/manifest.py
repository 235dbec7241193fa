"""The batch manifest and results table: what has run, and its figures.

Only the process driving a batch writes these files, each through a
temporary file and a rename after every finished job, so a batch stopped at
any moment leaves a manifest that matches the job folders on disk.
"""

from __future__ import annotations

import csv
import io
import json
import os
from datetime import datetime, timezone
from pathlib import Path

from pverosion.batch.job import JOBS_FOLDER, read_result, write_json
from pverosion.batch.scenario import Job
from pverosion.io import atomic_path

__all__ = ["MANIFEST_FILE", "Manifest", "collect_results", "write_results"]

MANIFEST_FILE = "manifest.json"


class Manifest:
    """Status of every job ever run into a batch folder, keyed by job id.

    Parameters
    ----------
    root : path-like
        The batch output folder; ``root/manifest.json`` is read if present.

    Attributes
    ----------
    entries : dict
        Job id -> ``{"status", "index", "label", "folder", "error", "finished", "runs"}``.
    """

    def __init__(self, root: str | os.PathLike):
        self.root = Path(root)
        self.path = self.root / MANIFEST_FILE
        self.entries: dict[str, dict] = {}
        if self.path.is_file():
            try:
                data = json.loads(self.path.read_text(encoding="utf-8"))
            except json.JSONDecodeError as exc:
                raise ValueError(f"{self.path} is not valid JSON ({exc}); move it away to rebuild it") from None
            self.entries = dict(data.get("jobs", {}))

    def done(self, job: Job) -> bool:
        """Whether ``job`` completed (its folder holds a result)."""
        return self.entries.get(job.id, {}).get("status") == "done"

    def reconcile(self, jobs: tuple[Job, ...] | list[Job], rows: dict[str, dict]) -> int:
        """Bring the manifest in line with the job folders on disk; return how many results it had missed.

        A batch stopped between a job's folder rename and the manifest update
        leaves a complete folder the manifest does not know; its result is
        recorded rather than recomputed. Entries claiming "done" whose folder
        has gone are dropped, so those jobs run again.

        Parameters
        ----------
        jobs : sequence of Job
        rows : dict
            Result rows on disk by job id (:func:`collect_results`).
        """
        found = 0
        for job in jobs:
            row = rows.get(job.id)
            complete = row is not None and row["status"] == "done"
            if complete and not self.done(job):
                self.record(row, save=False)
                found += 1
            elif not complete and self.done(job):
                del self.entries[job.id]
        self.save()
        return found

    def record(self, result: dict, *, save: bool = True) -> None:
        """Store a job's result row (from :func:`~pverosion.batch.job.run_job`)."""
        previous = self.entries.get(result["id"], {})
        self.entries[result["id"]] = {
            "status": result["status"],
            "index": result["index"],
            "label": result["label"],
            "folder": result["folder"],
            "error": result.get("error", ""),
            "finished": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "runs": previous.get("runs", 0) + (0 if result.get("reused") else 1),
        }
        if save:
            self.save()

    def save(self) -> None:
        """Write the manifest atomically."""
        write_json({"jobs": self.entries}, self.path)


def collect_results(root: str | os.PathLike, jobs: tuple[Job, ...] | list[Job]) -> dict[str, dict]:
    """Result rows of ``jobs`` found on disk, by job id.

    Completed jobs are read from ``jobs/<folder>/result.json``, failed ones
    from ``jobs/<folder>.failed/result.json``; jobs not run yet are left out.
    """
    root = Path(root)
    rows = {}
    for job in jobs:
        row = read_result(root / JOBS_FOLDER / job.folder) or read_result(root / JOBS_FOLDER / f"{job.folder}.failed")
        if row is not None:
            rows[job.id] = row
    return rows


def write_results(root: str | os.PathLike, rows: list[dict]) -> None:
    """Write result rows to ``root/results.json`` and ``root/results.csv`` (union of all columns), atomically."""
    root = Path(root)
    write_json(rows, root / "results.json")
    columns: list[str] = []
    for row in rows:
        columns += [key for key in row if key not in columns]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, restval="", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    with atomic_path(root / "results.csv") as tmp:
        tmp.write_text(buffer.getvalue(), encoding="utf-8")
