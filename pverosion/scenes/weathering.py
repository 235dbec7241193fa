"""Reproductions of the papers' scenes, shared by ``pipelines/`` and ``pverosion demo``.

Each scene writes its results atomically: the surface at every checkpoint as
a ``.pvd`` time series, a PNG strip rendered off-screen with the curvature
colour coding, and a chart of the per-step statistics.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyvista as pv

from pverosion._progress import step_bar
from pverosion.filters.weathering import weathering_output
from pverosion.io import TimeSeriesWriter
from pverosion.kernels.weathering.model import WeatheringSolver
from pverosion.plotting import plot_statistics, render_strip

__all__ = [
    "WeatheringRun",
    "cube_to_sphere",
    "hills_cube",
    "power_modifier",
    "sixteen_cell_block",
    "weathering_checkpoints",
]


@dataclass(frozen=True)
class WeatheringRun:
    """Outputs of one weathering run at its checkpoints."""

    label: str
    steps: list[int]
    meshes: list[pv.PolyData]
    statistics: dict
    retries: int
    series: Path


def weathering_checkpoints(
    mesh: pv.PolyData, checkpoints: list[int], series: Path, *, label: str = "", progress: bool = True, **options
) -> WeatheringRun:
    """Weather ``mesh`` and keep (and write to the ``.pvd`` ``series``) the surface at each checkpoint.

    Parameters
    ----------
    mesh : pyvista.PolyData
    checkpoints : list of int
        Steps to keep; 0 keeps the input.
    series : pathlib.Path
        ``.pvd`` file of the kept steps.
    label : str
        Name of the run in charts.
    progress : bool, default: True
        Show a progress bar.
    **options
        Options of :class:`~pverosion.kernels.weathering.model.WeatheringSolver`.

    Returns
    -------
    WeatheringRun
    """
    steps = sorted(set(checkpoints))
    solver = WeatheringSolver(mesh.points, mesh.regular_faces, **options)
    meshes: list[pv.PolyData] = []
    writer = TimeSeriesWriter(series)

    def keep(s: WeatheringSolver) -> None:
        out = pv.PolyData()
        weathering_output(s, mesh, out)
        meshes.append(out)
        writer.write(out, time=s.step_count)

    if steps and steps[0] == 0:
        keep(solver)
    with step_bar(steps[-1], label=solver.PROGRESS_LABEL, enabled=progress) as on_step:
        solver.run(steps[-1], outputs=steps, callback=keep, on_step=on_step)
    return WeatheringRun(label, steps, meshes, solver.statistics, solver.retries, writer.path)


def cube_to_sphere(out_dir: Path, *, resolution: int = 10, checkpoints=(0, 30, 100, 200)) -> WeatheringRun:
    """Skorkovská 2019, Figure 6: a cube weathered into a sphere (n = 1).

    Writes ``cube_to_sphere.pvd`` (+ folder), ``cube_to_sphere.png`` (strip)
    and ``cube_to_sphere_statistics.png`` into ``out_dir``.
    """
    from pverosion.examples import load_cube

    out_dir = Path(out_dir)
    run = weathering_checkpoints(load_cube(resolution=resolution), list(checkpoints),
                                 out_dir / "cube_to_sphere.pvd", label="cube, n = 1", power=1.0)
    render_strip([run.meshes], out_dir / "cube_to_sphere.png", labels=[[f"step {s}" for s in run.steps]])
    plot_statistics({run.label: run.statistics}, out_dir / "cube_to_sphere_statistics.png")
    return run


def power_modifier(mesh: pv.PolyData, out_dir: Path, *, powers=(1.0, 2.0, 3.0),
                   checkpoints=(0, 20, 50, 100, 200)) -> list[WeatheringRun]:
    """Skorkovská 2019, Figure 7: one row per power modifier n, columns at the checkpoints.

    Writes ``power_n<n>.pvd`` per row, ``power_modifier.png`` (rows of
    renders) and ``power_modifier_statistics.png`` into ``out_dir``.
    """
    out_dir = Path(out_dir)
    runs = [weathering_checkpoints(mesh, list(checkpoints), out_dir / f"power_n{n:g}.pvd", label=f"n = {n:g}",
                                   power=float(n)) for n in powers]
    render_strip([r.meshes for r in runs], out_dir / "power_modifier.png",
                 labels=[[f"n = {r.label[4:]}, step {s}" for s in r.steps] for r in runs])
    plot_statistics({r.label: r.statistics for r in runs}, out_dir / "power_modifier_statistics.png")
    return runs


def sixteen_cell_block(*, resolution: int = 16, seed: int = 0, hardness_range=(1.0, 8.0)):
    """Thesis Figure 11.10b: a block split into 16 vertical cells (4 x 4) of random hardness.

    Returns
    -------
    block : pyvista.PolyData
        A 2 x 2 x 1 box (``load_cube`` scaled), grid cells ``resolution`` per unit.
    field : BSPMaterials
        BSP tree of 3 + 3 axis planes (x and y at -0.5, 0, 0.5) with one material
        per cell, hardness drawn from ``hardness_range`` with ``seed``.
    cell_of : callable
        ``cell_of(points) -> (N,)`` cell index 0..15 of points.
    """
    from pverosion.examples import load_cube
    from pverosion.kernels.materials.bsp import BSPNode, BSPTree
    from pverosion.kernels.materials.field import BSPMaterials
    from pverosion.kernels.materials.surfaces import Plane

    block = load_cube(resolution=resolution, size=2.0)
    block.points[:, 2] *= 0.5
    cuts = (-0.5, 0.0, 0.5)

    def split(axis: int, lo: int, hi: int, inner):
        """Balanced subtree over cuts[lo:hi] along ``axis``; ``inner(slot)`` builds each slab."""
        if lo == hi:
            return inner(lo)
        mid = (lo + hi) // 2
        normal = [0.0, 0.0, 0.0]
        normal[axis] = 1.0
        return BSPNode(Plane(tuple(normal), -cuts[mid]), split(axis, lo, mid, inner), split(axis, mid + 1, hi, inner))

    tree = BSPTree.from_nodes(split(0, 0, 3, lambda i: split(1, 0, 3, lambda j: 4 * i + j)))
    rng = np.random.default_rng(seed)
    field = BSPMaterials(tree, rng.uniform(*hardness_range, 16))

    def cell_of(points):
        p = np.asarray(points)
        return 4 * np.searchsorted(cuts, p[:, 0]) + np.searchsorted(cuts, p[:, 1])

    return block, field, cell_of


def hills_cube(*, resolution: int = 16):
    """Thesis Figure 11.14: a cube of layered material, hard bedrock below sinc-shaped soft hills.

    Returns
    -------
    cube : pyvista.PolyData
    field : BSPMaterials
        Bedrock (hardness 8) below z = -0.4, hills (hardness 4) under a sinc
        surface, soft cover (hardness 1) above, with a gradual falloff.
    """
    from pverosion.examples import load_cube
    from pverosion.kernels.materials.bsp import BSPNode, BSPTree
    from pverosion.kernels.materials.field import BSPMaterials, Gradual
    from pverosion.kernels.materials.surfaces import Plane, SincSurface

    hills = SincSurface(centre=(0.0, 0.0), height=-0.1, amplitude=0.7, width=0.6)
    tree = BSPTree.from_nodes(BSPNode(Plane((0.0, 0.0, 1.0), 0.4), 0, BSPNode(hills, 1, 2)))
    return load_cube(resolution=resolution), BSPMaterials(tree, [8.0, 4.0, 1.0], gradual=Gradual(0.3, floor=0.5))
