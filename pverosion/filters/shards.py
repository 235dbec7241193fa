"""Freeze–thaw weathering on Voronoi shards (Mateos et al.): the ShardGraph and FreezeThaw filters.

Both take a closed triangle mesh. :class:`ShardGraph` fractures it into
shards (Voronoi cells of a seed pattern, clipped exactly to the mesh);
:class:`FreezeThaw` also runs water paths over the shards and outputs the
eroded model. Outputs are MultiBlocks:

- ``surface``: the eroded surface, the closed boundary of the union of the
  solid cells, with cell arrays ``cell_id`` (the solid cell each triangle
  bounds), ``link_id``, ``link_life`` and ``shard_colour``;
- ``shards``: every remaining cell's own closed surface, cell arrays ``cell_id``,
  ``core`` (1 on core cells) and ``shard_colour`` (0..19, scrambled so
  neighbours differ, for a categorical colour map);
- ``links``: every living link's face, cell arrays ``link_id``, ``link_life``
  and ``exterior`` (1 where water can infiltrate);
- ``paths`` (FreezeThaw): the water paths of the last time step as polylines
  through the link centroids, point array ``water`` (the water arriving there).

Field data of ``surface``: ``shard_cells``, ``shard_solid_cells``,
``shard_interior_links``, ``shard_exterior_links``, ``shard_paths``,
``shard_breaks`` and ``shard_mean_area``.
"""

from __future__ import annotations

import math

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonDataModel import vtkImageData

from pverosion.filters.base import (
    ErosionFilter,
    Param,
    TimeSteppedFilter,
    parse_numbers,
    polydata_triangles,
    set_field_value,
    set_multiblock,
)
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.mesh.topology import boundary_edges
from pverosion.kernels.shards.freeze_thaw import (
    CORE,
    FreezeThawParameters,
    FreezeThawSimulation,
    FreezeThawSolver,
    PathRecord,
)
from pverosion.kernels.shards.geometry import LinkMesh, cell_surfaces, cells_boundary, link_polygons
from pverosion.kernels.shards.graph import ShardGraph as Graph
from pverosion.kernels.shards.graph import build_shards
from pverosion.kernels.shards.seed_patterns import (
    hex_column_seeds,
    inside_mesh,
    jittered_grid_seeds,
    mesh_vertex_seeds,
    poisson_disc_seeds,
    slab_seeds,
    uniform_seeds,
)
from pverosion.kernels.validation import InvalidMeshError, check_proper_faces, check_welded
from pverosion.limits import check_memory, check_work

__all__ = ["CORE_CHOICES", "PATTERNS", "FreezeThaw", "ShardGraph", "pattern_seeds", "shard_blocks"]

PATTERNS = ("uniform", "grid", "hex", "slabs", "poisson", "vertices")
CORE_CHOICES = ("none", "surface")

BYTES_PER_SHARD = 16384
"""Upper estimate of the memory of one shard (its clipped Voronoi cell, links and output surface)."""


def _positive_layers(text: str) -> None:
    """``ValueError`` unless every thickness of ``layers`` is positive."""
    if any(value <= 0.0 for value in parse_numbers(text, "layers")):
        raise ValueError(f"layers must be positive thicknesses; got {text!r}")


def _positive_radius(text: str) -> None:
    """``ValueError`` unless the sphere ``core_window`` x,y,z,r has a positive radius."""
    if parse_numbers(text, "core_window", count=4)[3] <= 0.0:
        raise ValueError(f"core_window needs a positive radius r in x,y,z,r; got {text!r}")


