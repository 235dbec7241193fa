"""Particle fluid: rest density, settling, mesh collision without tunnelling, sliding, emitters, drains, contacts,
reproducibility and bad input."""

import math

import numba
import numpy as np
import pytest
import pyvista as pv

from pverosion.kernels.fluid.collision import _drift_buckets
from pverosion.kernels.fluid.grids import _mesh_grid
from pverosion.kernels.fluid.particle_fluid import Drain, Emitter, FluidParameters, ParticleFluid

R = 0.05
D = 2.0 * R
H = 4.0 * R


def _block(nx, ny, nz, corner=(0.0, 0.0, 0.0), spacing=D):
    """Cubic lattice of nx * ny * nz particle centres, the lowest one r in from ``corner``."""
    idx = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    return np.asarray(corner) + R + idx * spacing


def _box_mesh(lo, hi, *, inward):
    box = pv.Box(bounds=(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]), level=1).triangulate()
    faces = box.regular_faces
    return np.asarray(box.points, dtype=np.float64), faces[:, ::-1] if inward else faces


def _pool_figures(fluid, lo, hi):
    """Mean density of interior particles and N (2r)³ / (floor area * pool height); height = 2 * mean height."""
    x = fluid.positions
    z = x[:, 2] - lo[2]
    height = 2.0 * z.mean()
    interior = (z > H) & (z < height - H) & np.all((x[:, :2] > lo[:2] + H) & (x[:, :2] < hi[:2] - H), axis=1)
    assert interior.sum() > 50
    area = (hi[0] - lo[0]) * (hi[1] - lo[1])
    return fluid.density()[interior].mean(), len(x) * D**3 / (area * height)


def test_rest_density_is_the_lattice_sum():
    fluid = ParticleFluid(FluidParameters(radius=R), domain=((0, 0, 0), (3, 3, 3)))
    fluid.add_particles(_block(12, 12, 12))
    centre = np.all(np.abs(fluid.positions - fluid.positions.mean(axis=0)) < 2 * D, axis=1)
    assert np.allclose(fluid.density()[centre], 1.0, rtol=1e-12, atol=0.0)
    assert FluidParameters(radius=2.0).rest_density == pytest.approx(FluidParameters(radius=1.0).rest_density / 8)


@pytest.mark.parametrize("container", ["walls", "mesh"])
def test_dam_break_stays_in_the_box_and_settles_at_rest_density(container):
    lo, hi = np.zeros(3), np.array([16 * D, 8 * D, 24 * D])
    params = FluidParameters(radius=R)
    if container == "walls":
        fluid = ParticleFluid(params, domain=(lo, hi), walls=True)
    else:
        fluid = ParticleFluid(params, domain=(lo - 1.0, hi + 1.0))
        fluid.set_mesh(*_box_mesh(lo, hi, inward=True))
    fluid.add_particles(_block(8, 8, 16))
    n = len(fluid.positions)
    for _ in range(int(8.0 / fluid.dt)):
        fluid.step()
        assert len(fluid.positions) == n and fluid.drained == 0
        assert np.all(fluid.positions >= lo + 0.99 * R) and np.all(fluid.positions <= hi - 0.99 * R)
    interior_density, bulk = _pool_figures(fluid, lo, hi)
    assert interior_density == pytest.approx(1.0, abs=0.05)
    assert bulk == pytest.approx(1.0, abs=0.05)
    speed = np.linalg.norm(fluid.velocities, axis=1)
    assert speed.max() < 0.2 * math.sqrt(9.81 * 8 * D)


def test_still_pool_comes_to_rest():
    lo, hi = np.zeros(3), np.array([12 * D, 6 * D, 20 * D])
    fluid = ParticleFluid(FluidParameters(radius=R), domain=(lo, hi), walls=True)
    fluid.add_particles(_block(12, 6, 10))
    depth = 10 * D
    for _ in range(50):
        fluid.step()
    early = np.linalg.norm(fluid.velocities, axis=1).max()
    for _ in range(550):
        fluid.step()
    speed = np.linalg.norm(fluid.velocities, axis=1)
    assert speed.max() < 0.02 * math.sqrt(9.81 * depth) and speed.max() < 0.2 * early
    z = fluid.positions[:, 2]
    assert z.min() == pytest.approx(R, abs=0.05 * R)  # resting on the floor, not squeezed into it
    assert 2 * z.mean() == pytest.approx(depth, rel=0.05)


