"""Live hydraulic erosion: view updates per second while the solver steps in the background.

The scene of ``bench_hydraulic.py``'s bunny: the scan (``../shared/data/bunny.ply``, holes
closed) in a tank, a block of ~17.7k particles dropped on it, and a water source picked on its
back. The worker thread steps the solver; the main thread calls
:meth:`pverosion.live.LiveSession.update_view` every ``TIMER_MS`` milliseconds (at once when the
last call overran), as a window's timer does, and renders off-screen. A *view update* is one
rendered frame that shows a later simulated time than every frame before (its ``shown_time``: an
iteration's end, or the water between two of the fluid's substeps on the surface of the iteration
before), so the rate cannot exceed the solver's substep rate. The JSON also gives the milliseconds (wall and
CPU) of one iteration with the view idle (the peer, measured in the same run on as many kernel
threads as the worker), of one update with the worker running and stopped (moving the arrays and
rendering alone), and the load average before and after.

Where the time goes (Linux: ``/proc/thread-self/schedstat``): per iteration, the worker thread's
CPU time, its wait for a free core (runnable, not running) and the rest of its wall time, spent
blocked (on the interpreter lock, say); per update, the CPU time of the process's other threads
(the main thread and the software rasterizer's; with ``--threads`` > 1 the kernels' helper threads
too), and the cores the process used on average.

Usage: ``python benchmarks/bench_live.py [--seconds 20] [--warmup 10] [--particles 17700] [--threads N] [--load N]``
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _load import add_load_option, run  # noqa: E402
from bench_hydraulic import bunny_tank  # noqa: E402  (the same bunny scene)

from pverosion.live import TIMER_MS, interactive  # noqa: E402


def bunny_session(n_particles: int, threads: int | None = None):
    scene, block, domain = bunny_tank(n_particles)
    session = interactive(scene.mesh, stage="hydraulic", off_screen=True, window_size=(1024, 768),
                          radius=scene.radius, domain=domain, walls=True, threads=threads)
    session.solver.fluid.add_particles(block)
    top = scene.mesh.points[np.argmax(scene.mesh.points[:, 2])]
    session.pick(top)
    return session


def _median_ms(times: list[float]) -> float | None:
    return round(1000.0 * float(np.median(times)), 1) if times else None


def _sched(thread: int | None = None) -> tuple[float, float] | None:
    """CPU time and run-queue wait in seconds of a thread (native id; default: the calling one), None where the
    kernel does not say."""
    try:
        with open(f"/proc/self/task/{thread}/schedstat" if thread else "/proc/thread-self/schedstat") as f:
            cpu, wait = f.read().split()[:2]
    except OSError:
        return None
    return int(cpu) * 1e-9, int(wait) * 1e-9


def _per(total: float | None, count: int) -> float | None:
    return round(1000.0 * total / count, 1) if total is not None and count else None


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def _worker_split(done: list) -> dict | None:
    """The worker's wall time between its first and last iteration split into CPU, wait for a core and blocked."""
    if len(done) < 2 or done[0][1] is None:
        return None
    (t0, (c0, w0)), (t1, (c1, w1)) = done[0], done[-1]
    n = len(done) - 1
    return {"wall": _per(t1 - t0, n), "cpu": _per(c1 - c0, n), "waiting_for_a_core": _per(w1 - w0, n),
            "blocked": _per((t1 - t0) - (c1 - c0) - (w1 - w0), n)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=20.0, help="length of the measured stretch")
    parser.add_argument("--warmup", type=int, default=10, help="iterations run before measuring (compilation)")
    parser.add_argument("--particles", type=int, default=17_700)
    parser.add_argument("--threads", type=int, default=None,
                        help="worker's kernel threads (default: LiveSession's, all but one)")
    add_load_option(parser)
    args = parser.parse_args()
    session = bunny_session(args.particles, args.threads)
    session.step(args.warmup)
    session.plotter.show(auto_close=False)  # a shown plotter renders on every update, as a window does
    load_before = _load()
    alone_it, alone_cpu = [], []  # the peer: iterations with no view updating, on the worker's kernel threads
    numba.set_num_threads(session.threads)
    for _ in range(5):
        clock, cpu_clock = time.perf_counter(), time.process_time()
        session.step(1)
        alone_it.append(time.perf_counter() - clock)
        alone_cpu.append(time.process_time() - cpu_clock)
    session.update_view()
    shown, step0 = session.shown_time, session.steps
    updates, update_times, done = 0, [], []
    worker_id: list[int] = []

    def record(_step: int) -> None:  # after every iteration the worker runs, redone ones included
        done.append((time.perf_counter(), _sched()))
        worker_id[:] = [threading.get_native_id()]

    session.on_step(record)
    cpu_start = time.process_time()
    session.start()
    start = time.perf_counter()
    tick = start
    while time.perf_counter() - start < args.seconds:
        tick = max(tick + TIMER_MS / 1000.0, time.perf_counter())  # the window's repeating timer
        time.sleep(max(tick - time.perf_counter(), 0.0))
        clock = time.perf_counter()
        if session.update_view():  # rendered the newest published state
            update_times.append(time.perf_counter() - clock)
            # a frame counts only when it shows a later simulated time (an iteration's end, or the water
            # between two of its substeps) than any frame before
            updates += session.shown_time > shown
            shown = max(shown, session.shown_time)
    elapsed = time.perf_counter() - start
    cpu = time.process_time() - cpu_start
    worker_total = _sched(worker_id[0]) if worker_id else None  # the worker started after cpu_start
    session.stop()
    steps = len(done)
    worker = _worker_split(done)
    alone = []  # the view's own cost: the same update and render with the worker stopped
    for _ in range(5):
        session._shown = -1
        clock = time.perf_counter()
        session.update_view()
        alone.append(time.perf_counter() - clock)
    print(json.dumps({
        "worker_threads": session.threads, "vertices": session.mesh.n_points, "faces": session.mesh.n_cells,
        "particles": session.particles.n_points,
        "seconds": round(elapsed, 2), "view_updates": updates, "iterations": steps,
        "iterations_net": session.steps - step0,
        "view_updates_per_s": round(updates / elapsed, 2), "iterations_per_s": round(steps / elapsed, 2),
        "iteration_ms": round(1000.0 * elapsed / steps, 1) if steps else None,
        "iteration_ms_view_idle": _median_ms(alone_it), "iteration_cpu_ms_view_idle": _median_ms(alone_cpu),
        "update_ms_median": _median_ms(update_times), "update_ms_worker_stopped": _median_ms(alone),
        "worker_ms_per_iteration": worker,
        "other_threads_cpu_ms_per_update": _per(None if worker_total is None else cpu - worker_total[0],
                                                len(update_times)),
        "process_cores_used": round(cpu / elapsed, 2),
        "load_average_before": load_before, "load_average_after": _load(),
        "target_updates_per_s": 10.0, "meets_target": updates / elapsed >= 10.0,
    }, indent=2))


if __name__ == "__main__":
    run(main, timings=("iteration_ms", "iteration_ms_view_idle", "update_ms_median", "update_ms_worker_stopped"))
