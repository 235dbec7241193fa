"""Voxel erosion–deposition: conservation, the cohesive threshold, deposition, saturation, bad input."""

import numpy as np
import pytest

from pverosion.filters.voxel import _grid_array
from pverosion.kernels.voxel.erosion import ErosionParameters, VoxelErosionSolver, erosion_step
from pverosion.scenes.voxel import bank_erosion, meander_grid


def _channel():
    grid, _ = meander_grid((40, 20, 16), spacing=0.05, depth=4, half_width=4.0, amplitude=3.0)
    return tuple(_grid_array(grid, name) for name in ("material_amount", "water")) + tuple(
        _grid_array(grid, name) != 0 for name in ("source", "drain"))


def test_material_is_conserved_every_step_apart_from_drains():
    amount, water, source, drain = _channel()
    solver = VoxelErosionSolver(amount, water, spacing=0.05, source=source, source_velocity=(1.5, 0, 0), drain=drain,
                                params=ErosionParameters(friction=0.05))
    eroded = 0.0
    for _ in range(40):
        figures = solver.step(0.01)
        eroded += figures["eroded"]
        assert solver.mass_error() <= 1e-9
    assert eroded > 0.0 and solver.drained_material > 0.0
    assert solver.amount.sum() < amount.sum()


def test_cohesive_erodes_nothing_below_the_critical_shear_stress():
    amount, water, source, drain = _channel()
    # tau = f rho U^2 / 2 stays far below tau_ce = 10 for U < 3 m/s with f = 1e-4
    params = ErosionParameters(friction=1e-4)
    solver = VoxelErosionSolver(amount, water, spacing=0.05, source=source, source_velocity=(1.5, 0, 0), drain=drain,
                                params=params)
    for _ in range(30):
        figures = solver.step(0.01)
        assert figures["eroded"] == 0.0 and figures["max_speed"] < 3.0
    assert np.array_equal(solver.amount, amount)


def test_meander_erodes_its_outer_banks_more_than_its_inner_banks():
    # the slow test of the suite (about a minute): the bends need room for the flow's inertia to matter
    grid, meander = meander_grid((128, 64, 32))
    amount, water, source, drain = (_grid_array(grid, name) for name in ("material_amount", "water", "source", "drain"))
    solver = VoxelErosionSolver(amount, water, spacing=0.05, source=source != 0, source_velocity=(1.0, 0, 0),
                                drain=drain != 0, advection="maccormack")
    for _ in range(400):
        solver.step(0.01)
    banks = bank_erosion(amount, solver.amount, meander)
    assert banks["outer"] > 1.2 * banks["inner"] > 0.0


def test_loaded_still_water_deposits_on_the_bed_below():
    n = (6, 6, 6)
    amount = np.zeros(n)
    amount[:, :, :2] = 0.5          # a bed with room
    water = np.zeros(n)
    water[:, :, 2:4] = 1.0
    load = np.where(water > 0, 0.2, 0.0)
    speed = np.zeros(n)
    params = ErosionParameters(model="cohesionless")
    before = amount.sum() + load.sum()
    figures = erosion_step(params, liquid=water > 0, amount=amount, erodibility=np.ones(n), water=water,
                           load=load, speed=speed, dt=0.5)
    assert figures["deposited"] > 0.0 and figures["eroded"] == 0.0
    assert amount[:, :, 1].min() > 0.5 and np.all(amount[:, :, 0] == 0.5)   # only the top of the bed grows
    assert np.all(load[:, :, 3] == 0.2)                                      # water not touching the bed keeps its load
    assert amount.sum() + load.sum() == pytest.approx(before, rel=1e-12)


def test_oversaturated_water_becomes_material():
    n = (5, 5, 5)
    amount = np.zeros(n)
    amount[:, :, 0] = 1.0
    water = np.zeros(n)
    water[:, :, 1:3] = 1.0
    load = np.zeros(n)
    load[2, 2, 1] = 0.8            # beyond c_max = 0.5
    before = amount.sum() + load.sum()
    figures = erosion_step(ErosionParameters(), liquid=water > 0, amount=amount, erodibility=np.ones(n), water=water,
                           load=load, speed=np.zeros(n), dt=0.01)
    assert figures["saturated"] == 1
    assert amount[2, 2, 1] == pytest.approx(0.5) and load[2, 2, 1] == 0.0 and water[2, 2, 1] == 0.0
    assert water[2, 2, 2] == 2.0   # its water moved up
    assert amount.sum() + load.sum() == pytest.approx(before, rel=1e-12)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="model must be one of"):
        ErosionParameters(model="sticky")
    with pytest.raises(ValueError, match="saturation"):
        ErosionParameters(saturation=0.0)
    with pytest.raises(ValueError, match="in \\[0, 1\\]"):
        VoxelErosionSolver(np.full((4, 4, 4), 2.0), np.zeros((4, 4, 4)), spacing=1.0)
    with pytest.raises(ValueError, match="erodibility has shape"):
        VoxelErosionSolver(np.zeros((4, 4, 4)), np.zeros((4, 4, 4)), spacing=1.0, erodibility=np.ones((4, 4)))
