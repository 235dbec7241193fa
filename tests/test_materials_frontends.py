import warnings

import numpy as np
import pytest
import pyvista as pv

import pverosion
from pverosion.cli import main
from pverosion.filters import MaterialSampler, MaterialsFromVolume
from pverosion.kernels.materials.bsp import BSPTree
from pverosion.kernels.materials.field import BSPMaterials
from pverosion.kernels.materials.surfaces import Sphere
from pverosion.kernels.weathering.model import WeatheringSolver
from pverosion.scenes.weathering import sixteen_cell_block


def _ball_image(n=20):
    axis = np.linspace(-1.0, 1.0, n)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    image = pv.ImageData(dimensions=(n, n, n), origin=(-1.0, -1.0, -1.0), spacing=(2 / (n - 1),) * 3)
    image["density"] = (1.0 - np.sqrt(x**2 + y**2 + z**2)).transpose(2, 1, 0).ravel()  # x fastest
    return image


def test_filter_builds_from_an_image_and_reports_agreement(tmp_path):
    image = _ball_image()
    out = pv.wrap(MaterialsFromVolume(thresholds="0.2, 0.6", tree_file=str(tmp_path / "t.json")).run(image))
    assert out.field_data["agreement"][0] >= 0.99
    centre = out.find_closest_point((0.0, 0.0, 0.0))
    corner = out.find_closest_point((1.0, 1.0, 1.0))
    assert out["material_id"][centre] == 2 and out["material_id"][corner] == 0
    assert np.array_equal(out["hardness"], out["material_id"] + 1.0)
    resampled = pverosion.sample_materials(str(tmp_path / "t.json"), dimensions=(20, 20, 20), bounds=image.bounds)
    assert np.array_equal(resampled["material_id"], out["material_id"])
    with pytest.raises(ValueError, match="thresholds are required"):
        MaterialsFromVolume().run(image)
    with pytest.raises(ValueError, match="thresholds must be numbers"):
        MaterialsFromVolume(thresholds="low, high").run(image)


def test_nan_scalars_and_cell_only_data_are_refused_by_name():
    """A NaN voxel is in no material: refused, not silently put in material 0; cell data is named."""
    image = _ball_image(8)
    image["density"][5] = np.nan
    before = image.copy()
    with pytest.raises(ValueError, match="'density' has 1 NaN"):
        MaterialsFromVolume(thresholds="0.2").run(image)
    assert image == before
    cells = pv.ImageData(dimensions=(8, 8, 8))
    cells.cell_data["density"] = np.ones(cells.n_cells)
    with pytest.raises(ValueError, match=r"no point scalars \(its cell arrays \['density'\]"):
        MaterialsFromVolume(thresholds="0.2").run(cells)


def test_fitted_tree_file_is_compact_and_resamples_alike(tmp_path):
    image = _ball_image()
    path = tmp_path / "fitted.json"
    out = pv.wrap(MaterialsFromVolume(thresholds="0.2, 0.6", method="fitted", tree_file=str(path)).run(image))
    assert out.field_data["agreement"][0] == 1.0
    assert path.stat().st_size < out.field_data["bsp_bytes"][0] < out.field_data["volume_bytes"][0]
    resampled = pverosion.sample_materials(str(path), dimensions=(20, 20, 20), bounds=image.bounds)
    assert np.array_equal(resampled["material_id"], out["material_id"])


def test_sampler_refuses_a_grid_whose_points_coincide_or_are_nowhere(tmp_path):
    """Zero spacing puts every sample at one point, a NaN origin puts them nowhere: both refused by name."""
    image = _ball_image(8)
    path = tmp_path / "t.json"
    MaterialsFromVolume(thresholds="0.2", tree_file=str(path)).run(image)
    flat = pv.ImageData(dimensions=(8, 8, 8))
    flat.SetSpacing(0.0, 0.0, 0.0)
    lost = pv.ImageData(dimensions=(8, 8, 8))
    lost.SetOrigin(np.nan, 0.0, 0.0)
    for grid in (flat, lost):
        with pytest.raises(ValueError, match="finite origin and a finite, non-zero spacing"):
            MaterialSampler(tree_file=str(path)).run(grid)
    thin = pv.ImageData(dimensions=(1, 8, 8), spacing=(0.0, 0.25, 0.25), origin=(0.0, -1.0, -1.0))
    assert pv.wrap(MaterialSampler(tree_file=str(path)).run(thin))["material_id"].size == 64  # one slice: fine


