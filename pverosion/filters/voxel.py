"""Voxel hydraulic erosion on ImageData: grid builders, surface extraction and the VoxelErosion filter.

A voxel grid is a vtkImageData whose points are the voxel centres, with
point arrays (x fastest):

- ``material_amount`` (required): material per voxel in [0, 1]; MAT voxels are > 0;
- ``water``: water fraction in [0, 1] (default 0);
- ``source``, ``drain``: inflow and outflow voxels (non-zero = yes);
- ``hardness`` (erodibility is 1 / hardness, default 1) and ``material_id``, from a material field.

The filter adds ``voxel_class`` (0 EMPTY, 1 FULL, 2 MAT), ``dissolved``,
``velocity`` (at the centres) and ``pressure``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pyvista as pv
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkImageData

from pverosion.filters.base import (
    Param,
    TimeSteppedFilter,
    check_axis_aligned,
    parse_numbers,
    polydata_triangles,
    set_field_value,
    set_multiblock,
)
from pverosion.filters.materials import grid_points, volume_values
from pverosion.kernels.materials.field import MaterialField
from pverosion.kernels.voxel.erosion import MODELS, ErosionParameters, VoxelErosionSolver
from pverosion.kernels.voxel.fluid import ADVECTION_SCHEMES, VoxelFluid, cell_velocity
from pverosion.kernels.voxel.isosurface import marching_cubes
from pverosion.kernels.voxel.pressure import LIQUID
from pverosion.kernels.voxel.voxelize import height_field_amount, voxelize_mesh
from pverosion.limits import check_memory, check_work

__all__ = [
    "EXTRACTORS",
    "VoxelErosion",
    "extract_material_surface",
    "voxel_grid",
    "voxel_grid_from_height_field",
    "voxel_grid_from_mesh",
    "voxel_grid_from_volume",
    "voxel_solver",
]

EXTRACTORS = ("flying_edges", "marching_cubes")
EMPTY, FULL, MAT = 0, 1, 2


def _grid_array(image, name: str, *, required: bool = False, default: float = 0.0) -> np.ndarray:
    """Point array ``name`` of an image as an (nx, ny, nz) float array."""
    dims = image.GetDimensions()
    arr = image.GetPointData().GetArray(name)
    if arr is None:
        if required:
            raise ValueError(f"the voxel grid needs a point array {name!r} (material per voxel in [0, 1]); build "
                             "one with voxel_grid_from_volume (a scan), voxel_grid_from_height_field (a DEM) or "
                             "voxel_grid_from_mesh in pverosion.filters.voxel")
        return np.full(dims, default)
    values = numpy_support.vtk_to_numpy(arr)
    if values.ndim != 1:
        raise ValueError(f"point array {name!r} must have one component; got {values.shape[1]}")
    return values.astype(np.float64).reshape(dims, order="F")


BUILD_BYTES_PER_VOXEL = 48
"""Estimated memory per voxel while a grid is built (the amount, water and work arrays in float64)."""


def _check_spacing(spacing) -> float:
    """``spacing`` as a float, or ``ValueError`` unless it is a finite number > 0."""
    if isinstance(spacing, (bool, np.bool_)) or not isinstance(spacing, (int, float, np.integer, np.floating)) \
            or not 0 < spacing < math.inf:
        raise ValueError(f"spacing must be a finite number > 0; got {spacing!r}")
    return float(spacing)


def _check_grid_size(extent, spacing: float, *, option: str = "spacing") -> tuple[int, ...]:
    """Voxels per axis covering ``extent`` (lengths) at ``spacing``, refused before allocation if too many."""
    counts = [math.floor(float(e) / spacing + 1e-9) + 1 for e in extent]
    check_memory(math.prod(counts) * BUILD_BYTES_PER_VOXEL, option=option, remedy=f"lower the grid's size ({option})",
                 what=f"a voxel grid of {' x '.join(map(str, counts))} voxels")
    return tuple(counts)


def voxel_grid(
    amount: np.ndarray,
    *,
    origin=(0.0, 0.0, 0.0),
    spacing: float = 1.0,
    water: np.ndarray | None = None,
    source: np.ndarray | None = None,
    drain: np.ndarray | None = None,
    material_field: MaterialField | None = None,
) -> pv.ImageData:
    """Build a voxel grid ImageData from (nx, ny, nz) arrays.

    Parameters
    ----------
    amount : numpy.ndarray, shape (nx, ny, nz)
        Material per voxel in [0, 1].
    origin : (3,) float
        Centre of voxel (0, 0, 0).
    spacing : float
        Voxel edge (cubic voxels).
    water, source, drain : numpy.ndarray, shape (nx, ny, nz), optional
    material_field : MaterialField, optional
        Sampled at the voxel centres into ``material_id`` and ``hardness``.

    Returns
    -------
    pyvista.ImageData
    """
    amount = np.asarray(amount, dtype=np.float64)
    if amount.ndim != 3:
        raise ValueError(f"amount must be a 3-D array (nx, ny, nz); got shape {amount.shape}")
    spacing = _check_spacing(spacing)
    if not np.all(np.isfinite(np.asarray(origin, dtype=np.float64))):
        raise ValueError(f"origin must be finite; got {tuple(origin)!r}")
    image = pv.ImageData(dimensions=amount.shape, spacing=(spacing,) * 3, origin=tuple(origin))
    image.point_data["material_amount"] = amount.ravel(order="F")
    for name, values in (("water", water), ("source", source), ("drain", drain)):
        if values is not None:
            values = np.asarray(values)
            if values.shape != amount.shape:
                raise ValueError(f"{name} has shape {values.shape} but amount has shape {amount.shape}")
            image.point_data[name] = values.astype(np.float64 if name == "water" else np.uint8).ravel(order="F")
    if material_field is not None:
        sample = material_field.sample(grid_points(image, "point"))
        image.point_data["material_id"] = sample.material_id.astype(np.int32)
        image.point_data["hardness"] = sample.hardness
    return image


def voxel_grid_from_mesh(mesh, *, spacing: float, padding: int = 2, water_level: float | None = None,
                         material_field: MaterialField | None = None) -> pv.ImageData:
    """Voxelise a closed surface: voxels whose centre lies inside become material.

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed triangle surface.
    spacing : float
        Voxel edge.
    padding : int, default: 2
        Empty voxel layers around the mesh's bounds.
    water_level : float, optional
        Fill the open voxels whose centre lies below this height with water.
    material_field : MaterialField, optional

    Returns
    -------
    pyvista.ImageData
    """
    spacing = _check_spacing(spacing)
    if isinstance(padding, (bool, np.bool_)) or not isinstance(padding, (int, np.integer)) or padding < 0:
        raise ValueError(f"padding must be an integer >= 0; got {padding!r}")
    points, faces = polydata_triangles(mesh)
    lo = np.array(mesh.GetBounds()[::2]) - padding * spacing
    hi = np.array(mesh.GetBounds()[1::2]) + padding * spacing
    _check_grid_size(hi - lo + spacing, spacing, option="spacing, padding")
    dims = np.maximum(np.ceil((hi - lo) / spacing).astype(int) + 1, 1)
    amount = voxelize_mesh(points, faces, origin=lo, spacing=(spacing,) * 3, dims=dims).astype(np.float64)
    water = None
    if water_level is not None:
        z = lo[2] + spacing * np.arange(dims[2])
        water = np.where((amount == 0) & (z[None, None, :] < water_level), 1.0, 0.0)
    return voxel_grid(amount, origin=lo, spacing=spacing, water=water, material_field=material_field)


def voxel_grid_from_height_field(heights, *, spacing: float, air: float = 0.0, base: float | None = None,
                                 stride: int = 1, material_field: MaterialField | None = None) -> pv.ImageData:
    """A terrain block from a height field (a 2-D ImageData such as ``SainteHelens.dem``, or an array).

    Parameters
    ----------
    heights : pyvista.ImageData or numpy.ndarray, shape (nx, ny)
        Terrain heights; an image uses its active scalars and its x/y spacing.
    spacing : float
        Voxel edge (also the horizontal sample spacing of an array input).
    air : float, default: 0
        Height of open space kept above the highest point.
    base : float, optional
        Bottom of the block (default: one voxel below the lowest point).
    stride : int, default: 1
        Take every ``stride``-th height sample of an image.
    material_field : MaterialField, optional

    Returns
    -------
    pyvista.ImageData
        The surface voxels hold the fraction of their height below the terrain.
    """
    spacing = _check_spacing(spacing)
    if not math.isfinite(air) or air < 0:
        raise ValueError(f"air must be a finite height >= 0; got {air!r}")
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise ValueError(f"stride must be a whole number >= 1 (every stride-th sample); got {stride!r}")
    origin_xy = np.zeros(2)
    if isinstance(heights, vtkImageData):
        check_axis_aligned(heights)
        image = pv.wrap(heights)
        dims = image.dimensions
        if sum(d > 1 for d in dims) != 2 or dims[2] != 1:
            raise ValueError(f"a height-field image must be 2-D in x and y; got dimensions {dims}")
        values = np.asarray(image.active_scalars, dtype=np.float64).reshape(dims[:2], order="F")
        values = values[::stride, ::stride]
        _check_heights(values)
        origin_xy = np.array(image.origin[:2])
        xy_spacing = np.array(image.spacing[:2]) * stride
        _check_grid_size([(n - 1) * h for n, h in zip(values.shape, xy_spacing)]
                         + [np.ptp(values) + air + 2 * spacing], spacing)
        # resample to cubic voxels of the requested edge
        nx = max(round((values.shape[0] - 1) * xy_spacing[0] / spacing) + 1, 1)
        ny = max(round((values.shape[1] - 1) * xy_spacing[1] / spacing) + 1, 1)
        from scipy.ndimage import map_coordinates

        gx = np.linspace(0, values.shape[0] - 1, nx)
        gy = np.linspace(0, values.shape[1] - 1, ny)
        xx, yy = np.meshgrid(gx, gy, indexing="ij")
        values = map_coordinates(values, [xx, yy], order=1)
    else:
        values = np.asarray(heights, dtype=np.float64)
    if values.ndim != 2:
        raise ValueError(f"heights must be 2-D (nx, ny); got shape {values.shape}")
    _check_heights(values)
    bottom = values.min() - spacing if base is None else float(base)
    if not (math.isfinite(bottom) and bottom < values.max() + air):
        raise ValueError(f"base must be finite and below the highest point ({values.max():g}); got {base!r}")
    _check_grid_size([(values.shape[0] - 1) * spacing, (values.shape[1] - 1) * spacing,
                      values.max() + air - bottom + spacing], spacing)
    nz = int(np.ceil((values.max() + air - bottom) / spacing)) + 1
    z0 = bottom + 0.5 * spacing
    amount = height_field_amount(values, z0=z0, dz=spacing, nz=nz)
    origin = (origin_xy[0], origin_xy[1], z0)
    return voxel_grid(amount, origin=origin, spacing=spacing, material_field=material_field)


def _check_heights(values: np.ndarray) -> None:
    """``ValueError`` for a height field holding NaN or infinite heights (no-data samples)."""
    bad = int(np.count_nonzero(~np.isfinite(values)))
    if bad:
        raise ValueError(f"the height field has {bad} NaN or infinite height(s) (no-data samples); fill them first")


def voxel_grid_from_volume(volume, *, threshold: float, array: str | None = None,
                           material_field: MaterialField | None = None) -> pv.ImageData:
    """Material where a volume's values exceed ``threshold`` (on the volume's own grid; cubic voxels needed), as
    material 1 of :func:`~pverosion.materials_from_volume` with the same threshold is."""
    image = pv.wrap(volume)
    sx, sy, sz = image.spacing
    if not (np.isclose(sx, sy) and np.isclose(sx, sz)):
        spacing = tuple(float(s) for s in image.spacing)
        raise ValueError(f"voxel erosion needs cubic voxels; the volume's spacing is {spacing}")
    if not math.isfinite(threshold):
        raise ValueError(f"threshold must be finite; got {threshold!r}")
    values = volume_values(image, array or "")  # (nx, ny, nz); turned axes, vector arrays and NaN refused
    amount = (values > threshold).astype(np.float64)
    if not amount.any():
        raise ValueError(f"threshold {threshold:g} leaves no material: the volume's values are "
                         f"{values.min():g}..{values.max():g}")
    return voxel_grid(amount, origin=image.origin, spacing=sx, material_field=material_field)


def extract_material_surface(image, *, method: str = "flying_edges", iso: float = 0.5) -> pv.PolyData:
    """The material's isosurface as a closed PolyData, with ``material_id`` when the grid has it.

    The grid is padded with one empty layer, so material touching the border
    is capped and the surface is always closed.

    Parameters
    ----------
    image : vtkImageData
        A voxel grid with ``material_amount``.
    method : {"flying_edges", "marching_cubes"}, default: "flying_edges"
        VTK's vtkFlyingEdges3D, or scikit-image's marching cubes (Lewiner et al.) by
        :func:`pverosion.kernels.voxel.isosurface.marching_cubes`: manifold, with no repeated face, also
        where amounts equal ``iso``. Both take amounts equal to ``iso`` as material and cross the grid edges at
        the same points; they may split a cube's polygon into other triangles, and VTK's case table and
        Lewiner's tests resolve ambiguous cubes (material at two diagonal corners of a face or of the cube and
        not between) differently.
    iso : float, default: 0.5

    Returns
    -------
    pyvista.PolyData

    Raises
    ------
    ValueError
        An unknown ``method``, or NaN or infinite amounts.
    """
    if method not in EXTRACTORS:
        raise ValueError(f"method must be one of {EXTRACTORS}; got {method!r}")
    image = pv.wrap(image)
    check_axis_aligned(image)
    amount = _grid_array(image, "material_amount", required=True)
    bad = amount.size - int(np.count_nonzero(np.isfinite(amount)))
    if bad:
        raise ValueError(f"material_amount has {bad} NaN or infinite values; the surface through them is undefined")
    spacing = np.array(image.spacing)
    origin = np.array(image.origin) - spacing
    padded = np.pad(amount, 1)
    if method == "flying_edges":
        from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

        grid = pv.ImageData(dimensions=padded.shape, spacing=spacing, origin=origin)
        grid.point_data["material_amount"] = padded.ravel(order="F")
        alg = vtkFlyingEdges3D()
        alg.SetInputData(grid)
        alg.SetValue(0, iso)
        alg.ComputeNormalsOff()
        alg.ComputeGradientsOff()
        alg.ComputeScalarsOff()
        alg.Update()
        surface = pv.wrap(alg.GetOutput())
    else:
        # amounts equal to iso are material, as in flying edges
        verts, faces = marching_cubes(padded, iso, at_level="above", spacing=tuple(spacing))
        if not len(faces):
            return pv.PolyData()
        # scikit-image orients its triangles towards the higher values: flip to face the empty side
        surface = pv.PolyData.from_regular_faces(verts + origin, faces[:, ::-1])
    if surface.n_points and "material_id" in image.point_data:
        from scipy.ndimage import distance_transform_edt

        material_id = np.asarray(image["material_id"]).reshape(amount.shape, order="F")
        nearest = distance_transform_edt(amount < iso, return_distances=False, return_indices=True)
        index = np.rint((np.asarray(surface.points) - np.array(image.origin)) / spacing).astype(int)
        index = np.clip(index, 0, np.array(amount.shape) - 1)
        i, j, k = (nearest[d][index[:, 0], index[:, 1], index[:, 2]] for d in range(3))
        surface.point_data["material_id"] = material_id[i, j, k].astype(np.int32)
    return surface


def voxel_solver(grid, *, params: ErosionParameters | None = None, source_velocity=(0.0, 0.0, 0.0),
                 **fluid_options) -> VoxelErosionSolver:
    """A :class:`~pverosion.kernels.voxel.erosion.VoxelErosionSolver` for a voxel grid ImageData.

    Parameters
    ----------
    grid : vtkImageData
        Voxel grid (cubic voxels; ``material_amount`` and the optional arrays of this module).
    params : ErosionParameters, optional
    source_velocity : (3,) float, default: (0, 0, 0)
    **fluid_options
        ``viscosity``, ``tolerance``, ``cfl``, ... of :class:`~pverosion.kernels.voxel.fluid.VoxelFluid`.

    Raises
    ------
    ValueError
        Non-cubic voxels, a missing ``material_amount``, bad ``hardness`` or ``source_velocity``.
    """
    amount = _grid_array(grid, "material_amount", required=True)  # first: a raw scan or DEM lacks it
    check_axis_aligned(grid)
    spacing = np.array(grid.GetSpacing())
    if not (np.isclose(spacing[0], spacing[1]) and np.isclose(spacing[0], spacing[2])):
        raise ValueError(f"voxel erosion needs cubic voxels; the grid's spacing is {tuple(spacing.tolist())}")
    velocity = np.asarray(source_velocity, dtype=np.float64).ravel()
    if velocity.shape != (3,):
        raise ValueError(f"source_velocity needs three numbers x,y,z; got {velocity.size}")
    hardness = _grid_array(grid, "hardness", default=1.0)
    if np.any(hardness <= 0) or not np.all(np.isfinite(hardness)):
        raise ValueError("hardness must be finite and > 0 everywhere")
    return VoxelErosionSolver(
        amount, _grid_array(grid, "water"),
        spacing=float(spacing[0]), erodibility=1.0 / hardness, params=params,
        source=_grid_array(grid, "source") != 0, source_velocity=velocity, drain=_grid_array(grid, "drain") != 0,
        **fluid_options,
    )


BYTES_PER_VOXEL = 400
"""Upper estimate of the solver's memory per voxel (about 50 float64 fields and work arrays)."""

