"""Functional front end: ``pverosion.<stage>(mesh, ...)``, one call per filter class."""

from __future__ import annotations

import pyvista as pv

from pverosion._frontend import apply_filter
from pverosion.filters.curvature import Curvature
from pverosion.filters.weathering import Weathering
from pverosion.kernels.weathering import Erodibility

__all__ = ["curvature", "weather"]


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
    options = dict(iterations=iterations, power=power, step_divisor=step_divisor, direction=direction,
                   min_edge_ratio=min_edge_ratio, check_every=check_every, orientation=orientation)
    if isinstance(erodibility, str):
        return apply_filter(Weathering, mesh, erodibility_array=erodibility, **options)
    return apply_filter(Weathering, mesh, erodibility=erodibility, **options)
