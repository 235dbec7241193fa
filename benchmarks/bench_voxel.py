"""Voxel erosion speed: ms per step on a 128 x 64 x 64 meander grid, and extraction of a 256³ field.

Per step: advection (with forces, viscosity and walls), pressure projection,
transport of water and sediment, erosion-deposition, and surface extraction
of the material (flying edges), as medians over the measured steps after a
warm-up. Extraction alone: a 256³ field (a sphere with noise), VTK's flying
edges against scikit-image's marching cubes in the same run. Prints JSON;
targets: <= 150 ms per full step, <= 150 ms per 256³ extraction. Both
velocity advection schemes are measured (semi-Lagrangian, the default, and
MacCormack), each on a fresh grid.

Usage: python benchmarks/bench_voxel.py [--steps 30] [--repeat 5] [--load N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
import pyvista as pv
from _load import add_load_option, run

from pverosion.filters.voxel import extract_material_surface, voxel_grid, voxel_solver
from pverosion.kernels.voxel.fluid import ADVECTION_SCHEMES
from pverosion.scenes.voxel import meander_grid


def _steps(scheme: str, n: int, dt: float) -> dict:
    """Median ms per part of ``n`` steps of the meander grid with the given advection scheme."""
    grid, _ = meander_grid((128, 64, 64))
    solver = voxel_solver(grid, source_velocity=(1.0, 0.0, 0.0), advection=scheme)
    for _ in range(5):  # warm-up: compile, let the flow start
        solver.step(dt)
    parts = {name: [] for name in ("advection", "projection", "transport", "erosion", "extraction", "total")}
    substeps, iterations = [], []
    for _ in range(n):
        before = dict(solver.fluid.profile)
        start = time.perf_counter()
        figures = solver.step(dt)
        state = voxel_grid(solver.amount, origin=grid.origin, spacing=grid.spacing[0])
        clock = time.perf_counter()
        extract_material_surface(state)
        parts["extraction"].append(time.perf_counter() - clock)
        parts["total"].append(time.perf_counter() - start)
        for name in ("advection", "projection", "transport", "erosion"):
            parts[name].append(solver.fluid.profile[name] - before.get(name, 0.0))
        substeps.append(figures["substeps"])
        iterations.append(figures["iterations"])
    return {"median_ms": {name: round(1000 * statistics.median(values), 1) for name, values in parts.items()},
            "median_substeps": statistics.median(substeps),
            "median_pressure_iterations": statistics.median(iterations),
            "mass_error": solver.mass_error()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--time-step", type=float, default=0.01)
    add_load_option(parser)
    args = parser.parse_args()
    steps = {scheme: _steps(scheme, args.steps, args.time_step) for scheme in ADVECTION_SCHEMES}
    field = np.linalg.norm(np.mgrid[-1:1:256j, -1:1:256j, -1:1:256j], axis=0)
    field = np.clip(1.5 - 2.0 * field + 0.05 * np.random.default_rng(0).random(field.shape), 0.0, 1.0)
    big = pv.ImageData(dimensions=field.shape, spacing=(1 / 128,) * 3)
    big.point_data["material_amount"] = field.ravel(order="F")
    extraction = {}
    for method in ("flying_edges", "marching_cubes"):
        times = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            surface = extract_material_surface(big, method=method)
            times.append(time.perf_counter() - start)
        extraction[method] = {"median_ms": round(1000 * statistics.median(times), 1), "faces": surface.n_cells}
    print(json.dumps({
        "grid": [128, 64, 64],
        "time_step_s": args.time_step,
        "steps": args.steps,
        "advection": steps,
        "extraction_256": extraction,
        "targets_ms": {"full_step": 150, "extraction_256": 150},
    }, indent=2))


if __name__ == "__main__":
    run(main, timings=("advection.semi-lagrangian.median_ms.total", "extraction_256.flying_edges.median_ms"))
