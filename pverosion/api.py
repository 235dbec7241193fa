"""Functional front end: ``pverosion.<stage>(mesh, ...)``, one call per filter class."""

from __future__ import annotations

import numpy as np
import pyvista as pv

from pverosion._frontend import apply_filter
from pverosion.filters.curvature import Curvature
from pverosion.filters.materials import MaterialSampler
from pverosion.filters.voxel import VoxelErosion
from pverosion.filters.weathering import Weathering
from pverosion.kernels.bsp import BSPTree
from pverosion.kernels.materials import (
    BSPMaterials,
    Gradual,
    MaterialField,
    bsp_from_volume,
)
from pverosion.kernels.weathering import Erodibility

__all__ = ["curvature", "materials_from_volume", "sample_materials", "voxel_erosion", "weather"]


def curvature(mesh: pv.PolyData, *, orientation: str = "outward", normalization: str = "none") -> pv.PolyData:
    """Per-vertex curvature of a triangle surface (Rusinkiewicz 2004).

    Parameters
    ----------
    mesh : pyvista.PolyData
        Triangle surface; open meshes, holes and non-manifold spots are fine.
        It is not modified.
    orientation : {"outward", "inward", "keep"}, default: "outward"
        ``"outward"`` first makes faces consistent and outward, so convex
        regions get H > 0 whatever the file's winding. ``"keep"`` trusts the
        input's winding.
    normalization : {"none", "symmetric", "shifted"}, default: "none"
        Adds ``mean_curvature_normalized``: ``"symmetric"`` scales <-H, H> to
        <-1, 1> (weathering), ``"shifted"`` maps <Hmin, Hmax> to <0, 1>
        (hydraulic erosion).

    Returns
    -------
    pyvista.PolyData
        A copy with point arrays ``mean_curvature``, ``gaussian_curvature``,
        ``k1``, ``k2``, ``principal_direction_1``, ``principal_direction_2``,
        ``normals`` (and ``mean_curvature_normalized``), and field data
        ``face_orientation`` and ``flipped_faces``.

    Raises
    ------
    pverosion.InvalidMeshError
        Empty mesh, NaN points, or polygons that are not triangles.

    Examples
    --------
    >>> import pyvista as pv, pverosion
    >>> sphere = pv.Icosphere(radius=2.0, nsub=4)
    >>> out = pverosion.curvature(sphere)
    >>> round(float(out["mean_curvature"].mean()), 3)
    0.5
    """
    return apply_filter(Curvature, mesh, orientation=orientation, normalization=normalization)


def weather(
    mesh: pv.PolyData,
    *,
    iterations: int = 100,
    power: float = 1.0,
    step_divisor: float = 10.0,
    direction: str = "laplacian",
    erodibility: Erodibility | str = None,
    min_edge_ratio: float = 0.1,
    check_every: int = 10,
    orientation: str = "outward",
) -> pv.PolyData:
    """Curvature-driven weathering (Skorkovská et al. 2019, §3.3).

    Every step moves each convex vertex (H > 0) by ``H^n * e_avg / x`` along
    the unit uniform Laplacian, collapses triangles with edges shorter than
    ``min_edge_ratio * e_avg``, and every ``check_every`` steps rolls back and
    shortens the steps where the surface has started to self-intersect.

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed or open triangle surface; it is not modified.
    iterations : int, default: 100
        Number of steps.
    power : float, default: 1.0
        Power modifier n >= 1 (eq. 5); larger values erode protrusions and
        spare flatter regions.
    step_divisor : float, default: 10.0
        x of eq. 3: the largest displacement per step is ``e_avg / x``.
    direction : {"laplacian", "normal"}, default: "laplacian"
        Unit uniform Laplacian, or the inward vertex normal.
    erodibility : array of shape (V,), callable, str or None
        Non-negative speed multiplier: per-vertex values, a function of the
        current points (N, 3) -> (N,), or the name of a point array of ``mesh``.
    min_edge_ratio : float, default: 0.1
        Edge-collapse threshold relative to e_avg; 0 switches improvement off.
    check_every : int, default: 10
        Self-intersection guard period; 0 switches the guard off.
    orientation : {"outward", "inward", "keep"}, default: "outward"

    Returns
    -------
    pyvista.PolyData
        The weathered surface with point arrays ``mean_curvature``,
        ``displacement``, ``erosion_depth`` (and the input's point arrays,
        carried to the surviving vertices), and per-step statistics in field
        data (``weathering_volume``, ``weathering_eroded_volume``, ...).

    Examples
    --------
    >>> import pverosion
    >>> from pverosion.examples import load_cube
    >>> out = pverosion.weather(load_cube(resolution=6), iterations=20)
    >>> bool(out.field_data["weathering_volume"][-1] < 8.0)
    True
    """
    options = {"iterations": iterations, "power": power, "step_divisor": step_divisor, "direction": direction,
               "min_edge_ratio": min_edge_ratio, "check_every": check_every, "orientation": orientation}
    if isinstance(erodibility, str):
        return apply_filter(Weathering, mesh, erodibility_array=erodibility, **options)
    return apply_filter(Weathering, mesh, erodibility=erodibility, **options)


