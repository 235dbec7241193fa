"""Material filters: build a BSP material field from a volume, sample any field onto a grid."""

from __future__ import annotations

import warnings
from typing import ClassVar

import numpy as np
from vtkmodules.util import numpy_support

from pverosion.filters.base import ErosionFilter, Param, check_axis_aligned, parse_numbers, set_field_value
from pverosion.kernels.materials.bsp import BSP_METHODS, BSP_SURFACES, BSPTree
from pverosion.kernels.materials.field import (
    BSPMaterials,
    Gradual,
    MaterialField,
    bsp_from_volume,
)
from pverosion.limits import check_memory

__all__ = ["SURFACE_CHOICES", "MaterialSampler", "MaterialsFromVolume", "check_tree_memory", "grid_points",
           "parse_numbers", "store_sample", "surface_option", "volume_values"]

SURFACE_CHOICES = ("default", *BSP_SURFACES)
"""Values of the ``surface`` option: ``"default"`` lets the method choose (C-BSP: voxels, S-BSP: isosurface)."""


def surface_option(value: str) -> str | None:
    """The kernel's ``surface`` argument for option value ``value`` (None for ``"default"``)."""
    return None if value == "default" else value

ASSOCIATIONS = ("point", "cell")


def check_tree_memory(nbytes: float, n_faces: int) -> None:
    """The ``memory_check`` of :func:`~pverosion.kernels.materials.field.bsp_from_volume`: refuse a tree whose
    build would exceed the memory limit (:func:`~pverosion.limits.check_memory`)."""
    check_memory(nbytes, option="thresholds", what=f"the tree grown from {n_faces} isosurface triangles",
                 remedy="smooth or downsample the volume, give fewer thresholds, or build from the voxel surface "
                        "(the default) or with method='fitted'")


def volume_values(image, name: str = "") -> np.ndarray:
    """The thresholded point array ``name`` (the active scalars when empty) of a vtkImageData, (nx, ny, nz).

    Raises
    ------
    ValueError
        An image with turned axes (:func:`~pverosion.filters.base.check_axis_aligned`), no such point array
        (naming the image's point and cell arrays), more than one component, or NaN values.
    """
    check_axis_aligned(image)
    pd = image.GetPointData()
    arr = pd.GetArray(name) if name else pd.GetScalars()
    if arr is None:
        cd = image.GetCellData()
        cells = [cd.GetArrayName(i) for i in range(cd.GetNumberOfArrays())]
        points = [pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())]
        hint = (f" (its point arrays {points}: name one with the array option)" if points else
                f" (its cell arrays {cells} are not thresholded: convert them to point data)" if cells else "")
        raise ValueError((f"input image has no point array {name!r}" if name else "input image has no point "
                          "scalars") + hint)
    if arr.GetNumberOfComponents() != 1:
        raise ValueError(f"the thresholded array {arr.GetName()!r} must have one component; it has "
                         f"{arr.GetNumberOfComponents()}")
    dims = image.GetDimensions()
    values = numpy_support.vtk_to_numpy(arr).reshape(dims[::-1]).transpose(2, 1, 0)
    nans = int(np.count_nonzero(np.isnan(values)))
    if nans:
        raise ValueError(f"the thresholded array {arr.GetName()!r} has {nans} NaN value(s): a NaN voxel is in no "
                         "material; fill or mask them first")
    return values


