"""Functional front end: ``pverosion.<stage>(mesh, ...)``, one call per filter class.

Every function takes all options of its filter as keyword-only arguments with
the filter's defaults (vectors as tuples, unset vectors and structures as
None); the option descriptions in the docstrings are generated from the
filter's :class:`~pverosion.filters.base.Param` metadata (see
:mod:`pverosion._frontend`), and ``progress_bar=True`` shows a tqdm bar.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Sequence

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonDataModel import vtkPolyData

from pverosion._frontend import apply_filter, renamed, run_filter, stage_function
from pverosion.filters.curvature import Curvature
from pverosion.filters.hydraulic import HydraulicErosion
from pverosion.filters.materials import (
    MaterialSampler,
    MaterialsFromVolume,
    check_tree_memory,
    surface_option,
    volume_values,
)
from pverosion.filters.repair import BooleanOperation, RepairIntersections
from pverosion.filters.shards import FreezeThaw, ShardGraph
from pverosion.filters.voxel import VoxelErosion
from pverosion.filters.weathering import Weathering
from pverosion.kernels.fluid.particle_fluid import Drain, Emitter
from pverosion.kernels.materials.erodibility import Erodibility
from pverosion.kernels.materials.field import (
    BSPMaterials,
    Gradual,
    MaterialField,
    bsp_from_volume,
)
from pverosion.kernels.repair.mesh_repair import DEFAULT_TOLERANCE
from pverosion.limits import check_memory

__all__ = ["boolean", "curvature", "freeze_thaw", "hydraulic_erosion", "materials_from_volume", "repair",
           "sample_materials", "shard_graph", "voxel_erosion", "weather"]


@stage_function(Curvature)
def curvature(mesh: pv.PolyData, *, orientation: str = "outward", normalization: str = "none",
              progress_bar: bool = False) -> pv.PolyData:
    """Per-vertex curvature of a triangle surface (Rusinkiewicz 2004).

    Parameters
    ----------
    mesh : pyvista.PolyData
        Triangle surface; open meshes, holes and non-manifold spots are fine.
        It is not modified.
    {options}

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
    return apply_filter(Curvature, mesh, orientation=orientation, normalization=normalization,
                        progress_bar=progress_bar)


_ERODIBILITY = ("array of shape (V,), callable or None",
                ("Non-negative speed multiplier set from Python: per-vertex values, or a function of the current "
                "points (N, 3) -> (N,). A string names a point array (as ``erodibility_array``)."))


