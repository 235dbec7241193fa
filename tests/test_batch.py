"""Batch runs: scenario validation, resumable runs, Dask cluster equal to serial, worker death, forced stop."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

from pverosion.batch import Manifest, ScenarioError, load_scenario, parse_scenario, run_batch
from pverosion.batch.runner import _exclusive
from pverosion.cli import main

SWEEP = """
name = "rocks"
[input]
example = "rock"
subdivisions = 4
[[stages]]
stage = "weather"
iterations = 60
[[stages]]
stage = "curvature"
[sweep]
"weather.power" = [1.0, 2.0, 4.0]
"input.seed" = [1, 2, 3, 4]
[outputs]
save_every = 20
"""


def _write(folder: Path, text: str, name: str = "scenario.toml") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _outputs(root: Path) -> dict[str, bytes]:
    """Every file of the completed job folders except the log and result (which hold timings)."""
    files = {}
    for path in sorted((root / "jobs").rglob("*")):
        if path.is_file() and path.name not in ("log.txt", "result.json"):
            files[str(path.relative_to(root))] = path.read_bytes()
    return files


def _check_complete(root: Path, n_jobs: int) -> list[dict]:
    """All jobs exactly once: results, manifest and folders agree; no temporary folders left."""
    rows = json.loads((root / "results.json").read_text())
    assert len(rows) == n_jobs and len({r["id"] for r in rows}) == n_jobs
    assert all(r["status"] == "done" for r in rows)
    manifest = Manifest(root)
    assert {k for k, e in manifest.entries.items() if e["status"] == "done"} == {r["id"] for r in rows}
    folders = sorted(p.name for p in (root / "jobs").iterdir())
    assert folders == sorted(r["folder"] for r in rows)
    csv_lines = (root / "results.csv").read_text().strip().splitlines()
    assert len(csv_lines) == n_jobs + 1
    return rows


@pytest.fixture(scope="module")
def serial_reference(tmp_path_factory):
    folder = tmp_path_factory.mktemp("serial")
    scenario = _write(folder, SWEEP)
    report = run_batch(scenario, folder / "out", serial=True, progress=False)
    assert len(report.ran) == 12 and report.failed == 0
    return scenario, folder / "out"


# --- scenario files -------------------------------------------------------------------------------------


def test_sweep_expands_to_the_cartesian_product_in_order(tmp_path):
    scenario = load_scenario(_write(tmp_path, SWEEP))
    assert len(scenario.jobs) == 12
    powers = [job.stages[0]["options"]["power"] for job in scenario.jobs]
    seeds = [job.input["options"]["seed"] for job in scenario.jobs]
    assert powers == [1.0] * 4 + [2.0] * 4 + [4.0] * 4 and seeds == [1, 2, 3, 4] * 3
    assert len({job.id for job in scenario.jobs}) == 12
    # ids depend on content only: the same scenario parsed again gives the same jobs
    assert [j.id for j in load_scenario(tmp_path / "scenario.toml").jobs] == [j.id for j in scenario.jobs]


def test_scenario_seed_fills_unset_seed_options(tmp_path):
    text = '[input]\nexample = "rock"\n[[stages]]\nstage = "weather"\n'
    assert parse_scenario("seed = 7\n" + text).jobs[0].input["options"]["seed"] == 7
    swept = parse_scenario(text + '[sweep]\nseed = [3, 5]\n')
    assert [j.input["options"]["seed"] for j in swept.jobs] == [3, 5]


def test_input_file_is_resolved_against_the_scenario_folder(tmp_path):
    (tmp_path / "meshes").mkdir()
    pv.Sphere().save(tmp_path / "meshes" / "ball.vtp")
    scenario = load_scenario(_write(tmp_path, '[input]\nfile = "meshes/ball.vtp"\n[[stages]]\nstage = "curvature"\n'))
    assert scenario.jobs[0].input["file"] == str((tmp_path / "meshes" / "ball.vtp").resolve())


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "wether"\n', r"\[\[stages\]\] #1.*unknown stage 'wether'"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "weather"\npower = "high"\n',
         r"\[\[stages\]\] #1 \(weather\): power must be a number"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "weather"\npowr = 2\n', r"no option 'powr'"),
        ('[input]\nfile = "missing.ply"\n[[stages]]\nstage = "curvature"\n', r"\[input\] file: no such file 'missing.ply'"),
        ('[input]\nexample = "rock"\nsubdivisons = 3\n[[stages]]\nstage = "curvature"\n',
         r"\[input\] example 'rock': unknown key 'subdivisons'"),
        ('[input]\nexample = "boulder"\n[[stages]]\nstage = "curvature"\n', r"unknown example 'boulder'"),
        ('[input]\nexample = "rock"\n', r"\[\[stages\]\]: missing"),
        ('[[stages]]\nstage = "curvature"\n', r"\[input\]: missing"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "curvature"\n[output]\nformat = "vtp"\n',
         r"top level: unknown key 'output'"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "weather"\n[sweep]\n"weather.power" = [1.0, 0.5]\n',
         r"\[sweep\] weather.power = 0.5: .*power must be >= 1.0"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "weather"\n[sweep]\n"erosion.power" = [1.0]\n',
         r"\[sweep\] 'erosion.power': keys are seed, input.OPTION or STAGE.OPTION"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "materials"\n', r"takes ImageData but gets PolyData"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "curvature"\n[outputs]\nformat = "vti"\n',
         r"\[outputs\] format: 'vti' cannot hold the final PolyData"),
        ('[input\nexample = "rock"\n', r"not valid TOML"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "weather"\n[sweep]\n"weather.power" = [2, 2.0]\n',
         r"jobs 0 and 1 are identical"),
    ],
)
def test_malformed_scenario_fails_before_any_job_starts(tmp_path, text, message):
    path = _write(tmp_path, text, "bad.toml")
    with pytest.raises(ScenarioError, match=message) as info:
        run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert str(path) in str(info.value)
    assert not (tmp_path / "out").exists()


def test_cli_reports_a_malformed_scenario(tmp_path, capsys):
    path = _write(tmp_path, '[input]\nexample = "rock"\n[[stages]]\nstage = "wether"\n', "bad.toml")
    assert main(["batch", str(path), "--out", str(tmp_path / "out"), "--serial"]) == 2
    assert "unknown stage 'wether'" in capsys.readouterr().err


def test_a_folder_a_binary_file_or_json_as_the_scenario_is_named(tmp_path):
    """Each is refused with what it is, not as a missing file or a bare UnicodeDecodeError."""
    with pytest.raises(ScenarioError, match="is a folder, not a scenario file"):
        load_scenario(tmp_path)
    binary = tmp_path / "mesh.stl"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(ScenarioError, match="mesh.stl: not a TOML scenario"):
        load_scenario(binary)
    as_json = _write(tmp_path, '{"input": {"example": "rock"}}', "scenario.json")
    with pytest.raises(ScenarioError, match="not valid TOML.*scenario files are TOML"):
        load_scenario(as_json)


def test_a_scenario_seed_too_large_for_a_stage_fails_before_any_job():
    """The scenario's seed fills the stages' seed options: it is checked as theirs, not found at run time."""
    text = ('seed = 99999999999999999999\n[input]\nexample = "rock"\n[[stages]]\nstage = "hydraulic"\n'
            'emitter = "0,0,1,0,0,-1,0.2,50"\n')
    with pytest.raises(ScenarioError, match=r"seed \(the default of \[\[stages\]\] #1 \(hydraulic\)\).*64-bit"):
        parse_scenario(text)
    assert parse_scenario(text.replace("99999999999999999999", "7")).jobs[0].stages[0]["options"]["seed"] == 7


def test_a_local_cluster_too_large_or_zero_threads_is_refused_before_anything(tmp_path, monkeypatch):
    """100000 workers would start 100000 processes (the run hung); 0 threads per job silently meant the default."""
    from pverosion.limits import ResourceLimitError

    path = _write(tmp_path, '[input]\nexample = "rock"\nsubdivisions = 1\n[[stages]]\nstage = "curvature"\n')
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "4G")
    with pytest.raises(ResourceLimitError, match="workers: a local cluster of 100000 worker processes"):
        run_batch(path, tmp_path / "out", workers=100_000, progress=False)
    for threads in (0, -1):
        with pytest.raises(ValueError, match="threads_per_job must be >= 1"):
            run_batch(path, tmp_path / "out", serial=True, threads_per_job=threads, progress=False)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("stage, option", [("hydraulic", "emitter"), ("materials", "thresholds")])
def test_a_required_option_left_out_fails_before_any_job(tmp_path, stage, option):
    """Without it every job failed at run time (exit 1, a folder of failed jobs); now the scenario is refused."""
    source = '[input]\nexample = "rock"\n' if stage == "hydraulic" else '[input]\nfile = "v.vti"\n'
    pv.ImageData(dimensions=(4, 4, 4)).save(tmp_path / "v.vti")
    path = _write(tmp_path, source + f'[[stages]]\nstage = "{stage}"\n')
    with pytest.raises(ScenarioError, match=rf"\({stage}\): {option} is required, e\.g\. {option} = "):
        run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("where", ["file", "under_a_file"])
def test_an_output_folder_that_cannot_be_made_is_refused_before_any_job(tmp_path, capsys, where):
    good = _write(tmp_path, '[input]\nexample = "rock"\n[[stages]]\nstage = "curvature"\n', "good.toml")
    blocker = tmp_path / "taken"
    blocker.write_text("keep me")
    out = blocker if where == "file" else blocker / "out"
    with pytest.raises(ValueError, match=r"batch output folder .*taken"):
        run_batch(good, out, serial=True, progress=False)
    assert main(["batch", str(good), "--out", str(out), "--serial"]) == 2
    err = capsys.readouterr().err
    assert "batch output folder" in err and "Errno" not in err
    assert blocker.read_text() == "keep me"


@pytest.mark.filterwarnings("ignore:The VTK reader")
def test_cli_exit_status_tells_whether_every_job_succeeded(tmp_path, capsys):
    pv.Sphere().save(tmp_path / "ball.vtp")
    (tmp_path / "broken.vtp").write_text("not a mesh")
    good = _write(tmp_path, '[input]\nfile = "ball.vtp"\n[[stages]]\nstage = "curvature"\n', "good.toml")
    assert main(["batch", str(good), "--out", str(tmp_path / "good"), "--serial"]) == 0
    assert "1 ran, 0 already done, 0 failed" in capsys.readouterr().out
    bad = _write(tmp_path, '[input]\nfile = "broken.vtp"\n[[stages]]\nstage = "curvature"\n', "bad.toml")
    assert main(["batch", str(bad), "--out", str(tmp_path / "bad"), "--serial"]) == 1
    assert "failed:" in capsys.readouterr().err


# --- serial runs: resuming, failures, the manifest --------------------------------------------------------


def test_serial_batch_writes_every_job_and_a_rerun_skips_them(serial_reference):
    scenario, out = serial_reference
    rows = _check_complete(out, 12)
    for row in rows:
        mesh = pv.read(out / "jobs" / row["folder"] / "final.vtp")
        assert row["points"] == mesh.n_points and row["volume"] == pytest.approx(mesh.volume, rel=1e-9)
        assert row["volume_change"] < 0  # weathering only removes material
        series = pv.get_reader(out / "jobs" / row["folder"] / "weather.pvd")
        assert series.time_values == [0.0, 20.0, 40.0, 60.0]
        log = (out / "jobs" / row["folder"] / "log.txt").read_text()
        assert "stage weather done" in log and "done in" in log
    # stronger power modifiers spare flatter regions: less volume is lost
    by_power = {p: np.mean([r["volume_change"] for r in rows if r["weather.power"] == p]) for p in (1.0, 2.0, 4.0)}
    assert by_power[1.0] < by_power[2.0] < by_power[4.0]
    report = run_batch(scenario, out, serial=True, progress=False)
    assert report.ran == [] and report.skipped == 12 and len(report.rows) == 12


@pytest.mark.parametrize(("stage", "options", "block"), [
    ("hydraulic", 'iterations = 3\nemitter = "0,0,2,0,0,-1,0.3,20"\n', "mesh"),
    ("shard-graph", "cells = 30\n", "surface"),
    ("freeze-thaw", "iterations = 2\ncells = 40\npaths_per_step = 50\n", "surface"),
])
@pytest.mark.filterwarnings("ignore:hydraulic erosion. the water eroded nothing:UserWarning")
def test_stages_with_a_multiblock_result_finish_their_jobs(tmp_path, stage, options, block):
    """A job ending in one of these stages failed after writing its result (its figures were looked for in the
    blocks of a voxel result); the row now gives the figures of the result's surface block."""
    path = _write(tmp_path, f'[input]\nexample = "rock"\nsubdivisions = 2\n[[stages]]\nstage = "{stage}"\n{options}')
    report = run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert report.failed == 0 and [r["status"] for r in report.rows] == ["done"]
    row = report.rows[0]
    surface = pv.read(tmp_path / "out" / "jobs" / row["folder"] / "final.vtm")[block]
    assert row["points"] == surface.n_points and row["area"] == pytest.approx(surface.area, rel=1e-9)


