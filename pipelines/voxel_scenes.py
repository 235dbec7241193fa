"""Beneš et al. 2006 scenes on a voxel grid: river meanders, low hill sediment wash, a natural spring.

For each scene: runs VoxelErosion, writes <out>/<scene>.pvd (MultiBlock steps: the grid state and the
material's surface), <scene>.png (the surface at the saved steps, coloured by mean curvature) and
<scene>_slices.png (middle slices of voxel class and dissolved material at the end). The meander
also prints the material lost on the outer and inner banks of its bends.

    python pipelines/voxel_scenes.py [-o voxel_scenes] [--scene meander|hill|spring|all] [--steps 200]
                                     [--save-every 50] [--small]
"""

import argparse
from pathlib import Path

import numpy as np
import pyvista as pv

import pverosion
from pverosion.filters import VoxelErosion
from pverosion.filters.base import output_times
from pverosion.io import TimeSeriesWriter
from pverosion.plotting import plot_slices, render_strip
from pverosion.scenes.voxel import bank_erosion, hill_wash_grid, meander_grid, spring_grid

SCENES = {
    # builder of (grid, meander shape or None) at full or small size, options of the VoxelErosion filter
    "meander": (lambda small: meander_grid((64, 32, 32) if small else (128, 64, 64)),
                {"source_velocity": "1,0,0", "advection": "maccormack"}),
    "hill": (lambda small: (hill_wash_grid((40, 32, 28) if small else (64, 48, 40)), None),
             {"model": "cohesionless", "capacity": 0.7}),
    "spring": (lambda small: (spring_grid((40, 32, 28) if small else (64, 48, 40)), None),
               {"source_velocity": "1.5,0,0"}),
}


def run_scene(name: str, out: Path, *, steps: int, save_every: int, small: bool) -> None:
    build, options = SCENES[name]
    grid, meander = build(small)
    alg = VoxelErosion(iterations=steps, **options)
    series = TimeSeriesWriter(out / f"{name}.pvd")
    surfaces, labels = [], []

    def save(t, result):
        result = pv.wrap(result)
        series.write(result, time=t)
        surfaces.append(pverosion.curvature(result["surface"]))
        labels.append(f"{name}, step {int(t)}")

    final = pv.wrap(alg.step_through(grid, output_times(steps, save_every), on_output=save))
    render_strip([surfaces], out / f"{name}.png", labels=[labels])
    state = final["state"]
    plot_slices(state, out / f"{name}_slices.png", scalars="voxel_class", title=f"{name}: voxel class")
    plot_slices(state, out / f"{name}_dissolved.png", scalars="dissolved", title=f"{name}: dissolved material")
    lost = float(grid["material_amount"].sum() - state["material_amount"].sum())
    print(f"{name}: {steps} steps, {lost:.2f} voxels of material moved, mass error "
          f"{state.field_data['mass_error'][0]:.1e}")
    if meander is not None:
        shape = tuple(grid.dimensions)
        banks = bank_erosion(np.asarray(grid["material_amount"]).reshape(shape, order="F"),
                             np.asarray(state["material_amount"]).reshape(shape, order="F"), meander)
        print(f"  banks in the bends: outer {banks['outer']:.3f}, inner {banks['inner']:.3f} voxels lost")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("voxel_scenes"))
    parser.add_argument("--scene", choices=[*SCENES, "all"], default="all")
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--save-every", type=int, default=50)
    parser.add_argument("--small", action="store_true", help="smaller grids for a quick look")
    args = parser.parse_args()
    for name in SCENES if args.scene == "all" else [args.scene]:
        run_scene(name, args.output_dir, steps=args.steps, save_every=args.save_every, small=args.small)
    print(f"wrote the series and PNGs in {args.output_dir}")


if __name__ == "__main__":
    main()
