"""Thesis Figures 11.10 and 11.14: weathering follows the material under each vertex.

Writes into <out>:
  block_16_cells.png / .pvd   a block in 16 vertical cells of random hardness, weathered unevenly (Fig. 11.10b)
  hills_cube.png / .pvd       a cube of hard bedrock, sinc-shaped hills and a soft cover (Fig. 11.14)

    python pipelines/material_erosion.py [-o figures] [--iterations 150]
"""

import argparse
from pathlib import Path

import pyvista as pv

from pverosion.io import TimeSeriesWriter
from pverosion.kernels.weathering import WeatheringSolver
from pverosion.plotting import render_strip
from pverosion.scenes import hills_cube, sixteen_cell_block


def weather(mesh, field, iterations, series):
    solver = WeatheringSolver(mesh.points, mesh.regular_faces, erodibility=field)
    solver.run(iterations, progress=True)
    result = pv.PolyData.from_regular_faces(solver.points, solver.faces)
    result["hardness"] = field.sample(solver.points, ids=solver.ids).hardness
    result["mean_curvature"] = solver.mean_curvature()
    start = mesh.copy()
    start["hardness"] = field.sample(mesh.points).hardness
    with TimeSeriesWriter(series) as writer:
        writer.write(start, time=0)
        writer.write(result, time=iterations)
    return start, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("figures"))
    parser.add_argument("--iterations", type=int, default=150)
    args = parser.parse_args()
    out = args.output_dir
    block, field, _ = sixteen_cell_block()
    start, end = weather(block, field, args.iterations, out / "block_16_cells.pvd")
    render_strip([[start, end]], out / "block_16_cells.png", scalars="hardness", cmap="copper_r",
                 labels=[["16 cells, random hardness", f"after {args.iterations} steps"]])
    cube, field = hills_cube()
    start, end = weather(cube, field, args.iterations, out / "hills_cube.pvd")
    render_strip([[start, end]], out / "hills_cube.png", scalars="hardness", cmap="copper_r",
                 labels=[["bedrock, hills, cover", f"after {args.iterations} steps"]])
    print(f"wrote the series and PNGs in {out}")


if __name__ == "__main__":
    main()
