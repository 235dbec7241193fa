"""The one solver protocol: every time-stepped kernel steps, runs, and keeps its state and statistics alike."""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv

from pverosion.examples import load_cube
from pverosion.filters.base import polydata_triangles
from pverosion.filters.voxel import _grid_array
from pverosion.kernels.shards.freeze_thaw import FreezeThawSimulation, FreezeThawSolver
from pverosion.kernels.shards.graph import build_shards
from pverosion.kernels.solver.protocol import Solver
from pverosion.kernels.voxel.erosion import VoxelErosionSolver
from pverosion.kernels.weathering.model import WeatheringSolver
from pverosion.scenes.voxel import meander_grid


def _weathering():
    cube = load_cube(resolution=6)
    return WeatheringSolver(cube.points, cube.regular_faces, power=1.0)


def _voxel():
    grid, _ = meander_grid((24, 12, 10), spacing=0.05, depth=3, half_width=3.0, amplitude=2.0)
    amount, water = (_grid_array(grid, name) for name in ("material_amount", "water"))
    source, drain = (_grid_array(grid, name) != 0 for name in ("source", "drain"))
    return VoxelErosionSolver(amount, water, spacing=0.05, source=source, source_velocity=(1.5, 0, 0), drain=drain,
                              time_step=0.01)


def _freeze_thaw():
    cone = pv.Cone(center=(0, 0, 0.5), direction=(0, 0, 1), height=1.0, radius=1.0, resolution=24).triangulate()
    points, faces = polydata_triangles(cone)
    rng = np.random.default_rng(3)
    seeds = rng.uniform(-0.7, 0.7, (120, 3)) * [1, 1, 0.7] + [0, 0, 0.3]
    graph = build_shards(seeds, points, faces)
    return FreezeThawSolver(FreezeThawSimulation(graph, seed=5), paths_per_step=40, record_paths=True)


BUILDERS = {"weathering": _weathering, "voxel": _voxel, "freeze_thaw": _freeze_thaw}


@pytest.mark.parametrize("build", BUILDERS.values(), ids=BUILDERS.keys())
def test_run_n_equals_n_single_steps_and_keeps_one_statistics_row_per_step(build):
    together, alone = build(), build()
    assert isinstance(together, Solver) and together.step_count == 0
    together.run(3)
    for _ in range(3):
        alone.step()
    assert together.step_count == alone.step_count == 3
    assert together.state.keys() == alone.state.keys()
    for name, values in together.state.items():
        np.testing.assert_array_equal(values, alone.state[name], err_msg=name)
    for name, series in together.statistics.items():
        assert len(series) == 4, name  # step 0 and three steps
        np.testing.assert_array_equal(series, alone.statistics[name], err_msg=name)


@pytest.mark.parametrize("build", BUILDERS.values(), ids=BUILDERS.keys())
def test_run_calls_back_at_the_outputs_and_after_every_step(build):
    solver = build()
    seen, stepped = [], []
    solver.run(4, outputs=[2, 4, 9], callback=lambda s: seen.append(s.step_count),
               on_step=lambda s: stepped.append(s.step_count))
    assert seen == [2, 4]
    assert stepped == [1, 2, 3, 4]
    for bad in (-1, 1.5):
        with pytest.raises(ValueError, match="integer >= 0"):
            solver.run(bad)


def test_freeze_thaw_keeps_the_paths_of_its_last_checkpoint_step():
    solver = _freeze_thaw()
    solver.run(2)
    assert solver.record is not None and solver.record.n_paths == solver.paths_per_step
    assert solver.simulation.paths == 2 * solver.paths_per_step
