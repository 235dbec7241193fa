"""Filters over a solver that moves the vertices of a closed mesh (weathering, hydraulic erosion).

:class:`MeshSolverFilter` is the time-stepped filter of every stage built on
:class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`, and :func:`mesh_solver_output`
fills its output mesh.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkIdTypeArray, vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray

from pverosion.filters.base import (
    TimeSteppedFilter,
    polydata_triangles,
    replace_triangles,
    set_field_value,
    set_point_array,
)
from pverosion.kernels.materials.erodibility import Erodibility
from pverosion.kernels.mesh.locality import CanonicalMesh
from pverosion.kernels.mesh.topology import EdgeTopology
from pverosion.kernels.solver.mesh_evolution import GuardedMeshSolver, evolvable_topology

__all__ = ["MeshSolverFilter", "evolving_surface", "mesh_solver_output", "output_rows"]


def _renumbered_cells(cells: vtkCellArray, ids: np.ndarray, n_input: int) -> vtkCellArray:
    """The cells (vertices or lines) of ``cells`` in the numbering of the surviving input vertices ``ids``.

    Parameters
    ----------
    cells : vtkCellArray
        Cells over the input's ``n_input`` points.
    ids : numpy.ndarray, shape (V',)
        Input index of each output vertex.
    n_input : int
        Number of input points.

    Returns
    -------
    vtkCellArray
        The cells whose points all survive, renumbered; the others are dropped.
    """
    offsets = numpy_support.vtk_to_numpy(cells.GetOffsetsArray()).astype(np.int64)
    connectivity = numpy_support.vtk_to_numpy(cells.GetConnectivityArray()).astype(np.int64)
    new_index = np.full(n_input, -1, dtype=np.int64)
    from_input = ids < n_input  # the others were added (holes closed): no input cell uses them
    new_index[ids[from_input]] = np.flatnonzero(from_input)
    mapped = new_index[connectivity]
    sizes = np.diff(offsets)
    cell_of = np.repeat(np.arange(len(sizes)), sizes)
    keep = np.bincount(cell_of[mapped < 0], minlength=len(sizes)) == 0
    id_type = vtkIdTypeArray().GetDataType()
    kept_offsets = np.concatenate([[0], np.cumsum(sizes[keep])])
    result = vtkCellArray()
    result.SetData(numpy_support.numpy_to_vtk(kept_offsets, deep=True, array_type=id_type),
                   numpy_support.numpy_to_vtk(mapped[keep[cell_of]], deep=True, array_type=id_type))
    return result


def _with_missing_row(values: np.ndarray) -> np.ndarray:
    """``values`` (N, ...) and one more row for the points the input does not have (holes closed by the stage):
    NaN, or 0 for integers."""
    missing = np.zeros((1, *values.shape[1:]), values.dtype)
    if np.issubdtype(values.dtype, np.floating):
        missing[:] = np.nan
    return np.concatenate([values, missing])


def output_rows(solver: GuardedMeshSolver, canonical: CanonicalMesh | None) -> np.ndarray | None:
    """Which of the solver's vertices each output point is: None for the solver's order.

    A solver that runs on a :func:`~pverosion.kernels.mesh.locality.canonical_mesh`
    gives its output in the caller's numbering while it has the caller's
    vertices and faces (no collapse, no topology repair), else in its own.
    """
    if canonical is None or solver.collapses or solver.repairs:
        return None
    if len(solver.points) != len(canonical.renumbering.order):
        return None
    return canonical.renumbering.rank


def mesh_solver_output(solver: GuardedMeshSolver, source, out, *, prefix: str = "weathering",
                       canonical: CanonicalMesh | None = None,
                       point_arrays: Mapping[str, np.ndarray] | None = None) -> None:
    """Fill vtkPolyData ``out`` with the solver's current mesh and its arrays.

    Point arrays of ``source`` are carried to the surviving vertices (points
    the stage added, where it closed holes, get NaN, or 0 in integer
    arrays), and so are its vertex and line cells (those that lost a point
    are dropped). Adds
    ``mean_curvature``, ``displacement`` (cumulative vector), ``erosion_depth``
    (cumulative displacement into the original surface, along the original
    inward normal) and, as field data, one ``<prefix>_<statistic>`` series
    per step (step 0 first), ``retries`` and ``frozen_vertices``. Used by
    every stage built on :class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`.
    A solver built on ``canonical`` (the :func:`~pverosion.kernels.mesh.locality.canonical_mesh`
    of ``source``) has its output put back in the caller's numbering where
    :func:`output_rows` allows. ``point_arrays`` are more per-vertex arrays
    (V',) or (V', K) of the solver, by name, put in the output's order.
    """
    rows = output_rows(solver, canonical)

    def ordered(values: np.ndarray) -> np.ndarray:
        return values if rows is None else values[rows]

    out.ShallowCopy(source)
    points = vtkPoints()  # a new object: the shallow copy shares the input's points
    points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(ordered(solver.points)), deep=True))
    out.SetPoints(points)
    replace_triangles(out, solver.faces if canonical is None or rows is None else canonical.caller_faces(solver.faces))
    ids = solver.ids if canonical is None else canonical.renumbering.order[solver.ids]  # the caller's vertices
    n_input = source.GetNumberOfPoints()
    if rows is None and (canonical is not None or len(ids) != n_input):
        # vertices were collapsed (or are in the solver's numbering): the input's vertex and line cells follow them
        out.SetVerts(_renumbered_cells(source.GetVerts(), ids, n_input))
        out.SetLines(_renumbered_cells(source.GetLines(), ids, n_input))
    src_pd, out_pd = source.GetPointData(), out.GetPointData()
    out_pd.Initialize()
    for k in range(src_pd.GetNumberOfArrays()):
        arr = src_pd.GetAbstractArray(k)
        if arr is None or arr.GetName() is None or not hasattr(arr, "GetNumberOfComponents"):
            continue
        values = _with_missing_row(numpy_support.vtk_to_numpy(arr))
        carried = numpy_support.numpy_to_vtk(np.ascontiguousarray(ordered(values[np.minimum(ids, n_input)])),
                                             deep=True)
        carried.SetName(arr.GetName())
        out_pd.AddArray(carried)
    if len(solver.faces) != source.GetNumberOfCells() or (canonical is not None and rows is None):
        out.GetCellData().Initialize()  # faces were collapsed or renumbered: per-face input data no longer applies
    set_point_array(out, "mean_curvature", ordered(solver.mean_curvature()))
    set_point_array(out, "displacement", ordered(solver.displacement))
    set_point_array(out, "erosion_depth", ordered(solver.erosion_depth()))
    for name, values in (point_arrays or {}).items():
        set_point_array(out, name, ordered(values))
    out_pd.SetActiveScalars("mean_curvature")
    for name, series in solver.statistics.items():
        set_field_value(out, f"{prefix}_{name}", series)
    set_field_value(out, "retries", solver.retries)
    set_field_value(out, "frozen_vertices", solver.frozen)
    set_field_value(out, "topology_repairs", solver.repairs)


def evolving_surface(inp) -> tuple[np.ndarray, np.ndarray, EdgeTopology]:
    """Points (V, 3), triangles (F, 3) and edge topology of vtkPolyData ``inp``; ``InvalidMeshError`` if a
    :class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver` cannot evolve it.

    The checks of every front end of weathering and hydraulic erosion (the
    filters and the live viewer), before any other work: those of
    :func:`polydata_triangles` (finite points, a warning for coarsely stored
    ones) and :func:`~pverosion.kernels.solver.mesh_evolution.evolvable_topology`
    (proper, welded faces on a 2-manifold), which the solver repeats for its
    Python callers.
    """
    points, faces = polydata_triangles(inp)
    return points, faces, evolvable_topology(faces, len(points))


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
