"""Hydraulic erosion scenes of Skorkovská 2019 and the thesis: water poured over a model (Figure 10), a narrow canyon
with undercut walls (Figure 11), a river cut into the St Helens DEM with undercut banks (Figures 1, 15) and a lake
that fills and overflows (thesis Figure 8.3, with the shear-stress sediment model).

For each scene: runs the HydraulicErosion filter, writes <out>/<scene>.pvd (MultiBlock steps: eroded mesh and
particles), <scene>.png (top: scene with the fluid; bottom: the isolated model, curvature colour coding) and prints
a JSON line of figures: particles, eroded volume, the deepest particle inside the mesh over every step (in particle
radii; must stay below 1), and the overhanging vertices (a vertical ray up from them hits the mesh) before and after.
The bunny and the St Helens DEM are used when ../shared/data has them, procedural stand-ins otherwise.

    python pipelines/hydraulic_scenes.py [-o hydraulic_scenes] [--scene pour|canyon|river|lake|all] [--quick]
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pyvista as pv

from pverosion.examples import data_path
from pverosion.filters import HydraulicErosion
from pverosion.io import TimeSeriesWriter
from pverosion.kernels.hydraulic.overhangs import overhanging_vertices
from pverosion.plotting import render_strip
from pverosion.scenes.hydraulic import canyon_scene, lake_scene, pour_scene, river_scene

DATA = data_path()

# scene -> (builder, iterations, filter options)
SCENES = {
    "pour": (lambda: pour_scene(mesh=pv.read(DATA / "bunny.ply"), up=(0, 1, 0)) if (DATA / "bunny.ply").exists()
             else pour_scene(), 300, {"model": "curvature", "step_divisor": 10.0}),
    "canyon": (canyon_scene, 150, {"model": "curvature", "step_divisor": 10.0}),
    "river": (lambda: river_scene(dem=DATA / "SainteHelens.dem") if (DATA / "SainteHelens.dem").exists()
              else river_scene(), 200, {"model": "curvature", "step_divisor": 10.0}),
    "lake": (lake_scene, 300, {"model": "sediment", "step_divisor": 10.0}),
}


def _overhangs(mesh: pv.PolyData, base: float) -> int:
    points = np.asarray(mesh.points, dtype=np.float64)
    return int(np.count_nonzero(overhanging_vertices(points, mesh.regular_faces, mask=points[:, 2] > base)))


def run_scene(name: str, out: Path, *, quick: bool, save_every: int) -> dict:
    build, iterations, options = SCENES[name]
    scene = build()
    if quick:
        iterations = max(iterations // 5, 10)
    lo, hi = scene.domain
    alg = HydraulicErosion(iterations=iterations, emitter=scene.emitters, drain=scene.drains, radius=scene.radius,
                           domain=(*lo, *hi), **options)
    mesh = scene.mesh
    base = float(mesh.bounds[4]) + 1e-6
    series = TimeSeriesWriter(out / f"{name}.pvd")
    shown = sorted({0, iterations // 3, (2 * iterations) // 3, iterations})
    panels: dict[int, pv.MultiBlock] = {}
    deepest = 0.0

    def check(t, result):
        nonlocal deepest
        result = pv.wrap(result)
        particles, surface = result["particles"], result["mesh"]
        if particles.n_points:
            depth = -particles.compute_implicit_distance(surface)["implicit_distance"]
            deepest = max(deepest, float(depth.max()) / scene.radius)
        if int(t) % save_every == 0 or int(t) == iterations:
            series.write(result, time=t)
        if int(t) in shown:
            panels[int(t)] = result

    start = time.perf_counter()
    alg.step_through(mesh, range(iterations + 1), on_output=check)
    seconds = time.perf_counter() - start
    final = panels[iterations]["mesh"]
    stats = {key[len("hydraulic_"):]: float(final.field_data[key][-1]) for key in final.field_data
             if key.startswith("hydraulic_")}
    render_strip([[panels[t]["mesh"] for t in shown], [panels[t]["mesh"] for t in shown]], out / f"{name}.png",
                 labels=[[f"{name}: {t} iterations" for t in shown], ["isolated model"] * len(shown)],
                 particles=[[panels[t]["particles"] for t in shown], [None] * len(shown)])
    return {
        "scene": name, "faces": mesh.n_cells, "iterations": iterations, "model": options["model"],
        "particles_last": int(stats["particles"]), "volume_lost": float(
            final.field_data["hydraulic_volume"][0]) - stats["volume"],
        "deepest_particle_inside_radii": round(deepest, 4),
        "overhanging_vertices_before": _overhangs(mesh, base), "overhanging_vertices_after": _overhangs(final, base),
        "seconds": round(seconds, 1), "series": str(series.path),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("hydraulic_scenes"))
    parser.add_argument("--scene", choices=[*SCENES, "all"], default="all")
    parser.add_argument("--quick", action="store_true", help="a fifth of the iterations, for a quick look")
    parser.add_argument("--save-every", type=int, default=10, help="iterations between saved steps")
    args = parser.parse_args()
    args.output_dir.mkdir(parents=True, exist_ok=True)
    for name in SCENES if args.scene == "all" else [args.scene]:
        print(json.dumps(run_scene(name, args.output_dir, quick=args.quick, save_every=args.save_every)))


if __name__ == "__main__":
    main()