_GENERATION_PARAMS = (
    Param("cells", 1000, "About how many shards (seed points) to make.", minimum=1),
    Param("pattern", "uniform", "Seed pattern: uniform random, jittered cubic grid, jittered hexagonal columns "
          "(columnar basalt), slabs (strata), Poisson disc, or a subset of the mesh vertices.", choices=PATTERNS),
    Param("jitter", 0.2, "Jitter of the grid, hex and slab patterns, as a fraction of the spacing.", minimum=0.0,
          maximum=0.49, advanced=True),
    Param("layers", "", "Slab thicknesses from the bottom up, as t1,t2,... (cycled; default: the spacing); hex: "
          "the height of the column pieces (default: whole columns).", numbers=0, parse=_positive_layers),
    Param("tilt", 0.0, "Tilt of the slab pattern about x.", minimum=-90.0, maximum=90.0, units="degrees",
          advanced=True),
    Param("radius_gradient", "0,0,0", "Poisson disc: change of the radius per unit length, as x,y,z.", numbers=3,
          advanced=True),
    Param("seed", 0, "Random seed of the seed pattern and of the water paths.", minimum=0, advanced=True),
)


def pattern_seeds(points: np.ndarray, faces: np.ndarray, *, pattern: str = "uniform", cells: int = 1000,
                  jitter: float = 0.2, layers=(), tilt: float = 0.0, radius_gradient=(0.0, 0.0, 0.0),
                  seed: int = 0) -> np.ndarray:
    """Seed points of one of the :data:`PATTERNS` for about ``cells`` shards inside a closed mesh.

    The pattern's spacing is the edge of a cube of the mesh's volume divided
    by ``cells`` (hexagonal columns: the spacing giving ``cells`` columns over
    the mean cross-section; Poisson disc: 0.8 of it, so the count varies).

    Parameters
    ----------
    points : (m, 3) float
    faces : (k, 3) int
        A closed, outward-oriented triangle mesh.
    pattern : str
        One of :data:`PATTERNS`.
    cells : int
    jitter : float
        Fraction of the spacing (grid, hex, slabs).
    layers : sequence of float
        Slab thicknesses, bottom up (empty: the spacing); for hexagonal
        columns, the height of the column pieces (empty: whole columns).
    tilt : float
        Slab tilt about x in degrees.
    radius_gradient : (3,) float
        Poisson disc radius change per unit length.
    seed : int

    Returns
    -------
    (n, 3) float64
        Distinct seeds (inside the mesh, except ``"vertices"``: on it).
    """
    if pattern not in PATTERNS:
        raise ValueError(f"pattern must be one of {PATTERNS}; got {pattern!r}")
    if int(cells) != cells or cells < 1:
        raise ValueError(f"cells must be a positive integer; got {cells!r}")
    points = np.asarray(points, dtype=np.float64)
    lo, hi = points.min(axis=0), points.max(axis=0)
    volume = signed_volume(points, faces)
    if not volume > 0.0:
        raise ValueError(f"the mesh must be closed and outward-oriented with a positive volume; got {volume:g}")
    spacing = (volume / cells) ** (1.0 / 3.0)
    bounds = (lo, hi)
    if pattern == "vertices":
        return mesh_vertex_seeds(points, count=min(int(cells), len(np.unique(points, axis=0))), seed=seed)
    inside = inside_mesh(points, faces)
    if pattern == "uniform":
        return uniform_seeds(int(cells), bounds=bounds, inside=inside, seed=seed)
    if pattern == "grid":
        return jittered_grid_seeds(spacing, bounds=bounds, jitter=jitter, inside=inside, seed=seed)
    if pattern == "hex":  # with layers: columns broken by cross joints every layers[0]
        height = float(hi[2] - lo[2])
        layer = float(layers[0]) if len(layers) else None
        columns = cells / (math.ceil(height / layer) if layer else 1)
        spacing = math.sqrt(2.0 * volume / height / (math.sqrt(3.0) * columns))
        return hex_column_seeds(spacing, bounds=bounds, jitter=jitter, layer_spacing=layer, inside=inside, seed=seed)
    if pattern == "slabs":
        thickness = list(layers) if len(layers) else spacing
        return slab_seeds(thickness, bounds=bounds, spacing=spacing, tilt=tilt, jitter=jitter, inside=inside,
                          seed=seed)
    gradient = np.asarray(radius_gradient, dtype=float)
    return poisson_disc_seeds(0.8 * spacing, bounds=bounds, radius_gradient=gradient if gradient.any() else None,
                              inside=inside, seed=seed)


