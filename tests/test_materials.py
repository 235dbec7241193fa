import numpy as np
import pytest
from conftest import DATA, surface_defects, winding_numbers

from pverosion.kernels.materials.bsp import (
    LATTICE_DIRECTIONS,
    LEAF,
    BSPNode,
    BSPTree,
    LatticeBSPTree,
    build_from_labels,
    build_from_triangles,
    build_from_voxel_faces,
    voxel_faces,
)
from pverosion.kernels.materials.field import (
    BSPMaterials,
    Gradual,
    VertexMaterials,
    VolumeMaterials,
    bsp_from_volume,
)
from pverosion.kernels.materials.surfaces import (
    Cylinder,
    Ellipsoid,
    EllipticHyperboloid,
    Paraboloid,
    Plane,
    SincSurface,
    SinSurface,
    Sphere,
    UserSurface,
    surface_from_dict,
)

SURFACES = [
    Plane((1.0, 2.0, -0.5), 0.3),
    Sphere((0.1, -0.2, 0.3), 0.7),
    Ellipsoid((0.0, 0.1, 0.0), (0.9, 0.5, 0.7)),
    Paraboloid((0.0, 0.0, -0.5), 0.8, 1.2),
    EllipticHyperboloid((0.0, 0.0, 0.0), 0.4, 0.6, 0.8),
    Cylinder((0.2, 0.0, 0.0), (1.0, 1.0, 0.0), 0.5),
    SinSurface(0.1, 0.3, 3.0, 2.0),
    SincSurface((0.1, -0.1), -0.2, 0.8, 0.4),
]


def _random_tree(rng, depth):
    if depth == 0 or rng.random() < 0.15:
        return int(rng.integers(0, 5))
    surface = SURFACES[rng.integers(len(SURFACES))]
    return BSPNode(surface, _random_tree(rng, depth - 1), _random_tree(rng, depth - 1))


def _brute_force(node, points, rows, material, nearest, margin):
    """Reference location: recursive partition with the NumPy evaluators of each surface."""
    if not isinstance(node, BSPNode):
        material[rows] = node
        return
    d = node.surface.evaluate(points[rows])
    nearest[rows] = np.minimum(nearest[rows], np.abs(d))
    margin[rows] = np.minimum(margin[rows], np.abs(d))
    _brute_force(node.negative, points, rows[d < 0], material, nearest, margin)
    _brute_force(node.positive, points, rows[d >= 0], material, nearest, margin)


def test_surfaces_numba_and_numpy_agree_and_round_trip():
    rng = np.random.default_rng(0)
    points = rng.uniform(-1.5, 1.5, (2000, 3))
    for surface in SURFACES:
        tree = BSPTree.from_nodes(BSPNode(surface, 0, 1))
        material, distance = tree.locate(points)
        d = surface.evaluate(points)
        assert np.array_equal(material, np.where(d < 0, 0, 1)), surface
        assert np.allclose(distance, np.abs(d), rtol=1e-12, atol=1e-12)
        assert surface_from_dict(surface.to_dict()) == surface
    # a plane's value is the signed distance
    plane = Plane((0.0, 0.0, 2.0), -1.0)
    assert plane.evaluate(np.array([[0.0, 0.0, 3.0]]))[0] == pytest.approx(2.5)


def test_random_trees_locate_like_brute_force_on_100k_points(tmp_path):
    rng = np.random.default_rng(1)
    points = rng.uniform(-1.5, 1.5, (100_000, 3))
    for _ in range(3):
        root = _random_tree(rng, 6)
        if not isinstance(root, BSPNode):
            continue
        tree = BSPTree.from_nodes(root)
        material, distance = tree.locate(points)
        expected = np.full(len(points), -1)
        nearest = np.full(len(points), np.inf)
        margin = np.full(len(points), np.inf)
        _brute_force(root, points, np.arange(len(points)), expected, nearest, margin)
        far = margin > 1e-9  # exact agreement except within 1e-9 of a surface on the path
        assert far.mean() > 0.999
        assert np.array_equal(material[far], expected[far])
        assert np.allclose(distance[far], nearest[far], rtol=1e-12, atol=1e-12)
        # whole-array agreement with the Python-callable (level by level) path
        user_tree = BSPTree.from_nodes(BSPNode(UserSurface(lambda p: p[:, 0] - 10.0), root, 0))
        assert np.array_equal(user_tree.locate(points)[0], material)
        path = tree.to_json(tmp_path / "tree.json")
        assert np.array_equal(BSPTree.from_json(path).locate(points)[0], material)