@pytest.mark.filterwarnings("ignore:The VTK reader")
def test_a_failing_job_is_recorded_and_retried_on_the_next_run(tmp_path):
    pv.Sphere().save(tmp_path / "good.vtp")
    pv.Cube().triangulate().save(tmp_path / "cube.vtp")
    (tmp_path / "broken.vtp").write_text("not a mesh")
    path = _write(tmp_path, '[input]\nfile = "good.vtp"\n[[stages]]\nstage = "curvature"\n'
                            '[sweep]\n"input.file" = ["good.vtp", "broken.vtp", "cube.vtp"]\n')
    report = run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert [r["status"] for r in report.rows] == ["done", "failed", "done"] and report.failed == 1
    assert report.rows[1]["error"]
    failed = tmp_path / "out" / "jobs" / f"{report.rows[1]['folder']}.failed"
    assert "job failed" in (failed / "log.txt").read_text()
    pv.Sphere(radius=2.0).save(tmp_path / "broken.vtp")  # fix the input: the job runs again, now successfully
    again = run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert again.ran == [again.rows[1]["id"]] and again.failed == 0  # a new id: the input file changed
    assert not failed.exists()


def test_a_changed_input_file_is_computed_again(tmp_path):
    """The job id named the input file's path only: a re-run after the file changed reported the job as done
    and kept the old mesh's results. The file's bytes are part of the id now; an unchanged file is still skipped."""
    pv.Sphere(radius=0.5).save(tmp_path / "in.vtp")
    path = _write(tmp_path, '[input]\nfile = "in.vtp"\n[[stages]]\nstage = "curvature"\n')
    first = run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert run_batch(path, tmp_path / "out", serial=True, progress=False).skipped == 1
    pv.Sphere(radius=2.0).save(tmp_path / "in.vtp")
    again = run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert len(again.ran) == 1 and again.ran != first.ran
    row = again.rows[0]
    final = pv.read(tmp_path / "out" / "jobs" / row["folder"] / "final.vtp")
    assert final.bounds[1] == pytest.approx(2.0, rel=1e-2) and row["volume"] == pytest.approx(final.volume, rel=1e-9)


