"""Thesis Figures 11.10 and 11.14: weathering follows the material under each vertex.

Writes into <out>:
  block_16_cells.png / .pvd   a block in 16 vertical cells of random hardness, weathered unevenly (Fig. 11.10b)
  hills_cube.png / .pvd       a cube of hard bedrock, sinc-shaped hills and a soft cover (Fig. 11.14)

    python pipelines/material_erosion.py [-o figures] [--iterations 150]
"""

import argparse
from pathlib import Path

from pverosion.plotting import render_strip
from pverosion.scenes.weathering import hills_cube, sixteen_cell_block, weathering_checkpoints


def weather(mesh, field, iterations, series):
    """Weathered start and end surfaces, each coloured by the hardness at its current points."""
    run = weathering_checkpoints(mesh, [0, iterations], series, erodibility=field)
    for surface in run.meshes:
        surface["hardness"] = field.sample(surface.points).hardness
    return run.meshes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("figures"))
    parser.add_argument("--iterations", type=int, default=150)
    args = parser.parse_args()
    out = args.output_dir
    block, field, _ = sixteen_cell_block()
    render_strip([weather(block, field, args.iterations, out / "block_16_cells.pvd")], out / "block_16_cells.png",
                 scalars="hardness", cmap="copper_r",
                 labels=[["16 cells, random hardness", f"after {args.iterations} steps"]])
    cube, field = hills_cube()
    render_strip([weather(cube, field, args.iterations, out / "hills_cube.pvd")], out / "hills_cube.png",
                 scalars="hardness", cmap="copper_r", labels=[["bedrock, hills, cover", f"after {args.iterations} steps"]])
    print(f"wrote the series and PNGs in {out}")


if __name__ == "__main__":
    main()