def test_gradual_hardness_is_monotone_in_the_distance():
    field = BSPMaterials.split(Plane((0.0, 0.0, 1.0), 0.0), 0, 1, [2.0, 4.0], gradual=Gradual(scale=0.5, floor=0.25))
    z = np.linspace(0.0, 5.0, 200)
    points = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)
    sample = field.sample(points)
    assert np.all(sample.material_id[1:] == 1)
    assert np.all(np.diff(sample.hardness[1:]) <= 0)
    assert np.allclose(sample.hardness[1:], 4.0 * (0.25 + 0.75 * np.exp(-z[1:] / 0.5)))
    assert sample.hardness[-1] == pytest.approx(1.0, rel=0.01)  # the floor, far away
    below = field.sample(-points[1:])
    assert np.all(below.material_id == 0) and np.all(np.diff(below.hardness) <= 0)
    assert np.allclose(field.erodibility(points), 1.0 / sample.hardness)


def test_vertex_and_volume_fields():
    vertex = VertexMaterials([0, 2, 1, 2], [1.0, 2.0, 3.0])
    assert np.array_equal(vertex.sample(np.zeros((2, 3)), ids=[1, 2]).hardness, [3.0, 2.0])
    with pytest.raises(ValueError, match="pass ids="):
        vertex.sample(np.zeros((3, 3)))
    ids = np.zeros((4, 3, 2), np.int64)
    ids[2:] = 1
    volume = VolumeMaterials(ids, [1.0, 3.0], spacing=(1.0, 1.0, 1.0))
    s = volume.sample([[0.4, 1.0, 0.0], [1.5, 1.0, 0.0], [2.6, 1.0, 1.0], [9.0, 9.0, 9.0]])
    assert np.array_equal(s.material_id, [0, 1, 1, 1])  # nearest; outside clamps to the boundary
    assert s.hardness[0] == 1.0 and s.hardness[1] == pytest.approx(2.0) and s.hardness[2] == 3.0
    nearest = VolumeMaterials(ids, [1.0, 3.0], interpolation="nearest").sample([[1.4, 1.0, 0.0]])
    assert nearest.hardness[0] == 1.0


def test_build_from_triangles_reproduces_a_cube():
    import pyvista as pv

    cube = pv.Cube(center=(0.0, 0.0, 0.0), x_length=2.0, y_length=2.0, z_length=2.0).triangulate()
    tri = np.asarray(cube.points)[cube.regular_faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    outward = np.einsum("ij,ij->i", normal, tri.mean(axis=1)) > 0
    tri[~outward] = tri[~outward][:, ::-1]
    points = np.random.default_rng(2).uniform(-2, 2, (20_000, 3))
    inside = np.all(np.abs(points) < 1.0, axis=1)
    for method in ("complete", "simplified"):
        tree, inserted = build_from_triangles(tri, np.ones(len(tri), int), np.zeros(len(tri), int), method=method)
        assert inserted == 6  # two coplanar triangles per side: the second lies in the first's plane
        assert np.array_equal(tree.locate(points)[0] == 1, inside)


def _centres(shape, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0)):
    grid = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), -1).reshape(-1, 3)
    return np.asarray(origin) + grid * np.asarray(spacing)


def test_fitted_tree_splits_a_half_space_with_one_lattice_plane():
    i, j, k = np.indices((20, 16, 12))
    origin, spacing = np.array([-3.0, 2.0, 0.5]), np.array([0.5, 2.0, 1.5])
    for u in LATTICE_DIRECTIONS:
        labels = (u[0] * i + u[1] * j + u[2] * k > 4).astype(np.int64)
        tree = build_from_labels(labels, origin=origin, spacing=spacing)
        assert tree.n_nodes == 3 and tree.height == 1
        assert np.array_equal(LATTICE_DIRECTIONS[tree.direction[0]], u) and tree.value[0] == 4
        assert tree.direction[1] == tree.direction[2] == LEAF and tree.value[1:].tolist() == [0, 1]
        normal = tree.to_bsp_tree().params[0, :3]
        assert np.linalg.norm(normal) == pytest.approx(1.0)
        np.testing.assert_allclose(normal, (u / spacing) / np.linalg.norm(u / spacing), atol=1e-12)
        material, distance = tree.locate(_centres(labels.shape, origin, spacing))
        assert np.array_equal(material, labels.ravel())
        # the plane lies half a lattice step from the nearest centres, in world units
        assert distance.min() == pytest.approx(0.5 / np.linalg.norm(u / spacing), rel=1e-9)