@stage_function(Weathering, python_only={"erodibility": _ERODIBILITY})
def weather(
    mesh: pv.PolyData,
    *,
    iterations: int = 100,
    power: float = 1.0,
    step_divisor: float = 10.0,
    normalization: str = "scale_free",
    direction: str = "laplacian",
    min_edge_ratio: float = 0.1,
    check_every: int = 10,
    repair: str = "retry",
    erodibility_array: str = "",
    orientation: str = "outward",
    erodibility: Erodibility | str = None,
    progress_bar: bool = False,
) -> pv.PolyData:
    """Curvature-driven weathering (Skorkovská et al. 2019, §3.3).

    Every step moves each convex vertex (H > 0) by ``H^n * e_avg / x`` along
    the unit uniform Laplacian, collapses triangles with edges shorter than
    ``min_edge_ratio * e_avg``, and every ``check_every`` steps rolls back and
    shortens the steps where the surface has started to self-intersect
    (normalisation: see docs/topics/invariance-erosion.md).

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed or open triangle surface; it is not modified.
    {options}

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
    if isinstance(erodibility, str):
        erodibility_array, erodibility = erodibility, None
    return apply_filter(Weathering, mesh, iterations=iterations, power=power, step_divisor=step_divisor,
                        normalization=normalization, direction=direction, min_edge_ratio=min_edge_ratio,
                        check_every=check_every, repair=repair, erodibility_array=erodibility_array,
                        orientation=orientation, erodibility=erodibility, progress_bar=progress_bar)


@stage_function(MaterialsFromVolume, omitted=("tree_file",), positional=("thresholds",))
def materials_from_volume(
    volume,
    thresholds: Sequence[float] | str,
    *,
    array: str = "",
    method: str = "complete",
    surface: str = "default",
    seed: int = 0,
    hardness: Sequence[float] | str | None = None,
    gradual_scale: float = 0.0,
) -> BSPMaterials:
    """A BSP material field built from volume data (thesis §11.5).

    The filter's ``tree_file`` option is left out: save the tree with
    ``.tree.to_json(path)``. The field is built directly (no VTK pipeline
    runs), so there is no ``progress_bar``.

    Parameters
    ----------
    volume : pyvista.ImageData or numpy.ndarray of shape (nx, ny, nz)
        The scalar volume (an image's ``array`` or active scalars).
    {options}

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
    params = {p.name: p for p in MaterialsFromVolume.PARAMS}
    for name, value in (("array", array), ("method", method), ("seed", seed), ("gradual_scale", gradual_scale)):
        params[name].validate(value)
    if isinstance(thresholds, str):
        thresholds = [float(v) for v in params["thresholds"].validate(thresholds).split(",")]
    if isinstance(hardness, str):
        hardness = [float(v) for v in params["hardness"].validate(hardness).split(",")] if hardness else None
    if isinstance(volume, pv.ImageData):
        values = volume_values(volume, array)
        origin, spacing = volume.origin, volume.spacing
    else:
        values, origin, spacing = np.asarray(volume), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
    return bsp_from_volume(values, thresholds, origin=origin, spacing=spacing, method=method,
                           surface=surface_option(surface), seed=seed, hardness=hardness,
                           gradual=Gradual(gradual_scale) if gradual_scale > 0 else None,
                           memory_check=check_tree_memory)


_GRID = {"dimensions": ("tuple of int, default: (64, 64, 64)", "Grid points along x, y, z."),
         "bounds": ("tuple of float, default: (-1, 1, -1, 1, -1, 1)", "xmin, xmax, ymin, ymax, zmin, zmax.")}


SAMPLE_BYTES_PER_POINT = 96
"""Estimated memory per sampled grid point (coordinates, the tree's work arrays, the two output arrays)."""


@stage_function(MaterialSampler, python_only=_GRID, omitted=("tree_file",))
def sample_materials(
    field: MaterialField | str,
    *,
    dimensions=(64, 64, 64),
    bounds=(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0),
    association: str = "point",
    hardness: Sequence[float] | str | None = None,
    progress_bar: bool = False,
) -> pv.ImageData:
    """Sample a material field on a regular grid, for slices (Figures 11.11–11.13, 11.18).

    Parameters
    ----------
    field : MaterialField or str
        A field, or the path of a BSP tree JSON file (the filter's ``tree_file``).
    {options}

    Returns
    -------
    pyvista.ImageData
        With ``material_id`` and ``hardness`` arrays.
    """
    given = list(dimensions) if isinstance(dimensions, Sequence | np.ndarray) else [dimensions]
    if len(given) != 3 or not all(isinstance(n, int | np.integer) and not isinstance(n, bool) and n >= 1
                                  for n in given):
        raise ValueError(f"dimensions must be 3 positive integers; got {dimensions!r}")
    dims = np.array([int(n) for n in given], dtype=object)
    box = np.asarray(bounds, dtype=float)
    if box.shape != (6,) or not np.all(np.isfinite(box)) or np.any(box[1::2] < box[::2]):
        raise ValueError(f"bounds must be finite (xmin, xmax, ymin, ymax, zmin, zmax) with min <= max; got {bounds!r}")
    check_memory(float(np.prod(dims)) * SAMPLE_BYTES_PER_POINT, option="dimensions",
                 what=f"sampling {' x '.join(map(str, dims))} points")
    dims = dims.astype(np.int64)
    spacing = np.where(dims > 1, (box[1::2] - box[::2]) / np.maximum(dims - 1, 1), 1.0)
    grid = pv.ImageData(dimensions=dims.tolist(), origin=box[::2].tolist(), spacing=spacing.tolist())
    if isinstance(field, str):
        alg = MaterialSampler(tree_file=field, hardness=hardness, association=association)
    else:
        alg = MaterialSampler(field=field, hardness=hardness, association=association)
    return run_filter(alg, grid, progress_bar=progress_bar)


@stage_function(VoxelErosion)
def voxel_erosion(
    grid: pv.ImageData,
    *,
    iterations: int = 100,
    time_step: float = 0.01,
    model: str = "cohesive",
    friction: float = 0.05,
    erosion_rate: float = 0.01,
    deposition_rate: float = 0.01,
    fall_velocity: float = 0.2,
    tau_erosion: float = 10.0,
    tau_deposition: float = 10.0,
    capacity: float = 0.7,
    saturation: float = 0.5,
    time_scale: float = 1.0,
    viscosity: float = 1e-06,
    advection: str = "semi-lagrangian",
    source_velocity: Sequence[float] | str = (0.0, 0.0, 0.0),
    tolerance: float = 1e-06,
    extraction: str = "flying_edges",
    progress_bar: bool = False,
) -> pv.MultiBlock:
    """Voxel hydraulic erosion (Beneš et al. 2006) of a voxel grid.

    Parameters
    ----------
    grid : pyvista.ImageData
        A voxel grid (``material_amount``, optional ``water``, ``source``,
        ``drain``, ``hardness``, ``material_id`` point arrays); build one with
        :func:`pverosion.filters.voxel.voxel_grid_from_mesh`,
        ``voxel_grid_from_height_field`` or ``voxel_grid_from_volume``. Not modified.
    {options}

    Returns
    -------
    pyvista.MultiBlock
        ``state`` (the grid with ``voxel_class``, ``material_amount``,
        ``water``, ``dissolved``, ``velocity``, ``pressure`` and per-step
        statistics) and ``surface`` (the material's closed isosurface with
        ``material_id``).
    """
    return apply_filter(
        VoxelErosion, grid, iterations=iterations, time_step=time_step, model=model, friction=friction,
        erosion_rate=erosion_rate, deposition_rate=deposition_rate, fall_velocity=fall_velocity,
        tau_erosion=tau_erosion, tau_deposition=tau_deposition, capacity=capacity, saturation=saturation,
        time_scale=time_scale, viscosity=viscosity, advection=advection, source_velocity=source_velocity,
        tolerance=tolerance, extraction=extraction, progress_bar=progress_bar)


@stage_function(ShardGraph)
def shard_graph(
    mesh: pv.PolyData,
    *,
    cells: int = 1000,
    pattern: str = "uniform",
    jitter: float = 0.2,
    layers: Sequence[float] | str | None = None,
    tilt: float = 0.0,
    radius_gradient: Sequence[float] | str = (0.0, 0.0, 0.0),
    seed: int = 0,
    progress_bar: bool = False,
) -> pv.MultiBlock:
    """Fracture a closed mesh into Voronoi shards clipped exactly to it (Mateos et al. §4).

    Parameters
    ----------
    mesh : pyvista.PolyData
        A closed triangle mesh, convex or not. Not modified.
    {options}

    Returns
    -------
    pyvista.MultiBlock
        ``surface``, ``shards`` and ``links`` (see :mod:`pverosion.filters.shards`).
    """
    return apply_filter(ShardGraph, mesh, cells=cells, pattern=pattern, jitter=jitter, layers=layers, tilt=tilt,
                        radius_gradient=radius_gradient, seed=seed, progress_bar=progress_bar)


_RESISTANCE = ("float, callable or pyvista.ImageData, default: 0.0",
               ("Resistance field rho in [0, 1]: a constant (the filter's ``resistance``), a function of points "
               "(n, 3) -> (n,), or a 3-D image whose active scalars are sampled at the link centroids."))
_CORE = ('{"none", "surface"} or callable, default: "none"',
         ("Cells never removed: a mode of the filter's ``core`` option, or a function of the cells' seed points "
         "(n, 3) -> (n,) bool."))


def _paths_to_steps(function):
    """Accept the deprecated ``paths=N`` of :func:`freeze_thaw`: one time step of N paths."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        if "paths" in kwargs:
            paths = kwargs.pop("paths")
            warnings.warn("freeze_thaw: paths=N is deprecated; use iterations= and paths_per_step=",
                          DeprecationWarning, stacklevel=2)
            if isinstance(paths, bool) or not isinstance(paths, (int, np.integer)) or paths < 0:
                raise ValueError(f"paths must be a non-negative integer; got {paths!r}")
            kwargs.update(iterations=1 if paths else 0, paths_per_step=max(int(paths), 1))
        return function(*args, **kwargs)

    return wrapper


@_paths_to_steps
@stage_function(FreezeThaw, python_only={"resistance": _RESISTANCE, "core": _CORE})
def freeze_thaw(
    mesh: pv.PolyData,
    *,
    iterations: int = 10,
    paths_per_step: int = 100,
    cells: int = 1000,
    pattern: str = "uniform",
    jitter: float = 0.2,
    layers: Sequence[float] | str | None = None,
    tilt: float = 0.0,
    radius_gradient: Sequence[float] | str = (0.0, 0.0, 0.0),
    seed: int = 0,
    core="none",
    core_plane: Sequence[float] | str | None = None,
    core_window: Sequence[float] | str | None = None,
    water_direction: Sequence[float] | str = (0.0, 0.0, -1.0),
    spread: float = 0.0,
    gravity: Sequence[float] | str = (0.0, 0.0, -1.0),
    resistance=0.0,
    water: float = 1.0,
    k_solid: float = 0.1,
    k_air: float = 0.05,
    k_res: float = 0.25,
    k_dmg: float = 0.5,
    k_break: float = 0.4,
    break_probability: float = 0.9,
    complete_absorption: float = 1.0,
    shards: bool = True,
    record_paths: bool = True,
    progress_bar: bool = False,
) -> pv.MultiBlock:
    """Freeze–thaw weathering of a closed mesh on Voronoi shards (Mateos et al. §5).

    The mesh is fractured as by :func:`shard_graph`; then each of the
    ``iterations`` time steps runs ``paths_per_step`` water paths.
    ``paths=N`` (deprecated) runs one step of N paths.

    Parameters
    ----------
    mesh : pyvista.PolyData
        A closed triangle mesh, convex or not. Not modified.
    {options}

    Returns
    -------
    pyvista.MultiBlock
        ``surface``, ``shards``, ``links`` and ``paths`` (those of the last time step) after the run.
    """
    options = {"iterations": iterations, "paths_per_step": paths_per_step, "cells": cells, "pattern": pattern,
               "jitter": jitter, "layers": layers, "tilt": tilt, "radius_gradient": radius_gradient, "seed": seed,
               "core_plane": core_plane, "core_window": core_window, "water_direction": water_direction,
               "spread": spread, "gravity": gravity, "water": water, "k_solid": k_solid, "k_air": k_air,
               "k_res": k_res, "k_dmg": k_dmg, "k_break": k_break, "break_probability": break_probability,
               "complete_absorption": complete_absorption, "shards": shards, "record_paths": record_paths}
    alg = FreezeThaw(**options)
    if callable(core):
        alg.SetCoreCells(core)
    else:
        alg.set_option("core", core)
    if isinstance(resistance, pv.ImageData) or callable(resistance):
        alg.SetResistanceField(resistance)
    else:
        alg.set_option("resistance", resistance)
    if not isinstance(mesh, pv.PolyData):
        raise TypeError(f"freeze_thaw needs a PolyData surface; got {type(mesh).__name__}")
    return run_filter(alg, mesh, progress_bar=progress_bar)


@stage_function(RepairIntersections)
def repair(mesh: pv.PolyData, *, orientation: str = "outward", tolerance: float = DEFAULT_TOLERANCE,
           improve: bool = False, progress_bar: bool = False) -> pv.PolyData:
    """Remove the self-intersections of a closed triangle mesh (Skorkovská's thesis §10.2).

    The intersection curves are found with exact predicates and the faces
    cut along them; the result is the boundary of the region where the
    input's winding number is at least 1. Parts that ended up inside the
    solid or turned inside out are cut away, overlapping closed parts merge,
    and the result may consist of several closed pieces.

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed triangle mesh. It is not modified.
    {options}

    Returns
    -------
    pyvista.PolyData
        Closed, intersection-free triangle mesh with point data
        ``on_intersection`` (1 on the intersection curves), cell data
        ``source_face`` (the input face each face is a piece of) and the
        input's cell arrays, and field data ``intersection_cases`` (counts of
        the thesis' cases, named by ``intersection_case_names``),
        ``intersection_valid_cases``, ``intersection_impossible_cases``,
        ``intersection_segments``, ``intersection_loops``,
        ``intersection_touching`` and ``intersection_coplanar``.

    Raises
    ------
    pverosion.InvalidMeshError
        Empty or open mesh, non-triangles, or (``orientation="keep"``) faces
        pointing inward.
    pverosion.RepairError
        If the result could not be made a closed, oriented 2-manifold without
        self-intersections (nothing broken is returned).

    Examples
    --------
    Two overlapping spheres in one mesh merge into one closed surface:

    >>> import pyvista as pv, pverosion
    >>> two = pv.Icosphere(radius=1.0, nsub=3) + pv.Icosphere(radius=1.0, nsub=3, center=(1.0, 0.0, 0.0))
    >>> out = pverosion.repair(two)
    >>> out.n_open_edges, int(out.field_data["intersection_loops"][0])
    (0, 1)
    >>> bool(out.volume < two.volume)
    True
    """
    return apply_filter(RepairIntersections, mesh, orientation=orientation, tolerance=tolerance, improve=improve,
                        progress_bar=progress_bar)


@stage_function(BooleanOperation, inputs=2, positional=("operation",))
def boolean(a: pv.PolyData, b: pv.PolyData, operation: str = "union", *, orientation: str = "outward",
            tolerance: float = DEFAULT_TOLERANCE, improve: bool = False, progress_bar: bool = False) -> pv.PolyData:
    """Union, intersection or difference of two closed triangle meshes (Skorkovská's thesis §10.3).

    Parameters
    ----------
    a : pyvista.PolyData
        Closed triangle mesh A. It is not modified. An input that intersects
        itself stands for the region where its winding number is at least 1,
        as :func:`repair` would make it.
    b : pyvista.PolyData
        Closed triangle mesh B, likewise.
    {options}

    Returns
    -------
    pyvista.PolyData
        Closed triangle mesh with point data ``on_intersection`` (1 on the
        intersection curves), cell data ``source_mesh`` (0 for faces from
        ``a``, 1 from ``b``), ``source_face`` (the face of that input each face
        is a piece of) and the cell arrays both inputs have, and the
        field data of :func:`repair`. Empty when nothing is left (the
        intersection of disjoint meshes).

    Raises
    ------
    ValueError
        For an unknown operation.
    TypeError
        If ``a`` or ``b`` is not a PolyData surface.
    pverosion.InvalidMeshError
        Empty or open input, non-triangles, or faces pointing inward; the
        message names the input (mesh A or mesh B).

    Examples
    --------
    >>> import pyvista as pv, pverosion
    >>> box = pv.Box(bounds=(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0)).triangulate()
    >>> ball = pv.Icosphere(radius=1.2, nsub=3)
    >>> out = pverosion.boolean(box, ball, "difference")
    >>> out.n_open_edges, sorted(set(out["source_mesh"].tolist()))
    (0, [0, 1])
    >>> bool(0.0 < out.volume < box.volume)
    True
    """
    for name, mesh in (("a", a), ("b", b)):
        if not isinstance(mesh, vtkPolyData):
            hint = " (call .extract_surface() first)" if isinstance(mesh, pv.DataSet) else ""
            raise TypeError(f"boolean needs PolyData surfaces{hint}; {name} is {type(mesh).__name__}")
    alg = BooleanOperation(operation=operation, orientation=orientation, tolerance=tolerance, improve=improve)
    return run_filter(alg, a, b, progress_bar=progress_bar)


_HYDRAULIC_ERODIBILITY = ("array of shape (V,), callable or None",
                          ("Erosion multiplier set from Python: per-vertex values or a function of points. A string "
                          "names a point array (as ``erodibility_array``)."))


@renamed(emitters="emitter", drains="drain")
@stage_function(HydraulicErosion, python_only={"erodibility": _HYDRAULIC_ERODIBILITY})
def hydraulic_erosion(
    mesh: pv.PolyData,
    *,
    iterations: int = 100,
    model: str = "curvature",
    emitter: Emitter | str | Sequence | None = None,
    drain: Drain | str | Sequence | None = None,
    domain: Sequence[float] | str | None = None,
    walls: bool = False,
    radius: float = 0.0,
    gravity: Sequence[float] | str = (0.0, 0.0, -9.81),
    time_step: float = 0.0,
    substeps: int = 2,
    solver_iterations: int = 3,
    viscosity: float = 0.01,
    friction: float = 0.0,
    max_particles: int = 250000,
    power: float = 1.0,
    step_divisor: float = 10.0,
    normalization: str = "scale_free",
    influence: float = 1.0,
    erosion_rate: float = 0.001,
    critical_stress: float = 5.0,
    stress_constant: float = 1.0,
    stress_power: float = 1.0,
    rate_power: float = 1.0,
    erodibility_array: str = "",
    min_edge_ratio: float = 0.1,
    check_every: int = 10,
    repair: str = "retry",
    orientation: str = "outward",
    seed: int = 0,
    close_holes: bool = False,
    erodibility: Erodibility | str = None,
    progress_bar: bool = False,
) -> pv.MultiBlock:
    """Hydraulic erosion of a closed mesh by a particle fluid (Skorkovská 2019 §3.4; thesis ch. 8).

    ``emitter`` (at least one) is required. Emitters and drains given as
    :class:`~pverosion.kernels.fluid.particle_fluid.Emitter` /
    :class:`~pverosion.kernels.fluid.particle_fluid.Drain` objects reach the
    solver as they are. ``emitters=`` and ``drains=`` are deprecated names
    of ``emitter=`` and ``drain=``.

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed triangle surface (terrain block or model); the water flows on
        its outside. It is not modified.
    {options}

    Returns
    -------
    pyvista.MultiBlock
        ``mesh`` (eroded surface with ``erosion_depth``, ``f_distance``,
        statistics ``hydraulic_*`` in field data) and ``particles`` (positions,
        ``velocity``, ``speed``, ``sediment``).
    """
    if isinstance(erodibility, str):
        erodibility_array, erodibility = erodibility, None
    if radius is None:  # the default before radius=0.0 meant "automatic" too
        radius = 0.0
    return apply_filter(
        HydraulicErosion, mesh, iterations=iterations, model=model, emitter=emitter, drain=drain, domain=domain,
        walls=walls, radius=radius, gravity=gravity, time_step=time_step, substeps=substeps,
        solver_iterations=solver_iterations, viscosity=viscosity, friction=friction, max_particles=max_particles,
        power=power, step_divisor=step_divisor, normalization=normalization, influence=influence,
        erosion_rate=erosion_rate, critical_stress=critical_stress, stress_constant=stress_constant,
        stress_power=stress_power, rate_power=rate_power, erodibility_array=erodibility_array,
        min_edge_ratio=min_edge_ratio, check_every=check_every, repair=repair, orientation=orientation, seed=seed,
        close_holes=close_holes, erodibility=erodibility, progress_bar=progress_bar)
