"""Hydraulic erosion on meshes: milliseconds per iteration, split into parts (Skorkovská 2019, Table 2).

Scenes:

(a) the Stanford bunny scan (``../shared/data/bunny.ply``, holes closed) with
    ~17.7k particles: a block of water dropped on it in a tank around it;
(b) the procedural canyon of ~34k faces with ~67k particles: the channel
    filled with water and fed by the scene's emitter, drained at the outlet.

Each scene is warmed up (numba compilation, splash), then run for the
timed iterations in one call; the JSON gives medians of the whole iteration
and of its parts: fluid step (neighbours + density solve + emission/drains, the first two also apart),
collision (swept tests and push-out against the mesh, inside the fluid
step), affected vertices, curvature (with the Laplacian), displacement (with
mesh improvement and the collision grid update). The self-intersection
guard runs every ``check_every`` iterations as in any run: the median
iteration leaves it out, the mean iteration spreads it over all.

Each scene is run ``--repeats`` times (default 3), the scenes in turn; the
JSON gives the run with the median iteration time and every run's.

Usage: ``python benchmarks/bench_hydraulic.py [--iterations 30] [--warmup 10] [--repeats 3] [--scene bunny|canyon|all] [--load N]``
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import pyvista as pv
from _load import add_load_option, run

from pverosion.examples import data_path
from pverosion.kernels.fluid.particle_fluid import Drain, Emitter, FluidParameters
from pverosion.kernels.hydraulic.erosion import HydraulicSolver
from pverosion.kernels.spatial.mesh_query import TriangleIndex, point_inside
from pverosion.scenes.hydraulic import canyon_scene, pour_scene

DATA = data_path()
PAPER_MS = {"bunny": 291.520, "canyon": 309.441}
TARGET_MS = {"bunny": 60.0, "canyon": 150.0}


def _outside(mesh_points: np.ndarray, faces: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    index = TriangleIndex.build(mesh_points, faces)
    inside = np.array([point_inside(p, index.points, index.faces, index.lo, index.size, index.dims, index.start2,
                                    index.items2) for p in candidates])
    return candidates[~inside]


def _lattice(lo, hi, spacing: float) -> np.ndarray:
    axes = [np.arange(a + 0.5 * spacing, b, spacing) for a, b in zip(lo, hi)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def bunny_tank(n_particles: int = 17_700):
    """The bunny scene: its pour scene, a block of ``n_particles`` above it, and the tank's domain.

    Returns
    -------
    scene : pverosion.scenes.hydraulic.HydraulicScene
        ``pour_scene`` of the scan (holes closed), y up.
    block : numpy.ndarray, shape (n_particles, 3)
        Particle positions of a column of water over the model's middle.
    domain : tuple of numpy.ndarray
        Lower and upper corners of the tank.
    """
    path = DATA / "bunny.ply"
    if not path.exists():
        raise SystemExit(f"the bunny scan is not at {path}")
    scene = pour_scene(mesh=pv.read(path), up=(0.0, 1.0, 0.0))
    mesh = scene.mesh
    lo, hi = np.array(mesh.bounds[0::2]), np.array(mesh.bounds[1::2])
    size = hi - lo
    spacing = 2.0 * scene.radius
    # a column of water over the model's middle, as tall as it needs to be
    side = int(np.ceil(np.sqrt(n_particles / max(int(0.5 * size[2] / spacing), 1))))
    width = side * spacing
    centre = 0.5 * (lo + hi)
    block_lo = np.array([centre[0] - 0.5 * width, centre[1] - 0.5 * width, hi[2] + spacing])
    block = _lattice(block_lo, block_lo + [width, width, size[2]], spacing)[:n_particles]
    domain = (lo - [0.3 * size[0], 0.3 * size[1], 0.02 * size[2]], hi + [0.3 * size[0], 0.3 * size[1], 1.2 * size[2]])
    return scene, block, domain


def bunny_solver(n_particles: int = 17_700) -> HydraulicSolver:
    """The bunny in a tank with a block of ``n_particles`` dropped on it."""
    scene, block, domain = bunny_tank(n_particles)
    fluid = FluidParameters(radius=scene.radius)
    solver = HydraulicSolver(scene.mesh.points, scene.mesh.regular_faces, fluid=fluid, domain=domain, walls=True)
    solver.fluid.add_particles(block)
    return solver


def canyon_solver(n_particles: int = 67_000) -> HydraulicSolver:
    """The canyon with its channel filled by ``n_particles`` and the scene's emitter and drain."""
    scene = canyon_scene()
    mesh = scene.mesh
    points, faces = np.asarray(mesh.points, dtype=np.float64), np.asarray(mesh.regular_faces, dtype=np.int64)
    radius = 0.0042  # the channel (0.1 wide) about 12 particles across, room for ~67k particles
    spacing = 2.0 * radius
    lo, hi = np.array(mesh.bounds[0::2]), np.array(mesh.bounds[1::2])
    cells = _lattice([lo[0], -0.2, 0.1], [hi[0] - 0.05, 0.2, 0.45], spacing)
    water = _outside(points, faces, cells)
    water = water[np.argsort(water[:, 2], kind="stable")][:n_particles]
    scene_emitter = Emitter.parse(scene.emitters[0])
    emitter = Emitter(position=scene_emitter.position, direction=scene_emitter.direction,
                      radius=scene_emitter.radius, rate=4000.0)
    fluid = FluidParameters(radius=radius)
    solver = HydraulicSolver(points, faces, fluid=fluid, emitters=[emitter],
                             drains=[Drain.parse(d) for d in scene.drains], domain=scene.domain)
    solver.fluid.add_particles(water)
    return solver