def test_fitted_tree_of_a_box_has_six_planes():
    labels = np.zeros((12, 10, 9), np.int64)
    labels[2:9, 3:7, 1:8] = 2
    tree = build_from_labels(labels)
    assert (tree.leaf < 0).sum() == 6
    assert np.array_equal(tree.locate(_centres(labels.shape))[0], labels.ravel())


def test_fitted_tree_is_exact_and_smaller_than_the_volume_on_smooth_data():
    # four nested materials of a smooth 8-bit volume: tree bytes under the volume's, every voxel right (the
    # tree grows with the area of the material boundaries, the volume with its cube: finer volumes gain more)
    x, y, z = np.meshgrid(*[np.linspace(-1, 1, n) for n in (64, 57, 51)], indexing="ij")
    values = np.clip(255 * (1.2 - np.sqrt(x**2 + 1.3 * y**2 + 0.8 * z**2) + 0.1 * np.sin(3 * x)), 0, 255)
    values = values.astype(np.uint8)
    thresholds = (60, 120, 200)
    reference = (values[..., None] > np.array(thresholds)).sum(axis=-1).ravel()
    spacing = (0.7, 0.7, 1.1)
    fitted = bsp_from_volume(values, thresholds, spacing=spacing, method="fitted")
    assert np.array_equal(fitted.sample(_centres(values.shape, spacing=spacing)).material_id, reference)
    assert fitted.stats.tree_bytes < 0.25 * values.nbytes
    assert fitted.stats.tree_bytes == fitted.tree.nbytes
    assert fitted.stats.inserted_faces == (fitted.tree.leaf < 0).sum() and fitted.stats.extracted_faces == 0
    complete = bsp_from_volume(values, thresholds, spacing=spacing, method="complete", surface="isosurface")
    assert fitted.stats.nodes * 10 < complete.stats.nodes
    agreement = np.mean(complete.sample(_centres(values.shape, spacing=spacing)).material_id == reference)
    assert agreement < 1.0  # the inserted isosurfaces miss some voxel centres the fitted tree gets right
    voxels = bsp_from_volume(values, thresholds, spacing=spacing, method="complete")  # C-BSP of the voxel faces
    assert np.array_equal(voxels.sample(_centres(values.shape, spacing=spacing)).material_id, reference)
    assert voxels.stats.tree_bytes == voxels.tree.nbytes <= 0.5 * values.nbytes
    assert voxels.stats.nodes * 5 < complete.stats.nodes
    # the same input gives the same tree
    again = bsp_from_volume(values, thresholds, spacing=spacing, method="fitted")
    for name in ("direction", "value", "right"):
        assert np.array_equal(getattr(again.tree, name), getattr(fitted.tree, name))


@pytest.mark.parametrize("method, surface", [("fitted", None), ("complete", None), ("complete", "isosurface")])
def test_volume_trees_do_not_depend_on_units(method, surface):
    x, y, z = np.meshgrid(*[np.linspace(-1, 1, n) for n in (20, 18, 16)], indexing="ij")
    values = (200 * np.exp(-(x**2 + 2 * y**2 + z**2))).astype(np.uint8)
    trees = [bsp_from_volume(values, (80, 150), origin=np.array([1.0, -2.0, 0.5]) * scale,
                             spacing=np.array([0.5, 0.5, 0.8]) * scale, method=method, surface=surface).tree
             for scale in (1e-3, 1.0, 1e3)]
    if isinstance(trees[1], LatticeBSPTree):  # the same lattice nodes; their planes in world units scale
        for tree in trees:
            for name in ("direction", "value", "right"):
                assert np.array_equal(getattr(tree, name), getattr(trees[1], name))
        trees = [tree.to_bsp_tree() for tree in trees]
    for tree, scale in zip(trees, (1e-3, 1.0, 1e3)):
        assert np.array_equal(tree.leaf, trees[1].leaf) and np.array_equal(tree.negative, trees[1].negative)
        np.testing.assert_allclose(tree.params[:, :3], trees[1].params[:, :3], atol=1e-12)
        np.testing.assert_allclose(tree.params[:, 3], trees[1].params[:, 3] * scale, rtol=1e-9, atol=1e-12 * scale)


