import numpy as np
import pytest
import pyvista as pv
from conftest import height_field

import pverosion
import pverosion.examples
from pverosion.examples import load_cube, load_hand
from pverosion.filters import Weathering
from pverosion.kernels.intersection import intersecting_faces
from pverosion.kernels.topology import edge_topology
from pverosion.kernels.weathering import WeatheringSolver


def _spread(points):
    d = np.linalg.norm(points - points.mean(axis=0), axis=1)
    return d.std() / d.mean()


def test_cube_becomes_a_sphere():
    cube = load_cube(resolution=10)
    assert cube.n_points == 602
    solver = WeatheringSolver(cube.points, cube.regular_faces, power=1.0)
    assert 0.12 < _spread(solver.points) < 0.14
    solver.run(200)
    assert _spread(solver.points) <= 0.02


def test_finer_cube_rounds_at_every_checkpoint():
    cube = load_cube(resolution=20)
    solver = WeatheringSolver(cube.points, cube.regular_faces)
    spreads = [_spread(solver.points)]
    for steps in (30, 70, 100):
        solver.run(steps)
        spreads.append(_spread(solver.points))
    assert np.all(np.diff(spreads) < 0), spreads


def _invariants(mesh, iterations, every):
    solver = WeatheringSolver(mesh.points, mesh.regular_faces)
    start = edge_topology(solver.faces, len(solver.points))
    seen = []

    def check(s):
        assert not intersecting_faces(s.points, s.faces).any()
        topo = edge_topology(s.faces, len(s.points))
        assert topo.n_boundary_edges <= start.n_boundary_edges
        assert topo.n_nonmanifold_edges <= start.n_nonmanifold_edges
        seen.append(s.step_count)

    solver.run(iterations, outputs=range(every, iterations + 1, every), callback=check)
    assert seen == list(range(every, iterations + 1, every))
    volume = solver.statistics["volume"]
    assert len(volume) == iterations + 1
    assert np.all(np.diff(volume) <= 0)
    return solver


def test_cube_invariants_over_200_steps():
    solver = _invariants(load_cube(resolution=10), 200, 10)
    assert solver.statistics["eroded_volume"][-1] > 0


def test_bunny_invariants_over_200_steps(bunny):
    solver = _invariants(bunny, 200, 20)
    assert solver.statistics["eroded_volume"][-1] > 0


def test_only_convex_vertices_move():
    rock = pverosion.examples.load_rock(subdivisions=4, seed=3)
    solver = WeatheringSolver(rock.points, rock.regular_faces, min_edge_ratio=0.0, check_every=0)
    for _ in range(3):
        H = solver.mean_curvature()
        before = solver.points.copy()
        solver.run(1)
        moved = np.any(solver.points != before, axis=1)
        assert not moved[H <= 0].any()
        assert moved[H > 0].mean() > 0.9


def test_plane_stays_unchanged():
    plane = height_field(lambda x, y: 0.0 * x, n=21)
    out = pverosion.weather(plane, iterations=50)
    assert np.array_equal(out.points, plane.points)
    assert np.all(out["displacement"] == 0)


def test_same_inputs_give_bit_identical_outputs():
    cube = load_cube(resolution=8)
    a = pverosion.weather(cube, iterations=40, power=2.0)
    b = pverosion.weather(cube, iterations=40, power=2.0)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.regular_faces, b.regular_faces)


def test_outputs_and_statistics_are_independent_of_thread_count():
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs at least two threads to compare")
    rock = pverosion.examples.load_rock(subdivisions=4, seed=3)
    before = numba.get_num_threads()
    runs = []
    try:
        for threads in (1, numba.config.NUMBA_NUM_THREADS):
            numba.set_num_threads(threads)
            runs.append(pverosion.weather(rock, iterations=30, power=2.0))
    finally:
        numba.set_num_threads(before)
    one, many = runs
    assert np.array_equal(one.points, many.points)
    for name in one.field_data:  # volume, area, curvature statistics per step
        assert np.array_equal(one.field_data[name], many.field_data[name]), name


def test_higher_power_erodes_protrusions_relative_to_the_body():
    hand = load_hand(subdivisions=5)
    points = np.asarray(hand.points)
    tips = np.argsort(np.linalg.norm(points, axis=1))[-25:]
    ratios = {}
    for n in (1.0, 5.0):
        solver = WeatheringSolver(points, hand.regular_faces, power=n, min_edge_ratio=0.0)
        solver.run(50)
        moved = np.linalg.norm(solver.displacement, axis=1)
        ratios[n] = moved[tips].mean() / np.median(moved)
    assert ratios[5.0] > 2.0 * ratios[1.0], ratios


def test_erodibility_array_and_callable():
    cube = load_cube(resolution=8)
    upper = cube.points[:, 2] > 0
    out = pverosion.weather(cube, iterations=20, erodibility=upper.astype(float), min_edge_ratio=0.0)
    assert np.all(out["displacement"][~upper] == 0)
    assert np.any(out["displacement"][upper] != 0)

    def soft_above(points):
        return (points[:, 2] > 0).astype(float)

    by_callable = pverosion.weather(cube, iterations=20, erodibility=soft_above, min_edge_ratio=0.0)
    moved = np.any(by_callable["displacement"] != 0, axis=1)
    assert moved.any() and not moved[cube.points[:, 2] < -0.5].any()
    cube["hard"] = upper.astype(float)
    by_name = pverosion.weather(cube, iterations=20, erodibility="hard", min_edge_ratio=0.0)
    assert np.array_equal(by_name.points, out.points)


def test_filter_time_steps_continue_from_the_cache():
    cube = load_cube(resolution=8)
    alg = Weathering(iterations=30)
    alg.SetInputDataObject(0, cube)
    alg.UpdateTimeStep(10)
    assert alg._cached.step_count == 10
    alg.UpdateTimeStep(30)
    stepped = pv.wrap(alg.GetOutputDataObject(0)).copy()
    direct = pverosion.weather(cube, iterations=30)
    assert np.array_equal(stepped.points, direct.points)
    assert len(stepped.field_data["weathering_volume"]) == 31


def test_input_is_not_modified_and_bad_options_are_named():
    cube = load_cube(resolution=6)
    before = cube.copy(deep=True)
    pverosion.weather(cube, iterations=5)
    assert np.array_equal(cube.points, before.points) and cube.array_names == before.array_names
    with pytest.raises(ValueError, match="power must be >= 1"):
        pverosion.weather(cube, power=0.5)
    with pytest.raises(ValueError, match="direction must be one of"):
        pverosion.weather(cube, direction="up")
    with pytest.raises(ValueError, match="erodibility must have shape"):
        pverosion.weather(cube, erodibility=np.ones(3))
    with pytest.raises(ValueError, match="not a point array"):
        pverosion.weather(cube, erodibility="missing")
    with pytest.raises(TypeError, match="iterations must be an integer"):
        pverosion.weather(cube, iterations=2.5)
    with pytest.raises(ValueError, match="power must be a real number"):
        WeatheringSolver(cube.points, cube.regular_faces, power=np.nan)
    with pytest.raises(pverosion.InvalidMeshError, match="triangulate"):
        pverosion.weather(pv.Plane())
