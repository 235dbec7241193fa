"""Repair and Boolean filters: self-intersections cut away, union / intersection / difference of closed meshes.

Both wrap :mod:`pverosion.kernels.repair.mesh_repair` (Skorkovská's thesis §10.2–10.3)
and fill their output alike:

- point data ``on_intersection`` (int8, 1 on a vertex of an intersection curve);
- cell data ``source_face`` (int64, the input face each output face is a piece
  of) and, for Booleans, ``source_mesh`` (int8, 0 for input A, 1 for B;
  ``source_face`` then counts the faces of that input);
- cell arrays of the input(s) carried to the pieces of their faces (for a
  Boolean, those that both inputs have with the same number of components);
- field data: ``intersection_cases`` (int64, how often each case of the
  thesis' Table 10.1 occurred, in the order of ``intersection_case_names``,
  i.e. :data:`~pverosion.kernels.exact.intersection_curves.CASES`),
  ``intersection_valid_cases``, ``intersection_impossible_cases``,
  ``intersection_segments``, ``intersection_loops`` (the traced curves),
  ``intersection_touching`` (face pairs meeting in one point) and
  ``intersection_coplanar`` (coplanar face pairs whose boxes meet), all int64.

Input point data are not carried: the curve points are new vertices.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray
from vtkmodules.vtkCommonDataModel import vtkPolyData

from pverosion.filters.base import ErosionFilter, Param, polydata_triangles, replace_triangles
from pverosion.kernels.exact.intersection_curves import CASES
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.mesh.topology import boundary_edges
from pverosion.kernels.repair.mesh_repair import (
    DEFAULT_TOLERANCE,
    OPERATIONS,
    RepairResult,
    boolean_meshes,
    outward_parts,
    repair_intersections,
)
from pverosion.kernels.validation import InvalidMeshError, as_triangle_mesh, check_proper_faces

__all__ = ["REPAIR_ORIENTATIONS", "BooleanOperation", "RepairIntersections", "repair_output"]

REPAIR_ORIENTATIONS = ("keep", "outward")
"""Accepted values of the ``orientation`` option of the repair filters."""

_MESH_PARAMS = (
    Param("tolerance", DEFAULT_TOLERANCE, "Pre-pass: faces with an edge shorter than this, or a corner this close to "
          "the opposite edge (relative to the bounding-box diagonal), are nearly degenerate and removed first by "
          "edge collapse and flip; 0 skips it.", minimum=0.0, advanced=True),
    Param("improve", False, "Improve the mesh afterwards: collapse the needles and flip or split the caps the "
          "cutting made, keeping the intersection curves."),
)

_ORIENTATION_DOC = ("Face orientation of the input(s): outward (default) makes each closed part consistent and "
                    "outward first (a part wholly inside another becomes a cavity wall; overlapping parts stay "
                    "outward and merge), keep trusts the input's winding (it must point outward).")


def _closed_operand(mesh, orientation: str, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Points and outward triangles of one input; ``InvalidMeshError`` naming ``what`` otherwise."""
    try:
        points, faces = as_triangle_mesh(*polydata_triangles(mesh))
        check_proper_faces(faces)
    except InvalidMeshError as exc:
        raise InvalidMeshError(f"{what}: {exc}") from None
    if len(boundary_edges(faces, len(points))):
        raise InvalidMeshError(f"{what} must be closed: it has boundary edges "
                               "(merge duplicate points with .clean() or fill its holes first)")
    if orientation == "outward":
        faces = outward_parts(points, faces)
    volume = signed_volume(points, faces)  # about the centroid: far from the origin, about it the sum cancels
    if volume == 0.0:
        raise InvalidMeshError(f"{what} encloses no volume: its points lie in a plane or on a line, or coincide")
    if volume < 0.0:
        raise InvalidMeshError(f"{what} encloses a negative volume ({volume:.6g}): its faces point inward "
                               "(use orientation='outward' or reverse them)")
    return points, faces


def _int_field(mesh, name: str, values) -> None:
    arr = numpy_support.numpy_to_vtk(np.atleast_1d(np.asarray(values, dtype=np.int64)), deep=True)
    arr.SetName(name)
    mesh.GetFieldData().AddArray(arr)


def _cell_array(mesh, name: str, values: np.ndarray) -> None:
    arr = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    arr.SetName(name)
    mesh.GetCellData().AddArray(arr)


def _carried_cell_arrays(sources) -> dict[str, np.ndarray]:
    """Numeric cell arrays of the polygons of every source, concatenated, for those all sources share."""
    carried: dict[str, list[np.ndarray]] = {}
    for k, mesh in enumerate(sources):
        cd = mesh.GetCellData()
        first = mesh.GetNumberOfVerts() + mesh.GetNumberOfLines()  # polygons follow verts and lines
        count = mesh.GetPolys().GetNumberOfCells()
        names = set()
        for i in range(cd.GetNumberOfArrays()):
            arr = cd.GetArray(i)  # None for string and other non-numeric arrays
            if arr is None or not arr.GetName() or arr.GetNumberOfTuples() != mesh.GetNumberOfCells():
                continue
            values = numpy_support.vtk_to_numpy(arr)[first:first + count]
            if k == 0:
                carried[arr.GetName()] = [values]
                names.add(arr.GetName())
            elif arr.GetName() in carried and values.shape[1:] == carried[arr.GetName()][0].shape[1:]:
                carried[arr.GetName()].append(values)
                names.add(arr.GetName())
        carried = {name: parts for name, parts in carried.items() if name in names}
    return {name: np.concatenate(parts) for name, parts in carried.items()}


