"""Functional front end: ``pverosion.<stage>(mesh, ...)``, one call per filter class."""

from __future__ import annotations

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonDataModel import vtkPolyData

from pverosion._frontend import apply_filter
from pverosion.filters.curvature import Curvature
from pverosion.filters.hydraulic import HydraulicErosion
from pverosion.filters.materials import MaterialSampler
from pverosion.filters.repair import BooleanOperation, RepairIntersections
from pverosion.filters.shards import FreezeThaw, ShardGraph
from pverosion.filters.voxel import VoxelErosion
from pverosion.filters.weathering import Weathering
from pverosion.kernels.fluid.particle_fluid import Drain, Emitter
from pverosion.kernels.materials.bsp import BSPTree
from pverosion.kernels.materials.erodibility import Erodibility
from pverosion.kernels.materials.field import (
    BSPMaterials,
    Gradual,
    MaterialField,
    bsp_from_volume,
)
from pverosion.kernels.repair.mesh_repair import DEFAULT_TOLERANCE

__all__ = ["boolean", "curvature", "freeze_thaw", "hydraulic_erosion", "materials_from_volume", "repair",
           "sample_materials", "shard_graph", "voxel_erosion", "weather"]


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
    repair: str = "retry",
    normalization: str = "scale_free",
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
    repair : {"retry", "topology", "off"}, default: "retry"
        When the surface meets itself: roll back and shorten the steps there,
        cut the mesh along the intersection curves and go on (a wall eroded
        through opens a hole), or nothing.
    normalization : {"scale_free", "paper"}, default: "scale_free"
        Divide H by ``max |H|`` over the interior vertices (independent of units;
        open scans erode like closed ones), or the paper's rule (only when
        ``max |H| > 1``, over all vertices); see docs/topics/invariance-erosion.md.

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
               "min_edge_ratio": min_edge_ratio, "check_every": check_every, "orientation": orientation,
               "repair": repair, "normalization": normalization}
    if isinstance(erodibility, str):
        return apply_filter(Weathering, mesh, erodibility_array=erodibility, **options)
    return apply_filter(Weathering, mesh, erodibility=erodibility, **options)