def test_sample_materials_checks_the_grid_it_builds(tmp_path, monkeypatch):
    """A huge grid was a MemoryError, 2.7 points were truncated to 2, NaN bounds failed inside PyVista."""
    from pverosion.limits import ResourceLimitError

    path = tmp_path / "t.json"
    MaterialsFromVolume(thresholds="0.2", tree_file=str(path)).run(_ball_image(8))
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "1G")
    with pytest.raises(ResourceLimitError, match="dimensions: sampling 100000 x 100000 x 100000 points"):
        pverosion.sample_materials(str(path), dimensions=(100_000, 100_000, 100_000))
    with pytest.raises(ValueError, match="dimensions must be 3 positive integers"):
        pverosion.sample_materials(str(path), dimensions=(2.7, 5, 5))
    with pytest.raises(ValueError, match="bounds must be finite"):
        pverosion.sample_materials(str(path), dimensions=(5, 5, 5), bounds=(-1, np.nan, -1, 1, -1, 1))
    assert pverosion.sample_materials(str(path), dimensions=np.array([5, 5, 5])).dimensions == (5, 5, 5)


@pytest.mark.parametrize("method", ["complete", "fitted"])
def test_tree_file_keeps_its_volume_and_a_grid_outside_it_is_refused(tmp_path, method):
    image = _ball_image()
    path = tmp_path / f"{method}.json"
    MaterialsFromVolume(thresholds="0.2, 0.6", method=method, tree_file=str(path)).run(image)
    assert BSPTree.from_json(path).domain == tuple(image.bounds)
    far = [b + 10.0 for b in image.bounds]  # the same grid, 10 units away along every axis
    with pytest.raises(ValueError, match="wholly outside the volume the tree"):
        pverosion.sample_materials(str(path), dimensions=(5, 5, 5), bounds=far)
    half = [b + (1.0 if i < 2 else 0.0) for i, b in enumerate(image.bounds)]  # half of it beyond x = 1
    with pytest.warns(UserWarning, match="part of the grid lies outside"):
        pverosion.sample_materials(str(path), dimensions=(5, 5, 5), bounds=half)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the volume itself: no warning
        pverosion.sample_materials(str(path), dimensions=(5, 5, 5), bounds=image.bounds)


def test_sampler_points_and_cells_and_accessor():
    field = BSPMaterials.split(Sphere((0.0, 0.0, 0.0), 0.5), 0, 1, [3.0, 1.0])
    points = pverosion.sample_materials(field, dimensions=(11, 11, 11))
    inside = np.linalg.norm(points.points, axis=1) < 0.5
    assert np.array_equal(points["material_id"] == 0, inside)
    grid = pv.ImageData(dimensions=(5, 5, 5), origin=(-1, -1, -1), spacing=(0.5, 0.5, 0.5))
    cells = pv.wrap(MaterialSampler(field=field, association="cell").run(grid))
    centres = cells.cell_centers().points
    assert np.array_equal(cells.cell_data["hardness"], np.where(np.linalg.norm(centres, axis=1) < 0.5, 3.0, 1.0))
    assert _ball_image().erosion.materials([0.5]).n_materials == 2
    with pytest.raises(ValueError, match="no material field"):
        MaterialSampler().run(grid)
    with pytest.raises(ValueError, match="dimensions must be"):
        pverosion.sample_materials(field, dimensions=(0, 4, 4))


def test_cli_materials_writes_vti_tree_and_slices(tmp_path, capsys):
    _ball_image().save(tmp_path / "ball.vti")
    out = tmp_path / "m.vti"
    args = ["materials", str(tmp_path / "ball.vti"), "-o", str(out), "--thresholds", "0.2,0.6",
            "--method", "simplified", "--tree-file", str(tmp_path / "tree.json"), "--screenshot", str(tmp_path / "s.png")]
    assert main(args) == 0
    assert pv.read(out).field_data["bsp_method"][0] == "simplified"
    assert (tmp_path / "tree.json").exists() and (tmp_path / "s.png").stat().st_size > 5_000
    assert main(["materials", str(tmp_path / "ball.vti"), "-o", str(out)]) == 2
    assert "thresholds are required" in capsys.readouterr().err


def test_cli_checks_the_tree_file_before_the_run(tmp_path, capsys):
    """--tree-file naming the input overwrote the volume with JSON; under a file it failed after the run."""
    path = tmp_path / "ball.vti"
    _ball_image(8).save(path)
    before = path.read_bytes()
    (tmp_path / "plain").write_text("a file")
    for tree, message in ((path, "names the same file as the input"),
                          (tmp_path / "out.vti", "names the same file as -o"),
                          (tmp_path / "plain" / "t.json", "plain is not a folder")):
        assert main(["materials", str(path), "-o", str(tmp_path / "out.vti"), "--thresholds", "0.2",
                     "--tree-file", str(tree)]) == 2
        assert message in capsys.readouterr().err
        assert not (tmp_path / "out.vti").exists()
    assert path.read_bytes() == before


