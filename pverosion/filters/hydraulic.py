"""Hydraulic erosion filter: a particle fluid poured over a closed mesh erodes it, one iteration per time step.

Output: a MultiBlock with blocks ``mesh`` (the eroded surface) and
``particles`` (the fluid: positions, ``velocity``, ``speed``, ``sediment``,
``particle_id``, ``contact``).
"""

from __future__ import annotations

import warnings
from typing import ClassVar

import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonDataModel import vtkPolyData

from pverosion.filters.base import (
    Param,
    numbers_text,
    parse_numbers,
    set_field_value,
    set_multiblock,
)
from pverosion.filters.mesh_solver import MeshSolverFilter, evolving_surface, mesh_solver_output
from pverosion.kernels.curvature.normalize import SOLVER_NORMALIZATIONS
from pverosion.kernels.fluid.particle_fluid import Drain, Emitter, FluidParameters
from pverosion.kernels.hydraulic.erosion import MODELS, HydraulicSolver, ShearParameters
from pverosion.kernels.materials.erodibility import check_erodibility, renumbered_erodibility
from pverosion.kernels.mesh.geometry import average_edge_length
from pverosion.kernels.mesh.locality import CanonicalMesh, canonical_mesh
from pverosion.kernels.mesh.orientation import ORIENTATIONS
from pverosion.kernels.solver.mesh_evolution import REPAIR_MODES, evolvable_topology
from pverosion.kernels.validation import InvalidMeshError
from pverosion.limits import check_memory, check_work

__all__ = ["HydraulicErosion", "format_drains", "format_emitters", "parse_drains", "parse_emitters",
           "particles_polydata", "to_drains", "to_emitters"]

_SHEAR = ("erosion_rate", "critical_stress", "stress_constant", "stress_power", "rate_power")


def parse_emitters(text: str) -> list[Emitter]:
    """Emitters from ``"x,y,z,dx,dy,dz,r,rate[,speed]"`` specifications separated by ``;``."""
    return [Emitter.parse(part) for part in text.split(";") if part.strip()]


def parse_drains(text: str) -> list[Drain]:
    """Drains from ``"plane:nx,ny,nz,d"`` / ``"box:xmin,ymin,zmin,xmax,ymax,zmax"`` separated by ``;``."""
    return [Drain.parse(part) for part in text.split(";") if part.strip()]


def to_emitters(value) -> tuple[Emitter, ...]:
    """Emitters from their text, an :class:`Emitter`, 8 or 9 numbers, or a sequence of those.

    Raises
    ------
    ValueError, TypeError
        For a malformed specification (the message says which).
    """
    if isinstance(value, str):
        return tuple(parse_emitters(value))
    if isinstance(value, Emitter):
        return (value,)
    items = list(value)
    if items and all(isinstance(v, (int, float, np.integer, np.floating)) for v in items):
        items = [items]  # one emitter as its numbers
    emitters = []
    for item in items:
        if isinstance(item, (str, Emitter)):
            emitters.extend(to_emitters(item))
            continue
        numbers = np.asarray(item, dtype=np.float64).ravel()
        if numbers.size not in (8, 9):
            raise ValueError(f"an emitter is x,y,z,dx,dy,dz,radius,rate[,speed] (8 or 9 numbers); got {item!r}")
        emitters.append(Emitter(tuple(numbers[0:3]), tuple(numbers[3:6]), float(numbers[6]), float(numbers[7]),
                                float(numbers[8]) if numbers.size == 9 else None))
    return tuple(emitters)


def format_emitters(emitters) -> str:
    """The text ``"x,y,z,dx,dy,dz,r,rate[,speed];..."`` of emitters (read back by :func:`parse_emitters`)."""
    return ";".join(numbers_text([*e.position, *e.direction, e.radius, e.rate, *([] if e.speed is None else [e.speed])])
                    for e in emitters)


def to_drains(value) -> tuple[Drain, ...]:
    """Drains from their text, a :class:`Drain`, or a sequence of those.

    Raises
    ------
    ValueError, TypeError
        For a malformed specification.
    """
    if isinstance(value, str):
        return tuple(parse_drains(value))
    if isinstance(value, Drain):
        return (value,)
    drains = []
    for item in value:
        if not isinstance(item, (str, Drain)):
            raise TypeError(f"a drain is a Drain or its text 'plane:nx,ny,nz,d' / 'box:...'; got {item!r}")
        drains.extend(to_drains(item))
    return tuple(drains)


def format_drains(drains) -> str:
    """The text ``"plane:nx,ny,nz,d;box:..."`` of drains (read back by :func:`parse_drains`)."""
    return ";".join(f"{d.kind}:{numbers_text(d.values)}" for d in drains)


