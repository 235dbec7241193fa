"""Weathering filter: curvature-driven vertex displacement over time steps."""

from __future__ import annotations

from pverosion.filters.base import (
    Param,
)
from pverosion.filters.mesh_solver import MeshSolverFilter, evolving_surface, mesh_solver_output
from pverosion.kernels.curvature.normalize import SOLVER_NORMALIZATIONS
from pverosion.kernels.mesh.orientation import ORIENTATIONS
from pverosion.kernels.solver.mesh_evolution import REPAIR_MODES
from pverosion.kernels.weathering.model import DIRECTIONS, WeatheringSolver

__all__ = ["Weathering", "weathering_output"]

weathering_output = mesh_solver_output
"""The output of a weathering run (:func:`~pverosion.filters.mesh_solver.mesh_solver_output`)."""


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
              minimum=0.0, maximum=0.99, advanced=True),
        Param("check_every", 10, "Self-intersection guard period in steps (0: off).", minimum=0, advanced=True),
        Param("repair", "retry", "When the surface meets itself: roll back and shorten the steps there (retry), "
              "cut it along the intersection curves and go on (topology), or nothing (off).", choices=REPAIR_MODES,
                    advanced=True),
        Param("erodibility_array", "", "Input point array used as per-vertex erodibility (empty: uniform)."),
        Param("orientation", "outward", "Face orientation to use (outward: convex regions erode).",
              choices=ORIENTATIONS, advanced=True),
    )

    def _new_solver(self, inp) -> WeatheringSolver:
        points, faces, _ = evolving_surface(inp)
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
        mesh_solver_output(solver, inp, out)
