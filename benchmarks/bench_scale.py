"""Scale: curvature and weathering per face at 100k, 400k and 1.6M faces, and peak memory.

The meshes are the Stanford bunny scan with its holes filled, decimated to a
quarter, sixteenth, ... of the target and Loop-subdivided back up to about
the target face count (``--sizes``). Each size runs in its own process (so
its peak resident memory is its own) and prints, for that size:

- curvature: ``pverosion.curvature`` with the default orientation, the bare
  kernel on outward faces, and ``vtkCurvatures`` (mean curvature) on the same
  mesh in the same run; medians of ``--repeat`` interleaved calls, ns per face
  and the ratio to VTK;
- weathering: mean wall time of one iteration over ``--steps`` steps of
  :class:`~pverosion.kernels.weathering.model.WeatheringSolver` with its defaults
  (the self-intersection guard every 10 steps included), ns per face;
- ``peak_rss_mib``: the process's peak resident memory.

Numba compilation is excluded by a warm-up on the smallest mesh.

    python benchmarks/bench_scale.py [--data ../shared/data/bunny.ply] [--sizes 100000,400000,1600000]
        [--repeat 15] [--steps 10] [--load N]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyvista as pv
from _load import add_load_option, run

import pverosion
from pverosion.examples import data_path
from pverosion.kernels import orient_faces, principal_curvatures
from pverosion.kernels.weathering.model import WeatheringSolver
from pverosion.scenes.hydraulic import pour_scene

DEFAULT = data_path("bunny.ply")
TARGETS = {"curvature_ratio_vs_vtk": 0.4, "weathering_ns_per_face_1_6m": 250}


def subdivided_bunny(data: Path, n_faces: int) -> pv.PolyData:
    """The bunny, holes filled, decimated and Loop-subdivided to about ``n_faces`` faces."""
    closed = pour_scene(mesh=pv.read(data), up=(0.0, 1.0, 0.0)).mesh
    levels = 0
    while n_faces / 4**levels > 0.9 * closed.n_cells:
        levels += 1
    base = closed.decimate(1.0 - (n_faces / 4**levels) / closed.n_cells) if levels else closed
    return base.subdivide(levels, subfilter="loop") if levels else base


def _median_ms(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(1e3 * (time.perf_counter() - start))
    return float(np.median(times))


def one_size(data: Path, n_faces: int, repeat: int, steps: int) -> dict:
    """Figures of one mesh size (run in its own process)."""
    small = subdivided_bunny(data, 20_000)  # warm-up: numba compilation / cache load
    pverosion.curvature(small)
    WeatheringSolver(np.asarray(small.points, dtype=np.float64), small.regular_faces).run(12)  # past a guard check

    mesh = subdivided_bunny(data, n_faces)
    points = np.asarray(mesh.points, dtype=np.float64)
    faces = orient_faces(points, mesh.regular_faces).faces
    outward = pv.PolyData.from_regular_faces(points, faces)
    cases = {
        "pverosion_full": lambda: pverosion.curvature(mesh),
        "pverosion_kernel": lambda: principal_curvatures(points, faces),
        "vtk_curvatures": lambda: outward.curvature("mean"),
    }
    times = {name: [] for name in cases}
    for _ in range(repeat):  # interleaved, so a slow spell of a shared machine hits all alike
        for name, fn in cases.items():
            times[name].append(_median_ms(fn, 1))
    med = {name: float(np.median(t)) for name, t in times.items()}
    f = len(faces)
    solver = WeatheringSolver(points, faces)
    start = time.perf_counter()
    solver.run(steps)
    weather_ms = 1e3 * (time.perf_counter() - start) / steps
    return {
        "n_points": len(points),
        "n_faces": f,
        "curvature_median_ms": {k: round(v, 2) for k, v in med.items()},
        "curvature_ns_per_face": {k: round(1e6 * v / f, 1) for k, v in med.items()},
        "ratio_full_vs_vtk": round(med["pverosion_full"] / med["vtk_curvatures"], 3),
        "ratio_kernel_vs_vtk": round(med["pverosion_kernel"] / med["vtk_curvatures"], 3),
        "weathering_iteration_ms": round(weather_ms, 2),
        "weathering_ns_per_face": round(1e6 * weather_ms / f, 1),
        "weathering_retries": solver.retries,
        "peak_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT)
    parser.add_argument("--sizes", default="100000,400000,1600000", help="target face counts, comma separated")
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # internal: measure this size only
    add_load_option(parser)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_size(args.data, args.one, args.repeat, args.steps)))
        return
    sizes = {}
    for size in (int(s) for s in args.sizes.split(",")):
        cmd = [sys.executable, sys.argv[0], "--one", str(size), "--data", str(args.data), "--repeat", str(args.repeat),
               "--steps", str(args.steps)]
        done = subprocess.run(cmd, capture_output=True, text=True, env=os.environ)
        if done.returncode != 0:
            raise SystemExit(f"size {size} failed:\n{done.stderr[-2000:]}")
        sizes[str(size)] = json.loads(done.stdout.strip().splitlines()[-1])
    print(json.dumps({"benchmark": "scale", "mesh": f"{args.data.name}, holes filled, Loop-subdivided",
                      "cpus": os.cpu_count(), "sizes": sizes, "targets": TARGETS}, indent=2))


if __name__ == "__main__":
    run(main, timings=("sizes.100000.curvature_median_ms.pverosion_full", "sizes.100000.weathering_iteration_ms",
                       "sizes.1600000.curvature_median_ms.pverosion_full", "sizes.1600000.weathering_iteration_ms"))