@pytest.mark.parametrize("tensile", [0.0, 0.1])
def test_tensile_term_pushes_close_particles_apart_and_conserves_momentum(tensile):
    params = FluidParameters(radius=R, gravity=(0.0, 0.0, 0.0), time_step=0.01, tensile=tensile)
    fluid = ParticleFluid(params, domain=((-1, -1, -1), (1, 1, 1)))
    fluid.add_particles([[0.0, 0.0, 0.0], [R, 0.0, 0.0]])  # closer than rest spacing, yet far below rest density
    fluid.step()
    gap = fluid.positions[1, 0] - fluid.positions[0, 0]
    assert np.allclose(fluid.velocities.sum(axis=0), 0.0, atol=1e-12)
    if tensile:
        assert gap > 1.01 * R and fluid.velocities[1, 0] > 0.0
    else:
        assert gap == R and np.all(fluid.velocities == 0.0)


def _thin_plate(r):
    """A closed plate half a particle radius thick, across the x axis."""
    return pv.Box(bounds=(-0.25 * r, 0.25 * r, -0.4, 0.4, -0.4, 0.4), level=2).triangulate()


@pytest.mark.parametrize("shape", ["sphere", "thin plate"])
def test_fast_stream_never_enters_a_closed_object(shape):
    r = 0.02
    solid = pv.Icosphere(radius=0.3, nsub=3) if shape == "sphere" else _thin_plate(r)
    params = FluidParameters(radius=r)
    speed = 25.0
    assert speed * params.dt / params.substeps > 10 * r  # many radii per substep
    emitter = Emitter((-0.8, 0.0, 0.05), (1.0, 0.0, 0.0), 0.12, rate=4000.0, speed=speed)
    fluid = ParticleFluid(params, domain=((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)), emitters=[emitter], seed=3)
    fluid.set_mesh(np.asarray(solid.points, dtype=np.float64), solid.regular_faces)
    hits = 0
    for _ in range(25):
        fluid.step()
        inside = pv.PolyData(fluid.positions).select_interior_points(solid)["selected_points"]
        assert not np.any(inside)
        hits += np.count_nonzero(fluid.contact_face >= 0)
    assert fluid.emitted > 500 and hits > 500  # the stream did hit the object


def _incline(angle_deg):
    """A large plane through the origin tilted about y; its front (upper) side faces +z mostly."""
    t = math.radians(angle_deg)
    down = np.array([math.cos(t), 0.0, -math.sin(t)])  # downhill direction
    across = np.array([0.0, 1.0, 0.0])
    corners = np.array([-down - across, down - across, down + across, -down + across]) * 2.0
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    return corners, faces, normal / np.linalg.norm(normal), down


@pytest.mark.parametrize("friction", [0.0, 1.0])
def test_particle_slides_down_an_incline(friction):
    corners, faces, normal, down = _incline(30.0)
    assert normal[2] > 0
    fluid = ParticleFluid(FluidParameters(radius=R, friction=friction), domain=((-3, -3, -3), (3, 3, 3)))
    fluid.set_mesh(corners, faces)
    fluid.add_particles([3 * R * normal])
    for _ in range(10):  # land
        fluid.step()
    landed = fluid.positions[0].copy()
    for _ in range(20):
        fluid.step()
        assert fluid.contact_face[0] in (0, 1)
        assert fluid.contact_distance[0] == pytest.approx(R, rel=0.02)
        assert np.dot(fluid.positions[0], normal) == pytest.approx(R, rel=0.02)
    travel = np.dot(fluid.positions[0] - landed, down)
    t = 20 * fluid.dt
    if friction == 0.0:
        assert travel > 0.5 * (0.5 * 9.81 * math.sin(math.radians(30.0)) * t * t)
    else:
        assert abs(travel) < 0.01 * R