def test_fitted_tree_of_tilted_strata_is_a_few_percent_of_the_volume():
    i, j, k = np.indices((64, 48, 40))
    strata = (40 * np.floor((k + 0.3 * i) / 8) % 255).astype(np.uint8)  # layers 8 voxels thick, dipping along x
    field = bsp_from_volume(strata, (30, 90), method="fitted")
    reference = (strata[..., None] > np.array([30, 90])).sum(axis=-1).ravel()
    assert np.array_equal(field.sample(_centres(strata.shape)).material_id, reference)
    assert field.stats.tree_bytes < 0.05 * strata.nbytes


def _assert_compact_tree_locates_like_planes(tree: LatticeBSPTree, shape, *, seed: int) -> None:
    """The compact layout finds the same leaves as the same tree with float planes and explicit children."""
    planes = tree.to_bsp_tree()
    assert planes.n_nodes == tree.n_nodes and planes.height == tree.height
    box = tree.origin + np.array(shape) * tree.spacing
    random_points = np.random.default_rng(seed).uniform(tree.origin - 2 * tree.spacing, box, (100_000, 3))
    for points in (random_points, _centres(shape, tree.origin, tree.spacing)):
        material, distance = tree.locate(points)
        expected, expected_distance = planes.locate(points)
        assert np.array_equal(material, expected)
        np.testing.assert_allclose(distance, expected_distance, rtol=1e-12, atol=1e-12 * np.abs(box).max())


def _smooth_volume(shape=(64, 57, 51)) -> np.ndarray:
    x, y, z = np.meshgrid(*[np.linspace(-1, 1, n) for n in shape], indexing="ij")
    return np.clip(255 * (1.2 - np.sqrt(x**2 + 1.3 * y**2 + 0.8 * z**2) + 0.1 * np.sin(3 * x)), 0, 255).astype(np.uint8)


def test_compact_fitted_tree_locates_like_its_plane_tree_and_round_trips(tmp_path):
    i, j, k = np.indices((40, 30, 24))
    strata = (40 * np.floor((k + 0.3 * i - 0.2 * j) / 6) % 255).astype(np.uint8)
    rng = np.random.default_rng(5)
    noisy = (_smooth_volume((30, 28, 26)).astype(float) + rng.normal(0, 25, (30, 28, 26))).clip(0, 255)
    for values, thresholds, origin, spacing in ((strata, (30, 90), (-5.0, 2.0, 1.0), (0.5, 0.5, 0.8)),
                                                (noisy, (60, 120, 200), (0.0, 0.0, 0.0), (1.0, 2.0, 3.0))):
        field = bsp_from_volume(values, thresholds, origin=origin, spacing=spacing, method="fitted")
        tree = field.tree
        reference = (values[..., None] > np.array(thresholds)).sum(axis=-1).ravel()
        assert np.array_equal(field.sample(_centres(values.shape, origin, spacing)).material_id, reference)
        _assert_compact_tree_locates_like_planes(tree, values.shape, seed=6)
        # the arrays are the tree: 1 + 2 + 2 bytes a node, the int8 direction table, origin and spacing
        assert (tree.direction.dtype, tree.value.dtype, tree.right.dtype) == (np.uint8, np.int16, np.uint16)
        assert tree.nbytes == field.stats.tree_bytes == 5 * tree.n_nodes + LATTICE_DIRECTIONS.size + 6 * 8
        # inner nodes: the negative child is the next node; leaves hold the materials
        inner = tree.direction != LEAF
        assert np.array_equal(tree.leaf >= 0, ~inner) and set(tree.value[~inner]) <= {0, 1, 2, 3}
        for load in (BSPTree.from_json, LatticeBSPTree.from_json):
            path = tree.to_json(tmp_path / "tree.json")
            again = load(path)
            assert isinstance(again, LatticeBSPTree)
            for name in ("direction", "value", "right", "directions", "origin", "spacing"):
                assert np.array_equal(getattr(again, name), getattr(tree, name))
                assert getattr(again, name).dtype == getattr(tree, name).dtype
            assert path.stat().st_size < tree.nbytes  # compressed arrays
            points = _centres(values.shape, origin, spacing) + 0.3
            assert np.array_equal(BSPMaterials(again, [1.0, 2.0, 3.0, 4.0]).sample(points).material_id,
                                  tree.locate(points)[0])


