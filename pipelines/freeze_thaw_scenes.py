"""Mateos et al.'s freeze–thaw scenes: a cave carved into a hill (Figure 14), a columnar basalt wall (Figure 15),
tilted slabs with upward gravity (Figure 16) and a ridge from the St Helens DEM (Figure 17).

For each scene: runs the FreezeThaw filter, writes <out>/<scene>.pvd (MultiBlock steps: eroded surface, shards,
links, water paths of the step) and <scene>.png (the remaining shards at four times), and prints the cells left,
the links broken and the time per path. The ridge runs when ../shared/data/SainteHelens.dem (or --dem) exists.

    python pipelines/freeze_thaw_scenes.py [-o freeze_thaw_scenes] [--scene cave|basalt|slabs|ridge|all] [--small]
"""

import argparse
import time
from pathlib import Path

import pyvista as pv

from pverosion.examples import data_path
from pverosion.filters import FreezeThaw
from pverosion.io import TimeSeriesWriter
from pverosion.plotting import render_strip
from pverosion.scenes.shards import SCENES, ridge_scene

DEM = data_path("SainteHelens.dem")


def run_scene(name: str, build, out: Path) -> None:
    mesh, options, steps = build()
    alg = FreezeThaw(iterations=steps, **options)
    series = TimeSeriesWriter(out / f"{name}.pvd")
    shown = {0, steps // 3, (2 * steps) // 3, steps}
    panels, labels = [], []
    per_step = options["paths_per_step"]

    def save(t, result):
        result = pv.wrap(result)
        series.write(result, time=t)
        if int(t) in shown:
            panels.append(result["shards"])
            labels.append(f"{name}: {int(t) * per_step} paths")

    start = time.perf_counter()
    alg.step_through(mesh, range(steps + 1), on_output=save)
    seconds = time.perf_counter() - start
    surface = pv.wrap(alg.GetOutputDataObject(0))["surface"]
    field = {key: int(surface.field_data[key][0])
             for key in ("shard_cells", "shard_interior_links", "shard_paths", "shard_solid_cells", "shard_breaks")}
    render_strip([panels], out / f"{name}.png", labels=[labels], scalars="shard_colour", cmap="tab20")
    print(f"{name}: {field['shard_cells']} cells ({field['shard_interior_links']} interior links), "
          f"{field['shard_paths']} paths: {field['shard_solid_cells']} cells left, {field['shard_breaks']} links "
          f"broken; {seconds:.1f} s with generation and output -> {series.path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("freeze_thaw_scenes"))
    parser.add_argument("--scene", choices=[*SCENES, "ridge", "all"], default="all")
    parser.add_argument("--dem", type=Path, default=DEM, help="DEM of the ridge scene")
    parser.add_argument("--small", action="store_true", help="fewer cells and paths for a quick look")
    args = parser.parse_args()
    builders = {name: (lambda f=f: f(args.small)) for name, f in SCENES.items()}
    if args.dem.exists():
        builders["ridge"] = lambda: ridge_scene(args.dem, args.small)
    elif args.scene in ("ridge", "all"):
        print(f"ridge: skipped, no DEM at {args.dem}")
    for name in builders if args.scene == "all" else [args.scene]:
        if name in builders:
            run_scene(name, builders[name], args.output_dir)
    print(f"wrote the series and PNGs in {args.output_dir}")


if __name__ == "__main__":
    main()
