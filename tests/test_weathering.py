import numpy as np
import pytest
import pyvista as pv
from conftest import height_field

import pverosion
import pverosion.examples
from pverosion.examples import load_cube, load_hand
from pverosion.filters import Weathering
from pverosion.kernels.exact.intersection import intersecting_faces
from pverosion.kernels.mesh.remesh import CollapseTopology
from pverosion.kernels.mesh.topology import edge_topology
from pverosion.kernels.weathering.model import WeatheringSolver


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


@pytest.mark.parametrize("erodibility", [1.0, 100.0, 1e6])
def test_no_vertex_moves_more_than_the_step_bound_however_soft_the_material(erodibility):
    """A step is at most e_avg / step_divisor whatever the erodibility: a soft material (or a Gradual falloff)
    speeds up the vertices of lower curvature up to that bound. Erodibility 100 used to turn a sphere inside
    out in three steps, unseen by the guard (the surface passed through itself whole)."""
    from pverosion.kernels.mesh.geometry import average_edge_length, signed_volume

    sphere = pv.Icosphere(radius=1.0, nsub=3)
    points = np.asarray(sphere.points, dtype=np.float64)
    solver = WeatheringSolver(points, sphere.regular_faces, erodibility=np.full(len(points), erodibility),
                              min_edge_ratio=0.0, normalization="paper")
    largest = []
    for _ in range(5):
        before = solver.points.copy()
        bound = average_edge_length(before, solver.faces) / solver.step_divisor
        solver.step()
        largest.append(np.linalg.norm(solver.points - before, axis=1).max() / bound)
    assert max(largest) <= 1.0 + 1e-9
    assert min(largest) > 0.99  # the vertex of the largest curvature steps the whole bound
    assert 0.8 * signed_volume(points, sphere.regular_faces) < signed_volume(solver.points, solver.faces)
    assert solver.retries == 0


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
    with pytest.raises(ValueError, match="normalization must be one of"):
        pverosion.weather(cube, normalization="symmetric")
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


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_weathering_is_independent_of_units(scale):
    rock = pverosion.examples.load_rock(subdivisions=3)
    points, faces = np.asarray(rock.points, dtype=float), rock.regular_faces
    size = np.ptp(points, axis=0).max()
    runs = {}
    for normalization in ("scale_free", "paper"):
        for s in (1.0, scale):
            solver = WeatheringSolver(points * s, faces, power=2.0, normalization=normalization)
            solver.run(20)
            runs[normalization, s] = solver
    reference, scaled = runs["scale_free", 1.0], runs["scale_free", scale]
    assert np.array_equal(reference.faces, scaled.faces)
    np.testing.assert_allclose(scaled.points / scale, reference.points, rtol=0, atol=1e-9 * size)
    eroded = reference.statistics["eroded_volume"][-1]
    assert eroded > 0.01 * reference.statistics["volume"][0]
    np.testing.assert_allclose(scaled.statistics["eroded_volume"][-1], eroded * scale**3, rtol=1e-9)
    if scale > 1.0:  # the paper's rule skips the normalisation where max |H| <= 1: the rock in thousands erodes less
        paper = runs["paper", scale].statistics["eroded_volume"][-1] / scale**3
        assert paper < 0.5 * runs["paper", 1.0].statistics["eroded_volume"][-1]