OPERATIONS_PER_SUBSTEP = 200
"""Estimated operations per voxel of one substep without diffusion (advection, pressure solve, transport)."""


def _check_step_work(fluid: VoxelFluid, cells: int, dt: float) -> None:
    """Refuse a time step whose CFL substeps and diffusion passes would take effectively forever."""
    h, speed = fluid.spacing, math.hypot(*map(float, fluid.source_velocity))  # hypot: no overflow at 1e200
    # the substeps keep the fastest face under cfl cells: at least the source's speed and gravity's fall
    sub = min(math.sqrt(fluid.cfl * h / fluid.gravity) if fluid.gravity > 0 else math.inf,
              fluid.cfl * h / speed if speed > 0 else math.inf, dt)
    substeps = dt / sub if sub > 0 else math.inf  # sub underflows to 0 for an absurd source speed
    substeps = math.ceil(substeps) if math.isfinite(substeps) else substeps
    option = "source_velocity" if speed > 0 and fluid.cfl * h / speed < dt else "time_step"
    check_work(float(cells) * substeps * OPERATIONS_PER_SUBSTEP, option=option,
               what=f"a time step of {dt:.3g} s in at least {substeps:.3g} CFL substeps over {cells} voxels")
    passes = math.ceil(fluid.viscosity * sub / h**2 / 0.15)  # explicit diffusion passes per substep
    check_work(float(cells) * substeps * passes * 20, option="viscosity",
               what=f"viscosity {fluid.viscosity:.3g} ({passes:.3g} diffusion passes per substep over {cells} voxels)")