BYTES_PER_PARTICLE = 2048
"""Upper estimate of the fluid's memory per particle (state, work buffers, neighbour lists of about 60)."""

NEIGHBOURS = 60
"""Typical neighbours of a particle in the density solve, for the work estimate of one step."""


def _check_resources(fluid: FluidParameters, emitters: list[Emitter], n_points: int, n_faces: int) -> None:
    """Refuse a fluid whose particles or per-iteration work exceed the limits (:mod:`pverosion.limits`)."""
    n = fluid.max_particles
    for k, emitter in enumerate(emitters):
        side = 2 * (emitter.radius // fluid.spacing) + 1  # the disc's lattice is built on a square of this side
        check_memory(side * side * 64, option="emitter",
                     remedy="give the emitter a smaller radius or the particles a larger radius",
                     what=f"emitter {k} (radius {emitter.radius:g}, {side:.3g}^2 lattice points of spacing "
                          f"{fluid.spacing:.3g}, twice the particle radius)")
    check_memory(n * BYTES_PER_PARTICLE + 400 * (n_points + n_faces), option="max_particles",
                 what=f"a fluid of up to {n} particles")
    check_work(float(n) * fluid.substeps * fluid.solver_iterations * NEIGHBOURS, option="substeps",
               what=f"{fluid.substeps} substeps of {fluid.solver_iterations} solver iterations over up to {n} "
                    "particles (max_particles)")
    # a substep sweeps each particle's path through the collision grid, cell by cell (cells of about r)
    sub = fluid.dt / fluid.substeps
    speed = max((e.speed or 0.0 for e in emitters), default=0.0)
    radii = (float(np.linalg.norm(fluid.gravity)) * sub * sub + speed * sub) / fluid.radius
    check_work(float(n) * fluid.substeps * radii, option="time_step",
               what=f"a substep of {sub:.3g} s, in which a particle moves about {radii:.3g} radii,")


def _warn_without_water(solver: HydraulicSolver) -> None:
    """Warn when a run emitted no particle, lost every particle it emitted, or moved no vertex: nothing eroded."""
    fluid = solver.fluid
    if fluid.steps == 0:
        return
    if fluid.emitted == 0:
        seconds = fluid.steps * fluid.dt
        rates = ", ".join(f"emitter {k}: {e.rate:g} particles/s" for k, e in enumerate(fluid.emitters))
        warnings.warn(f"hydraulic erosion: no particle was emitted in {fluid.steps} iterations ({seconds:.3g} s of "
                      f"water at time_step {fluid.dt:.3g} s; {rates}); nothing eroded: raise the rate, time_step "
                      "or iterations", UserWarning, stacklevel=2)
    elif len(fluid.positions) == 0 and fluid.drained == fluid.emitted:
        warnings.warn(f"hydraulic erosion: all {fluid.emitted} emitted particles were drained or left the domain "
                      f"{fluid.domain[0].tolist()}..{fluid.domain[1].tolist()} at once; place the emitters inside "
                      "the domain, above the mesh, or widen the domain", UserWarning, stacklevel=2)
    elif not solver.displacement.any():
        warnings.warn(f"hydraulic erosion: the water eroded nothing in {fluid.steps} iterations ({fluid.emitted} "
                      "particles emitted): none reached the mesh, or, in the sediment model, their shear stress "
                      "stayed below critical_stress; aim the emitters at the mesh from outside it, run more "
                      "iterations, or lower critical_stress", UserWarning, stacklevel=2)


def particles_polydata(solver: HydraulicSolver) -> pv.PolyData:
    """The fluid particles as a point cloud with ``velocity``, ``speed``, ``sediment``, ``particle_id``, ``contact``."""
    fluid = solver.fluid
    cloud = pv.PolyData(fluid.positions.copy()) if len(fluid.positions) else pv.PolyData()
    if len(fluid.positions):
        cloud["velocity"] = fluid.velocities.copy()
        cloud["speed"] = np.linalg.norm(fluid.velocities, axis=1)
        cloud["sediment"] = fluid.sediment.copy()
        cloud["particle_id"] = fluid.ids.copy()
        cloud["contact"] = (fluid.contact_face >= 0).astype(np.int8)
    return cloud


class HydraulicErosion(MeshSolverFilter):
    """Hydraulic erosion on a triangle mesh by our own particle fluid (Skorkovská 2019 §3.4; thesis ch. 8).

    Water enters from disc emitters, flows over the closed, outward-oriented
    input mesh (position-based fluid with mesh collision) and leaves through
    drains or the domain box. Each time step is one fluid step followed by
    one erosion step: ``model="curvature"`` moves the vertices near colliding
    particles by the shifted-curvature rule (eqs. 6–7); ``model="sediment"``
    exchanges sediment by shear stress (eqs. 8.2–8.4) and moves vertices so
    the volume changes by exactly the sediment (eqs. 8.5–8.7). TIME_STEPS are
    0..iterations; a later time continues from the cached state, an earlier
    one reruns (same seed, same result). The solver runs on the mesh
    numbered by its geometry (:func:`~pverosion.kernels.mesh.locality.canonical_mesh`),
    so results do not depend on the order of the input's vertices and faces;
    the output mesh is in the input's numbering unless edges were collapsed
    or the topology repaired.

    Output blocks: ``mesh`` with point arrays ``mean_curvature``,
    ``displacement``, ``erosion_depth``, ``f_distance`` (the last
    iteration's), ``pending_sediment``, and field data ``hydraulic_<stat>``
    per iteration; ``particles`` with ``velocity``, ``speed``, ``sediment``,
    ``particle_id``, ``contact``.
    """

    LABEL = "Hydraulic erosion (particle fluid)"
    COMMAND = "hydraulic"
    OUTPUT_TYPE = "vtkMultiBlockDataSet"
    REQUIRED: ClassVar[dict[str, str]] = {"emitter": "x,y,z,dx,dy,dz,r,rate"}
    PARAMS = (
        Param("iterations", 100, "Iterations: one fluid step and one erosion step each.", minimum=0),
        Param("model", "curvature", "Erosion model: curvature (Skorkovska 2019 eqs. 6-7) or sediment (shear stress, "
              "thesis ch. 8).", choices=MODELS),
        Param("emitter", "", "Water sources x,y,z,dx,dy,dz,r,rate[,speed] (disc centre, direction, disc radius, "
              "particles per second, speed), several separated by ';'.", parse=parse_emitters, convert=to_emitters,
              format=format_emitters, python_type="Emitter, 8 or 9 numbers, str, or a sequence of them"),
        Param("drain", "", "Water sinks plane:nx,ny,nz,d (removes n.x > d) or box:xmin,ymin,zmin,xmax,ymax,zmax, "
              "separated by ';'. Particles leaving the domain are always drained.", parse=parse_drains, convert=to_drains,
              format=format_drains, python_type="Drain, str, or a sequence of them"),
        Param("domain", "", "Box of the fluid xmin,ymin,zmin,xmax,ymax,zmax (empty: the mesh and emitters, padded).",
              numbers=6),
        Param("walls", False, "Keep particles inside the domain box (a tank) instead of draining those leaving it."),
        Param("radius", 0.0, "Particle radius (0: half the mesh's average edge length).", minimum=0.0,
              units="model units", advanced=True),
        Param("gravity", "0,0,-9.81", "Gravity vector gx,gy,gz.", numbers=3, units="model units/s^2"),
        Param("time_step", 0.0, "Time per iteration (0: automatic from the particle radius and gravity).",
              minimum=0.0, units="s", advanced=True),
        Param("substeps", 2, "Fluid substeps per iteration.", minimum=1, advanced=True),
        Param("solver_iterations", 3, "Density-constraint iterations per substep.", minimum=1, advanced=True),
        Param("viscosity", 0.01, "XSPH viscosity.", minimum=0.0, maximum=1.0, advanced=True),
        Param("friction", 0.0, "Fraction of the tangential motion removed at mesh contacts.", minimum=0.0,
              maximum=1.0, advanced=True),
        Param("max_particles", 250_000, "Emitters pause at this many particles.", minimum=1, advanced=True),
        Param("power", 1.0, "Power n of the shifted curvature (curvature model).", minimum=1.0),
        Param("step_divisor", 10.0, "Divisor x >= 1: a vertex moves at most e_avg / x per iteration (below 1 a step "
              "could turn the surface inside out).", minimum=1.0),
        Param("normalization", "scale_free", "Curvature range H_min..H_max over the interior vertices (scale_free: "
              "open scans) or over all vertices (paper); curvature model.", choices=SOLVER_NORMALIZATIONS),
        Param("influence", 1.0, "Region of influence d_influence of a particle (from its surface), in average "
              "edge lengths (curvature model).", minimum=1e-6, advanced=True),
        Param("erosion_rate", 1e-3, "k of the erosion rate k (tau - tau_c)^a (sediment model).", minimum=0.0),
        Param("critical_stress", 5.0, "Critical shear stress tau_c (sediment model).", minimum=0.0),
        Param("stress_constant", 1.0, "K of the shear stress K theta^m (sediment model).", minimum=0.0, advanced=True),
        Param("stress_power", 1.0, "m of the shear stress K theta^m (sediment model).", minimum=1e-6, advanced=True),
        Param("rate_power", 1.0, "a of the erosion rate k (tau - tau_c)^a (sediment model).", minimum=1e-6,
              advanced=True),
        Param("erodibility_array", "", "Input point array used as per-vertex erodibility (empty: uniform)."),
        Param("min_edge_ratio", 0.1, "Collapse edges shorter than this times e_avg among moved vertices (0: off).",
              minimum=0.0, maximum=0.99, advanced=True),
        Param("check_every", 10, "Self-intersection guard period in iterations (0: off).", minimum=0, advanced=True),
        Param("repair", "retry", "When the surface meets itself: roll back and shorten the steps there (retry), "
              "cut it along the intersection curves and go on (topology), or nothing (off).", choices=REPAIR_MODES,
                    advanced=True),
        Param("orientation", "outward", "Face orientation to use (outward: the fluid is outside the mesh).",
              choices=ORIENTATIONS, advanced=True),
        Param("seed", 0, "Seed of the fluid's random numbers.", minimum=0, advanced=True),
        Param("close_holes", False, "Close the holes of an open input mesh first (the fluid needs a closed mesh)."),
    )

    _canonical: CanonicalMesh | None = None  # the numbering of the solver made by _new_solver

    def _new_solver(self, inp) -> HydraulicSolver:
        points, faces, topology = evolving_surface(inp)
        emitters = list(self.structured_option("emitter"))
        drains = list(self.structured_option("drain"))
        if not emitters:
            raise ValueError("hydraulic erosion needs water: give at least one emitter x,y,z,dx,dy,dz,r,rate")
        holes = topology.n_boundary_edges
        if holes and self.get_option("close_holes"):
            from pverosion.meshing import fill_holes  # loads matplotlib: only when a hole is filled

            points, faces = fill_holes(points, faces)
            try:
                evolvable_topology(faces, len(points))
            except InvalidMeshError as error:  # the patches repeat the faces of a sheet: a sheet has no inside
                raise InvalidMeshError(f"closing the input's {holes} boundary edges did not give a closed surface to "
                                       f"erode ({error}): an open sheet has no inside to close; give a closed "
                                       "mesh, or one whose holes are openings in a closed shape") from None
        elif holes:
            raise InvalidMeshError(f"hydraulic erosion needs a closed mesh; the input has {holes} boundary edges "
                                   "(holes): fill them first, or set close_holes=True to close them")
        self._canonical = canonical = canonical_mesh(np.asarray(points, np.float64), np.asarray(faces, np.int64))
        local_points = canonical.renumbering.to_local(np.asarray(points, np.float64))
        radius = self.get_option("radius") or 0.5 * average_edge_length(local_points, canonical.faces)
        fluid = FluidParameters(
            radius=radius, gravity=tuple(parse_numbers(self.get_option("gravity"), "gravity", count=3)),
            time_step=self.get_option("time_step") or None, substeps=self.get_option("substeps"),
            solver_iterations=self.get_option("solver_iterations"), viscosity=self.get_option("viscosity"),
            friction=self.get_option("friction"), max_particles=self.get_option("max_particles"))
        _check_resources(fluid, emitters, len(points), len(faces))
        erodibility = renumbered_erodibility(check_erodibility(self._erodibility_for(inp), len(points)),
                                             canonical.renumbering.order)
        domain = None
        if self.get_option("domain"):
            box = parse_numbers(self.get_option("domain"), "domain", count=6)
            domain = (box[:3], box[3:])
        return HydraulicSolver(
            local_points, canonical.faces, fluid=fluid, emitters=emitters, drains=drains, domain=domain,
            walls=self.get_option("walls"),
            model=self.get_option("model"), power=self.get_option("power"),
            normalization=self.get_option("normalization"),
            step_divisor=self.get_option("step_divisor"), influence=self.get_option("influence"),
            shear=ShearParameters(**{name: self.get_option(name) for name in _SHEAR}),
            erodibility=erodibility, min_edge_ratio=self.get_option("min_edge_ratio"),
            check_every=self.get_option("check_every"), orientation=self.get_option("orientation"),
            repair=self.get_option("repair"), seed=self.get_option("seed"))

    def _fill(self, solver: HydraulicSolver, inp, out) -> None:
        if self.requested_step() == self.get_option("iterations"):  # judged on the whole run, not its first steps
            _warn_without_water(solver)
        mesh = vtkPolyData()
        mesh_solver_output(solver, inp, mesh, prefix="hydraulic", canonical=self._canonical,
                           point_arrays={"f_distance": solver.f_distance, "pending_sediment": solver.pending})
        set_field_value(mesh, "model", solver.model)
        set_field_value(mesh, "time", solver.fluid.time)
        set_multiblock(out, pv.MultiBlock({"mesh": pv.wrap(mesh), "particles": particles_polydata(solver)}))
