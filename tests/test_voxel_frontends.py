"""Voxel grids, surface extraction, the VoxelErosion filter and its front ends."""

import numpy as np
import pytest
import pyvista as pv
from conftest import surface_defects

import pverosion
from pverosion.cli import main
from pverosion.examples import load_torus
from pverosion.filters import MaterialsFromVolume, VoxelErosion
from pverosion.filters.materials import grid_points
from pverosion.filters.voxel import (
    extract_material_surface,
    voxel_grid,
    voxel_grid_from_height_field,
    voxel_grid_from_mesh,
    voxel_grid_from_volume,
)
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.voxel.isosurface import UNTIED_LEVEL, marching_cubes, untied_field
from pverosion.scenes.voxel import meander_grid


def _meander_grid():
    grid, _ = meander_grid((40, 20, 16), spacing=0.05, depth=4, half_width=4.0, amplitude=3.0)
    grid["material_id"] = (1 + (grid.points[:, 2] > 0.2)).astype(np.int32)  # two layers
    return grid


def test_voxelised_torus_has_the_analytic_volume():
    grid = voxel_grid_from_mesh(load_torus(n_major=120, n_minor=60), spacing=0.05)
    volume = grid["material_amount"].sum() * 0.05**3
    assert volume == pytest.approx(2 * np.pi**2 * 3.0 * 1.0**2, rel=0.01)
    assert grid["material_amount"].reshape(grid.dimensions, order="F")[0].sum() == 0  # the padding is empty


def test_height_field_columns_hold_the_terrain_height():
    x, y = np.meshgrid(np.arange(12), np.arange(9), indexing="ij")
    heights = 1.0 + 0.3 * np.sin(x / 3.0) * np.cos(y / 4.0)
    grid = voxel_grid_from_height_field(heights, spacing=0.1)
    amount = grid["material_amount"].reshape(grid.dimensions, order="F")
    bottom = grid.origin[2] - 0.05
    assert np.allclose(bottom + amount.sum(axis=2) * 0.1, heights)
    image = pv.ImageData(dimensions=(12, 9, 1), spacing=(0.1, 0.1, 1.0))
    image["elevation"] = heights.ravel(order="F")
    from_image = voxel_grid_from_height_field(image, spacing=0.1)
    assert np.allclose(from_image["material_amount"], grid["material_amount"])


def test_volume_threshold_and_cubic_voxels():
    image = pv.ImageData(dimensions=(8, 8, 8), spacing=(0.5, 0.5, 0.5))
    image["v"] = image.points[:, 2]
    grid = voxel_grid_from_volume(image, threshold=1.0)
    assert np.array_equal(grid["material_amount"] > 0, image["v"] > 1.0)
    image.spacing = (0.5, 0.5, 1.0)
    with pytest.raises(ValueError, match="cubic"):
        voxel_grid_from_volume(image, threshold=1.0)


