"""Weathering filter: curvature-driven vertex displacement over time steps."""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints

from pverosion.filters.base import (
    Param,
    TimeSteppedFilter,
    polydata_triangles,
    replace_triangles,
    set_field_value,
    set_point_array,
)
from pverosion.kernels.curvature.normalize import SOLVER_NORMALIZATIONS
from pverosion.kernels.mesh.orientation import ORIENTATIONS
from pverosion.kernels.mesh.topology import EdgeTopology, edge_topology
from pverosion.kernels.solver.mesh_evolution import REPAIR_MODES, GuardedMeshSolver
from pverosion.kernels.validation import InvalidMeshError
from pverosion.kernels.weathering.model import DIRECTIONS, Erodibility, WeatheringSolver

__all__ = ["MeshSolverFilter", "Weathering", "weathering_output"]


def weathering_output(solver: GuardedMeshSolver, source, out, *, prefix: str = "weathering") -> None:
    """Fill vtkPolyData ``out`` with the solver's current mesh and its arrays.

    Point arrays of ``source`` are carried to the surviving vertices. Adds
    ``mean_curvature``, ``displacement`` (cumulative vector), ``erosion_depth``
    (cumulative displacement into the original surface, along the original
    inward normal) and, as field data, one ``<prefix>_<statistic>`` series
    per step (step 0 first), ``retries`` and ``frozen_vertices``. Used by
    every stage built on :class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`.
    """
    out.ShallowCopy(source)
    points = vtkPoints()  # a new object: the shallow copy shares the input's points
    points.SetData(numpy_support.numpy_to_vtk(solver.points, deep=True))
    out.SetPoints(points)
    replace_triangles(out, solver.faces)
    src_pd, out_pd = source.GetPointData(), out.GetPointData()
    out_pd.Initialize()
    for k in range(src_pd.GetNumberOfArrays()):
        arr = src_pd.GetAbstractArray(k)
        if arr is None or arr.GetName() is None or not hasattr(arr, "GetNumberOfComponents"):
            continue
        values = numpy_support.vtk_to_numpy(arr)
        carried = numpy_support.numpy_to_vtk(np.ascontiguousarray(values[solver.ids]), deep=True)
        carried.SetName(arr.GetName())
        out_pd.AddArray(carried)
    if len(solver.faces) != source.GetNumberOfCells():
        out.GetCellData().Initialize()  # faces were collapsed: per-face input data no longer applies
    set_point_array(out, "mean_curvature", solver.mean_curvature())
    set_point_array(out, "displacement", solver.displacement)
    set_point_array(out, "erosion_depth", solver.erosion_depth())
    out_pd.SetActiveScalars("mean_curvature")
    for name, series in solver.statistics.items():
        set_field_value(out, f"{prefix}_{name}", series)
    set_field_value(out, "retries", solver.retries)
    set_field_value(out, "frozen_vertices", solver.frozen)
    set_field_value(out, "topology_repairs", solver.repairs)


class MeshSolverFilter(TimeSteppedFilter):
    """A stage over a :class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`, kept between updates.

    Subclasses build the solver in ``_new_solver(inp)`` and fill the output in
    ``_fill(solver, inp, out)``. Asking for a later time continues the cached
    solver; an earlier time, a new input or changed options start over. The
    erodibility is a Python value (array, callable, material field) or the
    ``erodibility_array`` option.
    """

    def __init__(self, *, erodibility: Erodibility = None, **options):
        super().__init__(**options)
        self._erodibility = erodibility

    def _new_solver(self, inp) -> GuardedMeshSolver:
        raise NotImplementedError

    @staticmethod
    def _surface(inp) -> tuple[np.ndarray, np.ndarray, EdgeTopology]:
        """Points (V, 3), triangles (F, 3) and edge topology of ``inp``; ``InvalidMeshError`` if it is non-manifold.

        A surface that evolves needs every edge between at most two faces:
        curvature and the self-intersection guard are undefined elsewhere.
        """
        points, faces = polydata_triangles(inp)
        topology = edge_topology(np.asarray(faces, np.int64), len(points))
        if topology.n_nonmanifold_edges:
            raise InvalidMeshError(f"mesh has {topology.n_nonmanifold_edges} non-manifold edges (shared by more than "
                                   "two faces): repair it first (pverosion repair, or pverosion.repair)")
        return points, faces, topology

    def _fill(self, solver: GuardedMeshSolver, inp, out) -> None:
        raise NotImplementedError

    def execute(self, inp, out) -> None:
        """Advance (or restart) the cached solver to the requested step and fill ``out``."""
        step = self.requested_step()
        solver, _ = self.cached_solver(inp, step, self._new_solver)
        start = solver.step_count
        total = max(step - start, 1)

        def progress(s: GuardedMeshSolver) -> None:
            self.UpdateProgress(min((s.step_count - start) / total, 1.0))

        solver.run(step - start, outputs=[step], on_step=progress)
        self._fill(solver, inp, out)
        out.GetInformation().Set(out.DATA_TIME_STEP(), float(step))

    def set_erodibility(self, erodibility: Erodibility) -> None:
        """Per-vertex array (V,) or callable of points (N, 3) -> (N,); None for uniform."""
        self._erodibility = erodibility
        self.Modified()

    def _erodibility_for(self, inp):
        name = self.get_option("erodibility_array")
        if not name:
            return self._erodibility
        arr = inp.GetPointData().GetArray(name)
        if arr is None:
            raise ValueError(f"erodibility_array {name!r} is not a point array of the input")
        values = numpy_support.vtk_to_numpy(arr)
        if values.ndim != 1:
            raise ValueError(f"erodibility_array {name!r} must have one component; got {values.shape[1]}")
        return values