def materials_from_volume(
    volume,
    thresholds,
    *,
    array: str | None = None,
    method: str = "complete",
    surface: str | None = None,
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
    method : {"complete", "simplified", "fitted"}, default: "complete"
        C-BSP (exact partition by clipping), S-BSP (faster, coarser) or a
        tree fitted to the voxels (exact at voxel centres, the smallest).
    surface : {"voxels", "isosurface"}, optional
        What C-BSP inserts: the voxels' boundary faces, coplanar ones merged
        (default; exact at voxel centres, smaller than the volume) or the
        marching-cubes isosurfaces as in the thesis (about 100x the volume).
        S-BSP inserts isosurfaces only.
    seed : int, default: 0
        Face insertion order of isosurface trees; the same seed gives the same tree.
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
    return bsp_from_volume(values, thresholds, origin=origin, spacing=spacing, method=method, surface=surface,
                           seed=seed, hardness=hardness, gradual=Gradual(gradual_scale) if gradual_scale > 0 else None)


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



def shard_graph(mesh: pv.PolyData, *, cells: int = 1000, pattern: str = "uniform", seed: int = 0,
                **options) -> pv.MultiBlock:
    """Fracture a closed mesh into Voronoi shards clipped exactly to it (Mateos et al. §4).

    Parameters
    ----------
    mesh : pyvista.PolyData
        A closed triangle mesh, convex or not. Not modified.
    cells : int, default: 1000
        About how many shards.
    pattern : {"uniform", "grid", "hex", "slabs", "poisson", "vertices"}, default: "uniform"
        Seed pattern (see :func:`pverosion.filters.shards.pattern_seeds`).
    seed : int, default: 0
    **options
        ``jitter``, ``layers``, ``tilt``, ``radius_gradient`` of :class:`pverosion.filters.ShardGraph`.

    Returns
    -------
    pyvista.MultiBlock
        ``surface``, ``shards`` and ``links`` (see :mod:`pverosion.filters.shards`).
    """
    return apply_filter(ShardGraph, mesh, cells=cells, pattern=pattern, seed=seed, **options)


def freeze_thaw(mesh: pv.PolyData, *, paths: int = 1000, cells: int = 1000, pattern: str = "uniform",
                water_direction=(0.0, 0.0, -1.0), gravity=(0.0, 0.0, -1.0), resistance=0.0, core=None,
                seed: int = 0, **options) -> pv.MultiBlock:
    """Freeze–thaw weathering of a closed mesh on Voronoi shards (Mateos et al. §5).

    Parameters
    ----------
    mesh : pyvista.PolyData
        A closed triangle mesh, convex or not. Not modified.
    paths : int, default: 1000
        Water paths to run.
    cells, pattern, seed
        Shards as in :func:`shard_graph`.
    water_direction, gravity : (3,) float
        Mean direction the water travels in, and the direction it flows in between links.
    resistance : float, callable or pyvista.ImageData, default: 0
        Resistance field rho in [0, 1]: a constant, a function of points (n, 3) -> (n,), or a 3-D image
        whose active scalars are sampled at the link centroids.
    core : {"none", "surface"} or callable, optional
        Cells never removed: a mode of the filter's ``core`` option, or a function of the cells' seed
        points (n, 3) -> (n,) bool.
    **options
        Other options of :class:`pverosion.filters.FreezeThaw` (``spread``, ``core_window``, ``k_solid``,
        ``k_dmg``, ``shards``, ``record_paths``, ...).

    Returns
    -------
    pyvista.MultiBlock
        ``surface``, ``shards``, ``links`` and ``paths`` (all of them) after the run.
    """
    if int(paths) != paths or paths < 0:
        raise ValueError(f"paths must be a non-negative integer; got {paths!r}")
    vector = {name: ",".join(repr(float(v)) for v in np.asarray(value, dtype=float).reshape(3))
              for name, value in (("water_direction", water_direction), ("gravity", gravity))}
    alg = FreezeThaw(iterations=1 if paths else 0, paths_per_step=max(int(paths), 1), cells=cells, pattern=pattern, seed=seed, **vector,
                     **options)
    if callable(core):
        alg.SetCoreCells(core)
    elif core is not None:
        alg.set_option("core", core)
    if isinstance(resistance, pv.ImageData) or callable(resistance):
        alg.SetResistanceField(resistance)
    else:
        alg.set_option("resistance", resistance)
    if not isinstance(mesh, pv.PolyData):
        raise TypeError(f"freeze_thaw needs a PolyData surface; got {type(mesh).__name__}")
    return pv.wrap(alg.run(mesh))


def repair(mesh: pv.PolyData, *, orientation: str = "outward", tolerance: float = DEFAULT_TOLERANCE,
           improve: bool = False) -> pv.PolyData:
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
    orientation : {"outward", "keep"}, default: "outward"
        ``"outward"`` first makes each closed part consistent and outward (a
        part wholly inside another is a cavity wall; overlapping parts stay
        outward and merge); ``"keep"`` trusts the input's winding, which must
        then point outward.
    tolerance : float, default: 1e-9
        Pre-pass: nearly degenerate faces (an edge shorter than this, or a
        corner this close to the opposite edge, relative to the bounding-box
        diagonal) are removed first by edge collapse and flip; 0 skips it.
    improve : bool, default: False
        Improve the mesh afterwards: collapse the needles and flip or split
        the caps that cutting along the curves made (the curves stay).

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
    return apply_filter(RepairIntersections, mesh, orientation=orientation, tolerance=tolerance, improve=improve)


def boolean(a: pv.PolyData, b: pv.PolyData, operation: str = "union", *, orientation: str = "outward",
            tolerance: float = DEFAULT_TOLERANCE, improve: bool = False) -> pv.PolyData:
    """Union, intersection or difference of two closed triangle meshes (Skorkovská's thesis §10.3).

    Parameters
    ----------
    a, b : pyvista.PolyData
        Closed triangle meshes. They are not modified. An input that
        intersects itself stands for the region where its winding number is
        at least 1, as :func:`repair` would make it.
    operation : {"union", "intersection", "difference", "reverse_difference"}, default: "union"
        A ∪ B, A ∩ B, A ∖ B or B ∖ A.
    orientation : {"outward", "keep"}, default: "outward"
        As in :func:`repair`, for each input.
    tolerance, improve
        Pre-pass and mesh improvement, as in :func:`repair`.

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
    return pv.wrap(BooleanOperation(operation=operation, orientation=orientation, tolerance=tolerance,
                                     improve=improve).run(a, b))


def _spec(item, kind: str) -> str:
    """One emitter/drain as the filter's text form (from text, numbers or the kernel's dataclass)."""
    if isinstance(item, str):
        return item
    if isinstance(item, Emitter):
        values = [*item.position, *item.direction, item.radius, item.rate]
        if item.speed is not None:
            values.append(item.speed)
        return ",".join(repr(float(v)) for v in values)
    if isinstance(item, Drain):
        return f"{item.kind}:" + ",".join(repr(float(v)) for v in item.values)
    if kind == "emitter":
        return ",".join(repr(float(v)) for v in np.asarray(item, dtype=float).ravel())
    raise TypeError(f"a drain is a string like 'plane:0,0,1,5' or a Drain; got {type(item).__name__}")


def hydraulic_erosion(
    mesh: pv.PolyData,
    *,
    emitters,
    iterations: int = 100,
    model: str = "curvature",
    drains=(),
    radius: float | None = None,
    erodibility: Erodibility | str = None,
    seed: int = 0,
    **options,
) -> pv.MultiBlock:
    """Hydraulic erosion of a closed mesh by a particle fluid (Skorkovská 2019 §3.4; thesis ch. 8).

    Parameters
    ----------
    mesh : pyvista.PolyData
        Closed triangle surface (terrain block or model); the water flows on
        its outside. It is not modified.
    emitters : sequence
        Water sources, each ``"x,y,z,dx,dy,dz,r,rate[,speed]"``, a sequence of
        those 8 or 9 numbers, or a :class:`~pverosion.kernels.fluid.particle_fluid.Emitter`.
    iterations : int, default: 100
        Iterations (one fluid step and one erosion step each).
    model : {"curvature", "sediment"}, default: "curvature"
        Shifted-curvature displacement near colliding particles (eqs. 6–7), or
        shear-stress erosion and deposition with volume-exact displacement
        (thesis eqs. 8.2–8.7).
    drains : sequence, optional
        ``"plane:nx,ny,nz,d"`` / ``"box:xmin,ymin,zmin,xmax,ymax,zmax"`` strings
        or :class:`~pverosion.kernels.fluid.particle_fluid.Drain` objects; particles
        leaving the domain are drained anyway.
    radius : float, optional
        Particle radius; default half the mesh's average edge length.
    erodibility : array of shape (V,), callable, str or None
        Erosion multiplier: per-vertex values, a function of points, or the
        name of a point array of ``mesh``.
    seed : int, default: 0
        Same seed, same result (bit for bit).
    **options
        Other options of :class:`pverosion.filters.HydraulicErosion`
        (``gravity``, ``time_step``, ``substeps``, ``power``, ``step_divisor``,
        ``influence``, ``erosion_rate``, ``critical_stress``, ...).

    Returns
    -------
    pyvista.MultiBlock
        ``mesh`` (eroded surface with ``erosion_depth``, ``f_distance``,
        statistics ``hydraulic_*`` in field data) and ``particles`` (positions,
        ``velocity``, ``speed``, ``sediment``).
    """
    if isinstance(emitters, (str, Emitter)):
        emitters = [emitters]
    if isinstance(drains, (str, Drain)):
        drains = [drains]
    options["emitter"] = ";".join(_spec(e, "emitter") for e in emitters)
    options["drain"] = ";".join(_spec(d, "drain") for d in drains)
    if radius is not None:
        options["radius"] = radius
    for name in ("gravity",):
        if name in options and not isinstance(options[name], str):
            options[name] = ",".join(repr(float(v)) for v in np.asarray(options[name], dtype=float).reshape(3))
    if "domain" in options and not isinstance(options["domain"], str):
        options["domain"] = ",".join(repr(float(v)) for v in np.asarray(options["domain"], dtype=float).ravel())
    options.update(iterations=iterations, model=model, seed=seed)
    if isinstance(erodibility, str):
        return apply_filter(HydraulicErosion, mesh, erodibility_array=erodibility, **options)
    return apply_filter(HydraulicErosion, mesh, erodibility=erodibility, **options)
