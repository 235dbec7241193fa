"""Shared machinery of the stages that move the vertices of a closed mesh step by step.

:class:`GuardedMeshSolver` holds the evolving mesh (points, faces, input ids,
cumulative displacement), the mesh improvement of Skorkovská 2019 §4.1
(collapse of edges shorter than ``min_edge_ratio * e_avg`` after every step,
:mod:`pverosion.kernels.mesh.remesh`) and the self-intersection guard with
rollback. Weathering and hydraulic erosion subclass it and only write their
step.

Self-intersection guard (periodic, with rollback): every ``check_every``
steps, and at every step the caller asks to see, the mesh is tested for
intersecting non-adjacent triangles (two that touch only where distinct vertices coincide count as adjacent)
(:func:`pverosion.kernels.exact.intersection.intersecting_faces`). A clean mesh
becomes the new restart point. When intersections have appeared, the solver
restores the last clean state, halves the displacement length of the
vertices of the intersecting faces and of their two-ring neighbourhood, and
redoes the steps (the paper's "restart with shorter displacements", applied
where the mesh tangled instead of everywhere, so the rest of the model keeps
its pace). A vertex that was slowed down before has its displacement length
multiplied by :attr:`GuardedMeshSolver.REPEAT_FACTOR` (1/8 in weathering:
three halvings at once) instead: a place that tangles again at half its pace
(on the bunny scan, a sharp crease) would otherwise tangle, and be rolled
back and redone, once per halving. Hydraulic erosion keeps 1/2: there the
water makes tangles that mostly come undone before the next check. The
slowing down is kept for the rest of the run; a vertex slowed down more than
``max_halvings`` halvings' worth is frozen (it stops moving and is never
collapsed). ``retries`` counts the rollbacks, ``frozen`` the frozen vertices.
Only the check of the whole mesh rolls back or makes a restart point, so a
run does not depend on the number of threads.

Subclasses with more state than the mesh (a fluid, say) extend
:meth:`GuardedMeshSolver._extra_state` and
:meth:`GuardedMeshSolver._restore_extra`, so a rollback replays the same
steps bit for bit.

That is ``repair="retry"``. With ``repair="topology"`` the guard instead
accepts that two parts of the surface met (erosion pierced a thin wall,
deposition merged two lobes): it cuts the mesh along the intersection curves
and keeps the boundary of the region of winding number >= 1
(:func:`pverosion.kernels.repair.mesh_repair.repair_intersections`), which may
open holes or split the mesh into pieces, and the run goes on from there
(``repairs`` counts them). ``repair="off"`` leaves intersections in place.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels._scatter import CHUNKS, chunk_range
from pverosion.kernels._threads import for_chunks, for_ranges
from pverosion.kernels.curvature.operator import CurvatureOperator
from pverosion.kernels.exact.intersection import intersecting_faces, spatial_order
from pverosion.kernels.mesh.geometry import average_edge_length, vertex_normals
from pverosion.kernels.mesh.orientation import ORIENTATIONS, orient_faces
from pverosion.kernels.mesh.remesh import CollapseTopology, apply_collapses, plan_collapses, short_edges_and_mean_length
from pverosion.kernels.mesh.topology import EdgeTopology, edge_topology, vertex_fan_counts
from pverosion.kernels.solver.protocol import SolverLoop
from pverosion.kernels.validation import InvalidMeshError, as_triangle_mesh, check_proper_faces, check_welded

__all__ = ["REPAIR_MODES", "GuardedMeshSolver", "evolvable_topology", "volume_area"]

REPAIR_MODES = ("retry", "topology", "off")
"""Accepted values of the ``repair`` option."""


def evolvable_topology(faces: np.ndarray, n_vertices: int) -> EdgeTopology:
    """The :func:`~pverosion.kernels.mesh.topology.edge_topology` of a surface that a :class:`GuardedMeshSolver`
    can evolve; ``InvalidMeshError`` naming what makes another surface unfit, and the remedy.

    A surface that evolves needs proper, welded triangles
    (:func:`~pverosion.kernels.validation.check_proper_faces`,
    :func:`~pverosion.kernels.validation.check_welded`), every edge between at
    most two faces and one fan of faces around every vertex: the normal, the
    curvature and the self-intersection guard are undefined elsewhere (at a
    vertex where two surfaces touch they would mix both).

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
        Triangles as vertex indices in ``[0, V)``.
    n_vertices : int
        Number of vertices V.

    Returns
    -------
    EdgeTopology

    Raises
    ------
    InvalidMeshError
        For degenerate or repeated faces, an unwelded triangle soup, edges
        shared by more than two faces, or vertices where separate fans of faces
        meet.
    """
    check_proper_faces(faces)
    check_welded(faces, n_vertices)
    faces64 = np.asarray(faces, np.int64)
    topology = edge_topology(faces64, n_vertices)
    if topology.n_nonmanifold_edges:
        raise InvalidMeshError(f"mesh has {topology.n_nonmanifold_edges} non-manifold edges (shared by more than "
                               "two faces): repair it first (pverosion repair, or pverosion.repair)")
    pinched = np.flatnonzero(vertex_fan_counts(faces64, n_vertices, topology=topology) > 1)
    if len(pinched):
        count = f"{len(pinched)} non-manifold {'vertex' if len(pinched) == 1 else 'vertices'}"
        remedy = ("repair it first (pverosion repair, or pverosion.repair, splits each into one vertex per fan)"
                  if topology.n_boundary_edges == 0 else "split each into one vertex per fan first (pverosion "
                  "repair does so for a closed mesh only; this one has boundary edges)")
        raise InvalidMeshError(f"mesh has {count} (where separate fans of faces meet at one point, as two "
                               f"surfaces touching at a vertex; the first is vertex {pinched[0]}): {remedy}")
    return topology


@njit(cache=True, error_model="numpy", nogil=True)
def _volume_area_chunk(points, faces, origin, partial, c):
    """Add six times the signed volume and twice the area of chunk ``c`` of the faces to ``partial[c]``."""
    lo, hi = chunk_range(faces.shape[0], c)
    for f in range(lo, hi):
        a = v3.sub(v3.row(points, faces[f, 0]), (origin[0], origin[1], origin[2]))
        b = v3.sub(v3.row(points, faces[f, 1]), (origin[0], origin[1], origin[2]))
        cc = v3.sub(v3.row(points, faces[f, 2]), (origin[0], origin[1], origin[2]))
        partial[c, 0] += v3.dot(a, v3.cross(b, cc))
        partial[c, 1] += v3.norm(v3.cross(v3.sub(b, a), v3.sub(cc, a)))


def volume_area(points: np.ndarray, faces: np.ndarray, origin: np.ndarray) -> tuple[float, float]:
    """Enclosed volume and area; summed in fixed face chunks, so bit-identical for any thread count.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64
    faces : numpy.ndarray, shape (F, 3), int64
    origin : numpy.ndarray, shape (3,), float64
        Apex of the tetrahedra whose signed volumes are summed.

    Returns
    -------
    volume, area : float
    """
    partial = np.zeros((CHUNKS, 2))
    for_chunks(_volume_area_chunk, faces.shape[0], points, faces, origin, partial)
    volume = 0.0
    area = 0.0
    for c in range(CHUNKS):
        volume += float(partial[c, 0])
        area += float(partial[c, 1])
    return volume / 6.0, area / 2.0


@njit(cache=True, error_model="numpy", nogil=True)
def _moved_vertex_range(points, clean, source, out, start, stop):
    """Vertices ``start`` to ``stop``: not at their place ``clean[source]`` of the restart point."""
    for v in range(start, stop):
        s = source[v]
        out[v] = points[v, 0] != clean[s, 0] or points[v, 1] != clean[s, 1] or points[v, 2] != clean[s, 2]


@njit(cache=True, error_model="numpy", nogil=True)
def _moved_range(moved_vertex, faces, made, out, start, stop):
    """Faces ``start`` to ``stop`` of :meth:`GuardedMeshSolver._moved_faces`: ``made`` or with a vertex
    ``moved_vertex``."""
    for f in range(start, stop):
        out[f] = made[f] | moved_vertex[faces[f, 0]] | moved_vertex[faces[f, 1]] | moved_vertex[faces[f, 2]]


@njit(cache=True, error_model="numpy")
def _grow_by_ring(ring_ptr, ring_idx, near):
    """``near`` (V,) and every vertex with a one-ring neighbour (CSR ``ring_ptr``, ``ring_idx``) in it."""
    grown = near.copy()
    for v in range(near.shape[0]):
        for k in range(ring_ptr[v], ring_ptr[v + 1]):
            if near[ring_idx[k]]:
                grown[v] = True
                break
    return grown


@dataclass
class _State:
    """Everything a rollback restores."""

    points: np.ndarray
    faces: np.ndarray
    ids: np.ndarray
    displacement: np.ndarray
    step: int
    collapses: int
    stats: list = field(default_factory=list)
    extra: Any = None


class GuardedMeshSolver(SolverLoop):
    """Base of the vertex-displacement stages: mesh state, improvement, self-intersection guard.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        Triangles; they are first oriented as ``orientation`` says.
    min_edge_ratio : float, default: 0.1
        Mesh improvement: collapse edges shorter than ``min_edge_ratio *
        e_avg`` after every step; 0 switches it off.
    check_every : int, default: 10
        Self-intersection guard period in steps; 0 switches the guard off.
    max_halvings : int, default: 4
        Freeze a vertex whose displacement had to be halved more than this
        many times (a slowing down by :attr:`REPEAT_FACTOR` counts as
        log2(1 / REPEAT_FACTOR) halvings).
    orientation : {"outward", "inward", "keep"}, default: "outward"
    repair : {"retry", "topology", "off"}, default: "retry"
        What the guard does when the surface meets itself: roll back and
        shorten the steps there, cut the mesh along the intersection curves
        and go on, or nothing (no guard).

    Attributes
    ----------
    points, faces : numpy.ndarray
        Current mesh.
    ids : numpy.ndarray, shape (V',)
        Input index of every current vertex (collapses remove vertices).
    displacement : numpy.ndarray, shape (V', 3)
        Cumulative displacement of every current vertex.
    initial_normals : numpy.ndarray, shape (V, 3)
        Outward unit normals of the input vertices (index with ``ids``).
    step_count : int
        Steps done (time).
    retries : int
        Rollbacks made by the self-intersection guard.
    repairs : int
        Topology repairs made by the guard (``repair="topology"``).
    collapses : int
        Edges collapsed by the mesh improvement.
    profile : dict or None
        Set it to ``{}`` to collect the seconds spent per part of each step.
    """

    STAT_NAMES: ClassVar[tuple[str, ...]] = ()
    """Names of the per-step statistics (one row per step, step 0 first); rows come from :meth:`_row`."""
    PROGRESS_LABEL: ClassVar[str] = "steps"
    REPEAT_FACTOR: ClassVar[float] = 0.125
    """Step length factor of a vertex slowed down before that the guard slows down again (others: 0.5)."""
    _curvature_estimator: ClassVar[type] = CurvatureOperator
    """Curvature of the current points, built per connectivity (:class:`CurvatureTracker` where few points move)."""

    def __init__(
        self,
        points,
        faces,
        *,
        min_edge_ratio: float = 0.1,
        check_every: int = 10,
        max_halvings: int = 4,
        orientation: str = "outward",
        repair: str = "retry",
    ) -> None:
        pts, fcs = as_triangle_mesh(points, faces)
        evolvable_topology(fcs, len(pts))
        if not (np.isfinite(min_edge_ratio) and 0.0 <= min_edge_ratio < 1.0):
            raise ValueError(f"min_edge_ratio must be in [0, 1); got {min_edge_ratio!r}")
        if int(check_every) != check_every or check_every < 0:
            raise ValueError(f"check_every must be an integer >= 0; got {check_every!r}")
        if int(max_halvings) != max_halvings or max_halvings < 0:
            raise ValueError(f"max_halvings must be an integer >= 0; got {max_halvings!r}")
        if orientation not in ORIENTATIONS:
            raise ValueError(f"orientation must be one of {ORIENTATIONS}; got {orientation!r}")
        if repair not in REPAIR_MODES:
            raise ValueError(f"repair must be one of {REPAIR_MODES}; got {repair!r}")
        self.min_edge_ratio = float(min_edge_ratio)
        self.repair = repair
        self.check_every = 0 if repair == "off" else int(check_every)
        self.max_halvings = int(max_halvings)
        self.points = pts.copy()
        self.faces = orient_faces(pts, fcs, mode=orientation).faces
        self.ids = np.arange(len(pts))
        self.displacement = np.zeros_like(pts)
        self.step_count = 0
        self.retries = 0
        self.repairs = 0
        self.collapses = 0
        self.profile: dict[str, list[float]] | None = None
        self._scale = np.ones(len(pts))  # displacement length factor per input vertex
        self._origin = pts.mean(axis=0)
        self._collapsed: tuple | None = None  # collapses that :meth:`_build_topology` follows instead of a rebuild
        self._edge_mean: tuple = (None, None, 0.0)  # points and edges the last improvement measured, mean length
        self._build_topology()
        self.initial_normals = vertex_normals(self.points, self.faces, weighting="area")
        self._volume0 = self.volume()
        self._stats: list[tuple] = []
        self._baseline = 0
        self._clean: _State | None = None

    def _start(self) -> None:
        """Record step 0 and the first restart point; subclasses call it at the end of their ``__init__``."""
        self._stats = [self._row()]
        if self.check_every:
            self._baseline = int(np.count_nonzero(self._intersections()))
            if self._baseline:
                warnings.warn(
                    f"the input mesh already has {self._baseline} self-intersecting faces; "
                    "the guard only rejects steps that add more",
                    RuntimeWarning,
                    stacklevel=3,
                )
        self._set_clean()

    # -- hooks ---------------------------------------------------------------------------

    def _step(self) -> None:
        """Advance one step (move vertices, improve the mesh, append a statistics row)."""
        raise NotImplementedError

    def _row(self) -> tuple:
        """Statistics of the current state, in :attr:`STAT_NAMES` order."""
        raise NotImplementedError

    def _extra_state(self) -> Any:
        """State beyond the mesh that a rollback must restore (None: nothing)."""
        return None

    def _restore_extra(self, extra: Any) -> None:
        """Restore what :meth:`_extra_state` returned."""

    def progress_postfix(self) -> dict:
        return {"retries": self.retries, "collapses": self.collapses}

    # -- mesh ----------------------------------------------------------------------------

    def volume(self) -> float:
        """Enclosed volume of the current mesh."""
        return float(volume_area(self.points, self.faces, self._origin)[0])

    def area(self) -> float:
        """Surface area of the current mesh."""
        return float(volume_area(self.points, self.faces, self._origin)[1])

    def _build_topology(self) -> None:
        """Everything that depends on the faces only; after edge collapses (``_collapsed``), updated from before."""
        n = len(self.points)
        self._curvature = self._curvature_estimator(self.faces, n)
        if self._collapsed is None:
            self._topology = CollapseTopology.build(self.faces, n)
            self._order = None  # spatial face order of the intersection check, made on first use
        else:
            result, new_face = self._collapsed
            self._collapsed = None
            self._topology = self._topology.collapsed(result, new_face)
            if self._order is not None:  # the faces left keep their order, still a good one for the check
                order = new_face[self._order]
                self._order = order[order >= 0]
        self._ring = self._topology.ring
        self._edges = self._topology.edges
        self._usable = self._topology.usable
        self._fixed = self._topology.fixed
        # curvature statistics leave out the fixed vertices and their one-ring, whose estimates an open rim spoils
        ring_ptr, ring_idx = self._ring
        self._interior = ~self._fixed
        self._interior[ring_idx[np.repeat(self._fixed, np.diff(ring_ptr))]] = False

    def mean_curvature(self) -> np.ndarray:
        """Mean curvature H (V',) of the current mesh."""
        return self._curvature(self.points).mean

    def erosion_depth(self) -> np.ndarray:
        """Cumulative displacement (V',) of every current vertex into the input surface, along its input normal."""
        return -np.einsum("ij,ij->i", self.displacement, self.initial_normals[self.ids])

    def _mean_edge_length(self) -> float:
        """Mean edge length of the current mesh.

        The last mesh improvement measured it in its pass over the edges when the points and edges it saw are
        still :attr:`points` and the edges (the same arrays: every step and every change of the mesh makes new
        ones; do not write into :attr:`points` in place).
        """
        points, edges, mean = self._edge_mean
        if points is self.points and edges is self._edges:
            return mean
        return average_edge_length(self.points, self.faces, edges=self._edges)

    def _improve(self, min_length: float, *, movable: np.ndarray | None = None) -> None:
        """Collapse edges shorter than ``min_length`` (only between ``movable`` vertices (V',) when given)."""
        candidates, mean = short_edges_and_mean_length(self.points, self._edges, self._usable, min_length)
        self._edge_mean = (self.points, self._edges, mean)  # for the next step, unless a collapse changes the mesh
        if len(candidates) == 0:
            return
        locked = self._fixed | (self._scale[self.ids] == 0.0)
        if movable is not None:
            locked = locked | ~movable
        pairs, positions = plan_collapses(self.points, self.faces, candidates, locked,
                                          incidence=self._topology.incidence)
        if len(pairs) == 0:
            return
        result, new_face = apply_collapses(self.points, self.faces, pairs, positions)
        self.points, self.faces = result.points, result.faces
        self.ids = self.ids[result.kept]
        self.displacement = self.displacement[result.kept]
        self.collapses += result.n_collapsed
        # the faces at a merged vertex are new since the restart point; the others kept their vertices
        merged = np.zeros(len(result.kept), bool)
        merged[np.searchsorted(result.kept, pairs[:, 0])] = True
        self._since_clean = (self._since_clean[0][result.kept],
                             self._since_clean[1][new_face >= 0] | merged[self.faces].any(axis=1))
        self._after_collapse(result.kept)
        self._collapsed = (result, new_face)
        self._build_topology()

    def _after_collapse(self, kept: np.ndarray) -> None:
        """Carry per-vertex state of a subclass over to the ``kept`` vertices (input indices)."""

    # -- state ---------------------------------------------------------------------------

    def _set_clean(self) -> None:
        """Make the current state the restart point."""
        self._clean = _State(self.points.copy(), self.faces.copy(), self.ids.copy(), self.displacement.copy(),
                             self.step_count, self.collapses, list(self._stats), self._extra_state())
        self._reset_tracking()

    def _restore(self, state: _State) -> None:
        faces_changed = len(state.faces) != len(self.faces) or not np.array_equal(state.faces, self.faces)
        self.points = state.points.copy()
        self.faces = state.faces.copy()
        self.ids = state.ids.copy()
        self.displacement = state.displacement.copy()
        self.step_count = state.step
        self.collapses = state.collapses
        self._stats = list(state.stats)
        if faces_changed:
            self._build_topology()
        self._reset_tracking()
        self._restore_extra(state.extra)

    def _reset_tracking(self) -> None:
        """Start following the mesh from the current state, the restart point: ``_since_clean`` holds the index
        of every vertex there (V',) and which faces (F',) collapses have made since."""
        self._since_clean = (np.arange(len(self.points)), np.zeros(len(self.faces), bool))

    def _intersections(self, query: np.ndarray | None = None) -> np.ndarray:
        """Mask (F,) of the faces meeting a non-adjacent face (in pairs with a ``query`` face); faces that touch
        only where distinct vertices coincide (the input's own contact, as ``pverosion repair`` leaves two parts
        that met at a point) do not count."""
        if self._order is None:
            self._order = spatial_order(self.points, self.faces)
        return intersecting_faces(self.points, self.faces, query=query, order=self._order, coincident="shared")

    def _moved_faces(self) -> np.ndarray | None:
        """Faces that are not, vertex for vertex, faces of the restart point (None: all faces).

        Two faces kept from the (clean) restart point, with their vertices where they were, still do not
        meet; only pairs with a moved or new face need a check.
        """
        if self._baseline:
            return None  # a self-intersecting input is always compared whole against its baseline
        source, made = self._since_clean
        moved_vertex = np.empty(len(self.points), bool)
        for_ranges(_moved_vertex_range, len(self.points), self.points, self._clean.points, source, moved_vertex)
        moved = np.empty(len(self.faces), bool)
        for_ranges(_moved_range, len(self.faces), moved_vertex, self.faces, made, moved)
        if moved.all():
            return None  # every face has a moved vertex
        return moved

    def _lap(self, part: str, start: float) -> float:
        """Add the time since ``start`` to :attr:`profile` (when profiling) and restart the clock."""
        now = time.perf_counter()
        if self.profile is not None:
            self.profile.setdefault(part, []).append(now - start)
        return now

    # -- running -------------------------------------------------------------------------

    def step(self) -> None:
        """Advance one step that the guard accepts (a rejected step is undone and tried again, shorter)."""
        self.run(1)

    def _advance(self, checkpoint: bool) -> bool:
        self._step()
        return self._accept() if self._due(checkpoint) else True

    @property
    def state(self) -> dict[str, np.ndarray]:
        """The current mesh (``points`` (V', 3), ``faces`` (F', 3)), input ``ids`` (V',) and ``displacement`` (V', 3)."""
        return {"points": self.points, "faces": self.faces, "ids": self.ids, "displacement": self.displacement}

    def _due(self, forced: bool) -> bool:
        if not self.check_every:
            return False
        return forced or self.step_count - self._clean.step >= self.check_every

    def _accept(self) -> bool:
        """Check the mesh; keep it as the restart point, or roll back and shorten local steps."""
        clock = time.perf_counter()
        # faces that both kept their place were clean at the restart point and still are
        hits = self._intersections(self._moved_faces())
        self._lap("guard", clock)
        if np.count_nonzero(hits) <= self._baseline:
            self._set_clean()
            return True
        if self.repair == "topology":
            # imported here: the repair's exact predicates compile on import, and most runs never repair
            from pverosion.kernels.repair.mesh_repair import RepairError

            try:
                self._repair_topology()
            except RepairError:
                pass  # no clean surface came out: roll back as "retry" does
            else:
                self._set_clean()
                return True
        self._roll_back(hits)
        return False

    def _roll_back(self, hits: np.ndarray) -> None:
        """Restore the restart point after halving the steps of the vertices of the faces ``hits`` (F,) and of their
        two-ring neighbourhood."""
        near = np.zeros(len(self.points), bool)
        near[self.faces[hits].ravel()] = True
        ring_ptr, ring_idx = self._ring
        near = _grow_by_ring(ring_ptr, ring_idx, _grow_by_ring(ring_ptr, ring_idx, near))
        ids = self.ids[near]
        if not np.any(self._scale[ids] > 0.0):
            raise RuntimeError(
                f"self-intersections appeared after step {self._clean.step} next to frozen vertices only; "
                "switch mesh improvement off (min_edge_ratio=0) or repair the input"
            )
        # a place that tangles again at half its pace needs far shorter steps
        self._scale[ids] *= np.where(self._scale[ids] < 1.0, self.REPEAT_FACTOR, 0.5)
        self._scale[self._scale < 0.5**self.max_halvings] = 0.0
        self.retries += 1
        self._restore(self._clean)

    def _repair_topology(self) -> None:
        """Cut the mesh along its intersection curves and keep the boundary of winding number >= 1."""
        from pverosion.kernels.repair.mesh_repair import RepairError, repair_intersections

        clock = time.perf_counter()
        result = repair_intersections(self.points, self.faces)
        if len(result.faces) == 0:  # the steps turned the whole surface inside out: nothing is inside it
            raise RepairError("the topology repair left no surface")
        source = result.source_vertex
        # a new vertex (on a curve) takes the state of the first corner of the face it was cut from
        donor = np.full(len(result.points), -1, np.int64)
        donor[result.faces.ravel()] = self.faces[np.repeat(result.source_face, 3), 0]
        old = np.where(source >= 0, source, donor)
        # an old vertex the repair cut away (or merged into a coincident one) leaves its state to the nearest
        # vertex that stays
        gone = np.ones(len(self.points), bool)
        gone[source[source >= 0]] = False
        heir = np.full(len(self.points), -1, np.int64)
        if gone.any():
            from scipy.spatial import cKDTree  # on a repair only

            heir[gone] = cKDTree(result.points).query(self.points[gone])[1]
        self.points, self.faces = result.points, result.faces
        self.ids = self.ids[old]
        self.displacement = self.displacement[old]
        self._after_repair(source, old, heir)
        self._build_topology()
        self._baseline = 0
        self.repairs += 1
        self._lap("repair", clock)

    def _after_repair(self, source: np.ndarray, donor: np.ndarray, heir: np.ndarray) -> None:
        """Carry per-vertex state of a subclass over a topology repair: ``source`` (V',) is the old index of
        every vertex (-1 for a new one on a curve), ``donor`` (V',) an old vertex next to it, and ``heir`` (V,)
        the new vertex nearest to every old vertex that is gone (-1 for those that stay)."""
        self._after_collapse(donor)

    @property
    def frozen(self) -> int:
        """Number of current vertices frozen by the self-intersection guard."""
        return int(np.count_nonzero(self._scale[self.ids] == 0.0))