def capsule(*, radius: float = 1.0, length: float = 2.0, rings: int = 40, around: int = 48):
    """A cylinder capped by two hemispheres, mirror-symmetric about z = 0, and its rings' heights.

    Rings of ``around`` points at even arc-length steps along the profile,
    every other ring turned by half a step, fans at the poles (z = +-(length / 2
    + radius)); ``rings`` must be even so that a ring lies at z = 0.

    Returns
    -------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
    """
    total = np.pi * radius + length
    s = total * np.arange(1, rings) / rings
    quarter = 0.5 * np.pi * radius
    top, bottom = s < quarter, total - s < quarter
    phi = np.where(top, s, np.where(bottom, total - s, quarter)) / radius
    rho = radius * np.sin(phi)
    z = np.where(top, 0.5 * length + radius * np.cos(phi),
                 np.where(bottom, -0.5 * length - radius * np.cos(phi), 0.5 * length - (s - quarter)))
    k = np.arange(rings - 1)[:, None]
    angle = 2.0 * np.pi * (np.arange(around)[None, :] + 0.5 * (k % 2)) / around
    points = np.stack([rho[:, None] * np.cos(angle), rho[:, None] * np.sin(angle),
                       np.broadcast_to(z[:, None], angle.shape)], axis=-1).reshape(-1, 3)
    n = len(points)
    points = np.vstack([points, [[0.0, 0.0, 0.5 * length + radius], [0.0, 0.0, -0.5 * length - radius]]])
    i = np.arange(around)

    def at(ring, j):
        return ring * around + j % around

    faces = [np.stack([np.full(around, n), at(0, i), at(0, i + 1)], axis=1)]
    for r in range(rings - 2):
        if r % 2 == 0:  # ring r + 1 sits half a step ahead of ring r
            faces += [np.stack([at(r, i), at(r + 1, i), at(r, i + 1)], axis=1),
                      np.stack([at(r + 1, i), at(r + 1, i + 1), at(r, i + 1)], axis=1)]
        else:
            faces += [np.stack([at(r, i), at(r + 1, i), at(r + 1, i + 1)], axis=1),
                      np.stack([at(r, i), at(r + 1, i + 1), at(r, i + 1)], axis=1)]
    faces.append(np.stack([np.full(around, n + 1), at(rings - 2, i + 1), at(rings - 2, i)], axis=1))
    return points, np.vstack(faces)


def test_capsule_is_a_closed_outward_capsule():
    points, faces = capsule()
    assert edge_topology(faces, len(points)).n_boundary_edges == 0
    tri = points[faces]
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0
    assert volume == pytest.approx(2.0 * np.pi + 4.0 / 3.0 * np.pi, rel=0.01)  # cylinder + sphere, inscribed


def test_open_scan_erodes_like_the_closed_model():
    points, faces = capsule()
    # the open scan: the upper half, with a ragged rim of single-face flaps bent inward (as scans' rims are)
    centre = points[faces].mean(axis=1)
    on_rim = np.abs(points[faces][:, :, 2]) < 1e-12
    keep = centre[:, 2] > 0.0
    flaps = np.flatnonzero(~keep & (on_rim.sum(axis=1) == 2))[::2]
    keep[flaps] = True
    used = np.unique(faces[keep])
    open_points, open_faces = points[used].copy(), np.searchsorted(used, faces[keep])
    tips = np.searchsorted(used, faces[flaps][~on_rim[flaps]])
    open_points[tips, :2] *= 0.8
    moved = {}
    for normalization in ("scale_free", "paper"):
        closed = WeatheringSolver(points, faces, normalization=normalization)
        scan = WeatheringSolver(open_points, open_faces, normalization=normalization)
        h = scan.mean_curvature()
        assert np.abs(h).max() > 1.5 * np.abs(h[scan._interior]).max()  # the rim's curvature is the largest
        closed.run(10)
        scan.run(10)
        assert closed.collapses == scan.collapses == 0
        shared = open_points[scan.ids][:, 2] > 0.5  # the cap and the cylinder four rings or more from the rim
        mine = scan.displacement[shared]
        theirs = closed.displacement[used[scan.ids][shared]]
        moved[normalization] = np.linalg.norm(mine - theirs, axis=1) / np.linalg.norm(theirs, axis=1)
    assert moved["scale_free"].max() < 0.05
    assert moved["paper"].max() > 0.2  # the rim sets the paper's normalisation


def test_guard_query_after_a_collapse_holds_every_new_intersection():
    """After edge collapses the guard checks only the faces that are not faces of the restart point; a vertex
    then pushed through the far side is still found, exactly as by a check of the whole mesh, and a rollback
    leaves nothing to check."""
    from conftest import icosphere

    sphere = icosphere(1.0, 3)
    points, faces = np.asarray(sphere.points, dtype=np.float64), sphere.regular_faces.astype(np.int64)
    for a, b in faces[[0, 200, 400], :2]:  # three short edges for the improvement to collapse
        points[b] = points[a] + 0.02 * (points[b] - points[a])
    solver = WeatheringSolver(points, faces)
    assert not solver._moved_faces().any()
    solver._improve(0.05)
    assert solver.collapses == 3
    query = solver._moved_faces()
    assert 0 < query.sum() < len(solver.faces) // 4  # the collapsed fans only
    assert not intersecting_faces(solver.points, solver.faces, query=query).any()
    rebuilt = CollapseTopology.build(solver.faces, len(solver.points))
    assert np.array_equal(solver._edges, rebuilt.edges) and np.array_equal(solver._ring[1], rebuilt.ring[1])
    merged = solver.points[np.any(solver.points != points[solver.ids], axis=1)][0]
    far = int(np.argmin(solver.points @ merged))  # a vertex on the far side, pushed through
    solver.points = solver.points.copy()
    solver.points[far] *= -1.5
    hits = intersecting_faces(solver.points, solver.faces)
    assert hits.any()
    assert np.array_equal(intersecting_faces(solver.points, solver.faces, query=solver._moved_faces()), hits)
    assert not solver._accept()  # rolled back to the restart point
    assert len(solver.faces) == len(faces) and not solver._moved_faces().any()