def repair_output(result: RepairResult, sources, out: vtkPolyData) -> None:
    """Fill ``out`` with a repair or Boolean result and its arrays (see the module docstring).

    Parameters
    ----------
    result : RepairResult
    sources : sequence of vtkPolyData
        The input (repair) or the inputs A and B (Boolean), whose cell
        arrays are carried.
    out : vtkPolyData
    """
    out.Initialize()
    points = vtkPoints()
    points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(result.points, dtype=np.float64), deep=True))
    out.SetPoints(points)
    replace_triangles(out, result.faces)
    source_face = np.asarray(result.source_face, dtype=np.int64)
    for name, values in _carried_cell_arrays(sources).items():
        _cell_array(out, name, values[source_face])
    if len(sources) > 1:
        n_a = sources[0].GetPolys().GetNumberOfCells()
        from_b = source_face >= n_a
        _cell_array(out, "source_mesh", from_b.astype(np.int8))
        source_face = np.where(from_b, source_face - n_a, source_face)
    _cell_array(out, "source_face", source_face)
    on_curve = numpy_support.numpy_to_vtk(np.asarray(result.on_curve, dtype=np.int8), deep=True)
    on_curve.SetName("on_intersection")
    out.GetPointData().AddArray(on_curve)
    out.GetPointData().SetActiveScalars("on_intersection")
    curves = result.curves
    table = curves.case_table
    _int_field(out, "intersection_cases", [table[name] for name in CASES])
    names = vtkStringArray()
    names.SetName("intersection_case_names")
    for name in CASES:
        names.InsertNextValue(name)
    out.GetFieldData().AddArray(names)
    _int_field(out, "intersection_valid_cases", table["valid"])
    _int_field(out, "intersection_impossible_cases", table["impossible"])
    _int_field(out, "intersection_segments", len(curves.segments))
    _int_field(out, "intersection_loops", len(result.polylines))
    _int_field(out, "intersection_touching", curves.touching)
    _int_field(out, "intersection_coplanar", len(curves.coplanar))


class RepairIntersections(ErosionFilter):
    """Remove the self-intersections of a closed triangle mesh (Skorkovská's thesis §10.2).

    The intersection curves are found with exact predicates, the faces are
    cut along them, and what stays is the boundary of the region where the
    input's winding number is at least 1: parts that ended up inside the
    solid, or turned inside out, are cut away. Intersections between closed
    parts are resolved too (overlapping parts merge); the output may fall
    apart into several closed pieces. The input must be closed and made of
    triangles; it is oriented outward first unless ``orientation`` is keep.
    The output is a closed, oriented 2-manifold without self-intersections,
    or ``RepairError`` is raised.

    Output point data ``on_intersection``; cell data ``source_face`` and the
    input's cell arrays; field data ``intersection_cases`` (with
    ``intersection_case_names``), ``intersection_valid_cases``,
    ``intersection_impossible_cases``, ``intersection_segments``,
    ``intersection_loops``, ``intersection_touching``, ``intersection_coplanar``.
    """

    LABEL = "Repair self-intersections"
    COMMAND = "repair"
    PARAMS = (Param("orientation", "outward", _ORIENTATION_DOC, choices=REPAIR_ORIENTATIONS), *_MESH_PARAMS)

    def execute(self, inp, out) -> None:
        """Repair ``inp`` into ``out``."""
        points, faces = _closed_operand(inp, self.get_option("orientation"), "the mesh")
        self.UpdateProgress(0.1)
        result = repair_intersections(points, faces, tolerance=self.get_option("tolerance"),
                                      improve=self.get_option("improve"))
        repair_output(result, [inp], out)


class BooleanOperation(ErosionFilter):
    """Union, intersection or difference of two closed triangle meshes (Skorkovská's thesis §10.3).

    The two inputs (ports 0 = A and 1 = B) are cut along their exact
    intersection curves and the pieces of each kept or dropped by whether
    they lie inside the other: ``union`` A ∪ B, ``intersection`` A ∩ B,
    ``difference`` A ∖ B, ``reverse_difference`` B ∖ A (the subtracted
    operand's pieces turn around). Both inputs must be closed and made of
    triangles (oriented outward first unless ``orientation`` is keep); an
    input that intersects itself stands for the region where its winding
    number is at least 1.

    Output point data ``on_intersection``; cell data ``source_mesh`` (0 for
    A, 1 for B), ``source_face`` (the face of that input) and the cell arrays
    both inputs have; field data as :class:`RepairIntersections`.
    """

    LABEL = "Boolean operation"
    COMMAND = "boolean"
    INPUT_PORTS = ("InputA", "InputB")
    PARAMS = (
        Param("operation", "union", "union (A or B), intersection (A and B), difference (A minus B) "
              "or reverse_difference (B minus A).", choices=OPERATIONS),
        Param("orientation", "outward", _ORIENTATION_DOC, choices=REPAIR_ORIENTATIONS),
        *_MESH_PARAMS,
    )

    def execute(self, inp_a, inp_b, out) -> None:
        """Combine ``inp_a`` and ``inp_b`` into ``out``."""
        orientation = self.get_option("orientation")
        points_a, faces_a = _closed_operand(inp_a, orientation, "mesh A")
        points_b, faces_b = _closed_operand(inp_b, orientation, "mesh B")
        self.UpdateProgress(0.1)
        result = boolean_meshes(points_a, faces_a, points_b, faces_b, self.get_option("operation"),
                                tolerance=self.get_option("tolerance"), improve=self.get_option("improve"))
        repair_output(result, [inp_a, inp_b], out)