def test_contacts_on_a_floor_and_in_free_fall():
    floor = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    fluid = ParticleFluid(FluidParameters(radius=R), domain=((-1, -1, -1), (1, 1, 3)))
    fluid.set_mesh(floor, [[0, 1, 2], [0, 2, 3]])
    fluid.add_particles(_block(6, 6, 3, corner=(-0.3, -0.3, 0.0)))
    for _ in range(40):
        fluid.step()
    fluid.add_particles([[0.7, 0.7, 2.5]])  # falling, far from everything
    for _ in range(3):
        fluid.step()
    bottom = fluid.positions[:, 2] < 2 * R
    assert bottom.sum() >= 36
    assert np.all(fluid.contact_face[bottom] >= 0)
    assert np.allclose(fluid.contact_distance[bottom], R, rtol=0.02)
    falling = fluid.positions[:, 2] > 1.0
    assert falling.sum() == 1 and fluid.velocities[falling, 2] < -0.5
    assert fluid.contact_face[falling] == -1 and np.isinf(fluid.contact_distance[falling])


def test_mesh_moved_over_a_particle_pushes_it_back_to_the_front():
    floor = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    faces = [[0, 1, 2], [0, 2, 3]]
    fluid = ParticleFluid(FluidParameters(radius=R), domain=((-1, -1, -1), (1, 1, 1)))
    fluid.set_mesh(floor, faces)
    fluid.add_particles([[0.1, 0.1, R]])
    fluid.step()
    fluid.set_mesh(floor + [0.0, 0.0, 1.5 * R], faces)  # the floor rose past the particle's centre
    fluid.step()
    assert fluid.positions[0, 2] == pytest.approx(2.5 * R, rel=0.02)
    assert np.abs(fluid.velocities[0]).max() < 1e-6  # moved, not launched


def test_wall_closing_in_from_afar_pushes_resting_particles_ahead_of_it():
    # a floor and, far to the side, a wall facing the particles; only the wall's points move (same faces), from
    # beyond every search's reach to past the particles: each move must reach the searches carried over
    floor = [[-2.0, -1.0, 0.0], [2.0, -1.0, 0.0], [2.0, 1.0, 0.0], [-2.0, 1.0, 0.0]]
    wall = [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 1.0], [0.0, -1.0, 1.0]]
    points = np.array(floor + wall)
    faces = [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]]  # the wall faces -x
    fluid = ParticleFluid(FluidParameters(radius=R), domain=((-2, -1, -1), (2, 1, 1)))
    fluid.add_particles(_block(1, 3, 1, corner=(-R, -3 * R, 0.0)))  # centres at x = 0
    wall_only = np.repeat([[0.0], [1.0]], 4, axis=0) * [1.0, 0.0, 0.0]
    start = 10 * R
    fluid.set_mesh(points + start * wall_only, faces)
    for _ in range(10):
        fluid.step()
    for x in np.arange(start, -4 * R, -0.3 * R):
        fluid.set_mesh(points + x * wall_only, faces)
        fluid.step()
        assert fluid.positions[:, 0].max() <= x - R * (1.0 - 1e-6)  # never behind the wall
    assert fluid.positions[:, 2].min() == pytest.approx(R, rel=0.02)  # still on the floor


def test_emitter_rate_speed_and_direction_without_speed():
    params = FluidParameters(radius=0.02, gravity=(0.0, 0.0, 0.0), time_step=0.01)
    direction = np.array([1.0, 2.0, 2.0]) / 3.0
    emitter = Emitter((0.0, 0.0, 0.0), tuple(direction), 0.1, rate=500.0)
    fluid = ParticleFluid(params, domain=((-1, -1, -1), (3, 3, 3)), emitters=[emitter])
    for _ in range(100):
        fluid.step()
    points = len(emitter.lattice(params.spacing))
    assert abs(fluid.emitted - 500.0) <= points  # one layer at most
    speed = params.spacing * 500.0 / points
    # pair corrections and XSPH conserve momentum: the stream as a whole keeps the emitted velocity
    assert np.allclose(fluid.velocities.mean(axis=0), speed * direction, rtol=1e-9, atol=1e-12)
    assert np.all(fluid.velocities @ direction > 0.8 * speed)
    assert np.all(np.diff(fluid.ids) > 0) and fluid.ids[0] == 0


