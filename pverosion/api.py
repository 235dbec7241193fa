"""Functional front end: ``pverosion.<stage>(mesh, ...)``, one call per filter class."""

from __future__ import annotations

import pyvista as pv

from pverosion._frontend import apply_filter
from pverosion.filters.curvature import Curvature

__all__ = ["curvature"]


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
