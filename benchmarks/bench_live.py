"""Live hydraulic erosion: view updates per second while the solver steps in the background.

The scene of ``bench_hydraulic.py``'s bunny: the scan (``../shared/data/bunny.ply``, holes
closed) in a tank, a block of ~17.7k particles dropped on it, and a water source picked on
its back. The worker thread steps the solver; the main thread calls
:meth:`pverosion.live.LiveSession.update_view` every ``TIMER_MS`` milliseconds (at once when
the last call overran), as a window's timer does, and renders off-screen. A *view update* is one rendered frame that shows an iteration the
previous frame did not (its ``shown_step`` differs), so the rate cannot exceed the solver's
iteration rate. The JSON also gives the milliseconds of one iteration with the view idle
(the peer, measured in the same run), of one update with the worker running and stopped
(moving the arrays and rendering alone), and the load average before and after.

Usage: ``python benchmarks/bench_live.py [--seconds 20] [--warmup 10] [--particles 17700]``
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
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


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=20.0, help="length of the measured stretch")
    parser.add_argument("--warmup", type=int, default=10, help="iterations run before measuring (compilation)")
    parser.add_argument("--particles", type=int, default=17_700)
    parser.add_argument("--threads", type=int, default=None,
                        help="worker's kernel threads (default: LiveSession's, all but one)")
    args = parser.parse_args()
    session = bunny_session(args.particles, args.threads)
    session.step(args.warmup)
    session.plotter.show(auto_close=False)  # a shown plotter renders on every update, as a window does
    load_before = _load()
    alone_it = []  # the peer: iterations with no view updating, in the calling thread
    for _ in range(5):
        clock = time.perf_counter()
        session.step(1)
        alone_it.append(time.perf_counter() - clock)
    session.update_view()
    shown, step0 = session.steps, session.steps
    updates, update_times, done = 0, [], []
    session.on_step(done.append)  # every iteration the worker runs, redone ones included
    session.start()
    start = time.perf_counter()
    tick = start
    while time.perf_counter() - start < args.seconds:
        tick = max(tick + TIMER_MS / 1000.0, time.perf_counter())  # the window's repeating timer
        time.sleep(max(tick - time.perf_counter(), 0.0))
        clock = time.perf_counter()
        if session.update_view():  # rendered the newest published state
            update_times.append(time.perf_counter() - clock)
            step = session.shown_step
            updates += step > shown  # a frame counts only when it shows a later iteration than any before
            shown = max(shown, step)
    elapsed = time.perf_counter() - start
    session.stop()
    steps = len(done)
    alone = []  # the view's own cost: the same update and render with the worker stopped
    for _ in range(5):
        session._shown = -1
        clock = time.perf_counter()
        session.update_view()
        alone.append(time.perf_counter() - clock)
    print(json.dumps({
        "worker_threads": session.threads, "vertices": session.mesh.n_points, "faces": session.mesh.n_cells, "particles": session.particles.n_points,
        "seconds": round(elapsed, 2), "view_updates": updates, "iterations": steps,
        "iterations_net": session.steps - step0,
        "view_updates_per_s": round(updates / elapsed, 2), "iterations_per_s": round(steps / elapsed, 2),
        "iteration_ms": round(1000.0 * elapsed / steps, 1) if steps else None,
        "iteration_ms_view_idle": _median_ms(alone_it),
        "update_ms_median": _median_ms(update_times), "update_ms_worker_stopped": _median_ms(alone),
        "load_average_before": load_before, "load_average_after": _load(),
        "target_updates_per_s": 10.0, "meets_target": updates / elapsed >= 10.0,
    }, indent=2))


if __name__ == "__main__":
    main()