def test_grid_builders_refuse_bad_sizes_and_no_data_before_allocating(monkeypatch):
    """Tiny spacings were a MemoryError, zero an OverflowError, NaN heights or thresholds passed or failed unnamed."""
    from conftest import DATA

    from pverosion.filters.voxel import voxel_grid
    from pverosion.limits import ResourceLimitError

    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "1G")
    dem = pv.read(DATA / "SainteHelens.dem")
    with pytest.raises(ResourceLimitError, match="spacing: a voxel grid of .* voxels"):
        voxel_grid_from_height_field(dem, spacing=1e-3)
    for spacing in (0, -30.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="spacing must be a finite number > 0"):
            voxel_grid_from_height_field(dem, spacing=spacing)
    with pytest.raises(ValueError, match="1 NaN or infinite height"):
        voxel_grid_from_height_field(np.array([[1.0, np.nan], [1.0, 1.0]]), spacing=1.0)
    for stride in (0, -2, 1.5):  # 0 failed as "slice step cannot be zero"; -2 flipped the terrain
        with pytest.raises(ValueError, match="stride must be a whole number >= 1"):
            voxel_grid_from_height_field(dem, spacing=100.0, stride=stride)
    with pytest.raises(ResourceLimitError, match="spacing, padding"):
        voxel_grid_from_mesh(pv.Sphere(), spacing=1e-5)
    with pytest.raises(ValueError, match="padding must be an integer >= 0"):
        voxel_grid_from_mesh(pv.Sphere(), spacing=0.1, padding=-5)
    image = pv.ImageData(dimensions=(4, 4, 4))
    image["v"] = np.arange(64.0)
    with pytest.raises(ValueError, match="threshold must be finite"):
        voxel_grid_from_volume(image, threshold=np.nan)
    with pytest.raises(ValueError, match="threshold 1e\\+09 leaves no material: the volume's values are 0..63"):
        voxel_grid_from_volume(image, threshold=1e9)
    image["v"][3] = np.nan
    with pytest.raises(ValueError, match="1 NaN value"):
        voxel_grid_from_volume(image, threshold=10)
    with pytest.raises(ValueError, match="origin must be finite"):
        voxel_grid(np.ones((3, 3, 3)), origin=(np.nan, 0.0, 0.0))


@pytest.mark.parametrize("method", ["flying_edges", "marching_cubes"])
def test_extracted_surfaces_are_closed_outward_and_agree(method):
    grid = _meander_grid()
    surface = extract_material_surface(grid, method=method)
    assert surface.n_open_edges == 0 and surface.is_manifold
    reference = extract_material_surface(grid, method="flying_edges")
    volume = signed_volume(np.asarray(surface.points, dtype=float), surface.regular_faces)
    assert volume > 0  # outward
    # flying edges writes float32 points
    assert volume == pytest.approx(signed_volume(np.asarray(reference.points, dtype=float), reference.regular_faces),
                                   rel=1e-6)
    assert set(np.unique(surface["material_id"])) == {1, 2}
    with pytest.raises(ValueError, match="method must be one of"):
        extract_material_surface(grid, method="dual_contouring")


def _random_amount(seed: int, steps: int) -> np.ndarray:
    """(9, 8, 7) amounts drawn from ``steps`` evenly spaced values in [0, 1]."""
    return np.random.default_rng(seed).integers(0, steps, (9, 8, 7)) / (steps - 1.0)


def _amounts_at_the_level():
    """(amount, iso, whether flying edges gives the same surface) with samples exactly at ``iso``."""
    plateau = np.zeros((10, 10, 10))
    plateau[1:9, 1:9, 1:9] = 1.0
    plateau[2:8, 2:8, 2:8] = 0.5  # a layer at the level inside the material
    plateau[3:7, 3:7, 3:7] = 1.0
    radius = np.linalg.norm(np.indices((12, 12, 12)) - 5.5, axis=0)
    shell = np.where(radius < 3.0, 1.0, np.where(radius < 4.0, 0.5, 0.0))  # its outer layer at the level
    box = np.zeros((7, 8, 9))
    box[1:5, 1:6, 1:7] = 1.0
    return {
        "plateau at the level": (plateau, 0.5, True),
        "outer layer at the level": (shell, 0.5, True),
        "box at the level": (box, 1.0, True),
        # ambiguous cubes, which flying edges' case table and marching cubes' tests resolve differently
        "0, 0.5, 1 at random": (_random_amount(5, 3), 0.5, False),
        "quarters at random": (_random_amount(7, 5), 0.75, False),
        "0/1 at random, level 1": (_random_amount(0, 2), 1.0, False),
        "0/1 at random, saddles at the level": (_random_amount(1, 2), 0.5, False),
    }


