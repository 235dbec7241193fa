"""Curvature-driven weathering of triangle meshes (Skorkovská 2019, §3.2–3.3, §4.1).

Each step computes the mean curvature H of every vertex, normalises it
symmetrically (``<-H, H> -> <-1, 1>``, see ``normalization``), and moves each
convex vertex (H > 0) by the length

    d_i = min(H_i^n * erodibility_i, 1) * e_avg / x

along the unit uniform-Laplacian direction (eqs. 3–5), or along the inward
normal: never more than ``e_avg / x`` per step, however soft the material. Concave and flat vertices do not move; boundary vertices of open
scans stay fixed. After every step, triangles with an edge shorter than
``min_edge_ratio * e_avg`` are removed by edge collapse
(:mod:`pverosion.kernels.mesh.remesh`).

Self-intersection guard with rollback and local shortening of the steps, and
the mesh improvement, come from
:class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`; a vertex frozen
by the guard settles the sharp folds of noisy scans where any step tangles the
surface. A full check costs a few steps' worth of time on the bunny scan,
which is why it is periodic rather than per step.
"""

from __future__ import annotations

import time

import numpy as np

from pverosion.kernels.curvature.normalize import SOLVER_NORMALIZATIONS, normalize_symmetric
from pverosion.kernels.curvature.operator import MeanCurvatureOperator
from pverosion.kernels.materials.erodibility import Erodibility, check_erodibility, erodibility_now
from pverosion.kernels.mesh.locality import locality_renumbering
from pverosion.kernels.solver.mesh_evolution import GuardedMeshSolver, volume_area
from pverosion.kernels.validation import as_triangle_mesh
from pverosion.kernels.weathering.displacement import displace

__all__ = ["DIRECTIONS", "STAT_NAMES", "WeatheringSolver"]

DIRECTIONS = ("laplacian", "normal")
"""Accepted values of the ``direction`` option."""

STAT_NAMES = ("volume", "area", "mean_abs_curvature", "max_abs_curvature", "eroded_volume", "retries", "collapses")
"""Per-step statistics recorded by :class:`WeatheringSolver` (one row per step, step 0 first)."""