class Weathering(MeshSolverFilter):
    """Curvature-driven weathering (Skorkovská et al. 2019, §3.3).

    Convex vertices move along the unit uniform Laplacian by
    ``H^n * e_avg / x`` per step, small triangles are collapsed after every
    step, and a periodic self-intersection guard rolls back and shortens the
    steps where the surface tangles. The output publishes TIME_STEPS
    0..iterations (time n = step n); requesting a later time continues from
    the cached state, an earlier one restarts.

    Output point arrays: ``mean_curvature``, ``displacement``,
    ``erosion_depth``; field data: per-step ``weathering_volume``,
    ``weathering_area``, ``weathering_mean_abs_curvature``,
    ``weathering_max_abs_curvature``, ``weathering_eroded_volume``,
    ``weathering_retries``, ``weathering_collapses``, and ``retries``,
    ``frozen_vertices``.
    """

    LABEL = "Weathering (curvature-driven)"
    COMMAND = "weather"
    PARAMS = (
        Param("iterations", 100, "Number of weathering steps (time steps 0..iterations).", minimum=0),
        Param("power", 1.0, "Power modifier n >= 1 of the curvature (eq. 5): larger spares flat regions.",
              minimum=1.0),
        Param("step_divisor", 10.0, "Divisor x >= 1: the largest displacement per step is e_avg / x (below 1 a step "
              "could turn the surface inside out).", minimum=1.0),
        Param("normalization", "scale_free", "Curvature normalisation: divide by max |H| over the interior vertices "
              "(scale_free: any units, open scans) or the paper's rule (only when max |H| > 1, all vertices).",
              choices=SOLVER_NORMALIZATIONS),
        Param("direction", "laplacian", "Displacement direction: unit uniform Laplacian or inward normal.",
              choices=DIRECTIONS),
        Param("min_edge_ratio", 0.1, "Collapse edges shorter than this times e_avg after every step (0: off).",
              minimum=0.0, maximum=0.99),
        Param("check_every", 10, "Self-intersection guard period in steps (0: off).", minimum=0),
        Param("repair", "retry", "When the surface meets itself: roll back and shorten the steps there (retry), "
              "cut it along the intersection curves and go on (topology), or nothing (off).", choices=REPAIR_MODES),
        Param("erodibility_array", "", "Input point array used as per-vertex erodibility (empty: uniform)."),
        Param("orientation", "outward", "Face orientation to use (outward: convex regions erode).",
              choices=ORIENTATIONS),
    )

    def _new_solver(self, inp) -> WeatheringSolver:
        points, faces, _ = self._surface(inp)
        return WeatheringSolver(
            points,
            faces,
            power=self.get_option("power"),
            step_divisor=self.get_option("step_divisor"),
            normalization=self.get_option("normalization"),
            direction=self.get_option("direction"),
            erodibility=self._erodibility_for(inp),
            min_edge_ratio=self.get_option("min_edge_ratio"),
            check_every=self.get_option("check_every"),
            orientation=self.get_option("orientation"),
            repair=self.get_option("repair"),
        )

    def _fill(self, solver: WeatheringSolver, inp, out) -> None:
        weathering_output(solver, inp, out)
