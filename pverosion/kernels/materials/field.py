"""Material fields: which material is where, and how hard it is (thesis ch. 11).

Every field answers one question for any points (N, 3): the ``material_id``
(int) and the ``hardness`` (float) there, through :meth:`MaterialField.sample`.
Erosion stages divide their speed by the hardness (``erodibility =
1 / hardness``) *at the current position* of each vertex, voxel or link, so a
surface eroding into a harder layer slows down.

Fields: :class:`VertexMaterials` (per-vertex arrays, §11.1),
:class:`BSPMaterials` (division by a plane or an implicit surface, §11.2–11.3,
and BSP trees of them, §11.4; :func:`bsp_from_volume` builds one from volume
data, §11.5), :class:`VolumeMaterials` (an ImageData-style 3D texture, nearest
or trilinear). A :class:`Gradual` falloff makes the hardness decrease with the
distance from the splitting surfaces (§11.3, §11.6).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pverosion.kernels.materials.bsp import (
    BSP_METHODS,
    BSP_SURFACES,
    NODE_BYTES,
    BSPStats,
    BSPTree,
    LatticeBSPTree,
    build_from_labels,
    build_from_triangles,
    build_from_voxel_faces,
)
from pverosion.kernels.materials.surfaces import ImplicitSurface
from pverosion.kernels.voxel.isosurface import marching_cubes

__all__ = [
    "BUILD_BYTES_PER_FACE",
    "BSPMaterials",
    "Gradual",
    "MaterialField",
    "MaterialSample",
    "VertexMaterials",
    "VolumeMaterials",
    "bsp_from_volume",
]

INTERPOLATIONS = ("nearest", "linear")

BUILD_BYTES_PER_FACE = {"complete": 4096, "simplified": 1536}
"""Peak memory of growing an isosurface tree, per extracted triangle, by method: C-BSP clips straddling faces
into about nine nodes per triangle (3.6 to 3.7 KB per triangle measured on noise volumes of 24^3 to 32^3
samples), S-BSP routes them whole (about 0.9 KB, with a margin here)."""


@dataclass(frozen=True)
class MaterialSample:
    """Materials at some points: ``material_id`` (N,) int64 and ``hardness`` (N,) float64."""

    material_id: np.ndarray
    hardness: np.ndarray

    @property
    def erodibility(self) -> np.ndarray:
        """Erosion speed multiplier ``1 / hardness`` (N,)."""
        return 1.0 / self.hardness


@dataclass(frozen=True)
class Gradual:
    """Hardness falling off with the distance ``|d|`` from the splitting surfaces.

    ``hardness = h_material * (floor + (1 - floor) * exp(-|d| / scale))``: the
    full hardness on the surfaces, softer farther away, never below
    ``floor * h_material``. Monotone non-increasing in ``|d|``.

    Parameters
    ----------
    scale : float
        Distance over which the hardness drops by a factor e towards the floor.
    floor : float, default: 0.2
        Fraction of the hardness kept far from the surfaces, in (0, 1].
    """

    scale: float
    floor: float = 0.2

    def __post_init__(self):
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale must be > 0; got {self.scale!r}")
        if not (0.0 < self.floor <= 1.0):
            raise ValueError(f"floor must be in (0, 1]; got {self.floor!r}")

    def factor(self, distance: np.ndarray) -> np.ndarray:
        """Multiplier (N,) of the hardness at distances ``|d|`` (N,)."""
        return self.floor + (1.0 - self.floor) * np.exp(-np.abs(distance) / self.scale)


def _hardness_table(hardness, n_required: int) -> np.ndarray:
    table = np.asarray(hardness, dtype=np.float64).ravel()
    if table.size < n_required:
        raise ValueError(f"hardness needs a value for each of the {n_required} materials; got {table.size}")
    if not np.all(np.isfinite(table)) or np.any(table <= 0):
        raise ValueError("hardness values must be finite and > 0")
    return table


def _points(points) -> np.ndarray:
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3); got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points contain NaN or infinite coordinates")
    return pts


class MaterialField:
    """Base class of all material fields."""

    def sample(self, points, *, ids=None) -> MaterialSample:
        """Materials at ``points`` (N, 3); ``ids`` (N,) names the input vertex of each
        point for per-vertex fields (others ignore it)."""
        raise NotImplementedError

    def erodibility(self, points, *, ids=None) -> np.ndarray:
        """Erosion speed multiplier ``1 / hardness`` at ``points``, shape (N,)."""
        return self.sample(points, ids=ids).erodibility

    @property
    def n_materials(self) -> int:
        """Number of material ids the field can return."""
        raise NotImplementedError


class VertexMaterials(MaterialField):
    """One material per input vertex (§11.1); carried along when the mesh is remeshed.

    Parameters
    ----------
    material_id : array_like of int, shape (V,)
    hardness : array_like, shape (M,)
        Hardness of each material id.
    """

    def __init__(self, material_id, hardness) -> None:
        ids = np.asarray(material_id)
        if ids.ndim != 1 or not np.issubdtype(ids.dtype, np.integer) or np.any(ids < 0):
            raise ValueError("material_id must be a 1-D array of non-negative integers")
        self.material_id = ids.astype(np.int64)
        self.hardness = _hardness_table(hardness, int(ids.max()) + 1)

    @property
    def n_materials(self) -> int:
        return len(self.hardness)

    def sample(self, points, *, ids=None) -> MaterialSample:
        pts = _points(points)
        if ids is None:
            if len(pts) != len(self.material_id):
                raise ValueError(
                    f"per-vertex materials hold {len(self.material_id)} vertices; got {len(pts)} points "
                    "(pass ids= to name the input vertex of each point)"
                )
            ids = np.arange(len(pts))
        mat = self.material_id[np.asarray(ids, dtype=np.int64)]
        return MaterialSample(mat, self.hardness[mat])


class BSPMaterials(MaterialField):
    """Materials of the leaves of a BSP tree of planes and implicit surfaces (§11.2–11.4).

    Parameters
    ----------
    tree : BSPTree or LatticeBSPTree
    hardness : array_like, shape (M,)
        Hardness of each material id found in the leaves.
    gradual : Gradual, optional
        Softer farther from the splitting surfaces (the smallest ``|d|`` met on the
        point's path through the tree).
    stats : BSPStats, optional
        Build statistics, for trees made by :func:`bsp_from_volume`.
    """

    def __init__(self, tree: BSPTree | LatticeBSPTree, hardness, *, gradual: Gradual | None = None,
                 stats: BSPStats | None = None) -> None:
        self.tree = tree
        self.hardness = _hardness_table(hardness, int(tree.leaf.max()) + 1)
        self.gradual = gradual
        self.stats = stats

    @classmethod
    def split(cls, surface: ImplicitSurface, negative: int, positive: int, hardness, *,
              gradual: Gradual | None = None) -> BSPMaterials:
        """Division by one plane or implicit surface: ``negative`` where F < 0, else ``positive``."""
        from pverosion.kernels.materials.bsp import split

        return cls(split(surface, negative, positive), hardness, gradual=gradual)

    @property
    def n_materials(self) -> int:
        return len(self.hardness)

    def sample(self, points, *, ids=None) -> MaterialSample:
        material, distance = self.tree.locate(_points(points))
        hardness = self.hardness[material]
        if self.gradual is not None:
            hardness = hardness * self.gradual.factor(distance)
        return MaterialSample(material, hardness)


class VolumeMaterials(MaterialField):
    """A 3D texture on a regular grid (an ImageData): material ids and optional hardness values.

    Parameters
    ----------
    material_id : array_like of int, shape (nx, ny, nz)
        Material of each grid point, indexed ``[i, j, k]`` along x, y, z.
    hardness : array_like, shape (M,) or (nx, ny, nz)
        Hardness of each material id, or a hardness value at every grid point.
    origin, spacing : array_like, shape (3,)
        Position of grid point (0, 0, 0) and the grid steps.
    interpolation : {"nearest", "linear"}, default: "linear"
        How per-point hardness is read between grid points (material ids are
        always nearest). Points outside the grid take the nearest boundary value.
    """

    def __init__(self, material_id, hardness, *, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0),
                 interpolation: str = "linear") -> None:
        ids = np.asarray(material_id)
        if ids.ndim != 3 or not np.issubdtype(ids.dtype, np.integer) or np.any(ids < 0):
            raise ValueError("material_id must be a 3-D array of non-negative integers")
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {INTERPOLATIONS}; got {interpolation!r}")
        self.material_id = ids.astype(np.int64)
        values = np.asarray(hardness, dtype=np.float64)
        if values.shape == ids.shape:
            if not np.all(np.isfinite(values)) or np.any(values <= 0):
                raise ValueError("hardness values must be finite and > 0")
            self.hardness_grid = values
            self.hardness = np.array([values[ids == m].mean() if np.any(ids == m) else 1.0
                                      for m in range(int(ids.max()) + 1)])
        else:
            self.hardness = _hardness_table(values, int(ids.max()) + 1)
            self.hardness_grid = self.hardness[self.material_id]
        self.origin = np.asarray(origin, dtype=np.float64).reshape(3)
        self.spacing = np.asarray(spacing, dtype=np.float64).reshape(3)
        if np.any(self.spacing <= 0):
            raise ValueError(f"spacing must be > 0; got {spacing!r}")
        self.interpolation = interpolation

    @property
    def n_materials(self) -> int:
        return len(self.hardness)

    def sample(self, points, *, ids=None) -> MaterialSample:
        index = ((_points(points) - self.origin) / self.spacing).T  # (3, N) fractional grid indices
        upper = np.array(self.material_id.shape)[:, None] - 1
        nearest = np.clip(np.rint(index), 0, upper).astype(np.int64)
        material = self.material_id[nearest[0], nearest[1], nearest[2]]
        if self.interpolation == "nearest":
            hardness = self.hardness_grid[nearest[0], nearest[1], nearest[2]]
        else:
            from scipy.ndimage import map_coordinates  # SciPy (0.3 s to import) only when a field is sampled

            hardness = map_coordinates(self.hardness_grid, np.clip(index, 0, upper), order=1, mode="nearest")
        return MaterialSample(material, hardness)


def _oriented(verts: np.ndarray, faces: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Triangles (T, 3, 3) in index space, wound so the normal points to lower values."""
    from scipy.ndimage import map_coordinates

    tri = verts[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    tri, normal, length = tri[length[:, 0] > 0], normal[length[:, 0] > 0], length[length[:, 0] > 0]
    centre = tri.mean(axis=1)
    step = 0.25 * normal / length
    ahead = map_coordinates(values, (centre + step).T, order=1, mode="nearest")
    behind = map_coordinates(values, (centre - step).T, order=1, mode="nearest")
    if np.count_nonzero(ahead > behind) > np.count_nonzero(ahead < behind):
        tri = tri[:, ::-1]
    return tri


def bsp_from_volume(
    values,
    thresholds,
    *,
    origin=(0.0, 0.0, 0.0),
    spacing=(1.0, 1.0, 1.0),
    method: str = "complete",
    surface: str | None = None,
    seed: int = 0,
    hardness=None,
    gradual: Gradual | None = None,
    memory_check: Callable[[float, int], None] | None = None,
) -> BSPMaterials:
    """Build a BSP material field from volume data (thesis §11.5).

    Material ``k`` is where the value exceeds exactly ``k`` of the sorted
    thresholds. The tree is grown from a surface between the materials:

    - ``surface="voxels"`` (the default of C-BSP): the boundary surface of the
      thresholded voxels, its coplanar faces merged into rectangles, grown by
      :func:`~pverosion.kernels.materials.bsp.build_from_voxel_faces` (each cell
      split by the plane that holds the most face area at the least clipping;
      all faces of the cell in that plane inserted at once, straddling faces
      clipped). Every voxel centre gets its material, the tree is held in the
      compact :class:`~pverosion.kernels.materials.bsp.LatticeBSPTree` layout
      (5 bytes a node) and is smaller than the volume on the 8-bit MR head
      (0.77x its bytes, benchmarks/bench_materials.py). It does not depend on
      ``seed``.
    - ``surface="isosurface"`` (the thesis' Algorithm 1, and the only surface
      of S-BSP): for each threshold the isosurface is extracted by marching
      cubes (on the volume padded by one layer below every threshold, so the
      surfaces are closed), oriented towards lower values, and its faces are
      inserted in a seeded Fisher–Yates order (NumPy's ``default_rng(seed)``,
      whose seeds give independent orders); C-BSP clips straddling faces,
      S-BSP routes each face by its centre. Nearly every face of smooth data
      is inserted: trees of about 100x the volume's bytes on the MR head.

    ``method="fitted"``: the tree is grown from the voxels' materials by
    :func:`~pverosion.kernels.materials.bsp.build_from_labels`, splitting with the
    lattice plane that leaves the purest sides; it gives every voxel centre
    its material exactly, in the same compact layout.

    Parameters
    ----------
    values : array_like, shape (nx, ny, nz)
        Scalar volume indexed ``[i, j, k]`` along x, y, z.
    thresholds : sequence of float
        Material boundaries (distinct).
    origin, spacing : array_like, shape (3,)
        World position of voxel (0, 0, 0) and the voxel size.
    method : {"complete", "simplified", "fitted"}
        C-BSP, S-BSP or the fitted tree.
    surface : {"voxels", "isosurface"}, optional
        Surface inserted by C-BSP (default ``"voxels"``) and S-BSP (only ``"isosurface"``);
        not accepted with ``"fitted"``.
    seed : int
        Insertion order seed (isosurface C-BSP and S-BSP; the other trees have no random part).
    memory_check : callable, optional
        Called as ``memory_check(nbytes, n_faces)`` with the estimated peak memory of an isosurface tree's
        build (:data:`BUILD_BYTES_PER_FACE` per extracted triangle) once the triangles are extracted, before
        the tree is grown; it raises to stop a build too large (a noisy volume's isosurfaces have millions
        of faces).
    hardness : array_like, shape (len(thresholds) + 1,), optional
        Hardness of each material; by default ``1, 2, ..., m + 1``.
    gradual : Gradual, optional

    Returns
    -------
    BSPMaterials
        With ``stats`` (:class:`~pverosion.kernels.materials.bsp.BSPStats`). Voxel
        C-BSP: ``extracted_faces`` counts the merged rectangles, ``inserted_faces``
        the coplanar groups inserted (inner nodes), ``tree_bytes`` is the real size
        of the arrays. Fitted tree: no faces are extracted, ``inserted_faces``
        counts its splitting planes and ``tree_bytes`` is the real size of its
        arrays. Isosurface C-BSP and S-BSP bytes are counted at 24 bytes a node,
        as in the thesis.

    Raises
    ------
    ValueError
        Bad volume (NaN or infinite samples included), thresholds outside the value range, unknown ``method`` or a
        ``surface`` the method does not take.
    """
    raw = np.asarray(values)
    vol = raw.astype(np.float64)
    if vol.ndim != 3 or min(vol.shape) < 2:
        raise ValueError(f"values must be a 3-D array with at least 2 samples per axis; got {vol.shape}")
    bad = vol.size - int(np.count_nonzero(np.isfinite(vol)))
    if bad:
        raise ValueError(f"values has {bad} NaN or infinite samples; their material is undefined")
    levels = np.sort(np.asarray(thresholds, dtype=np.float64).ravel())
    if not np.isfinite(levels).all():
        raise ValueError(f"thresholds must be finite numbers; got {np.asarray(thresholds).ravel().tolist()}")
    if levels.size == 0 or len(np.unique(levels)) != levels.size:
        raise ValueError("thresholds must be one or more distinct numbers")
    if hardness is not None and np.size(hardness) != levels.size + 1:
        raise ValueError(f"hardness needs one value per material: {levels.size} thresholds make {levels.size + 1} "
                         f"materials; got {np.size(hardness)} values")
    lo, hi = float(vol.min()), float(vol.max())
    if levels[0] <= lo or levels[-1] >= hi:
        raise ValueError(f"thresholds must lie strictly inside the value range ({lo}, {hi}); got {levels.tolist()}")
    if method not in BSP_METHODS:
        raise ValueError(f"method must be one of {BSP_METHODS}; got {method!r}")
    accepted = {"complete": BSP_SURFACES, "simplified": ("isosurface",), "fitted": ()}[method]
    if surface is not None and surface not in accepted:
        raise ValueError(f"method {method!r} takes surface in {accepted}; got {surface!r}")
    origin = np.asarray(origin, dtype=np.float64).reshape(3)
    spacing = np.asarray(spacing, dtype=np.float64).reshape(3)
    table = np.arange(1.0, levels.size + 2.0) if hardness is None else hardness
    if method == "fitted":
        tree = build_from_labels((vol[..., None] > levels).sum(axis=-1), origin=origin, spacing=spacing)
        stats = BSPStats(method=method, extracted_faces=0, inserted_faces=int((tree.leaf < 0).sum()),
                         nodes=tree.n_nodes, height=tree.height, tree_bytes=tree.nbytes,
                         volume_bytes=int(raw.nbytes), seed=int(seed))
        return BSPMaterials(tree, table, gradual=gradual, stats=stats)
    if method == "complete" and surface != "isosurface":
        tree, faces, inserted = build_from_voxel_faces((vol[..., None] > levels).sum(axis=-1), origin=origin,
                                                       spacing=spacing)
        stats = BSPStats(method=method, extracted_faces=faces, inserted_faces=inserted, nodes=tree.n_nodes,
                         height=tree.height, tree_bytes=tree.nbytes, volume_bytes=int(raw.nbytes), seed=int(seed))
        return BSPMaterials(tree, table, gradual=gradual, stats=stats)
    padded = np.pad(vol, 1, constant_values=lo - 1.0)
    triangles, inside = [], []
    for k, level in enumerate(levels, start=1):
        verts, faces = marching_cubes(padded, level, at_level="below")  # material k is above its threshold
        tri = _oriented(verts, faces, padded)
        triangles.append(origin + (tri - 1.0) * spacing)
        inside.append(np.full(len(tri), k))
    tri = np.concatenate(triangles)
    inside_ids = np.concatenate(inside)
    if memory_check is not None:
        memory_check(BUILD_BYTES_PER_FACE[method] * float(len(tri)), len(tri))
    tree, inserted = build_from_triangles(tri, inside_ids, inside_ids - 1, method=method, seed=seed)
    stats = BSPStats(method=method, extracted_faces=len(tri), inserted_faces=inserted, nodes=tree.n_nodes,
                     height=tree.height, tree_bytes=NODE_BYTES * tree.n_nodes, volume_bytes=int(raw.nbytes),
                     seed=int(seed))
    return BSPMaterials(tree, table, gradual=gradual, stats=stats)