def test_guard_queries_and_kept_connectivity_match_whole_rebuilds_over_a_run(bunny):
    """Over a run of the scan with edge collapses and rollbacks, every guard check of the queried faces finds
    exactly what a check of the whole mesh finds, and the connectivity carried through the collapses equals
    one rebuilt from the faces."""

    class Checked(WeatheringSolver):
        checks = 0

        def _intersections(self, query=None):
            hits = super()._intersections(query)
            if query is not None:
                assert np.array_equal(hits, intersecting_faces(self.points, self.faces))
                self.checks += 1
            rebuilt = CollapseTopology.build(self.faces, len(self.points))
            for mine, theirs in zip((self._edges, self._usable, self._fixed, *self._ring),
                                    (rebuilt.edges, rebuilt.usable, rebuilt.fixed, *rebuilt.ring)):
                assert np.array_equal(mine, theirs)
            return hits

    solver = Checked(bunny.points, bunny.regular_faces, min_edge_ratio=0.25)
    solver.run(60)
    assert solver.collapses > 0 and solver.retries > 0 and solver.checks >= 6


def test_guard_rolls_back_from_whole_checks_to_clean_restart_points_alike_on_any_thread_count(bunny):
    """On the scan's sharp crease every rollback comes from a check of the whole mesh (``check_every`` steps after
    the restart point), every restart point has no intersecting faces, and the run is the same with one thread
    and with all."""
    import numba

    class Recorded(WeatheringSolver):
        def _set_clean(self):
            assert not intersecting_faces(self.points, self.faces).any()
            super()._set_clean()

        def _roll_back(self, hits):
            self.rolled.append(self.step_count - self._clean.step)
            super()._roll_back(hits)

    before = numba.get_num_threads()
    runs = []
    try:
        for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(threads)
            solver = Recorded(bunny.points, bunny.regular_faces)
            solver.rolled = []
            solver.run(60)
            runs.append(solver)
    finally:
        numba.set_num_threads(before)
    solver = runs[0]
    assert solver.rolled and all(gap == solver.check_every for gap in solver.rolled)
    for other in runs[1:]:
        assert other.rolled == solver.rolled and np.array_equal(other.points, solver.points)


def test_guard_halves_a_place_once_then_slows_its_slowed_vertices_by_the_repeat_factor():
    """A first rollback halves the steps of the two-ring around the tangled faces; a second one around the same
    face multiplies the already slowed vertices by ``REPEAT_FACTOR`` (three halvings) and halves the ones it
    reaches for the first time; past ``max_halvings`` halvings a vertex is frozen."""
    from conftest import icosphere

    sphere = icosphere(1.0, 3)
    solver = WeatheringSolver(sphere.points, sphere.regular_faces, max_halvings=3)
    assert solver.REPEAT_FACTOR == 0.125
    first = np.zeros(len(solver.faces), bool)
    first[0] = True
    solver._roll_back(first)
    once = solver._scale.copy()
    assert set(np.unique(once)) == {0.5, 1.0} and solver.retries == 1
    assert np.all(once[solver.faces[0]] == 0.5)
    second = np.zeros(len(solver.faces), bool)
    second[np.flatnonzero((once[solver.faces] == 0.5).all(axis=1))[-1]] = True  # a face at the first ring's rim
    solver._roll_back(second)
    changed = solver._scale != once
    again = changed & (once == 0.5)
    assert again.any() and (changed & (once == 1.0)).any()
    # 0.5 / 8 is four halvings, more than max_halvings = 3: frozen; first reached: halved
    assert np.all(solver._scale[again] == 0.0) and np.all(solver._scale[changed & (once == 1.0)] == 0.5)
    assert solver.frozen == np.count_nonzero(again)

    class Halving(WeatheringSolver):
        REPEAT_FACTOR = 0.5  # as hydraulic erosion: every rollback halves

    plain = Halving(sphere.points, sphere.regular_faces, max_halvings=3)
    plain._roll_back(first)
    plain._roll_back(second)
    assert np.all(plain._scale[again] == 0.25)


