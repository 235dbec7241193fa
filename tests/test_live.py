"""Live erosion driven off-screen: picks place water or brushes, the worker steps, the view shows the changes."""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import touching_spheres

import pverosion
from pverosion.examples import load_cube


def _display(plotter, point) -> tuple[float, float]:
    renderer = plotter.renderer
    renderer.SetWorldPoint(*point, 1.0)
    renderer.WorldToDisplay()
    x, y, _ = renderer.GetDisplayPoint()
    return x, y


def _run_until(session, steps: int, *, limit: float = 600.0) -> None:
    """Let the worker step in the background until ``steps`` iterations are done and the view has shown
    at least two of its states (bounded wait): a fast worker may finish ``steps`` between two polls."""
    session.start()
    start = time.monotonic()
    while ((session.steps < steps or session.updates < 2) and time.monotonic() - start < limit
           and session.error is None):
        time.sleep(0.05)
        session.update_view()
    session.pause()
    assert session.error is None, session.error
    assert session.steps >= steps
    assert session.updates >= 2  # the view followed the worker while it stepped


def _moved(session, mesh) -> np.ndarray:
    shown = session.mesh
    return np.linalg.norm(shown.points - mesh.points[shown["input_id"]], axis=1) > 0.0


def test_water_erodes_where_it_falls_and_nowhere_else():
    mesh = load_cube(resolution=12)
    session = pverosion.interactive(mesh, stage="hydraulic", off_screen=True, window_size=(400, 400))
    try:
        picked = session.pick_screen(*_display(session.plotter, (0.4, 0.4, 1.0)))  # a click on the top face
        np.testing.assert_allclose(picked, (0.4, 0.4, 1.0), atol=1e-3)
        assert session.source[2] > 1.0  # the source hangs above the picked point
        wet = np.zeros(mesh.n_points, dtype=bool)
        first = []

        def record(_step: int) -> None:  # the vertices the water reached, iteration by iteration
            now = session.solver.ids[session.solver.f_distance > 0.0]
            if len(now) and not wet.any():
                first.append(mesh.points[now])
            wet[now] = True

        session.on_step(record)
        _run_until(session, 12)
        session.update_view()
        moved = _moved(session, mesh)
        assert session.particles.n_points > 0
        assert moved.sum() > 0
        changed = session.mesh["input_id"][moved]
        gone = np.setdiff1d(np.arange(mesh.n_points), session.mesh["input_id"])  # collapsed away
        assert wet[changed].all() and wet[gone].all()  # every change lies where the water was
        assert not wet[mesh.points[:, 2] < -0.5].any()  # it never reached the lower part of the cube
        # the water first touched the surface under the source
        assert np.linalg.norm(first[0][:, :2] - (0.4, 0.4), axis=1).max() <= session.source_radius + 4 * session.radius
        # pause holds the state; reset goes back to the input without water
        held = session.steps
        time.sleep(0.3)
        assert session.steps == held
        session.reset()
        assert session.steps == 0 and session.source is None and session.particles.n_points == 0
        assert not _moved(session, mesh).any()
    finally:
        session.stop()
        session.plotter.close()


def test_the_view_shows_the_water_between_substeps_on_the_last_surface():
    mesh = load_cube(resolution=8)
    session = pverosion.interactive(mesh, stage="hydraulic", off_screen=True, window_size=(200, 200))
    try:
        assert session.solver.fluid.params.substeps == 2
        session.pick((0.4, 0.4, 1.0))
        session.step(4)
        session.update_view()
        assert session.shown_time == session.shown_step == 4
        surface = session.mesh.points.copy()
        water = dict(zip(session.particles["particle_id"], session.particles.points.copy()))
        assert water
        hook = session.solver.fluid.on_substep
        seen = []

        def show(done, positions, velocities, ids):  # the view takes the state the hook publishes
            hook(done, positions, velocities, ids)
            assert session.update_view(render=False)
            seen.append((session.shown_time, session.mesh.points.copy(), session.particles.points.copy(),
                         session.particles["particle_id"].copy(), positions.copy(), ids.copy()))

        session.solver.fluid.on_substep = show
        session.step(1)
        assert len(seen) == 1
        shown_time, points, particles, shown_ids, positions, ids = seen[0]
        assert shown_time == 4.5
        np.testing.assert_array_equal(points, surface)  # the surface of the iteration before
        np.testing.assert_array_equal(particles, positions)  # the water after the first substep
        np.testing.assert_array_equal(shown_ids, ids)
        common = [k for k, i in enumerate(ids) if i in water]
        assert common and all(not np.array_equal(particles[k], water[ids[k]]) for k in common)  # it moved
        assert session.update_view(render=False) and session.shown_time == 5.0  # then the iteration's end
        assert not np.array_equal(session.particles.points, particles) or session.particles.n_points != len(particles)
    finally:
        session.stop()
        session.plotter.close()


def test_weathering_brush_erodes_only_inside_it(tmp_path):
    mesh = load_cube(resolution=12)
    session = pverosion.interactive(mesh, stage="weather", off_screen=True, window_size=(400, 400),
                                    source_radius=0.5, min_edge_ratio=0.0)
    try:
        corner = np.array([1.0, 1.0, 1.0])
        session.pick(corner)
        _run_until(session, 5)
        session.update_view()
        moved = _moved(session, mesh)
        assert moved.any()
        original = mesh.points[session.mesh["input_id"]]
        assert np.linalg.norm(original[moved] - corner, axis=1).max() <= 0.5 + 1e-9
        # the shading normals shown are the shown surface's own (computed by the worker, not by the view)
        from pverosion.kernels.mesh.geometry import vertex_normals

        shown = session.mesh
        np.testing.assert_allclose(shown.point_data.active_normals,
                                   vertex_normals(np.asarray(shown.points), shown.regular_faces), atol=1e-12)
        path = session.save(tmp_path / "state.vtp")
        import pyvista as pv

        np.testing.assert_array_equal(pv.read(path).points, session.mesh.points)
    finally:
        session.stop()
        session.plotter.close()


def test_live_rejects_unknown_stage():
    with pytest.raises(ValueError, match="stage"):
        pverosion.interactive(load_cube(resolution=4), stage="volcano", off_screen=True)


def test_live_rejects_bad_thread_count():
    import numba

    for threads in (0, numba.config.NUMBA_NUM_THREADS + 1):
        with pytest.raises(ValueError, match="threads"):
            pverosion.interactive(load_cube(resolution=4), off_screen=True, threads=threads)


@pytest.mark.parametrize("stage", ["weather", "hydraulic"])
def test_live_refuses_what_the_stage_refuses(stage):
    """The live viewer checks its mesh as the stage's filter does: a non-manifold vertex is refused, and float32
    points a million units out are warned about."""
    pinched, _ = touching_spheres()
    with pytest.raises(pverosion.InvalidMeshError, match="1 non-manifold vertex"):
        pverosion.interactive(pinched, stage=stage, off_screen=True)
    far = load_cube(resolution=4)
    far.points = (np.asarray(far.points, dtype=np.float64) + 1e6).astype(np.float32)
    with pytest.warns(UserWarning, match="stored as float32"):
        pverosion.interactive(far, stage=stage, off_screen=True).plotter.close()