def grid_points(image, association: str) -> np.ndarray:
    """World coordinates (N, 3) of the points or cell centres of a vtkImageData, x fastest; ``ValueError`` for an
    image with turned axes (:func:`~pverosion.filters.base.check_axis_aligned`)."""
    check_axis_aligned(image)
    dims = np.array(image.GetDimensions())
    origin, spacing = np.array(image.GetOrigin()), np.array(image.GetSpacing())
    if association == "cell":
        dims = np.maximum(dims - 1, 1)
        origin = origin + 0.5 * spacing
    axes = [origin[k] + spacing[k] * np.arange(dims[k]) for k in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def store_sample(field: MaterialField, image, out, association: str) -> None:
    """Sample ``field`` at the grid of ``image`` into ``out`` as ``material_id`` and ``hardness``."""
    if association not in ASSOCIATIONS:
        raise ValueError(f"association must be one of {ASSOCIATIONS}; got {association!r}")
    sample = field.sample(grid_points(image, association))
    data = out.GetPointData() if association == "point" else out.GetCellData()
    for name, values in (("material_id", sample.material_id.astype(np.int32)), ("hardness", sample.hardness)):
        arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
        arr.SetName(name)
        data.AddArray(arr)
    data.SetActiveScalars("material_id")


class MaterialsFromVolume(ErosionFilter):
    """Build a BSP material field from volume data (thesis §11.5) and sample it back.

    The input image's scalar array is thresholded into materials (material k
    where the value exceeds k thresholds); a C-BSP of the voxels' boundary
    faces (coplanar faces merged; exact at the voxels, smaller than the volume),
    an S-BSP of the isosurfaces or a fitted tree is built (see
    :func:`~pverosion.kernels.materials.field.bsp_from_volume`; the thesis'
    isosurface C-BSP is ``bsp_from_volume(..., surface="isosurface")``) and
    sampled at the image's points into ``material_id``
    and ``hardness``. The tree can be saved to JSON (``tree_file``). Field
    data: ``bsp_method``, ``extracted_faces``, ``inserted_faces``,
    ``bsp_nodes``, ``bsp_height``, ``bsp_bytes``, ``volume_bytes``,
    ``agreement`` (fraction of grid points whose tree material equals the
    thresholded value).
    """

    LABEL = "Materials from volume (BSP)"
    COMMAND = "materials"
    INPUT_TYPE = "vtkImageData"
    OUTPUT_TYPE = "vtkImageData"
    REQUIRED: ClassVar[dict[str, str]] = {"thresholds": "40,100,160"}
    PARAMS = (
        Param("thresholds", "", "Material boundaries, comma separated (required), e.g. 40,100,160.", numbers=0),
        Param("array", "", "Input point array to threshold (default: the active scalars)."),
        Param("method", "complete", "complete (C-BSP of the voxels' boundary faces, coplanar faces merged, straddling "
              "faces clipped: exact at voxel centres, smaller than the volume), simplified (S-BSP of the isosurfaces, "
              "face centre) or fitted (planes chosen to fit the voxels' materials: exact, the smallest).",
              choices=BSP_METHODS),
        Param("surface", "default", "What C-BSP inserts: voxels (the voxels' boundary faces, the default) or isosurface "
              "(marching-cubes isosurfaces as in the thesis, about 100x the volume); S-BSP takes isosurface only.",
              choices=SURFACE_CHOICES, advanced=True),
        Param("seed", 0, "Seed of the face insertion order (isosurface trees).", minimum=0, advanced=True),
        Param("hardness", "", "Hardness per material, comma separated (default 1, 2, ..., m+1).", numbers=0),
        Param("gradual_scale", 0.0, "Softer away from the boundaries over this distance (0: off).", minimum=0.0,
              advanced=True),
        Param("tree_file", "", "Also save the tree to this JSON file.", path="output"),
    )

    def __init__(self, **options):
        super().__init__(**options)
        self.field: BSPMaterials | None = None

    def execute(self, inp, out) -> None:
        """Build the tree from ``inp`` and write the sampled materials into ``out``."""
        if not self.get_option("thresholds"):
            raise ValueError("thresholds are required, e.g. thresholds='40,100,160'")
        thresholds = parse_numbers(self.get_option("thresholds"), "thresholds")
        hardness = parse_numbers(self.get_option("hardness"), "hardness") if self.get_option("hardness") else None
        scale = self.get_option("gradual_scale")
        values = volume_values(inp, self.get_option("array"))
        field = bsp_from_volume(values, thresholds, origin=inp.GetOrigin(), spacing=inp.GetSpacing(),
                                method=self.get_option("method"), surface=surface_option(self.get_option("surface")),
                                seed=self.get_option("seed"), hardness=hardness,
                                gradual=Gradual(scale) if scale > 0 else None, memory_check=check_tree_memory)
        self.UpdateProgress(0.8)
        out.ShallowCopy(inp)
        store_sample(field, inp, out, "point")
        reference = (values[..., None] > np.sort(thresholds)).sum(axis=-1).transpose(2, 1, 0).ravel()
        material = numpy_support.vtk_to_numpy(out.GetPointData().GetArray("material_id"))
        stats = field.stats
        for name, value in (("bsp_method", stats.method), ("extracted_faces", stats.extracted_faces),
                            ("inserted_faces", stats.inserted_faces), ("bsp_nodes", stats.nodes),
                            ("bsp_height", stats.height), ("bsp_bytes", stats.tree_bytes),
                            ("volume_bytes", stats.volume_bytes),
                            ("agreement", float(np.mean(material == reference)))):
            set_field_value(out, name, value)
        if self.get_option("tree_file"):
            field.tree.to_json(self.get_option("tree_file"), domain=inp.GetBounds(),
                               materials={"hardness": field.hardness.tolist(), "gradual_scale": scale})
        self.field = field


class MaterialSampler(ErosionFilter):
    """Sample a material field on the grid of the input image (for slices and textures).

    The field is set from Python (``MaterialSampler(field=...)`` or
    :meth:`set_field`), or loaded from a BSP JSON file (``tree_file``, with
    ``hardness``, else the hardness and falloff saved with the tree, else
    1, 2, ...). Adds ``material_id`` and ``hardness`` as point or cell data.
    """

    LABEL = "Material field sampling"
    COMMAND = "sample-materials"
    INPUT_TYPE = "vtkImageData"
    OUTPUT_TYPE = "vtkImageData"
    PARAMS = (
        Param("association", "point", "Sample at the grid points or at the cell centres.", choices=ASSOCIATIONS),
        Param("tree_file", "", "BSP tree JSON file to sample when no field is set from Python.", path="input"),
        Param("hardness", "", "Hardness per material of the tree file, comma separated (default: the hardness "
              "saved with the tree, else 1, 2, ...).", numbers=0),
    )

    def __init__(self, *, field: MaterialField | None = None, **options):
        super().__init__(**options)
        self._field = field

    def set_field(self, field: MaterialField) -> None:
        """Sample this field (overrides ``tree_file``)."""
        self._field = field
        self.Modified()

    def _current_field(self) -> MaterialField:
        if self._field is not None:
            return self._field
        path = self.get_option("tree_file")
        if not path:
            raise ValueError("no material field: set one with field= / set_field(), or give tree_file")
        tree = BSPTree.from_json(path)
        text = self.get_option("hardness")
        saved = tree.materials or {}
        if text:
            return BSPMaterials(tree, parse_numbers(text, "hardness"))
        if saved:
            scale = saved["gradual_scale"]
            return BSPMaterials(tree, saved["hardness"], gradual=Gradual(scale) if scale > 0 else None)
        return BSPMaterials(tree, np.arange(1.0, tree.leaf.max() + 2.0))

    def execute(self, inp, out) -> None:
        """Sample the field at the grid of ``inp`` into ``out``."""
        if inp.GetNumberOfPoints() == 0:
            raise ValueError("the grid is empty: it has no points to sample at")
        dims, origin, spacing = (np.array(get()) for get in (inp.GetDimensions, inp.GetOrigin, inp.GetSpacing))
        if not (np.all(np.isfinite(origin)) and np.all(np.isfinite(spacing))) or np.any((spacing == 0) & (dims > 1)):
            raise ValueError(f"the grid needs a finite origin and a finite, non-zero spacing; got origin "
                             f"{tuple(origin.tolist())}, spacing {tuple(spacing.tolist())}")
        field = self._current_field()
        domain = getattr(getattr(field, "tree", None), "domain", None)
        if domain is not None:
            _check_overlap(inp.GetBounds(), domain, self.get_option("tree_file"))
        out.ShallowCopy(inp)
        store_sample(field, inp, out, self.get_option("association"))


def _check_overlap(bounds, domain, path: str) -> None:
    """``ValueError`` if the grid ``bounds`` lie wholly outside the ``domain`` the tree file ``path`` was built for;
    a warning if partly outside (the tree's planes go on beyond its volume, where they mean nothing)."""
    lo, hi = np.asarray(bounds[::2]), np.asarray(bounds[1::2])
    dlo, dhi = np.asarray(domain[::2]), np.asarray(domain[1::2])
    slack = 1e-9 * max(float(np.max(dhi - dlo)), float(np.max(np.abs(domain))), 1e-300)
    shown = ", ".join(f"{a:g}..{b:g}" for a, b in zip(domain[::2], domain[1::2]))
    if np.any(lo > dhi + slack) or np.any(hi < dlo - slack):
        raise ValueError(f"the grid (x, y, z: {', '.join(f'{a:g}..{b:g}' for a, b in zip(lo, hi))}) lies wholly "
                         f"outside the volume the tree {path} was built for ({shown}); every sample would be "
                         "made up")
    if np.any(lo < dlo - slack) or np.any(hi > dhi + slack):
        warnings.warn(f"part of the grid lies outside the volume the tree {path} was built for ({shown}); "
                      "the materials there are the tree's extrapolation", UserWarning, stacklevel=2)