class VoxelErosion(TimeSteppedFilter):
    """Voxel hydraulic erosion (Beneš et al. 2006): water flow eroding and depositing material.

    Each time step advances the water by ``time_step`` seconds (MAC-grid
    Navier–Stokes with a volume-of-fluid free surface, see
    :mod:`pverosion.kernels.voxel.fluid`) and exchanges material at the
    water/material interface with the cohesive or cohesionless model (see
    :mod:`pverosion.kernels.voxel.erosion`). The output is a MultiBlock of
    the grid state (``state``) and the material's isosurface (``surface``).
    TIME_STEPS are 0..iterations; a later time continues from the cached
    state, an earlier one restarts.

    Field data of the state: per-step ``voxel_<statistic>`` series (solid,
    dissolved and drained material, eroded and deposited this step, water
    volume, substeps, pressure iterations, divergence) and ``mass_error``.
    """

    LABEL = "Voxel hydraulic erosion"
    COMMAND = "voxel"
    INPUT_TYPE = "vtkImageData"
    OUTPUT_TYPE = "vtkMultiBlockDataSet"
    PARAMS = (
        Param("iterations", 100, "Number of time steps (time steps 0..iterations).", minimum=0),
        Param("time_step", 0.01, "Time per time step (split into CFL substeps).", minimum=1e-9, units="s"),
        Param("model", "cohesive", "Erosion-deposition model.", choices=MODELS),
        Param("friction", 0.05, "f in the bed shear stress tau = f rho U^2 / 2.", minimum=0.0),
        Param("erosion_rate", 0.01, "e, cohesive erosion-rate constant.", minimum=0.0),
        Param("deposition_rate", 0.01, "d, cohesive deposition-rate constant.", minimum=0.0),
        Param("fall_velocity", 0.2, "omega, fall velocity within the water.", minimum=0.0, units="m/s"),
        Param("tau_erosion", 10.0, "tau_ce, shear strength of the material.", minimum=1e-12, units="Pa"),
        Param("tau_deposition", 10.0, "tau_cd, shear stress below which particles deposit.", minimum=1e-12,
              units="Pa"),
        Param("capacity", 0.7, "k in C_hat = min(k |u|, c_max) (cohesionless).", minimum=0.0),
        Param("saturation", 0.5, "c_max, the most dissolved material a water voxel holds.", minimum=1e-9,
              maximum=1.0),
        Param("time_scale", 1.0, "T, adjustment time of the cohesionless load.", minimum=1e-9, units="s",
              advanced=True),
        Param("viscosity", 1e-6, "Kinematic viscosity of the water.", minimum=0.0, units="m^2/s", advanced=True),
        Param("advection", "semi-lagrangian", "Velocity advection: semi-lagrangian (fastest) or maccormack "
              "(keeps the flow's inertia, about twice the advection time).", choices=ADVECTION_SCHEMES, advanced=True),
        Param("source_velocity", "0,0,0", "Velocity of the water at source voxels, as x,y,z.", numbers=3, units="m/s"),
        Param("tolerance", 1e-6, "Projection tolerance on max |div u| dt / h.", minimum=1e-14, advanced=True),
        Param("extraction", "flying_edges", "Isosurface extraction of the material.", choices=EXTRACTORS,
              advanced=True),
    )

    def _new_solver(self, inp) -> VoxelErosionSolver:
        velocity = parse_numbers(self.get_option("source_velocity"), "source_velocity", count=3)
        params = ErosionParameters(**{name: self.get_option(name) for name in (
            "model", "friction", "erosion_rate", "deposition_rate", "fall_velocity", "tau_erosion", "tau_deposition",
            "capacity", "saturation", "time_scale")})
        cells = inp.GetNumberOfPoints()
        if cells == 0:
            raise ValueError("the voxel grid is empty: it has no voxels")
        check_memory(cells * BYTES_PER_VOXEL, option="input grid", what=f"the solver of {cells} voxels",
                     remedy="use coarser voxels")
        solver = voxel_solver(inp, params=params, source_velocity=velocity, viscosity=self.get_option("viscosity"),
                              tolerance=self.get_option("tolerance"), advection=self.get_option("advection"),
                              time_step=self.get_option("time_step"))
        _check_step_work(solver.fluid, cells, self.get_option("time_step"))
        if not solver.fluid.source.any() and not solver.fluid.water.any():
            warnings.warn("voxel erosion: the grid has no water outside the material (its 'water' array is missing "
                          "or zero there) and no 'source' voxels, so no water flows and nothing erodes: give it "
                          "water or sources (voxel_grid(..., water=..., source=...) in pverosion.filters.voxel, or "
                          "point arrays 'water' and 'source' on the grid)", UserWarning, stacklevel=2)
        return solver

    def _fill(self, solver: VoxelErosionSolver, inp, out) -> None:
        state = self._state(inp, solver)
        surface = extract_material_surface(state, method=self.get_option("extraction"))
        if surface.n_points == 0 and self.requested_step() == self.get_option("iterations"):
            warnings.warn(f"voxel erosion: after {self.requested_step()} iterations no voxel's material_amount "
                          "reaches 0.5, the level of the surface, so the surface is empty: the grid had no "
                          "material, or all of it dissolved", UserWarning, stacklevel=2)
        set_multiblock(out, pv.MultiBlock({"state": state, "surface": surface}))

    def _state(self, inp, solver: VoxelErosionSolver) -> pv.ImageData:
        state = pv.ImageData()
        state.ShallowCopy(inp)
        state = state.copy(deep=False)
        fluid = solver.fluid
        classes = np.where(solver.amount > 0, MAT, np.where(fluid.types == LIQUID, FULL, EMPTY)).astype(np.int8)
        for name, values in (("material_amount", solver.amount), ("water", fluid.water),
                             ("dissolved", fluid.material), ("voxel_class", classes), ("pressure", fluid.pressure)):
            state.point_data[name] = values.ravel(order="F")
        velocity = cell_velocity(fluid.u, fluid.v, fluid.w)
        state.point_data["velocity"] = velocity.transpose(2, 1, 0, 3).reshape(-1, 3)
        for name, series in solver.statistics.items():
            set_field_value(state, f"voxel_{name}", series)
        set_field_value(state, "mass_error", solver.mass_error())
        return state