def shard_blocks(graph: Graph, *, solid: np.ndarray | None = None, core: np.ndarray | None = None,
                 life: np.ndarray | None = None, exterior: np.ndarray | None = None, shards: bool = True,
                 links: LinkMesh | None = None) -> pv.MultiBlock:
    """The ``surface``, ``shards`` and ``links`` blocks of a shard graph in some state (see the module doc).

    Parameters
    ----------
    graph : ShardGraph
    solid, core : (n_cells,) bool, optional
        Cells still there (default all) and core cells (default none).
    life : (n_links,) float, optional
        Link life (default 1).
    exterior : (n_links,) bool, optional
        Current exterior links (default: the mesh surface's).
    shards : bool
        Include the per-cell ``shards`` block (the heaviest).
    links : LinkMesh, optional
        Precomputed :func:`~pverosion.kernels.shards.geometry.link_polygons`.
    """
    solid = np.ones(graph.n_cells, bool) if solid is None else solid
    core = np.zeros(graph.n_cells, bool) if core is None else core
    life = np.ones(graph.n_links) if life is None else life
    exterior = graph.exterior if exterior is None else exterior
    links = link_polygons(graph) if links is None else links
    blocks = pv.MultiBlock()
    pts, tris, tri_link, _flipped = cells_boundary(graph, solid, links=links)
    surface = _polydata(pts, tris)
    cells = graph.link_cells[tri_link]
    surface.cell_data["cell_id"] = np.where(solid[cells[:, 0]], cells[:, 0], cells[:, 1])
    surface.cell_data["link_id"] = tri_link
    surface.cell_data["link_life"] = life[tri_link]
    surface.cell_data["shard_colour"] = (surface.cell_data["cell_id"] * 7919) % 20
    blocks["surface"] = surface
    if shards:
        ids = np.flatnonzero(solid)
        pts, tris, tri_cell = cell_surfaces(graph, ids, links=links)
        piece = _polydata(pts, tris)
        piece.cell_data["cell_id"] = tri_cell
        piece.cell_data["core"] = core[tri_cell].astype(np.int8)
        piece.cell_data["shard_colour"] = (tri_cell * 7919) % 20  # neighbours get unrelated colours
        blocks["shards"] = piece
    c = graph.link_cells
    alive = solid[c[:, 0]] | np.where(c[:, 1] >= 0, solid[np.maximum(c[:, 1], 0)], False)
    keep = alive[links.triangle_link]
    face = _polydata(links.points, links.triangles[keep])
    tl = links.triangle_link[keep]
    face.cell_data["link_id"] = tl
    face.cell_data["link_life"] = life[tl]
    face.cell_data["exterior"] = exterior[tl].astype(np.int8)
    blocks["links"] = face.clean(point_merging=False)  # drop the unused points
    return blocks


def _polydata(points: np.ndarray, triangles: np.ndarray) -> pv.PolyData:
    if len(triangles) == 0:
        return pv.PolyData()
    return pv.PolyData.from_regular_faces(np.asarray(points, dtype=np.float64), np.asarray(triangles, np.int64))


def _path_lines(graph: Graph, record: PathRecord) -> pv.PolyData:
    """Water paths as polylines through the link centroids, with the water arriving at each point."""
    lengths = np.diff(record.start)
    keep = lengths >= 2
    if not keep.any():
        return pv.PolyData()
    pts = graph.link_centroid[record.link]
    lines = []
    for p in np.flatnonzero(keep):
        lines.append(np.concatenate([[lengths[p]], np.arange(record.start[p], record.start[p + 1])]))
    out = pv.PolyData(pts, lines=np.concatenate(lines))
    out.point_data["water"] = record.water
    out.point_data["link_id"] = record.link
    return out.clean(point_merging=False)