@pytest.mark.parametrize("case", list(_amounts_at_the_level()))
def test_marching_cubes_is_closed_and_manifold_with_samples_at_the_level(case):
    """With samples at the level (and faces whose saddle is at it) the surface has no repeated face, no face
    repeating a vertex and every edge in two faces wound oppositely, and it encloses the samples at the level, as
    flying edges does."""
    amount, iso, same_surface = _amounts_at_the_level()[case]
    grid = voxel_grid(amount)
    before = grid.copy(deep=True)
    surface = extract_material_surface(grid, method="marching_cubes", iso=iso)
    assert grid == before
    defects = surface_defects(surface.regular_faces)
    assert not any(defects.values()), defects
    volume = signed_volume(np.asarray(surface.points, dtype=float), surface.regular_faces)
    assert volume > 0
    if same_surface:
        reference = extract_material_surface(grid, method="flying_edges", iso=iso)
        assert volume == pytest.approx(signed_volume(np.asarray(reference.points, dtype=float),
                                                     reference.regular_faces), rel=1e-6)


@pytest.mark.parametrize("outlier", [-1e4, 1e12, -1e30])
def test_marching_cubes_stays_manifold_beside_a_far_outlier(outlier):
    """One sample far from the level (a bright spot of a CT volume) does not bring the saddles of the 0/1 samples
    near the level back into scikit-image's tie tolerance."""
    values = np.pad(np.random.default_rng(1).integers(0, 2, (9, 8, 7)).astype(float), 1)
    values[1, 1, 1] = outlier  # inside the zero border, so that the surface is closed
    verts, faces = marching_cubes(values, 0.5, at_level="above")
    defects = surface_defects(faces)
    assert len(faces) and not any(defects.values()), defects
    assert verts.dtype == np.float32 and np.isfinite(verts).all()


@pytest.mark.parametrize("method", ["flying_edges", "marching_cubes"])
def test_surface_extraction_refuses_amounts_that_are_not_finite(method):
    """Flying edges made a surface through a NaN amount without a word; both extractors name it."""
    amount = np.zeros((6, 6, 6))
    amount[1:5, 1:5, 1:5] = 1.0
    amount[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match="material_amount has 1 NaN or infinite values"):
        extract_material_surface(voxel_grid(amount), method=method)


def test_marching_cubes_refuses_samples_that_are_not_finite_or_beyond_float32():
    values = np.zeros((4, 4, 4))
    values[1:3, 1:3, 1:3] = 1.0
    values[0, 1, 2] = np.nan
    with pytest.raises(ValueError, match="1 NaN or infinite samples"):
        marching_cubes(values, 0.5, at_level="above")
    values[0, 1, 2] = -1e300
    with pytest.raises(ValueError, match="beyond the float32 range"):
        marching_cubes(values, 0.5, at_level="above")


def test_untied_field_keeps_every_sample_on_its_side_of_the_level():
    """Samples within 1e-13 of the level stay on their side of it (float32 alone would put them at it), a sample at
    the level goes to the side asked for, and none is left at the level; the input is not modified."""
    values = np.array([0.5, 0.5 + 1e-13, 0.5 - 1e-13, 0.0, 1.0, 0.25], dtype=np.float64).reshape(1, 2, 3)
    for at_level, above in (("above", [1, 1, 0, 0, 1, 0]), ("below", [0, 1, 0, 0, 1, 0])):
        field, level = untied_field(values, 0.5, at_level=at_level)
        assert field.dtype == np.float32 and level == UNTIED_LEVEL
        assert np.array_equal((field > level).ravel(), np.array(above, dtype=bool)), at_level
        assert not np.any(field == level)
    samples = values.astype(np.float32)
    untied_field(samples, 0.5, at_level="above")
    assert np.array_equal(samples, values.astype(np.float32))