def test_compact_tree_layout_is_checked():
    tree = build_from_labels((np.indices((6, 5, 4))[0] > 2).astype(int))
    arrays = {"direction": tree.direction, "value": tree.value, "right": tree.right}
    options = {"directions": tree.directions, "origin": tree.origin, "spacing": tree.spacing}
    LatticeBSPTree(**arrays, **options)
    for name, bad, match in (("right", np.array([1, 0, 0], np.uint16), "preorder"),
                             ("right", np.array([3, 0, 0], np.uint16), "preorder"),
                             ("direction", np.array([LEAF, LEAF, LEAF], np.uint8), "preorder"),
                             ("direction", np.array([200, LEAF, LEAF], np.uint8), "unknown directions"),
                             ("value", np.array([2, -1, 1], np.int16), "negative materials"),
                             ("value", tree.value.astype(np.int64), "dtype|int16")):
        with pytest.raises(ValueError, match=match):
            LatticeBSPTree(**{**arrays, name: bad}, **options)
    with pytest.raises(ValueError, match="spacing > 0"):
        LatticeBSPTree(**arrays, **{**options, "spacing": (1.0, 0.0, 1.0)})
    data = tree.to_dict()
    for damaged in ({**data, "value": {**data["value"], "data": "AAAA"}}, {**data, "shape": [7, 3]},
                    {k: v for k, v in data.items() if k != "right"}):
        with pytest.raises(ValueError, match="damaged"):
            LatticeBSPTree.from_dict(damaged)
    with pytest.raises(ValueError, match="version 1"):
        LatticeBSPTree.from_dict({**data, "version": 2})


def test_compact_tree_widens_its_integers_when_needed(tmp_path):
    # plane keys beyond int16 on a long volume; offsets past uint16 behave like the narrow ones
    labels = (np.arange(40_000) >= 35_000).astype(np.int64).reshape(1, 1, -1)
    tree = build_from_labels(labels, spacing=(1.0, 1.0, 0.25))
    assert tree.value.dtype == np.int32 and tree.value[0] == 34_999 and tree.n_nodes == 3
    centres = _centres(labels.shape, spacing=(1.0, 1.0, 0.25))
    assert np.array_equal(tree.locate(centres)[0], labels.ravel())
    wide = LatticeBSPTree(tree.direction, tree.value, tree.right.astype(np.uint32), directions=tree.directions,
                          origin=tree.origin, spacing=tree.spacing)
    assert wide.nbytes == tree.nbytes + 2 * tree.n_nodes
    again = LatticeBSPTree.from_json(wide.to_json(tmp_path / "wide.json"))
    assert again.right.dtype == np.uint32
    points = np.random.default_rng(7).uniform(-1, 10_001, (1000, 3))
    assert np.array_equal(again.locate(points)[0], tree.locate(points)[0])
    assert np.array_equal(tree.locate(points)[0], (points[:, 2] > 0.25 * 34_999.5).astype(int))


@pytest.mark.parametrize("labels", [np.zeros((3, 3)), -np.ones((2, 2, 2), int), np.zeros((2, 2, 2))])
def test_fitted_tree_rejects_bad_labels(labels):
    with pytest.raises(ValueError, match="labels"):
        build_from_labels(labels)


@pytest.fixture(scope="module")
def head():
    raw = DATA / "HeadMRVolume.raw"
    if not raw.exists():
        pytest.skip(f"real data not found at {raw}")
    return np.fromfile(raw, dtype=np.uint8).reshape(42, 62, 48).transpose(2, 1, 0)