def test_weathering_follows_the_hardness_of_the_16_cells():
    block, field, cell_of = sixteen_cell_block(seed=0)

    def column_volumes(points, faces):
        # divergence theorem with F = (0, 0, z): vertical cell walls add nothing
        tri = points[faces]
        area_normal = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        centre = tri.mean(axis=1)
        return np.bincount(cell_of(centre), weights=centre[:, 2] * area_normal[:, 2], minlength=16)

    solver = WeatheringSolver(block.points, block.regular_faces, erodibility=field)
    before = column_volumes(solver.points, solver.faces)
    solver.run(100)
    loss = before - column_volumes(solver.points, solver.faces)
    i, j = np.divmod(np.arange(16), 4)
    corner = np.isin(i, (0, 3)) & np.isin(j, (0, 3))
    edge = (np.isin(i, (0, 3)) | np.isin(j, (0, 3))) & ~corner
    for group in (corner, edge):  # cells of the same shape: the softer loses more
        cells = np.flatnonzero(group)
        by_hardness = cells[np.argsort(field.hardness[cells])]
        assert loss[by_hardness[0]] > 2.0 * loss[by_hardness[-1]]
        half = len(cells) // 2
        assert loss[by_hardness[:half]].mean() > 1.5 * loss[by_hardness[half:]].mean()


def test_an_isosurface_tree_too_large_for_the_memory_limit_is_refused_before_it_grows(tmp_path, monkeypatch, capsys):
    """A noisy volume's isosurfaces have millions of triangles: a 64^3 noise volume took 3.5 GB and 17 s whatever
    PVEROSION_MEMORY_LIMIT said. The build's estimate is checked once the triangles are extracted."""
    from pverosion.limits import ResourceLimitError

    noise = pv.ImageData(dimensions=(24, 24, 24))
    noise["v"] = np.random.default_rng(3).random(noise.n_points)
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "50M")
    message = r"thresholds: the tree grown from \d+ isosurface triangles would need about .* \(PVEROSION_MEMORY_LIMIT\)"
    for method in ("complete", "simplified"):
        with pytest.raises(ResourceLimitError, match=message):
            pverosion.materials_from_volume(noise, [0.5], method=method, surface="isosurface")
    noise.save(tmp_path / "noise.vti")
    out = tmp_path / "m.vti"
    assert main(["materials", str(tmp_path / "noise.vti"), "--thresholds", "0.5", "--surface", "isosurface",
                 "-o", str(out)]) == 2
    assert "isosurface triangles would need" in capsys.readouterr().err and not out.exists()
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "0")  # no limit: the same tree is built
    field = pverosion.materials_from_volume(noise, [0.5], method="simplified", surface="isosurface")
    assert field.stats.extracted_faces > 10_000


def test_the_python_function_names_an_unusable_array_as_the_filter_does():
    """materials_from_volume read arrays itself: a 3-component array failed with 'cannot reshape array', an image with
    cell data only with 'image has no active scalars'. It now shares the filter's reading."""
    image = _ball_image(8)
    image["vectors"] = np.zeros((image.n_points, 3))
    with pytest.raises(ValueError, match="'vectors' must have one component; it has 3"):
        pverosion.materials_from_volume(image, [0.2], array="vectors")
    cells = pv.ImageData(dimensions=(8, 8, 8))
    cells.cell_data["density"] = np.linspace(0.0, 1.0, cells.n_cells)
    with pytest.raises(ValueError, match=r"no point scalars \(its cell arrays \['density'\] are not thresholded"):
        pverosion.materials_from_volume(cells, [0.5])
    with pytest.raises(ValueError, match="no point array 'missing'"):
        pverosion.materials_from_volume(image, [0.2], array="missing")


@pytest.mark.parametrize("method", ["complete", "fitted"])
def test_a_tree_file_keeps_the_hardness_and_falloff_it_was_built_with(tmp_path, method):
    """The tree file kept the planes only: sampling it gave hardness 1, 2, ... and no falloff, without a word,
    whatever hardness the tree was built with. Both tree kinds now save them; a hardness given wins."""
    import json

    image = _ball_image(16)
    tree_file = tmp_path / "t.json"
    built = pv.wrap(MaterialsFromVolume(thresholds="0.2, 0.6", hardness="10, 20, 30", gradual_scale=0.3,
                                        method=method, tree_file=str(tree_file)).run(image))
    sampled = pv.wrap(MaterialSampler(tree_file=str(tree_file)).run(image))
    np.testing.assert_array_equal(sampled["material_id"], built["material_id"])
    np.testing.assert_allclose(sampled["hardness"], built["hardness"], rtol=1e-12)
    assert sampled["hardness"].max() > 20 and len(np.unique(sampled["hardness"])) > 3  # the falloff is kept
    given = pv.wrap(MaterialSampler(tree_file=str(tree_file), hardness="1, 2, 3").run(image))
    np.testing.assert_array_equal(given["hardness"], given["material_id"] + 1.0)
    data = json.loads(tree_file.read_text())
    data["materials"]["hardness"] = [10, -1, 30]
    tree_file.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="damaged materials: hardness must be finite numbers > 0"):
        MaterialSampler(tree_file=str(tree_file)).run(image)
