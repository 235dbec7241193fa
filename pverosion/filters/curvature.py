"""Curvature filter: principal, mean and Gaussian curvature of a triangle surface."""

from __future__ import annotations

import warnings

import numpy as np

from pverosion.filters.base import (
    ErosionFilter,
    Param,
    polydata_triangle_mesh,
    replace_triangles,
    set_field_value,
    set_point_array,
)
from pverosion.kernels.curvature.normalize import NORMALIZATIONS, normalize_curvature
from pverosion.kernels.curvature.operator import CurvatureOperator, principal_curvatures
from pverosion.kernels.mesh.locality import locality_renumbering
from pverosion.kernels.mesh.orientation import ORIENTATIONS, orient_sorted
from pverosion.kernels.validation import InvalidMeshError, check_welded

__all__ = ["Curvature"]


class Curvature(ErosionFilter):
    """Per-vertex curvature after Rusinkiewicz (2004).

    Output point arrays: ``mean_curvature``, ``gaussian_curvature``, ``k1``,
    ``k2`` (k1 >= k2), ``principal_direction_1``, ``principal_direction_2``,
    ``normals``, and with a normalisation ``mean_curvature_normalized``.
    Field data: ``face_orientation`` (the orientation used) and
    ``flipped_faces`` (how many faces were reversed to get it).

    With ``orientation="outward"`` (default) the faces are made consistent and
    outward first, so convex regions get H > 0 whatever the file's winding;
    the output carries the reoriented faces.
    """

    LABEL = "Curvature (Rusinkiewicz)"
    PARAMS = (
        Param(
            "orientation",
            "outward",
            "Face orientation to use: outward (convex is H > 0), inward, or keep the input's.",
            choices=ORIENTATIONS,
        ),
        Param(
            "normalization",
            "none",
            "Extra array mean_curvature_normalized: symmetric <-H,H> -> <-1,1> (weathering) "
            "or shifted <Hmin,Hmax> -> <0,1> (hydraulic erosion).",
            choices=NORMALIZATIONS,
        ),
    )

    def execute(self, inp, out) -> None:
        """Compute the curvature arrays of ``inp`` into ``out``."""
        points, faces = polydata_triangle_mesh(inp)
        check_welded(faces, len(points))
        mode = self.get_option("orientation")
        if mode == "keep":
            n_flipped = 0
            result = principal_curvatures(points, faces)
        else:
            # the orientation's faces come sorted the way the curvature operator sorts them, in the
            # same vertex numbering (the caller's, or the Morton order of a mesh of poor locality)
            renumbering = locality_renumbering(points, faces)
            if renumbering is None:
                local_points, local_faces = points, faces
            else:
                local_points, local_faces = renumbering.to_local(points), renumbering.faces(faces)
            oriented = orient_sorted(local_points, local_faces, mode=mode)
            n_flipped = oriented.n_flipped
            if oriented.n_nonmanifold:
                warnings.warn(f"curvature: {oriented.n_nonmanifold} face sides lie on edges shared by more than two "
                              "faces; the curvature near them mixes the surfaces that meet there (pverosion repair "
                              "separates them)", UserWarning, stacklevel=2)
            operator = CurvatureOperator.from_sorted(oriented.faces, len(points), renumbering=renumbering,
                                                     owned=oriented.owned)
            result = operator.at_local_points(local_points)
        if not result.point_areas.any():
            raise InvalidMeshError("mesh has no area: every triangle is degenerate (its points lie on a line or "
                                   "coincide), so it has no curvature")
        out.ShallowCopy(inp)
        if n_flipped:
            replace_triangles(out, oriented.input_faces(faces))
        mean = result.mean  # the result arrays are fresh: the output shares their memory instead of copying it
        set_point_array(out, "mean_curvature", mean, copy=False)
        set_point_array(out, "gaussian_curvature", result.gaussian, copy=False)
        set_point_array(out, "k1", result.k1, copy=False)
        set_point_array(out, "k2", result.k2, copy=False)
        set_point_array(out, "principal_direction_1", result.direction1, copy=False)
        set_point_array(out, "principal_direction_2", result.direction2, copy=False)
        set_point_array(out, "normals", result.normals, copy=False)
        method = self.get_option("normalization")
        if method != "none":
            set_point_array(out, "mean_curvature_normalized", normalize_curvature(mean, method), copy=False)
        out.GetPointData().SetActiveScalars("mean_curvature")
        set_field_value(out, "face_orientation", mode)
        set_field_value(out, "flipped_faces", n_flipped)
        set_field_value(out, "mean_abs_curvature", float(np.mean(np.abs(mean))))