def test_warnings_of_every_job_go_to_its_log_and_the_results(tmp_path):
    """A float32 mesh a million units out is warned about in each job of a sweep (a worker's stderr would show the
    same message once per process): in the job's log and in the results' warnings column; a job without a warning
    has the column empty."""
    far = pv.Sphere(radius=0.5)
    far.points = (np.asarray(far.points, dtype=np.float64) + 1e6).astype(np.float32)
    for name in ("far.ply", "far_again.ply"):
        far.save(tmp_path / name)
    pv.Sphere().save(tmp_path / "near.vtp")
    path = _write(tmp_path, '[input]\nfile = "far.ply"\n[[stages]]\nstage = "curvature"\n'
                            '[sweep]\n"input.file" = ["far.ply", "far_again.ply", "near.vtp"]\n')
    report = run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert report.failed == 0
    for row in report.rows[:2]:
        assert "UserWarning: the points are stored as float32" in row["warnings"]
        log = (tmp_path / "out" / "jobs" / row["folder"] / "log.txt").read_text()
        assert "WARNING UserWarning: the points are stored as float32" in log
    assert report.rows[2]["warnings"] == ""
    assert "stored as float32" in (tmp_path / "out" / "results.csv").read_text()


def test_a_result_the_manifest_missed_is_recovered_not_recomputed(serial_reference, tmp_path):
    scenario, reference = serial_reference
    out = tmp_path / "out"
    out.mkdir()
    # a batch stopped after job 3's folder was renamed into place but before the manifest was updated
    job = load_scenario(scenario).jobs[3]
    (out / "jobs").mkdir()
    shutil.copytree(reference / "jobs" / job.folder, out / "jobs" / job.folder)
    (out / "jobs" / f".tmp-{job.folder}-half").mkdir()  # and a half-written attempt of another
    report = run_batch(scenario, out, serial=True, progress=False)
    assert report.skipped == 1 and job.id not in report.ran and len(report.ran) == 11
    _check_complete(out, 12)
    assert _outputs(out) == _outputs(reference)