def test_head_volume_bsp_agrees_with_thresholded_voxels(head):
    thresholds = (40, 100, 160)
    reference = (head[..., None] > np.array(thresholds)).sum(axis=-1).ravel()
    centres = np.stack(np.meshgrid(*[np.arange(n) for n in head.shape], indexing="ij"), -1).reshape(-1, 3) * 4.0
    agreement = {}
    for method in ("complete", "simplified"):
        field = bsp_from_volume(head, thresholds, spacing=(4, 4, 4), method=method, surface="isosurface", seed=3)
        agreement[method] = np.mean(field.sample(centres).material_id == reference)
        assert field.stats.extracted_faces >= field.stats.inserted_faces > 0
        assert field.stats.tree_bytes == 24 * field.stats.nodes
    assert agreement["complete"] >= 0.99
    assert agreement["simplified"] <= agreement["complete"]
    again = bsp_from_volume(head, thresholds, spacing=(4, 4, 4), method="complete", surface="isosurface", seed=3)
    first = bsp_from_volume(head, thresholds, spacing=(4, 4, 4), method="complete", surface="isosurface", seed=3)
    assert np.array_equal(again.tree.params, first.tree.params) and np.array_equal(again.tree.leaf, first.tree.leaf)
    fitted = bsp_from_volume(head, thresholds, spacing=(4, 4, 4), method="fitted")
    assert np.array_equal(fitted.sample(centres).material_id, reference)
    assert fitted.stats.tree_bytes * 100 < first.stats.tree_bytes


def test_head_volume_c_bsp_of_voxel_faces_is_smaller_than_the_volume(head, tmp_path):
    thresholds = (40, 100, 160)
    reference = (head[..., None] > np.array(thresholds)).sum(axis=-1).ravel()
    field = bsp_from_volume(head, thresholds, spacing=(4, 4, 4), method="complete")
    assert np.mean(field.sample(_centres(head.shape, spacing=(4, 4, 4))).material_id == reference) >= 0.999
    assert field.stats.tree_bytes == field.tree.nbytes <= head.nbytes
    assert field.tree.to_json(tmp_path / "head.json").stat().st_size <= head.nbytes
    assert field.stats.extracted_faces >= field.stats.inserted_faces > 0
    _assert_compact_tree_locates_like_planes(field.tree, head.shape, seed=5)


def test_head_volume_fitted_tree_is_smaller_than_the_volume_in_memory_and_on_disk(head, tmp_path):
    thresholds = (40, 100, 160)
    reference = (head[..., None] > np.array(thresholds)).sum(axis=-1).ravel()
    fitted = bsp_from_volume(head, thresholds, spacing=(4, 4, 4), method="fitted")
    tree = fitted.tree
    assert fitted.stats.tree_bytes == tree.nbytes <= head.nbytes
    assert np.mean(fitted.sample(_centres(head.shape, spacing=(4, 4, 4))).material_id == reference) >= 0.999
    assert tree.to_json(tmp_path / "head.json").stat().st_size <= head.nbytes
    _assert_compact_tree_locates_like_planes(tree, head.shape, seed=4)


def _nearest_voxel_label(labels, points):
    """Label of the voxel whose cell holds each point (index space), 0 outside the volume."""
    index = np.rint(points).astype(int)
    inside = np.all((index >= 0) & (index < np.array(labels.shape)), axis=1)
    out = np.zeros(len(points), np.int64)
    out[inside] = labels[tuple(index[inside].T)]
    return out


def test_voxel_faces_merge_into_rectangles_covering_exactly_the_boundary():
    rng = np.random.default_rng(7)
    labels = (rng.random((9, 8, 7)) < 0.3).astype(int) + (rng.random((9, 8, 7)) < 0.2)
    axis, lo, hi, below, above = voxel_faces(labels)
    padded = np.pad(labels, 1)
    unit = sum(np.count_nonzero(np.diff(padded, axis=ax)) for ax in range(3))
    area = np.prod(np.maximum(hi - lo, 1), axis=1) // 4  # doubled coordinates: 4 per voxel face
    assert area.sum() == unit and len(axis) < unit  # every face once, in fewer rectangles
    assert np.all(below != above) and np.all(lo[np.arange(len(axis)), axis] % 2 == 1)
    for f in rng.choice(len(axis), 50, replace=False):  # the materials on either side are the voxels'
        corner = (lo[f] + 1) // 2 + 1  # padded index of the first voxel above the rectangle
        lower = corner.copy()
        lower[axis[f]] -= 1
        assert padded[tuple(lower)] == below[f] and padded[tuple(corner)] == above[f]


