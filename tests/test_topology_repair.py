"""The erosion stages' guard with repair="topology": a surface pushed through itself is cut along the curves and the
run goes on with a closed, intersection-free mesh; "retry" rolls back instead, "off" leaves the intersections."""

import numpy as np
import pytest
import pyvista as pv

from pverosion.kernels.exact.intersection import intersecting_faces
from pverosion.kernels.exact.intersection_curves import intersection_curves
from pverosion.kernels.fluid.particle_fluid import FluidParameters
from pverosion.kernels.hydraulic.erosion import HydraulicSolver
from pverosion.kernels.solver.mesh_evolution import GuardedMeshSolver, volume_area


class Dent(GuardedMeshSolver):
    """Pushes the top of a thin slab down by ``depth`` per step where |x|, |y| < 0.3 (through the bottom)."""

    STAT_NAMES = ("volume",)

    def __init__(self, points, faces, *, depth, **options):
        super().__init__(points, faces, min_edge_ratio=0.0, check_every=1, **options)
        self.depth = depth
        p = self.points
        self._dent = (p[:, 2] > 0.0) & (np.abs(p[:, 0]) < 0.3) & (np.abs(p[:, 1]) < 0.3)  # by input id
        self._start()

    def _step(self):
        moving = self._dent[self.ids] & (self._scale[self.ids] > 0.0) & (self.points[:, 2] > -0.5)
        self.points = self.points.copy()
        self.points[moving, 2] -= self.depth * self._scale[self.ids[moving]]
        self.step_count += 1
        self._stats.append(self._row())

    def _row(self):
        return (float(volume_area(self.points, self.faces, self._origin)[0]),)


def _slab():
    slab = pv.Box(bounds=(-1, 1, -1, 1, -0.05, 0.05), level=(20, 20, 1)).triangulate().clean()
    return np.asarray(slab.points, dtype=float), slab.regular_faces


def _closed(faces):
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    keys = {tuple(e) for e in directed.tolist()}
    return len(keys) == len(directed) and all((b, a) in keys for a, b in keys)


def test_topology_repair_opens_a_hole_where_the_wall_was_pushed_through():
    points, faces = _slab()
    solver = Dent(points, faces, depth=0.07, repair="topology")
    before = solver.volume()
    solver.run(3)
    assert solver.repairs >= 1 and solver.retries == 0
    assert _closed(solver.faces)
    curves = intersection_curves(solver.points, solver.faces)
    assert len(curves.segments) == 0 and not intersecting_faces(solver.points, solver.faces).any()
    # the pushed-through part is gone: a hole through the slab, about 0.6 x 0.6 across
    assert solver.volume() < before - 0.6 * 0.6 * 0.1 * 0.5
    assert len(solver.ids) == len(solver.points) and len(solver.displacement) == len(solver.points)


def test_retry_rolls_back_and_off_leaves_the_intersections():
    points, faces = _slab()
    retry = Dent(points, faces, depth=0.07, repair="retry")
    retry.run(3)
    assert retry.retries >= 1 and retry.repairs == 0
    assert not intersecting_faces(retry.points, retry.faces).any()
    off = Dent(points, faces, depth=0.07, repair="off")
    off.run(3)
    assert off.check_every == 0 and intersecting_faces(off.points, off.faces).any()
    with pytest.raises(ValueError, match="repair"):
        Dent(points, faces, depth=0.07, repair="sometimes")


def test_hydraulic_repair_hands_the_sediment_of_vertices_cut_away_to_the_nearest_ones_left():
    points, faces = _slab()
    solver = HydraulicSolver(points, faces, fluid=FluidParameters(radius=0.02), model="sediment", repair="topology")
    rng = np.random.default_rng(3)
    solver.pending = rng.uniform(-1e-4, 1e-4, len(solver.points))
    owed = solver.pending.sum()
    pushed = solver.points.copy()
    dent = (pushed[:, 2] > 0.0) & (np.abs(pushed[:, 0]) < 0.3) & (np.abs(pushed[:, 1]) < 0.3)
    pushed[dent, 2] -= 0.14  # the dent's top goes through the bottom
    solver.points = pushed
    solver._repair_topology()
    assert solver.repairs == 1 and _closed(solver.faces)
    assert len(solver.pending) == len(solver.points) < len(points)
    assert solver.pending.sum() == pytest.approx(owed, rel=1e-12, abs=1e-15)


def test_a_topology_repair_that_leaves_no_surface_rolls_back_as_retry(monkeypatch):
    """Steps that turn the whole surface inside out leave nothing of winding number >= 1: the solver rolls back
    and shortens the steps, as with repair="retry", instead of failing on an empty mesh ("mesh is empty")."""
    import dataclasses

    from pverosion.kernels.repair import mesh_repair

    real = mesh_repair.repair_intersections

    def nothing_left(points, faces):
        result = real(points, faces)
        return dataclasses.replace(result, points=result.points[:0], faces=result.faces[:0],
                                   source_face=result.source_face[:0], source_vertex=result.source_vertex[:0])

    monkeypatch.setattr(mesh_repair, "repair_intersections", nothing_left)
    points, faces = _slab()
    solver = Dent(points, faces, depth=0.07, repair="topology")
    solver.run(3)
    assert solver.retries >= 1 and solver.repairs == 0
    assert len(solver.points) == len(points) and not intersecting_faces(solver.points, solver.faces).any()