def test_a_mesh_of_poor_locality_is_renumbered_and_weathers_as_in_its_own_order():
    from conftest import icosphere

    from pverosion.kernels.mesh.locality import poor_locality

    s = icosphere(1.0, 6)
    p = np.asarray(s.points, dtype=np.float64)
    p = p * (1.0 + 0.05 * np.sin(3 * p[:, :1]) * np.cos(2 * p[:, 1:2]))
    faces = s.regular_faces.astype(np.int64)
    perm = np.random.default_rng(4).permutation(len(p))  # shuffled vertex i is vertex perm[i]
    rank = np.empty_like(perm)
    rank[perm] = np.arange(len(perm))
    shuffled_points, shuffled_faces = p[perm], rank[faces]
    assert poor_locality(shuffled_faces, len(p))
    solvers = [WeatheringSolver(pts, fcs, min_edge_ratio=0.0, check_every=0)
               for pts, fcs in ((p, faces), (shuffled_points, shuffled_faces))]
    plain, local = solvers
    assert not poor_locality(local.faces, len(p)) and not np.array_equal(local.ids, np.arange(len(p)))
    assert np.array_equal(np.sort(local.ids), np.arange(len(p)))
    assert np.array_equal(local.points, shuffled_points[local.ids])
    assert np.allclose(local.initial_normals, plain.initial_normals[perm], rtol=0.0, atol=1e-12)
    for solver in solvers:
        solver.run(3)

    def by_input(solver, values):
        out = np.empty_like(values)
        out[solver.ids] = values
        return out

    assert np.allclose(by_input(local, local.points), by_input(plain, plain.points)[perm], rtol=0.0, atol=1e-12)
    assert np.allclose(by_input(local, local.displacement), by_input(plain, plain.displacement)[perm], rtol=0.0,
                       atol=1e-12)


def test_displacement_along_the_ring_equals_the_laplacian_vectors_bit_for_bit():
    """A step whose direction the displacement kernel sums from the one-ring moves every vertex exactly as one
    along :func:`laplacian_vectors`, on a scan with fixed rim vertices, concave and frozen places."""
    from pverosion.kernels.mesh.laplacian import laplacian_vectors
    from pverosion.kernels.weathering.displacement import displace

    rock = pverosion.examples.load_rock(subdivisions=3, seed=5)
    solver = WeatheringSolver(rock.points, rock.regular_faces)
    points = solver.points
    h = solver.mean_curvature()
    h_norm = h / np.abs(h).max()
    factor = np.where(np.arange(len(points)) % 5 == 0, 0.0, 1.0)  # some frozen vertices
    fixed = np.zeros(len(points), bool)
    fixed[::11] = True
    e_avg = 0.01
    runs = []
    for direction, ring in ((laplacian_vectors(points, solver.faces, ring=solver._ring), None),
                            (None, solver._ring)):
        displacement = np.zeros_like(points)
        moved = displace(points, direction, True, h_norm, h, e_avg, 2.0, e_avg / 10, factor, fixed, displacement,
                         ring=ring)
        runs.append((moved, displacement))
    (by_vectors, d_vectors), (by_ring, d_ring) = runs
    assert np.array_equal(by_ring, by_vectors) and np.array_equal(d_ring, d_vectors)
    changed = np.any(by_ring != points, axis=1)
    assert changed.any() and not changed[fixed].any() and not changed[factor == 0.0].any()
    assert not changed[h <= 0].any()


def test_the_mean_edge_length_of_a_step_is_measured_again_after_the_mesh_changes():
    """The improvement's pass over the edges measures the mean edge length the next step uses; it equals a
    measure of the current mesh (over its edges in the solver's order, as a step sums them) after steps,
    collapses and rollbacks alike."""
    from conftest import icosphere

    from pverosion.kernels.mesh.geometry import average_edge_length

    sphere = icosphere(1.0, 3)
    points, faces = np.asarray(sphere.points, dtype=np.float64), sphere.regular_faces.astype(np.int64)
    for a, b in faces[[0, 200, 400], :2]:  # three short edges for the improvement to collapse
        points[b] = points[a] + 0.02 * (points[b] - points[a])
    solver = WeatheringSolver(points, faces, min_edge_ratio=0.3, check_every=2)
    for _ in range(6):
        solver.run(1)
        assert solver._mean_edge_length() == average_edge_length(solver.points, None, edges=solver._edges)
    assert solver.collapses == 3
    solver._step()  # unchecked
    solver._roll_back(np.arange(len(solver.faces)) == 0)  # back to the restart point of step 6
    assert solver.step_count == 6
    assert solver._mean_edge_length() == average_edge_length(solver.points, None, edges=solver._edges)
    solver.points = solver.points * 2.0  # a mesh handed in from outside: measured anew
    assert solver._mean_edge_length() == average_edge_length(solver.points, None, edges=solver._edges)