def test_voxel_c_bsp_of_one_material_is_one_leaf_or_its_box():
    tree, faces, inserted = build_from_voxel_faces(np.zeros((3, 4, 2), int))
    assert (faces, inserted, tree.n_nodes) == (0, 0, 1) and tree.locate(np.zeros((1, 3)))[0][0] == 0
    tree, faces, inserted = build_from_voxel_faces(np.full((3, 4, 2), 2))
    assert faces == inserted == 6  # the six sides of the box, each one rectangle
    points = np.array([[1.0, 1.5, 0.5], [-0.6, 1.0, 0.0], [1.0, 3.6, 1.0], [1.0, 1.0, -0.51]])
    assert tree.locate(points)[0].tolist() == [2, 0, 0, 0]


@pytest.mark.parametrize("candidates, split_weight", [(1, 0.0), (64, 4.0)])
def test_voxel_c_bsp_gives_every_point_its_voxel_label(candidates, split_weight):
    # the C-BSP of the voxel boundary faces partitions space along the voxel cells: any point, not only the
    # centres, gets the label of the voxel it lies in (0 outside the volume)
    rng = np.random.default_rng(3)
    labels = np.zeros((14, 12, 10), int)
    labels[rng.random(labels.shape) < 0.25] = 1
    labels[rng.random(labels.shape) < 0.1] = 2
    tree, faces, inserted = build_from_voxel_faces(labels, candidates=candidates, split_weight=split_weight)
    assert faces >= inserted == (tree.leaf < 0).sum() > 0
    points = rng.uniform(-2.0, np.array(labels.shape) + 1.0, (50_000, 3))
    points = points[np.all(np.abs(np.abs(points - np.rint(points)) - 0.5) > 1e-3, axis=1)]  # off the cell walls
    assert np.array_equal(tree.locate(points)[0], _nearest_voxel_label(labels, points))


def test_voxel_c_bsp_of_a_sphere_and_a_box_classifies_analytic_points():
    shape, spacing, origin = (30, 26, 22), np.array([0.1, 0.1, 0.125]), np.array([-1.5, -1.3, -1.4])
    centres = _centres(shape, origin, spacing)
    ball = np.linalg.norm(centres, axis=1) < 1.0
    box = np.all(np.abs(centres - [0.4, 0.0, 0.0]) < [0.3, 0.45, 0.6], axis=1)
    values = (100 * ball + 100 * box).reshape(shape).astype(np.uint8)  # 0 outside, 100 in one, 200 in both
    field = bsp_from_volume(values, (50, 150), origin=origin, spacing=spacing, method="complete")
    points = np.random.default_rng(1).uniform(origin - 0.2, origin + np.array(shape) * spacing, (100_000, 3))
    half_cell = 0.5 * np.linalg.norm(spacing)  # the voxel surface lies within half a cell of the true one
    r = np.linalg.norm(points, axis=1)
    far_box = np.all(np.abs(points - [0.4, 0.0, 0.0]) < np.array([0.3, 0.45, 0.6]) - half_cell, axis=1)
    out_box = np.any(np.abs(points - [0.4, 0.0, 0.0]) > np.array([0.3, 0.45, 0.6]) + half_cell, axis=1)
    material = field.sample(points).material_id
    assert np.all(material[(r < 1.0 - half_cell) & far_box] == 2)
    assert np.all(material[(r < 1.0 - half_cell) & out_box] == 1)
    assert np.all(material[(r > 1.0 + half_cell) & out_box] == 0)
    assert field.stats.tree_bytes <= 0.25 * values.nbytes  # smooth boundaries: a fraction of the 8-bit volume