def test_emitter_rate_with_speed_and_its_limit():
    params = FluidParameters(radius=0.02, gravity=(0.0, 0.0, 0.0), time_step=0.01)
    emitter = Emitter((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.1, rate=300.0, speed=3.0)
    fluid = ParticleFluid(params, domain=((-1, -1, -1), (1, 1, 10)), emitters=[emitter], seed=5)
    for _ in range(200):
        fluid.step()
    assert fluid.emitted == pytest.approx(600, rel=0.1)
    assert np.allclose(fluid.velocities.mean(axis=0), [0.0, 0.0, 3.0], rtol=1e-9, atol=1e-12)
    d = fluid.positions[:, None, :] - fluid.positions[None, :, :]
    gaps = np.linalg.norm(d, axis=2) + np.eye(len(d)) * 1.0
    assert gaps.min() > 0.99 * params.spacing  # no overlaps
    points = len(emitter.lattice(params.spacing))
    with pytest.raises(ValueError, match=f"at most {points * 3.0 / params.spacing:g} particles/s"):
        ParticleFluid(params, domain=((-1, -1, -1), (1, 1, 1)),
                      emitters=[Emitter((0, 0, 0), (0, 0, 1), 0.1, rate=1e5, speed=3.0)])


def _sediment_by_id(fluid):
    fluid.sediment = 0.5 * fluid.ids.astype(np.float64)  # exact in binary


def test_plane_box_and_domain_drains_count_particles_and_sediment_exactly():
    params = FluidParameters(radius=0.02, gravity=(0.0, 0.0, 0.0), time_step=0.01)
    drains = [Drain.parse("plane:0,0,1,0.5"), Drain.parse("box:0.2,-1,-1,0.4,0,1")]
    fluid = ParticleFluid(params, domain=((-1, -1, -1), (1, 1, 1)), drains=drains)
    rng = np.random.default_rng(0)
    start = rng.uniform(-0.3, 0.3, (200, 3))
    fluid.add_particles(start, rng.normal(0.0, 2.0, (200, 3)))
    _sediment_by_id(fluid)
    for _ in range(40):
        before, drained, carried = set(fluid.ids.tolist()), fluid.drained, fluid.drained_sediment
        fluid.step()
        gone = before - set(fluid.ids.tolist())
        assert set(fluid.ids.tolist()) <= before
        assert fluid.drained - drained == len(gone)
        assert fluid.drained_sediment - carried == 0.5 * sum(gone)
        x = fluid.positions
        assert np.all(x[:, 2] <= 0.5) and np.all(np.abs(x) <= 1.0)
        assert not np.any(np.all((x >= [0.2, -1, -1]) & (x <= [0.4, 0, 1]), axis=1))
    assert fluid.drained == 200 - len(fluid.positions) and fluid.drained > 100
    expected = 0.5 * (sum(range(200)) - int(fluid.ids.sum()))
    assert fluid.drained_sediment == expected
    assert len(np.unique(fluid.ids)) == len(fluid.ids)


def _run(seed, steps, *, fluid=None):
    points, faces = _box_mesh(np.zeros(3), np.array([1.0, 0.6, 1.0]), inward=True)
    if fluid is None:
        params = FluidParameters(radius=0.03)
        emitter = Emitter((0.2, 0.3, 0.8), (1.0, 0.0, -0.5), 0.08, rate=150.0, speed=2.5)
        fluid = ParticleFluid(params, domain=((-0.1, -0.1, -0.1), (1.1, 0.7, 1.1)), emitters=[emitter], seed=seed)
        fluid.set_mesh(points, faces)
        fluid.add_particles(_block(6, 4, 4, corner=(0.5, 0.1, 0.0), spacing=0.06) * 0.6)
    for _ in range(steps):
        fluid.step()
    return fluid


def _same(a, b):
    for name in ("positions", "velocities", "ids", "sediment", "contact_face", "contact_distance"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert (a.emitted, a.drained, a.steps) == (b.emitted, b.drained, b.steps)


def test_same_seed_same_state_bit_for_bit_for_any_thread_count():
    first = _run(7, 30)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        second = _run(7, 30)
    finally:
        numba.set_num_threads(threads)
    _same(first, second)
    other = _run(8, 30)
    assert other.emitted != first.emitted or not np.array_equal(other.positions, first.positions)


def test_restore_reruns_bit_for_bit():
    fluid = _run(11, 10)
    fluid.sediment[:] = 1.0
    snapshot = fluid.state()
    reference = _run(0, 15, fluid=fluid)
    expected = {name: getattr(reference, name).copy() for name in ("positions", "velocities", "ids", "sediment")}
    fluid.restore(snapshot)
    assert fluid.steps == 10 and np.all(fluid.sediment == 1.0)
    _run(0, 15, fluid=fluid)
    for name, value in expected.items():
        assert np.array_equal(getattr(fluid, name), value), name


def test_set_mesh_refits_and_rebuilds_and_clears():
    points, faces = _box_mesh(np.zeros(3), np.ones(3), inward=True)
    fluid = ParticleFluid(FluidParameters(radius=R), domain=((-1, -1, -1), (2, 2, 2)))
    fluid.add_particles(_block(3, 3, 3, corner=(0.3, 0.3, 0.0)))
    fluid.set_mesh(points, faces)
    for rise in range(4):  # the floor rises by 0.8 r at a time: refits, then a rebuild past the grid's margin
        shift = 0.8 * R * rise
        fluid.set_mesh(points + [0.0, 0.0, shift], faces)
        for _ in range(15):
            fluid.step()
        assert fluid.positions[:, 2].min() == pytest.approx(shift + R, rel=0.02)
    walls = faces[~np.all(points[faces][:, :, 2] == 1.0, axis=1)]  # fewer faces (no roof): rebuilt
    fluid.set_mesh(points, walls)
    for _ in range(15):
        fluid.step()
    assert fluid.positions[:, 2].min() == pytest.approx(R, rel=0.02)
    assert np.all(fluid.contact_face < len(walls))
    fluid.set_mesh(None, None)
    for _ in range(5):
        fluid.step()
    assert np.all(fluid.contact_face == -1) and fluid.positions[:, 2].max() < 0.0


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="radius"):
        FluidParameters(radius=-1.0)
    with pytest.raises(ValueError, match="friction"):
        FluidParameters(radius=1.0, friction=1.5)
    with pytest.raises(ValueError, match="substeps"):
        FluidParameters(radius=1.0, substeps=0)
    with pytest.raises(ValueError, match="time_step is required"):
        FluidParameters(radius=1.0, gravity=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="gravity"):
        FluidParameters(radius=1.0, gravity=(0.0, math.nan, 0.0))
    with pytest.raises(ValueError, match="domain"):
        ParticleFluid(FluidParameters(radius=R), domain=((0, 0, 0), (1, 0, 1)))
    fluid = ParticleFluid(FluidParameters(radius=R), domain=((0, 0, 0), (1, 1, 1)))
    with pytest.raises(ValueError, match="NaN"):
        fluid.add_particles([[0.5, math.nan, 0.5]])
    with pytest.raises(ValueError, match=r"shape \(M, 3\)"):
        fluid.add_particles([0.5, 0.5, 0.5])
    with pytest.raises(ValueError, match="velocities must have the shape"):
        fluid.add_particles([[0.5, 0.5, 0.5]], [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="max_particles"):
        ParticleFluid(FluidParameters(radius=R, max_particles=2), domain=((0, 0, 0), (1, 1, 1))).add_particles(
            np.full((3, 3), 0.5))
    with pytest.raises(ValueError, match="triangulate"):
        fluid.set_mesh(np.zeros((4, 3)), [[0, 1, 2, 3]])
    with pytest.raises(ValueError, match="indices"):
        fluid.set_mesh(np.zeros((3, 3)), [[0, 1, 5]])
    with pytest.raises(ValueError, match="drain kind"):
        Drain("sphere", (0, 0, 0, 1))
    with pytest.raises(ValueError, match="drain kind"):
        Drain.parse("disc:0,0,1,0")
    with pytest.raises(ValueError, match="4 finite numbers"):
        Drain.parse("plane:0,0,1")
    with pytest.raises(ValueError, match="comma-separated"):
        Drain.parse("box:a,b,c,d,e,f")
    with pytest.raises(ValueError, match="min <= max"):
        Drain.parse("box:1,0,0,0,1,1")
    with pytest.raises(ValueError, match="8 or 9 numbers"):
        Emitter.parse("0,0,0,0,0,1,0.1")
    with pytest.raises(ValueError, match="direction"):
        Emitter.parse("0,0,0,0,0,0,0.1,10")
    with pytest.raises(ValueError, match="rate"):
        Emitter((0, 0, 0), (0, 0, 1), 0.1, rate=-1.0)
    assert Emitter.parse("1,2,3,0,0,2,0.5,10,4") == Emitter((1, 2, 3), (0, 0, 1), 0.5, 10.0, 4.0)
    fluid.add_particles([[0.5, 0.5, 0.5]])
    fluid.sediment = np.zeros(2)
    with pytest.raises(ValueError, match="sediment must be an array of shape"):
        fluid.step()


def test_density_matches_a_kd_tree_sum_for_clustered_and_scattered_points():
    """The neighbour lists behind density() find exactly the pairs closer than h: a dense cluster (more
    neighbours than the first list capacity) and points scattered far apart (cells sharing hash buckets)."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(7)
    params = FluidParameters(radius=R)
    h = params.kernel_radius
    cluster = rng.uniform(0.0, 3.0 * h, size=(1500, 3))
    scattered = rng.uniform(-200.0 * h, 200.0 * h, size=(3000, 3))
    near_scattered = scattered[:500] + rng.normal(scale=0.5 * h, size=(500, 3))
    points = np.concatenate((cluster, scattered, near_scattered))
    fluid = ParticleFluid(params, domain=(points.min(axis=0) - 1.0, points.max(axis=0) + 1.0))
    fluid.add_particles(points)
    k6 = 315.0 / (64.0 * math.pi * h**9)
    expected = np.full(len(points), k6 * h**6)
    for i, j in cKDTree(points).query_pairs(h, output_type="ndarray"):
        r2 = float(np.sum((points[i] - points[j]) ** 2))
        if r2 < h * h:
            w = k6 * (h * h - r2) ** 3
            expected[i] += w
            expected[j] += w
    assert max(len(n) for n in cKDTree(points).query_ball_point(cluster, h)) > 65  # beyond the first capacity
    np.testing.assert_allclose(fluid.density(), expected / params.rest_density, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("share", [0.02, 1.0])  # few faces moved: per-face writes; all of them: dense dilation
def test_drift_buckets_cover_every_cell_near_a_moved_face(share):
    sphere = pv.Icosphere(radius=1.0, nsub=3)
    points = np.asarray(sphere.points, dtype=np.float64)
    faces = np.asarray(sphere.regular_faces, dtype=np.int64)
    grid = _mesh_grid(points, faces, 0.05)[0]
    data, lo, size, dims, start = grid[:5]
    rng = np.random.default_rng(1)
    move = np.where(rng.random(len(faces)) < share, rng.uniform(0.01, 0.1, len(faces)), 0.0)
    box = 0.17
    drift = _drift_buckets(grid, move, box)
    mask = len(start) - 2
    corners = data[:, :9].reshape(-1, 3, 3)

    def exact(grow: float) -> np.ndarray:
        """Largest move of a face whose box grown by ``grow`` meets a cell of each bucket."""
        out = np.zeros(mask + 1)
        for f in np.flatnonzero(move):
            c0 = np.clip(np.floor((corners[f].min(axis=0) - grow - lo) / size).astype(int), 0, dims - 1)
            c1 = np.clip(np.floor((corners[f].max(axis=0) + grow - lo) / size).astype(int), 0, dims - 1)
            i, j, k = np.meshgrid(*[np.arange(a, b + 1) for a, b in zip(c0, c1)], indexing="ij")
            np.maximum.at(out, (i + dims[0] * (j + dims[1] * k)).ravel() & mask, move[f])
        return out

    within = exact(box)
    assert np.count_nonzero(within) > 10
    assert np.all(drift >= within)
    assert np.all(drift <= exact(box + size))  # at most one cell of rounding