def test_a_rollback_slows_down_exactly_the_two_ring_of_the_tangled_faces():
    from conftest import icosphere

    sphere = icosphere(1.0, 3)
    solver = WeatheringSolver(sphere.points, sphere.regular_faces)
    hits = np.zeros(len(solver.faces), bool)
    hits[[3, 500]] = True
    topo = edge_topology(solver.faces, len(solver.points))
    near = np.zeros(len(solver.points), bool)
    near[solver.faces[hits].ravel()] = True
    for _ in range(2):  # two rings by the edges, from the vertices of the tangled faces
        a, b = topo.edges.T
        grown = near.copy()
        grown[a[near[b]]] = True
        grown[b[near[a]]] = True
        near = grown
    solver._roll_back(hits)
    assert np.array_equal(solver._scale[solver.ids] == 0.5, near) and np.all(solver._scale[~near] == 1.0)


def test_filled_holes_weather_alike_wherever_the_model_sits(bunny):
    """Hole filling puts vertices at the centroid of their ring: their Laplacian is within rounding of zero, no
    direction. Moved 1000 or 100,000 units away, the model weathers as at the origin, to the rounding of the
    coordinates there (stepping along the rounding noise put the two results 1.5e-4 apart after one step on this
    0.16-unit model; a membrane relaxed by 100 iterations instead of solved left Laplacians above the rounding at
    the origin, and the results 1.5e-6 and 4e-4 of the size apart)."""
    import warnings

    from pverosion.meshing import fill_holes

    coarse = bunny.decimate_pro(0.93, preserve_topology=True).clean().triangulate()
    points, faces = fill_holes(np.asarray(coarse.points, float), coarse.regular_faces)
    faces = faces[:, ::-1]  # inward, as scans come too
    moved = []
    for shift in (0.0, 1e3, 1e5):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # the decimated scan already self-intersects
            out = pverosion.weather(pv.PolyData.from_regular_faces(points + shift, faces), iterations=1,
                                    min_edge_ratio=0)
        moved.append(np.asarray(out.points) - shift)
    size = float(np.ptp(points, axis=0).max())
    step = np.linalg.norm(moved[0] - points, axis=1).max()
    assert step > 1e-4 * size  # the step did move the surface
    for far in moved[1:]:
        assert np.abs(far - moved[0]).max() <= 1e-8 * size  # rounding of the coordinates 1e5 units out: 1e-10


def test_vertex_and_line_cells_follow_the_collapsed_vertices():
    """Vertex and line cells of the input name the same input points after edges were collapsed."""
    sphere = pv.Sphere(theta_resolution=24, phi_resolution=24).triangulate().clean()
    n = sphere.n_points
    lines = np.array([2, n - 2, n - 1, 3, 0, 1, 2, 2, 5, 9])
    verts = np.array([1, n - 1, 1, 0, 1, 7])
    mesh = pv.PolyData(sphere.points, faces=sphere.faces, lines=lines, verts=verts)
    mesh.point_data["input_id"] = np.arange(n)
    out = pverosion.weather(mesh, iterations=10, min_edge_ratio=0.9)
    assert out.n_points < n / 2  # most vertices were collapsed
    source = out.point_data["input_id"]
    for kind, given in (("lines", lines), ("verts", verts)):
        cells, kept = getattr(out, kind), []
        k = 0
        while k < len(cells):
            ids = cells[k + 1:k + 1 + cells[k]]
            assert ids.max() < out.n_points
            kept.append(tuple(source[ids]))
            k += cells[k] + 1
        original, k = [], 0
        while k < len(given):
            original.append(tuple(given[k + 1:k + 1 + given[k]]))
            k += given[k] + 1
        assert set(kept) == {c for c in original if set(c) <= set(source.tolist())}