def test_voxel_c_bsp_does_not_depend_on_voxel_order():
    # the same volume mirrored and with its axes swapped gives the same materials at the matching points
    rng = np.random.default_rng(11)
    labels = (rng.random((10, 9, 8)) < 0.3).astype(int) + (rng.random((10, 9, 8)) < 0.15)
    tree = build_from_voxel_faces(labels)[0]
    turned = build_from_voxel_faces(labels[::-1].transpose(2, 1, 0))[0]
    points = rng.uniform(-0.4, 7.4, (20_000, 3))
    moved = np.stack([points[:, 2], points[:, 1], labels.shape[0] - 1 - points[:, 0]], axis=1)
    assert np.array_equal(tree.locate(points)[0], turned.locate(moved)[0])
    again = build_from_voxel_faces(labels)[0]
    for name in ("direction", "value", "right"):
        assert np.array_equal(getattr(again, name), getattr(tree, name))


def test_isosurface_trees_insert_a_closed_surface_at_a_threshold_the_labels_reach():
    """Labels 0/1/2 at threshold 1, with samples at the threshold: the inserted marching-cubes surface is closed and
    manifold, encloses exactly the labels above the threshold, and is the surface the tree is built from."""
    from pverosion.kernels.voxel.isosurface import marching_cubes

    labels = np.random.default_rng(3).integers(0, 3, (10, 9, 8)).astype(np.uint8)
    padded = np.pad(labels.astype(np.float64), 1, constant_values=-1.0)  # as bsp_from_volume pads
    verts, faces = marching_cubes(padded, 1.0, at_level="below")
    defects = surface_defects(faces)
    assert not any(defects.values()), defects
    outward = faces[:, ::-1]
    off_level = labels.ravel() != 1  # the samples at the threshold lie on the surface
    winding = winding_numbers(_centres(labels.shape)[off_level] + 1.0, verts, outward)
    np.testing.assert_allclose(winding, (labels.ravel() == 2)[off_level], atol=1e-6)
    triangles = verts[outward].astype(np.float64)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    field = bsp_from_volume(labels, (1,), method="complete", surface="isosurface")
    assert field.stats.extracted_faces == np.count_nonzero(np.linalg.norm(normals, axis=1) > 0)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="radius must be > 0"):
        Sphere((0, 0, 0), -1.0)
    with pytest.raises(ValueError, match="unknown surface type"):
        surface_from_dict({"type": "Torus"})
    with pytest.raises(ValueError, match="hardness needs a value"):
        BSPMaterials.split(Plane(), 0, 3, [1.0, 2.0])
    with pytest.raises(ValueError, match="strictly inside the value range"):
        bsp_from_volume(np.arange(27.0).reshape(3, 3, 3), [100.0])
    for thresholds in ([np.nan], [5.0, np.nan]):  # a lone NaN made a tree of one material; a second was dropped
        with pytest.raises(ValueError, match=r"thresholds must be finite numbers; got \[.*nan"):
            bsp_from_volume(np.arange(27.0).reshape(3, 3, 3), thresholds)
    with pytest.raises(ValueError, match="values has 1 NaN or infinite samples"):
        bsp_from_volume(np.where(np.arange(27) == 4, np.nan, np.arange(27.0)).reshape(3, 3, 3), [10.0])
    with pytest.raises(ValueError, match="method must be one of"):
        bsp_from_volume(np.arange(27.0).reshape(3, 3, 3), [10.0], method="fast")
    with pytest.raises(ValueError, match="takes surface in"):
        bsp_from_volume(np.arange(27.0).reshape(3, 3, 3), [10.0], method="simplified", surface="voxels")
    with pytest.raises(ValueError, match="takes surface in"):
        bsp_from_volume(np.arange(27.0).reshape(3, 3, 3), [10.0], method="complete", surface="mesh")
    with pytest.raises(ValueError, match="candidates must be"):
        build_from_voxel_faces(np.ones((3, 3, 3), int), candidates=0)
    with pytest.raises(ValueError, match="labels must be"):
        build_from_voxel_faces(-np.ones((3, 3, 3), int))
    with pytest.raises(ValueError, match="points must have shape"):
        BSPMaterials.split(Plane(), 0, 1, [1.0, 2.0]).sample(np.zeros(3))
    with pytest.raises(TypeError, match="cannot be saved"):
        BSPTree.from_nodes(BSPNode(UserSurface(lambda p: p[:, 0]), 0, 1)).to_json("x.json")
