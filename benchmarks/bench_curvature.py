"""Curvature speed on the Stanford bunny scan: pverosion vs vtkCurvatures, same run.

Prints one JSON object. Timings are medians over interleaved repetitions
(numba compilation excluded by a warm-up call).

    python benchmarks/bench_curvature.py [--data ../shared/data/bunny.ply] [--repeat 31] [--load N]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pyvista as pv
from _load import add_load_option, run

import pverosion
from pverosion.examples import data_path
from pverosion.kernels import orient_faces, principal_curvatures

DEFAULT = data_path("bunny.ply")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT)
    parser.add_argument("--repeat", type=int, default=31)
    add_load_option(parser)
    args = parser.parse_args()

    mesh = pv.read(args.data)
    points, faces = np.asarray(mesh.points, dtype=np.float64), mesh.regular_faces
    oriented = orient_faces(points, faces).faces
    outward = pv.PolyData.from_regular_faces(points, oriented)
    cases = {
        "pverosion_kernel": lambda: principal_curvatures(points, oriented),
        "pverosion_filter_keep": lambda: pverosion.curvature(outward, orientation="keep"),
        "pverosion_full": lambda: pverosion.curvature(mesh),
        "vtk_curvatures": lambda: outward.curvature("mean"),
    }
    for fn in cases.values():
        fn()  # warm-up: numba compilation / cache load
    times = {name: [] for name in cases}
    for _ in range(args.repeat):
        for name, fn in cases.items():
            start = time.perf_counter()
            fn()
            times[name].append(1e3 * (time.perf_counter() - start))
    med = {name: float(np.median(t)) for name, t in times.items()}
    print(json.dumps({
        "benchmark": "curvature",
        "mesh": args.data.name,
        "n_points": mesh.n_points,
        "n_faces": mesh.n_cells,
        "repeat": args.repeat,
        "median_ms": {k: round(v, 2) for k, v in med.items()},
        "ratio_kernel_vs_vtk": round(med["pverosion_kernel"] / med["vtk_curvatures"], 3),
        "ratio_filter_keep_vs_vtk": round(med["pverosion_filter_keep"] / med["vtk_curvatures"], 3),
        "ratio_full_vs_vtk": round(med["pverosion_full"] / med["vtk_curvatures"], 3),
        "paper_cpp_ms": 144.6,
    }, indent=2))


if __name__ == "__main__":
    run(main, timings=("median_ms.pverosion_kernel", "median_ms.pverosion_full", "median_ms.vtk_curvatures"))
