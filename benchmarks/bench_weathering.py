"""Weathering speed on the Stanford bunny scan: one iteration, split by part, vs a VTK-based iteration.

Prints one JSON object. pverosion runs ``--steps`` weathering steps with mesh
improvement and the self-intersection guard at their defaults (the guard
checks every 10 steps); the VTK-based iteration computes the mean curvature
with vtkCurvatures and applies the same displacement (uniform Laplacian,
eqs. 3-5). Both are measured in the same run; numba compilation is excluded
by a warm-up. The iteration median is that of the wall times between steps
that counted (a step redone after a rollback counts again); the mean is the
whole wall time, guard checks and redone steps included, per step of the
result. ``steps_run`` counts every step computed, rolled back or not.

    python benchmarks/bench_weathering.py [--data ../shared/data/bunny.ply] [--steps 100] [--load N]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pyvista as pv
from _load import add_load_option, run

from pverosion.examples import data_path
from pverosion.kernels.curvature.normalize import normalize_symmetric
from pverosion.kernels.mesh.geometry import average_edge_length
from pverosion.kernels.mesh.laplacian import laplacian_vectors
from pverosion.kernels.mesh.orientation import orient_faces
from pverosion.kernels.mesh.topology import edge_topology, one_ring
from pverosion.kernels.weathering.displacement import displace
from pverosion.kernels.weathering.model import WeatheringSolver

DEFAULT = data_path("bunny.ply")


def vtk_iteration(mesh: pv.PolyData, ring, edges, fixed, displacement) -> pv.PolyData:
    """One weathering step with vtkCurvatures as the curvature estimator, the same displacement."""
    h = np.asarray(mesh.curvature("mean"), dtype=np.float64)
    points = np.asarray(mesh.points, dtype=np.float64)
    e_avg = average_edge_length(points, None, edges=edges)
    direction = laplacian_vectors(points, None, ring=ring)
    mesh.points = displace(points, direction, True, normalize_symmetric(h), h, e_avg, 1.0, e_avg / 10.0,
                            np.ones(len(points)), fixed, displacement)
    return mesh


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT)
    parser.add_argument("--steps", type=int, default=100)
    add_load_option(parser)
    args = parser.parse_args()

    scan = pv.read(args.data)
    points = np.asarray(scan.points, dtype=np.float64)
    faces = orient_faces(points, scan.regular_faces).faces

    topo = edge_topology(faces, len(points))
    ring = one_ring(faces, len(points), edges=topo.edges)
    fixed = topo.irregular_vertices(len(points))
    mesh = pv.PolyData.from_regular_faces(points.copy(), faces)
    vtk_displacement = np.zeros_like(points)

    WeatheringSolver(points, faces).run(12)  # warm-up: numba compilation / cache load
    vtk_iteration(mesh, ring, topo.edges, fixed, vtk_displacement)
    solver = WeatheringSolver(points, faces)
    solver.profile = {}
    vtk_times = []
    stamps = [time.perf_counter()]  # pverosion's clock: wall time minus the VTK iterations

    def interleave(_solver) -> None:
        # one VTK-based iteration after every pverosion step, timed apart, so both see the same machine
        now = time.perf_counter()
        vtk_iteration(mesh, ring, topo.edges, fixed, vtk_displacement)
        vtk_times.append(1e3 * (time.perf_counter() - now))
        stamps.append(now - 1e-3 * sum(vtk_times[:-1]))

    solver.run(args.steps, on_step=interleave)
    # wall time between steps that counted (a step redone after a rollback counts again); the guard checks and
    # the rolled-back work fall between them
    per_step = 1e3 * np.diff(stamps)
    parts = {k: round(1e3 * float(np.median(v)), 2) for k, v in solver.profile.items()}
    guard_checks = len(solver.profile.get("guard", []))

    median = float(np.median(per_step))
    mean = float(stamps[-1] - stamps[0]) * 1e3 / args.steps  # per step of the result, all the work included
    vtk = float(np.median(vtk_times))
    print(json.dumps({
        "benchmark": "weathering",
        "mesh": args.data.name,
        "n_points": scan.n_points,
        "n_faces": scan.n_cells,
        "steps": args.steps,
        "iteration_median_ms": round(median, 2),
        "iteration_mean_ms_with_guard_and_retries": round(mean, 2),
        "parts_median_ms": parts,
        "steps_run": len(solver.profile.get("curvature", [])),
        "guard_checks": guard_checks,
        "retries": solver.retries,
        "frozen_vertices": solver.frozen,
        "collapses": solver.collapses,
        "vtk_iteration_median_ms": round(vtk, 2),
        "ratio_median_vs_vtk": round(median / vtk, 3),
        "ratio_mean_vs_vtk": round(mean / vtk, 3),
        "paper_cpp_ms": 182.7,
    }, indent=2))


if __name__ == "__main__":
    run(main, timings=("iteration_median_ms", "vtk_iteration_median_ms"))