def test_a_second_batch_into_the_same_folder_is_refused(tmp_path):
    path = _write(tmp_path, '[input]\nexample = "cube"\n[[stages]]\nstage = "curvature"\n')
    with _exclusive(tmp_path / "out"), pytest.raises(RuntimeError, match="another batch is running"):
        run_batch(path, tmp_path / "out", serial=True, progress=False)


# --- Dask ------------------------------------------------------------------------------------------------


def test_only_jobs_on_dask_workers_stop_the_thread_pool_adapting_to_load(serial_reference):
    from distributed import Client, LocalCluster

    from pverosion.batch.job import _on_dask_worker
    from pverosion.kernels import _threads

    assert _threads._adapt[0]  # the serial batch ran its jobs in this process: nothing changed here
    assert not _on_dask_worker()
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
                      silence_logs=50) as cluster, Client(cluster) as client:
        assert client.submit(_on_dask_worker, pure=False).result()


def test_local_cluster_outputs_equal_the_serial_run_bit_for_bit(serial_reference, tmp_path):
    scenario, reference = serial_reference
    report = run_batch(scenario, tmp_path / "out", workers=2, progress=False)
    assert report.workers == 2 and len(report.ran) == 12
    rows = _check_complete(tmp_path / "out", 12)
    assert len({r["worker"] for r in rows}) == 2  # both workers took jobs
    assert _outputs(tmp_path / "out") == _outputs(reference)