def test_filter_steps_continue_from_the_cache_and_conserve_material():
    grid = _meander_grid()
    before = grid.copy(deep=True)
    alg = VoxelErosion(iterations=6, source_velocity="1.5,0,0")
    stepped = pv.wrap(alg.run_time(grid, 3))
    stepped = pv.wrap(alg.run_time(grid, 6))
    direct = pv.wrap(VoxelErosion(iterations=6, source_velocity="1.5,0,0").run(grid))
    for name in ("material_amount", "water", "dissolved", "velocity"):
        assert np.array_equal(stepped["state"][name], direct["state"][name]), name
    state = direct["state"]
    assert state.field_data["mass_error"][0] <= 1e-9
    assert len(state.field_data["voxel_eroded"]) == 7 and state.field_data["voxel_eroded"].sum() > 0
    assert set(np.unique(state["voxel_class"])) == {0, 1, 2}
    assert grid == before  # the input is not modified


def test_bad_grids_and_options_are_named():
    grid = _meander_grid()
    with pytest.raises(ValueError, match="material_amount"):
        VoxelErosion(iterations=1).run(pv.ImageData(dimensions=(4, 4, 4)))
    dem = pv.ImageData(dimensions=(4, 4, 1), spacing=(30.0, 30.0, 1.0))  # a DEM as read: heights, no material
    dem["elevation"] = np.arange(16.0)
    with pytest.raises(ValueError, match="'material_amount'.*voxel_grid_from_height_field \\(a DEM\\)"):
        VoxelErosion(iterations=1).run(dem)
    with pytest.raises(ValueError, match="source_velocity needs 3 numbers"):
        VoxelErosion(iterations=1, source_velocity="1,0").run(grid)
    odd = grid.copy()
    odd.spacing = (0.05, 0.05, 0.1)
    with pytest.raises(ValueError, match="cubic voxels"):
        VoxelErosion(iterations=1).run(odd)
    with pytest.raises(ValueError, match="model must be one of"):
        VoxelErosion(model="sticky")
    with pytest.raises(TypeError, match="ImageData"):
        pverosion.voxel_erosion(pv.Sphere())


def test_an_absurd_source_speed_is_refused_by_the_work_check():
    """A speed whose squared norm overflows (1e200 m/s) is named by the work check, not a ZeroDivisionError."""
    from pverosion.limits import ResourceLimitError

    grid = _meander_grid()
    for speed in ("1e200,0,0", "1e308,0,0"):
        with pytest.raises(ResourceLimitError, match="source_velocity"):
            VoxelErosion(iterations=1, source_velocity=speed).run(grid)


def test_function_accessor_and_cli_agree(tmp_path):
    grid = _meander_grid()
    out = pverosion.voxel_erosion(grid, iterations=3, source_velocity=(1.5, 0, 0))
    via_accessor = grid.erosion.voxel(iterations=3, source_velocity=(1.5, 0, 0))
    assert np.array_equal(out["state"]["material_amount"], via_accessor["state"]["material_amount"])
    grid.save(tmp_path / "grid.vti")
    assert main(["voxel", str(tmp_path / "grid.vti"), "-o", str(tmp_path / "out.vtm"), "--iterations", "3",
                 "--source-velocity", "1.5,0,0", "--save-every", "1"]) == 0
    saved = pv.read(tmp_path / "out.vtm")
    assert np.array_equal(saved["state"]["material_amount"], out["state"]["material_amount"])
    assert pv.get_reader(tmp_path / "out.pvd").time_values == [0.0, 1.0, 2.0, 3.0]


def test_saint_helens_dem_becomes_a_closed_terrain_block():
    from conftest import DATA

    path = DATA / "SainteHelens.dem"
    if not path.exists():
        pytest.skip(f"real data not found at {path}")
    dem = pv.read(path)
    grid = voxel_grid_from_height_field(dem, spacing=120.0, air=240.0)
    amount = np.asarray(grid["material_amount"]).reshape(grid.dimensions, order="F")
    heights = grid.origin[2] - 60.0 + amount.sum(axis=2) * 120.0
    elevation = np.asarray(dem.active_scalars)
    assert heights.max() == pytest.approx(elevation.max(), abs=120.0)   # the summit, resampled
    assert heights.min() == pytest.approx(elevation.min(), abs=120.0)
    assert np.all(amount[:, :, -2:] == 0)                                # air above the summit
    surface = extract_material_surface(grid)
    assert surface.n_open_edges == 0 and surface.is_manifold