def materials_from_volume(
    volume,
    thresholds,
    *,
    array: str | None = None,
    method: str = "complete",
    seed: int = 0,
    hardness=None,
    gradual_scale: float = 0.0,
) -> BSPMaterials:
    """A BSP material field built from volume data (thesis §11.5).

    Parameters
    ----------
    volume : pyvista.ImageData or numpy.ndarray of shape (nx, ny, nz)
        The scalar volume (an image's ``array`` or active scalars).
    thresholds : sequence of float
        Material boundaries; material k is where the value exceeds k of them.
    array : str, optional
        Point array of an image volume.
    method : {"complete", "simplified"}, default: "complete"
        C-BSP (exact partition by clipping) or S-BSP (faster, coarser).
    seed : int, default: 0
        Face insertion order; the same seed gives the same tree.
    hardness : sequence of float, optional
        Hardness of materials 0..m; default 1, 2, ..., m + 1.
    gradual_scale : float, default: 0
        When > 0, materials soften away from the boundaries over this distance.

    Returns
    -------
    BSPMaterials
        ``.sample(points)``, ``.erodibility(points)``, ``.tree`` (save with
        ``.tree.to_json(path)``) and ``.stats``.

    Examples
    --------
    >>> import numpy as np, pverosion
    >>> x, y, z = np.mgrid[-1:1:24j, -1:1:24j, -1:1:24j]
    >>> field = pverosion.materials_from_volume(-np.sqrt(x**2 + y**2 + z**2), [-0.5])
    >>> field.sample([[11.5, 11.5, 11.5], [0.0, 0.0, 0.0]]).material_id.tolist()
    [1, 0]
    """
    if isinstance(volume, pv.ImageData):
        name = array or volume.active_scalars_name
        if name is None or name not in volume.point_data:
            raise ValueError(f"image has no point array {array!r}" if array else "image has no active scalars")
        nx, ny, nz = volume.dimensions
        values = np.asarray(volume.point_data[name]).reshape(nz, ny, nx).transpose(2, 1, 0)
        origin, spacing = volume.origin, volume.spacing
    else:
        values, origin, spacing = np.asarray(volume), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
    return bsp_from_volume(values, thresholds, origin=origin, spacing=spacing, method=method, seed=seed,
                           hardness=hardness, gradual=Gradual(gradual_scale) if gradual_scale > 0 else None)


def sample_materials(
    field: MaterialField | str,
    *,
    dimensions=(64, 64, 64),
    bounds=(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0),
    association: str = "point",
) -> pv.ImageData:
    """Sample a material field on a regular grid, for slices (Figures 11.11–11.13, 11.18).

    Parameters
    ----------
    field : MaterialField or str
        A field, or the path of a BSP tree JSON file.
    dimensions : tuple of int, default: (64, 64, 64)
        Grid points along x, y, z.
    bounds : tuple of float, default: (-1, 1, -1, 1, -1, 1)
        xmin, xmax, ymin, ymax, zmin, zmax.
    association : {"point", "cell"}, default: "point"
        Sample at the points or at the cell centres.

    Returns
    -------
    pyvista.ImageData
        With ``material_id`` and ``hardness`` arrays.
    """
    dims = np.asarray(dimensions, dtype=int)
    box = np.asarray(bounds, dtype=float)
    if dims.shape != (3,) or np.any(dims < 1):
        raise ValueError(f"dimensions must be 3 positive integers; got {dimensions!r}")
    if box.shape != (6,) or np.any(box[1::2] < box[::2]):
        raise ValueError(f"bounds must be (xmin, xmax, ymin, ymax, zmin, zmax) with min <= max; got {bounds!r}")
    spacing = np.where(dims > 1, (box[1::2] - box[::2]) / np.maximum(dims - 1, 1), 1.0)
    grid = pv.ImageData(dimensions=dims.tolist(), origin=box[::2].tolist(), spacing=spacing.tolist())
    if isinstance(field, str):
        tree = BSPTree.from_json(field)
        field = BSPMaterials(tree, np.arange(1.0, tree.leaf.max() + 2.0))
    return pv.wrap(MaterialSampler(field=field, association=association).run(grid))


def voxel_erosion(grid: pv.ImageData, *, iterations: int = 100, time_step: float = 0.01, model: str = "cohesive",
                  source_velocity=(0.0, 0.0, 0.0), **options) -> pv.MultiBlock:
    """Voxel hydraulic erosion (Beneš et al. 2006) of a voxel grid.

    Parameters
    ----------
    grid : pyvista.ImageData
        A voxel grid (``material_amount``, optional ``water``, ``source``,
        ``drain``, ``hardness``, ``material_id`` point arrays); build one with
        :func:`pverosion.filters.voxel.voxel_grid_from_mesh`,
        ``voxel_grid_from_height_field`` or ``voxel_grid_from_volume``. Not modified.
    iterations : int, default: 100
        Time steps.
    time_step : float, default: 0.01
        Seconds per step.
    model : {"cohesive", "cohesionless"}, default: "cohesive"
    source_velocity : (3,) float, default: (0, 0, 0)
        Velocity of the water entering at source voxels (m/s).
    **options
        Other options of :class:`pverosion.filters.VoxelErosion` (``friction``,
        ``erosion_rate``, ``tau_erosion``, ``saturation``, ``viscosity``, ``advection``,
        ``extraction``, ...).

    Returns
    -------
    pyvista.MultiBlock
        ``state`` (the grid with ``voxel_class``, ``material_amount``,
        ``water``, ``dissolved``, ``velocity``, ``pressure`` and per-step
        statistics) and ``surface`` (the material's closed isosurface with
        ``material_id``).
    """
    velocity = ",".join(repr(float(v)) for v in np.asarray(source_velocity, dtype=float).reshape(3))
    return apply_filter(VoxelErosion, grid, iterations=iterations, time_step=time_step, model=model,
                        source_velocity=velocity, **options)