def test_a_worker_killed_mid_sweep_loses_nothing(serial_reference, tmp_path):
    from distributed import Client, LocalCluster

    scenario, reference = serial_reference
    killed = []

    def kill_a_busy_worker(row, client):
        if killed:
            return
        busy = [w for w, keys in client.processing().items() if keys]
        if busy:
            pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=50) as cluster, Client(cluster) as client:
        report = run_batch(scenario, tmp_path / "out", client=client, progress=False,
                           on_result=kill_a_busy_worker)
    assert killed, "no worker was busy to kill"
    assert report.failed == 0
    _check_complete(tmp_path / "out", 12)
    assert _outputs(tmp_path / "out") == _outputs(reference)


def test_rerun_after_a_forced_stop_finishes_only_the_missing_jobs(serial_reference, tmp_path):
    scenario, reference = serial_reference
    out = tmp_path / "out"
    command = [sys.executable, "-m", "pverosion.cli", "batch", str(scenario), "--out", str(out), "--workers", "2"]
    proc = subprocess.Popen(command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    done: set[str] = set()
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                entries = json.loads((out / "manifest.json").read_text())["jobs"]
            except (FileNotFoundError, json.JSONDecodeError, KeyError):
                entries = {}
            done = {k for k, e in entries.items() if e["status"] == "done"}
            if len(done) >= 3:
                break
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert 3 <= len(done) < 12, f"the batch was not stopped mid-way ({len(done)} jobs done)"
    report = run_batch(scenario, out, workers=2, progress=False)
    assert not done & set(report.ran)  # jobs recorded before the stop did not run again
    assert report.skipped >= len(done) and report.skipped + len(report.ran) == 12
    _check_complete(out, 12)
    assert _outputs(out) == _outputs(reference)