def test_images_with_turned_axes_are_refused_by_every_image_stage(tmp_path, capsys):
    """An image whose direction matrix is not the identity (DICOM and some medical exports) was built, eroded and
    sampled as if its axes were x, y, z: materials agreed with the thresholded volume at 74 % of the head scan's
    voxels, and the extracted surface lay outside the grid. Every entry now refuses it, naming the remedy."""
    turn = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    ball = pv.ImageData(dimensions=(12, 12, 12), spacing=(0.2,) * 3, origin=(-1.1,) * 3)
    ball["density"] = 1.0 - np.linalg.norm(ball.points, axis=1)
    grid = voxel_grid_from_volume(ball, threshold=0.3)
    turned_ball, turned_grid = ball.copy(), grid.copy()
    turned_ball.direction_matrix = turned_grid.direction_matrix = turn
    message = r"axes are turned against x, y and z .*direction matrix \[0, -1, 0; 1, 0, 0; 0, 0, 1\].*identity"
    for run in (lambda: pverosion.materials_from_volume(turned_ball, [0.3]),
                lambda: MaterialsFromVolume(thresholds="0.3").run(turned_ball),
                lambda: grid_points(turned_ball, "point"),  # where the material sampler places an image's samples
                lambda: voxel_grid_from_volume(turned_ball, threshold=0.3),
                lambda: pverosion.voxel_erosion(turned_grid, iterations=1),
                lambda: extract_material_surface(turned_grid)):
        with pytest.raises(ValueError, match=message):
            run()
    np.testing.assert_array_equal(turned_ball.direction_matrix, turn)  # the input is left as it was
    path = tmp_path / "turned.vti"
    turned_ball.save(path)
    assert main(["materials", str(path), "--thresholds", "0.3", "-o", str(tmp_path / "m.vti")]) == 2
    assert "axes are turned" in capsys.readouterr().err and not (tmp_path / "m.vti").exists()


def test_a_grid_without_water_or_sources_is_warned_about():
    """A scan's voxel grid has material only: the run changed nothing and said nothing. With water it runs quietly."""
    import warnings

    amount = np.zeros((8, 8, 8))
    amount[:, :, :4] = 1.0
    with pytest.warns(UserWarning, match="no water outside the material .* and no 'source' voxels"):
        dry = pverosion.voxel_erosion(voxel_grid(amount, spacing=0.1), iterations=2)
    np.testing.assert_array_equal(dry["state"]["material_amount"], amount.ravel(order="F"))
    water = np.zeros_like(amount)
    water[:, :, 4:6] = 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        pverosion.voxel_erosion(voxel_grid(amount, spacing=0.1, water=water), iterations=2)


def test_a_volume_grid_and_its_materials_agree_at_values_equal_to_the_threshold():
    """The voxel grid took values at the threshold as material, the material tree as empty: 425 voxels of the head
    scan at threshold 40 (integer samples) differed. Both count values above the threshold now."""
    image = pv.ImageData(dimensions=(10, 10, 10))
    image["v"] = np.round(10.0 * np.linalg.norm(image.points - 4.5, axis=1))  # integers: many equal 30
    assert np.count_nonzero(image["v"] == 30.0) > 0
    grid = voxel_grid_from_volume(image, threshold=30.0)
    tree = pverosion.materials_from_volume(image, [30.0], method="fitted")
    np.testing.assert_array_equal(grid["material_amount"], tree.sample(image.points).material_id)
    np.testing.assert_array_equal(grid["material_amount"], image["v"] > 30.0)