def _closed_outward(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points (V, 3) and triangles (F, 3) of a closed mesh, each part outward and a nested part as its cavity.

    Raises
    ------
    InvalidMeshError
        Degenerate or duplicated faces, a triangle soup, or boundary edges (an open mesh); faces of zero area
        are refused by :func:`~pverosion.kernels.shards.graph.build_shards`.
    """
    check_proper_faces(faces)
    check_welded(faces, len(points))
    n_open = len(boundary_edges(np.asarray(faces, np.int64), len(points)))
    if n_open:
        raise InvalidMeshError(f"the mesh must be closed: it has {n_open} boundary edges (fill its holes first, "
                               "e.g. with pverosion.meshing.fill_holes)")
    # each part outward, a part inside another as its cavity: a consistent winding with a positive volume
    # still leaves a nested part that faces outward, which would fill the cavity
    from pverosion.kernels.repair.mesh_repair import outward_parts

    return points, outward_parts(points, faces)


class _ShardSource:
    """Generation shared by both filters: seeds from the options, the graph cached per input and options."""

    def _generation_options(self) -> tuple:
        return tuple(self.get_option(p.name) for p in _GENERATION_PARAMS)

    def _graph(self, inp) -> Graph:
        key = (inp.GetMTime(), self._generation_options())
        if getattr(self, "_graph_key", None) != key:
            points, faces = _closed_outward(*polydata_triangles(inp))
            cells = self.get_option("cells")
            check_memory(cells * BYTES_PER_SHARD, option="cells", what=f"a graph of {cells} shards")
            seeds = pattern_seeds(
                points, faces, pattern=self.get_option("pattern"), cells=self.get_option("cells"),
                jitter=self.get_option("jitter"),
                layers=parse_numbers(self.get_option("layers"), "layers") if self.get_option("layers") else (),
                tilt=self.get_option("tilt"),
                radius_gradient=parse_numbers(self.get_option("radius_gradient"), "radius_gradient", count=3),
                seed=self.get_option("seed"))
            self._shard_graph = build_shards(seeds, points, faces)
            self._links = link_polygons(self._shard_graph)
            self._graph_key = key
        return self._shard_graph


class ShardGraph(_ShardSource, ErosionFilter):
    """Fracture a closed mesh into Voronoi shards (Mateos et al. §4): cells clipped exactly to the mesh.

    Output: a MultiBlock with ``surface`` (the mesh rebuilt from the shards),
    ``shards`` (each cell's closed surface, ``cell_id``) and ``links`` (link
    faces with ``link_id`` and ``exterior``); see :mod:`pverosion.filters.shards`.
    """

    LABEL = "Voronoi shards"
    COMMAND = "shard-graph"
    OUTPUT_TYPE = "vtkMultiBlockDataSet"
    PARAMS = _GENERATION_PARAMS

    def execute(self, inp, out) -> None:
        """Build (or reuse) the shard graph and fill ``out``."""
        graph = self._graph(inp)
        blocks = shard_blocks(graph, links=self._links)
        _statistics(blocks["surface"], graph, np.ones(graph.n_cells, bool), graph.exterior, paths=0, breaks=0)
        set_multiblock(out, blocks)


def _statistics(surface, graph: Graph, solid: np.ndarray, exterior: np.ndarray, *, paths: int, breaks: int) -> None:
    inner = graph.link_cells[:, 1] >= 0
    for name, value in (("cells", graph.n_cells), ("solid_cells", int(solid.sum())),
                        ("interior_links", int(inner.sum())), ("exterior_links", int(exterior.sum())),
                        ("paths", paths), ("breaks", breaks), ("mean_area", graph.mean_area)):
        set_field_value(surface, f"shard_{name}", value)


class FreezeThaw(_ShardSource, TimeSteppedFilter):
    """Freeze–thaw weathering (Mateos et al. §5): water paths damage the links between shards until they detach.

    The input mesh is fractured as by :class:`ShardGraph`; then each time
    step runs ``paths_per_step`` water paths. TIME_STEPS are
    0..iterations; a later time continues from the cached simulation, an
    earlier one reruns it (same seed, same result). Core cells (``core``)
    are never removed (``core``, ``core_plane``); ``core_window`` keeps the cells within a sphere
    ``x,y,z,r`` out of the core so the erosion can enter there (the cave of
    Figure 14).
    """

    LABEL = "Freeze-thaw weathering"
    COMMAND = "freeze-thaw"
    OUTPUT_TYPE = "vtkMultiBlockDataSet"
    PARAMS = (
        Param("iterations", 10, "Time steps (time steps 0..iterations).", minimum=0),
        Param("paths_per_step", 100, "Water paths per time step.", minimum=1),
        *_GENERATION_PARAMS,
        Param("core", "none", "Cells never removed: none, or surface (the cells on the mesh surface).",
              choices=CORE_CHOICES),
        Param("core_plane", "", "Also make core the cells whose seed x has n . x >= d, as nx,ny,nz,d.", numbers=4),
        Param("core_window", "", "Sphere x,y,z,r whose cells are not core (an opening for the erosion).", numbers=4,
              parse=_positive_radius),
        Param("water_direction", "0,0,-1", "Mean direction the water travels in, as x,y,z.", numbers=3),
        Param("spread", 0.0, "Half-angle of the cone of water directions.", minimum=0.0, maximum=180.0,
              units="degrees", advanced=True),
        Param("gravity", "0,0,-1", "Direction water flows in between links, as x,y,z.", numbers=3),
        Param("resistance", 0.0, "Resistance rho of the rock to the flow, in [0, 1] (constant; Python front ends "
              "also take a function or a 3-D image).", minimum=0.0, maximum=1.0),
        Param("water", 1.0, "Water per path, w_in.", minimum=1e-12),
        Param("k_solid", 0.1, "Absorption per area on unbroken links, in units of 1/(mean link area).", minimum=0.0,
              advanced=True),
        Param("k_air", 0.05, "Absorption per area on broken links, in units of 1/(mean link area).", minimum=0.0,
              advanced=True),
        Param("k_res", 0.25, "Absorption per unit of flow resistance.", minimum=0.0, advanced=True),
        Param("k_dmg", 0.5, "Damage per absorbed water per area, in units of the mean link area.", minimum=0.0,
              advanced=True),
        Param("k_break", 0.4, "Life below which a link may break at random.", minimum=0.0, maximum=1.0, advanced=True),
        Param("break_probability", 0.9, "Probability of that break as the life reaches 0.", minimum=0.0, maximum=1.0,
              advanced=True),
        Param("complete_absorption", 1.0, "Scale of the chance 1 - w/w_in that a link absorbs all water left.",
              minimum=0.0, maximum=1.0, advanced=True),
        Param("shards", True, "Output every remaining cell's own surface (the shards block)."),
        Param("record_paths", True, "Output the water paths of the last time step (the paths block)."),
    )

    def __init__(self, **options):
        super().__init__(**options)
        self._resistance_field = None
        self._core_cells_function = None

    def SetResistanceField(self, field) -> None:
        """Use a resistance field instead of the constant ``resistance``.

        ``field`` is a function of points (n, 3) -> (n,), a vtkImageData
        whose active point scalars are sampled (trilinearly) at the link
        centroids, or None to go back to the constant.
        """
        if field is not None and not (callable(field) or isinstance(field, vtkImageData)):
            raise TypeError(f"the resistance field must be a function or an ImageData; got {type(field).__name__}")
        if field is not self._resistance_field:
            self._resistance_field = field
            self.Modified()

    def SetCoreCells(self, select) -> None:
        """Also make core the cells for which ``select(seeds (n, 3)) -> (n,) bool`` is True (None: no function)."""
        if select is not None and not callable(select):
            raise TypeError(f"core cells need a function of the seed points; got {type(select).__name__}")
        if select is not self._core_cells_function:
            self._core_cells_function = select
            self.Modified()

    def _resistance(self, graph: Graph):
        field = self._resistance_field
        if field is None:
            return self.get_option("resistance")
        if callable(field):
            return field
        image = pv.wrap(field)
        name = image.active_scalars_name
        if name is None:
            raise ValueError("the resistance image has no active scalars")
        probe = pv.PolyData(graph.link_centroid.copy()).sample(image)
        return np.asarray(probe[name], dtype=np.float64)

    def _new_simulation(self, graph: Graph) -> FreezeThawSimulation:
        params = FreezeThawParameters(
            water_direction=tuple(parse_numbers(self.get_option("water_direction"), "water_direction", count=3)),
            spread=self.get_option("spread"), gravity=tuple(parse_numbers(self.get_option("gravity"), "gravity", count=3)),
            **{name: self.get_option(name) for name in ("water", "k_solid", "k_air", "k_res", "k_dmg", "k_break",
                                                        "break_probability", "complete_absorption")})
        return FreezeThawSimulation(graph, params, core=self._core_cells(graph), resistance=self._resistance(graph),
                                    seed=self.get_option("seed"))

    def _core_cells(self, graph: Graph) -> np.ndarray:
        mode = self.get_option("core")
        core = np.zeros(graph.n_cells, bool)
        if mode == "surface":
            core[graph.link_cells[graph.exterior, 0]] = True
        plane = self.get_option("core_plane")
        if plane:
            nx, ny, nz, d = parse_numbers(plane, "core_plane", count=4)
            core |= graph.seeds @ np.array([nx, ny, nz]) >= d
        if self._core_cells_function is not None:
            chosen = np.asarray(self._core_cells_function(graph.seeds.copy()))
            if chosen.shape != (graph.n_cells,):
                raise ValueError(f"the core cell function must return shape ({graph.n_cells},); got {chosen.shape}")
            core |= chosen.astype(bool)
        window = self.get_option("core_window")
        if window:
            x, y, z, r = parse_numbers(window, "core_window", count=4)
            core &= np.linalg.norm(graph.seeds - np.array([x, y, z]), axis=1) > r
        return core

    def _new_solver(self, inp) -> FreezeThawSolver:
        # refused before the graph is built: the requested cell count sets the estimate
        per_step = self.get_option("paths_per_step")
        visits = 4.0 * self.get_option("cells") ** (1.0 / 3.0) + 1.0  # links a path crosses, about the diameter
        check_work(per_step * visits * 50.0, option="paths_per_step", what=f"{per_step} water paths")
        if self.get_option("record_paths"):
            check_memory(per_step * 64 * 16, option="paths_per_step", what=f"the record of {per_step} water paths")
        simulation = self._new_simulation(self._graph(inp))
        return FreezeThawSolver(simulation, paths_per_step=per_step, record_paths=self.get_option("record_paths"))

    def _fill(self, solver: FreezeThawSolver, inp, out) -> None:
        sim = solver.simulation
        graph = sim.graph
        blocks = shard_blocks(graph, solid=sim.solid, core=sim.state == CORE, life=sim.life, exterior=sim.exterior,
                              shards=self.get_option("shards"), links=self._links)
        if self.get_option("record_paths"):
            blocks["paths"] = _path_lines(graph, solver.record) if solver.record is not None else pv.PolyData()
        _statistics(blocks["surface"], graph, sim.solid, sim.exterior, paths=sim.paths, breaks=sim.n_breaks)
        set_multiblock(out, blocks)