def measure(solver: HydraulicSolver, iterations: int, warmup: int) -> dict:
    """Warm up, then run ``iterations`` iterations in one call, timing each; medians in ms.

    The self-intersection guard runs every ``check_every`` iterations, as in
    any run, so its cost lands on those iterations: the median leaves it
    out, the mean spreads it over all of them.
    """
    solver.run(warmup)
    solver.profile = {}
    solver.fluid.profile = {}
    walls, counts = [], []
    clock = [time.perf_counter()]

    def lap(_solver) -> None:
        now = time.perf_counter()
        walls.append(now - clock[0])
        counts.append(len(solver.fluid.positions))
        clock[0] = now

    solver.run(iterations, on_step=lap)
    fp, sp = solver.fluid.profile, solver.profile

    def med(values) -> float:
        return round(1000.0 * float(np.median(values)), 3) if len(values) else 0.0

    fluid_step = np.add.reduce([np.array(fp[k]) for k in ("neighbours", "solve", "emit_drain")])
    return {
        "vertices": len(solver.points), "faces": len(solver.faces),
        "particles_mean": round(float(np.mean(counts)), 1), "colliding_last": len(solver.colliding),
        "iteration_ms": med(walls), "iteration_mean_ms": round(1000.0 * float(np.mean(walls)), 3),
        "fluid_ms": med(fluid_step), "fluid_neighbours_ms": med(fp["neighbours"]), "fluid_solve_ms": med(fp["solve"]),
        "collision_ms": med(fp["collision"]),
        "affected_vertices_ms": med(sp.get("affected", [])), "curvature_ms": med(sp.get("curvature", [])),
        "displacement_ms": med(sp.get("displacement", [])), "guard_ms_when_run": med(sp.get("guard", [])),
        "check_every": solver.check_every, "iterations": len(walls),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--iterations", type=int, default=30)
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--scene", choices=("bunny", "canyon", "all"), default="all")
    parser.add_argument("--repeats", type=int, default=3,
                        help="runs of each scene, taken in turn; the figures are those of the run with the median "
                             "iteration time")
    add_load_option(parser)
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    result = {}
    builders = {"bunny": bunny_solver, "canyon": canyon_solver}
    names = [name for name in ("bunny", "canyon") if args.scene in (name, "all")]
    runs: dict[str, list[dict]] = {name: [] for name in names}
    for _ in range(args.repeats):  # in turn, so a slow spell of the shared machine hits both scenes alike
        for name in names:
            runs[name].append(measure(builders[name](), args.iterations, args.warmup))
    for name in names:
        ranked = sorted(runs[name], key=lambda run: run["iteration_ms"])
        figures = ranked[(len(ranked) - 1) // 2]
        figures["iteration_ms_runs"] = [run["iteration_ms"] for run in runs[name]]
        figures["paper_ms"] = PAPER_MS[name]
        figures["target_ms"] = TARGET_MS[name]
        figures["meets_target"] = figures["iteration_ms"] <= TARGET_MS[name]
        result[name] = figures
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    run(main, timings=("bunny.iteration_ms", "canyon.iteration_ms"))