class WeatheringSolver(GuardedMeshSolver):
    """Curvature-driven weathering that builds topology once and steps cheaply.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        Triangles; they are first oriented as ``orientation`` says (outward by
        default, so convex regions have H > 0 and erode).
    power : float, default: 1.0
        Power modifier n >= 1 of eq. 5; larger values spare flat regions and
        erode protrusions.
    step_divisor : float, default: 10.0
        x of eq. 3: the largest displacement per step is ``e_avg / x``.
    direction : {"laplacian", "normal"}, default: "laplacian"
        Displacement direction: the unit uniform Laplacian (regularises the
        mesh) or the inward vertex normal (Figure 4 comparison).
    erodibility : array_like of shape (V,), callable, MaterialField or None
        Non-negative multiplier of the displacement, which stays at most
        ``e_avg / step_divisor`` per step (values above 1 speed up the vertices
        of lower curvature up to that bound): one value per input
        vertex (carried along through edge collapses), a function of the
        current points (N, 3) returning (N,) values, or a material field
        (:mod:`pverosion.kernels.materials.field`, erodibility = 1 / hardness), the
        last two evaluated every step so that erosion follows the material
        under each vertex *now*.
    normalization : {"scale_free", "paper"}, default: "scale_free"
        ``"scale_free"``: H is divided by ``max |H|`` over the interior vertices
        (not fixed boundary vertices nor their one-ring) at every step, so the
        same model in other units gives the same points up to scale, and an
        open scan erodes as the closed model. ``"paper"``: the paper's rule,
        ``max |H|`` over all vertices and only when it exceeds 1 (depends on the
        units; an open rim's large ``|H|`` slows the whole scan down).
    min_edge_ratio, check_every, max_halvings, orientation, repair
        Mesh improvement and self-intersection guard, see
        :class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`.

    Attributes
    ----------
    points, faces, ids, displacement, initial_normals, step_count, retries, collapses
        As for :class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`.
        The vertices of an input of poor locality
        (:func:`~pverosion.kernels.mesh.locality.poor_locality`, as after Loop
        subdivision) are numbered along the Morton curve of their positions
        from the start, so ``points`` lists them in that order; ``ids`` maps
        every current vertex to its input index as always.
    profile : dict or None
        Set it to ``{}`` to collect the seconds spent per part of each step
        ("curvature", "displacement" with the direction, "improvement" with
        the statistics and the next step's mean edge length, "guard").

    Examples
    --------
    >>> import pyvista as pv
    >>> cube = pv.Cube().triangulate().subdivide(3)
    >>> solver = WeatheringSolver(cube.points, cube.regular_faces)
    >>> solver.run(5)
    >>> solver.step_count
    5
    """

    STAT_NAMES = STAT_NAMES
    PROGRESS_LABEL = "weathering"
    _curvature_estimator = MeanCurvatureOperator  # a step needs H (and the normals), not the directions

    def __init__(
        self,
        points,
        faces,
        *,
        power: float = 1.0,
        step_divisor: float = 10.0,
        direction: str = "laplacian",
        erodibility: Erodibility = None,
        min_edge_ratio: float = 0.1,
        check_every: int = 10,
        max_halvings: int = 4,
        orientation: str = "outward",
        repair: str = "retry",
        normalization: str = "scale_free",
    ) -> None:
        if not (np.isfinite(power) and power >= 1.0):
            raise ValueError(f"power must be a real number >= 1; got {power!r}")
        if not (np.isfinite(step_divisor) and step_divisor > 0.0):
            raise ValueError(f"step_divisor must be > 0; got {step_divisor!r}")
        if direction not in DIRECTIONS:
            raise ValueError(f"direction must be one of {DIRECTIONS}; got {direction!r}")
        if normalization not in SOLVER_NORMALIZATIONS:
            raise ValueError(f"normalization must be one of {SOLVER_NORMALIZATIONS}; got {normalization!r}")
        pts, fcs = as_triangle_mesh(points, faces)
        renumbering = locality_renumbering(pts, fcs)
        if renumbering is not None:  # every step's passes then run in the local numbering
            pts, fcs = renumbering.to_local(pts), renumbering.faces(fcs)
        super().__init__(pts, fcs, min_edge_ratio=min_edge_ratio, check_every=check_every,
                         max_halvings=max_halvings, orientation=orientation, repair=repair)
        if renumbering is not None:
            self.ids = renumbering.order.copy()
            self.initial_normals = renumbering.to_caller(self.initial_normals)
        self.power = float(power)
        self.step_divisor = float(step_divisor)
        self.direction = direction
        self.normalization = normalization
        self._erodibility = check_erodibility(erodibility, len(self.points))
        self._start()

    def _row(self, mean_curvature: np.ndarray | None = None) -> tuple:
        if mean_curvature is None:
            mean_curvature = self.mean_curvature()
        volume, area = volume_area(self.points, self.faces, self._origin)
        abs_h = np.abs(mean_curvature)
        return (float(volume), float(area), float(abs_h.mean()), float(abs_h.max()),
                self._volume0 - float(volume), self.retries, self.collapses)

    def _step(self) -> None:
        clock = time.perf_counter()
        curv = self._curvature(self.points)
        h = curv.mean
        clock = self._lap("curvature", clock)
        # the Laplacian of the vertices that move comes with their displacement
        direction = None if self.direction == "laplacian" else -curv.normals
        e_avg = self._mean_edge_length()
        factor = self._scale[self.ids]
        erodibility = None if self._erodibility is None else erodibility_now(self._erodibility, self.points, self.ids)
        if self.normalization == "paper":
            h_norm = normalize_symmetric(h)
        else:
            h_norm = normalize_symmetric(h, where=self._interior, always=True)
        self.points = displace(self.points, direction, self.direction == "laplacian", h_norm, h, e_avg, self.power,
                               e_avg / self.step_divisor, factor, self._fixed, self.displacement,
                               ring=self._ring if direction is None else None, erodibility=erodibility)
        clock = self._lap("displacement", clock)
        if self.min_edge_ratio > 0.0:
            self._improve(self.min_edge_ratio * e_avg)
        self.step_count += 1
        self._stats.append(self._row(h))
        self._lap("improvement", clock)
