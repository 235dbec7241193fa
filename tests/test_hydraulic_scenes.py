"""Hydraulic erosion scenes: closed, manifold, outward, self-intersection free meshes with sensible set-ups."""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv
from conftest import DATA
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from skimage.morphology import reconstruction

from pverosion.examples import load_cube, load_rock
from pverosion.kernels.exact.intersection import intersecting_faces
from pverosion.kernels.fluid.particle_fluid import Drain, Emitter, FluidParameters, ParticleFluid
from pverosion.kernels.hydraulic.overhangs import overhanging_vertices
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.mesh.orientation import winding_number
from pverosion.scenes.hydraulic import (
    HELENS_WINDOW,
    SCENES,
    HydraulicScene,
    canyon_scene,
    fill_holes,
    lake_scene,
    pour_scene,
    river_scene,
)

DEM = DATA / "SainteHelens.dem"


def assert_closed_solid(points: np.ndarray, faces: np.ndarray) -> None:
    """Closed, consistently oriented 2-manifold (edges and vertices), outward, clean, no self-intersections."""
    n = len(points)
    assert faces.shape[1] == 3 and len(np.unique(faces)) == n
    start, end = faces.ravel(), faces[:, [1, 2, 0]].ravel()
    key, reverse = start * n + end, end * n + start
    assert len(np.unique(key)) == len(key), "an edge is used twice in the same direction"
    order = np.argsort(key)
    at = np.searchsorted(key[order], reverse)
    assert (at < len(key)).all() and (key[order][np.minimum(at, len(key) - 1)] == reverse).all(), "open edge"
    # one fan of faces round every vertex: join the corners at a vertex across its edges
    twin = order[at]
    corner_across = 3 * (twin // 3) + (twin % 3 + 1) % 3
    graph = coo_matrix((np.ones(len(key)), (np.arange(len(key)), corner_across)), shape=(len(key),) * 2)
    assert connected_components(graph, directed=False)[0] == n, "a vertex with more than one fan"
    tri = points[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.min() > 1e-6 * area.mean()
    assert signed_volume(points, faces) > 0.0
    assert not intersecting_faces(points, faces).any()


def min_angles(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Smallest angle (degrees) of every triangle."""
    tri = points[faces]
    edge = np.linalg.norm(tri[:, [1, 2, 0]] - tri[:, [2, 0, 1]], axis=2)  # edge k opposite corner k
    a, b, c = edge.T
    cos = np.stack([(b * b + c * c - a * a) / (2 * b * c), (a * a + c * c - b * b) / (2 * a * c),
                    (a * a + b * b - c * c) / (2 * a * b)], axis=1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).min(axis=1)


def check_scene(scene: HydraulicScene) -> None:
    mesh = scene.mesh
    assert isinstance(mesh, pv.PolyData) and mesh.is_all_triangles
    points, faces = np.asarray(mesh.points, dtype=float), mesh.regular_faces.astype(np.int64)
    assert_closed_solid(points, faces)
    assert scene.radius > 0.0 and scene.iterations > 0
    lo, hi = (np.array(c) for c in scene.domain)
    assert (lo < hi).all()
    assert scene.emitters
    for emitter in scene.emitters:
        values = np.array(emitter.split(","), dtype=float)
        assert len(values) == 9 and np.isfinite(values).all()
        position, direction, (disc, rate, speed) = values[:3], values[3:6], values[6:]
        assert disc > scene.radius and rate > 0.0 and speed > 0.0
        assert direction[2] < 0.0
        assert (position > lo).all() and (position < hi).all()
        assert abs(winding_number(position, points, faces)) < 1e-6  # outside
        below, _ = mesh.ray_trace(position, position - [0.0, 0.0, 1e3 * (hi[2] - lo[2])])
        above, _ = mesh.ray_trace(position, position + [0.0, 0.0, 1e3 * (hi[2] - lo[2])])
        assert len(below) > 0 and len(above) == 0  # above the surface
    for drain in scene.drains:
        kind, values = drain.split(":")
        numbers = np.array(values.split(","), dtype=float)
        assert kind in ("plane", "box") and np.isfinite(numbers).all()
        if kind == "plane":
            assert len(numbers) == 4 and np.linalg.norm(numbers[:3]) > 0.0
        else:
            assert len(numbers) == 6 and (numbers[:3] < numbers[3:]).all()


def test_scene_registry():
    assert set(SCENES) == {"canyon", "river", "lake", "pour"}


def test_canyon_face_count_vertical_walls_and_clean_triangles():
    scene = canyon_scene()
    check_scene(scene)
    points, faces = np.asarray(scene.mesh.points), scene.mesh.regular_faces
    assert abs(len(faces) - 34_000) < 0.15 * 34_000
    assert min_angles(points, faces).min() > 20.0
    # nothing above the base overhangs: the walls are exactly vertical
    assert not overhanging_vertices(points, faces, mask=points[:, 2] > 0.0).any()
    normals = scene.mesh.face_normals
    walls = np.abs(normals[:, 2]) < 1e-12
    inner = walls & (np.abs(points[faces][:, :, 1]).max(axis=1) < 0.34) & (points[faces][:, :, 0].max(axis=1) < 1.99)
    assert inner.sum() > 0.1 * len(faces)  # canyon walls, away from the block's sides
    # the channel is narrower than deep and its floor falls towards the outlet
    z = points[:, 2]
    floor = (z > 0.0) & (z < 0.25) & (np.abs(points[:, 1]) < 0.34)
    assert np.polyfit(points[floor, 0], z[floor], 1)[0] < 0.0


def test_canyon_size_seed_and_bad_input():
    small = canyon_scene(n_faces=5000, seed=3)
    check_scene(small)
    assert abs(small.mesh.n_cells - 5000) < 750
    again = canyon_scene(n_faces=5000, seed=3)
    np.testing.assert_array_equal(small.mesh.points, again.mesh.points)
    np.testing.assert_array_equal(small.mesh.regular_faces, again.mesh.regular_faces)
    assert small.emitters == again.emitters
    other = canyon_scene(n_faces=5000, seed=4)
    assert other.mesh.n_points != small.mesh.n_points or not np.array_equal(other.mesh.points, small.mesh.points)
    with pytest.raises(ValueError, match="n_faces"):
        canyon_scene(n_faces=100)


def river_outlet_is_lower(scene: HydraulicScene) -> None:
    """The head (under the emitter) lies higher than the outlet (in the drain box)."""
    head = np.array(scene.emitters[0].split(",")[:3], dtype=float)
    box = np.array(scene.drains[0].split(":")[1].split(","), dtype=float)
    outlet = 0.5 * (box[:3] + box[3:])
    ground = []
    for x, y in (head[:2], outlet[:2]):
        hits, _ = scene.mesh.ray_trace((x, y, 1e5), (x, y, -1e5))
        ground.append(hits[:, 2].max())
    assert ground[0] > ground[1]


def test_river_procedural():
    scene = river_scene()
    check_scene(scene)
    assert scene.mesh.n_cells == 14_774
    river_outlet_is_lower(scene)
    again = river_scene()
    np.testing.assert_array_equal(scene.mesh.points, again.mesh.points)


def test_river_from_a_dem_file(tmp_path):
    i, j = np.meshgrid(np.arange(50), np.arange(60), indexing="ij")
    heights = 1500.0 - 4.0 * j - 0.05 * j**2 + 20.0 * np.sin(i / 5.0) * np.cos(j / 7.0)
    image = pv.ImageData(dimensions=(50, 60, 1), spacing=(25.0, 25.0, 1.0), origin=(5e5, 5e6, 0.0))
    image.point_data["elevation"] = heights.ravel(order="F")
    path = tmp_path / "dem.vti"
    image.save(path)
    scene = river_scene(dem=path, stride=1, window=(0, 0, 50, 60))
    check_scene(scene)
    assert scene.mesh.n_cells == 2 * 49 * 59 + 3 * 2 * (49 + 59)
    assert np.asarray(scene.mesh.points).min(axis=0)[0] == 0.0  # local coordinates
    river_outlet_is_lower(scene)
    with pytest.raises(ValueError, match="window"):
        river_scene(dem=path)  # the St Helens window does not fit
    with pytest.raises(ValueError, match="stride"):
        river_scene(stride=0)


@pytest.mark.skipif(not DEM.exists(), reason=f"real data not found at {DEM}")
def test_river_on_mount_st_helens():
    scene = river_scene(dem=DEM)
    check_scene(scene)
    assert scene.mesh.n_cells == 14_774
    assert HELENS_WINDOW[2] // 2 == 84
    river_outlet_is_lower(scene)


def test_lake_fills_and_spills_through_the_notch():
    scene = lake_scene()
    check_scene(scene)
    nx, ny = 101, 61
    top = np.asarray(scene.mesh.points)[: nx * ny].reshape(nx, ny, 3)  # height_field_solid lists the top first
    heights = top[..., 2]
    seed = heights.copy()
    seed[1:-1, 1:-1] = heights.max()
    filled = reconstruction(seed, heights, method="erosion")
    lake = filled - heights > 1e-9
    assert ndimage.label(lake, structure=np.ones((3, 3)))[1] == 1  # one basin, no other pits
    centre = np.array(scene.emitters[0].split(",")[:2], dtype=float)
    nearest = np.unravel_index(np.argmin(np.linalg.norm(top[..., :2] - centre, axis=-1)), (nx, ny))
    assert lake[nearest]
    volume = (filled - heights)[lake].sum() * (top[1, 0, 0] - top[0, 0, 0]) ** 2
    assert volume > 1000 * (2 * scene.radius) ** 3  # a lake of a thousand particles or more
    level = filled[lake].max()
    spill = ndimage.binary_dilation(lake, structure=np.ones((3, 3))) & ~lake & (heights <= level + 1e-12)
    assert spill.any()
    assert (top[spill][:, 0] > centre[0] + 0.3).all() and (np.abs(top[spill][:, 1] - centre[1]) < 0.1).all()
    with pytest.raises(ValueError, match="shape"):
        lake_scene(shape=(5, 5))


def test_pour_over_the_procedural_rock():
    scene = pour_scene()
    check_scene(scene)
    z = np.asarray(scene.mesh.points)[:, 2]
    plane = np.array(scene.drains[0].split(":")[1].split(","), dtype=float)
    assert plane[2] < 0.0 and -plane[3] < z.min()  # removes particles below the model
    with pytest.raises(TypeError, match="PolyData"):
        pour_scene(mesh=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="up"):
        pour_scene(up=(0.0, 0.0, 0.0))


def test_pour_rotates_the_model_up():
    rock = load_rock(subdivisions=3)
    rock.points[:, 0] *= 3.0
    scene = pour_scene(mesh=rock, up=(1.0, 0.0, 0.0))
    check_scene(scene)
    # +x turns to +z (and +z to -x)
    np.testing.assert_allclose(np.ptp(np.asarray(scene.mesh.points), axis=0)[[2, 1, 0]], np.ptp(rock.points, axis=0))


def test_pour_over_the_bunny(bunny):
    scene = pour_scene(mesh=bunny, up=(0.0, 1.0, 0.0))
    check_scene(scene)
    assert scene.mesh.n_cells > bunny.n_cells


@pytest.mark.parametrize("scale", [1e-3, 0.37, 1.0, 1e3])
def test_pour_scene_fits_its_emitter_at_any_scale(scale):
    # rates written with a few digits used to round above what the disc can emit (rock at 0.37: 343.909 > 343.909)
    rock = load_rock(subdivisions=3)
    reference = pour_scene(mesh=rock)
    rock.points = np.asarray(rock.points, dtype=float) * scale + [0.0, 0.0, 1e4 * scale]  # far from the origin too
    scene = pour_scene(mesh=rock)
    check_scene(scene)
    emitter = Emitter.parse(scene.emitters[0])
    spacing = 2.0 * scene.radius
    top = len(emitter.lattice(spacing)) * emitter.speed / spacing
    assert 1.0 - 1e-6 < emitter.rate / top <= 1.0
    fluid = ParticleFluid(FluidParameters(radius=scene.radius), domain=scene.domain, emitters=[emitter],
                          drains=[Drain.parse(d) for d in scene.drains])
    assert len(fluid.positions) == 0
    # the set-up scales with the model: radius, disc, emitter height and drain plane
    assert scene.radius == pytest.approx(reference.radius * scale, rel=1e-9)
    assert emitter.radius == pytest.approx(Emitter.parse(reference.emitters[0]).radius * scale, rel=1e-9)
    drain = np.array(scene.drains[0].split(":")[1].split(","), dtype=float)
    z = np.asarray(scene.mesh.points)[:, 2]
    assert -drain[3] < z.min() and z.min() - (-drain[3]) == pytest.approx(0.05 * np.ptp(np.asarray(scene.mesh.points),
                                                                                          axis=0).max(), rel=1e-6)


def _topless_rock() -> tuple[np.ndarray, np.ndarray]:
    """The procedural rock with its top (faces reaching above z = 0.6) cut off: points (V, 3), faces (F, 3)."""
    rock = load_rock(subdivisions=4)
    faces = rock.regular_faces
    kept = faces[np.asarray(rock.points)[faces][:, :, 2].max(axis=1) < 0.6]
    used = np.unique(kept)
    return np.asarray(rock.points)[used], np.searchsorted(used, kept)


def test_fill_holes_closes_a_rock_with_its_top_cut_off():
    points, kept = _topless_rock()
    filled_points, filled_faces = fill_holes(points, kept)
    np.testing.assert_array_equal(filled_points[: len(points)], points)
    np.testing.assert_array_equal(filled_faces[: len(kept)], kept)
    assert_closed_solid(filled_points, filled_faces)
    assert min_angles(filled_points, filled_faces[len(kept):]).min() > 15.0


def test_fill_holes_puts_every_new_point_at_the_mean_of_its_ring():
    """The patch is a membrane solved exactly: each new point's uniform Laplacian is zero to rounding (relaxed by
    a fixed number of iterations, the rock's patch kept residuals of 1e-5 of its size)."""
    points, kept = _topless_rock()
    filled_points, filled_faces = fill_holes(points, kept)
    edges = np.concatenate([filled_faces[:, [0, 1]], filled_faces[:, [1, 2]], filled_faces[:, [2, 0]]])
    edges = edges[edges[:, 0] >= len(points)]
    total = np.zeros_like(filled_points)
    np.add.at(total, edges[:, 0], filled_points[edges[:, 1]])
    valence = np.bincount(edges[:, 0], minlength=len(filled_points))
    new = np.arange(len(points), len(filled_points))
    assert len(new) > 10 and (valence[new] >= 3).all()
    laplacian = total[new] / valence[new, None] - filled_points[new]
    assert np.abs(laplacian).max() <= 1e-14 * np.ptp(filled_points, axis=0).max()


def _rows_sorted(rows: np.ndarray) -> np.ndarray:
    return rows[np.lexsort(rows.T[::-1])]


@pytest.mark.parametrize("change", ["winding", "face_order", "vertex_order"])
def test_fill_holes_patches_do_not_depend_on_numbering_or_winding(change):
    """A patch is built from its rim's points alone: the same new points and triangles (as point triples) when
    the faces are reversed or renumbered or the vertices renumbered (the rim had been followed from wherever the
    boundary walk met it first, and renumbered faces gave the rock's cut top 432 new points instead of 436)."""
    points, kept = _topless_rock()
    rng = np.random.default_rng(7)
    other_points, other_faces = points, kept
    if change == "winding":
        other_faces = kept[:, ::-1]
    elif change == "face_order":
        other_faces = kept[rng.permutation(len(kept))]
    else:
        order = rng.permutation(len(points))  # new vertex i is old vertex order[i]
        other_points, other_faces = points[order], np.argsort(order)[kept]

    def patch(p, f):
        filled_points, filled_faces = fill_holes(p, f)
        new = filled_points[len(p):]
        triples = filled_points[filled_faces[len(f):]].reshape(-1, 9)
        return new[np.lexsort(new.T[::-1])], triples

    (new, triples), (other_new, other_triples) = patch(points, kept), patch(other_points, other_faces)
    np.testing.assert_array_equal(other_new, new)
    if change == "winding":
        other_triples = other_triples.reshape(-1, 3, 3)[:, ::-1].reshape(-1, 9)
    np.testing.assert_array_equal(_rows_sorted(other_triples), _rows_sorted(triples))


def test_fill_holes_keeps_a_planar_patch_in_its_plane():
    cube = load_cube(resolution=6)
    faces = cube.regular_faces
    kept = faces[np.asarray(cube.points)[faces][:, :, 0].min(axis=1) < 1.0]  # the +x side removed
    used = np.unique(kept)
    points, faces = fill_holes(np.asarray(cube.points)[used], np.searchsorted(used, kept))
    assert len(points) > len(used) and (points[len(used):, 0] == 1.0).all()  # inner points, in the plane
    assert_closed_solid(points, faces)
    assert signed_volume(points, faces) == pytest.approx(8.0)


def test_fill_holes_rejects_non_manifold_edges():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], dtype=float)
    faces = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(ValueError, match="more than two faces"):
        fill_holes(points, faces)
