"""Hydraulic erosion of a closed triangle mesh by a particle fluid.

Each iteration advances the particle fluid by one time step
(:class:`~pverosion.kernels.fluid.particle_fluid.ParticleFluid`, colliding with the
current mesh), then erodes the mesh where particles touch it, with one of two
models:

``"curvature"`` (Skorkovská et al. 2019, §3.4, eqs. 6–7)
    Vertices within ``d_influence`` (default: the average edge length e_avg)
    of a colliding particle move by ``min(H_s^n * f_distance * erodibility, 1) * e_avg / x`` (never more than
    ``e_avg / x``, however soft the material), with
    ``f_distance = (d_influence - d_part) / d_influence`` (d_part: distance to
    the closest colliding particle's surface, the sphere of radius r it
    collides as, so a fine mesh under large particles still erodes) and H_s
    the mean curvature mapped from ``<H_min, H_max>`` onto ``<0, 1>`` (gaps
    erode slowest, protrusions fastest; H_min and H_max over the interior
    vertices, or over all with ``normalization="paper"``). The direction is the inward vertex normal where H = 0 and the
    unit uniform Laplacian where H reaches H_min or H_max, linearly
    interpolated (and made unit length) in between. No other vertex moves.

``"sediment"`` (Skorkovská thesis, ch. 8, eqs. 8.2–8.7)
    Each colliding particle sees the shear rate ``θ = |v_t| / d`` (tangential
    velocity over its distance to the contact face), the shear stress
    τ = K θ^m and the erosion rate ε = k (τ - τ_c)^a. Above τ_c the particle
    picks up ``ε dt π r²`` of volume from its contact footprint; below τ_c it
    drops ``min(carried, k (τ_c - τ)^a dt π r²)`` onto it. The footprint is
    the vertices within R of the contact point, reached along edges from the
    contact face's corners, each taking a share proportional to its area
    times ``1 - (d / R)²``, where R is r or, on a face with a longer edge,
    that edge's length up to the fluid's kernel radius 4 r (a mesh cannot
    carry a dent narrower than its faces); the corners of a face longer
    still share by barycentric weight when no vertex is within R. Fixed and
    frozen vertices take no share, and a vertex gives its share times its
    erodibility. Each vertex then moves
    along its area-weighted normal by exactly the displacement that changes
    the enclosed volume by its sediment balance (eq. 8.7: the volume of a
    vertex's fan is linear in the vertex's displacement, ``ΔV = t |G| / 6``
    with ``G`` the sum of the fan's edge cross products), one vertex after the
    other so that neighbours' moves never spoil the balance. A move is capped
    at ``e_avg / x`` per iteration for mesh health; the remainder waits on the
    vertex for the next iteration. Volume is conserved: eroded = carried +
    deposited + drained, and the mesh volume changes by deposited - eroded -
    pending.

Mesh health comes from :class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`:
small triangles are collapsed (only between vertices moved this iteration, so
erosion stays local) and a periodic self-intersection guard rolls mesh *and*
fluid back and shortens the steps where the surface tangled.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import prange

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels.curvature.normalize import SOLVER_NORMALIZATIONS, normalize_shifted
from pverosion.kernels.curvature.operator import CurvatureTracker
from pverosion.kernels.fluid.collision import _closest_on_boundary, _over
from pverosion.kernels.fluid.particle_fluid import FluidParameters, ParticleFluid
from pverosion.kernels.materials.erodibility import Erodibility, check_erodibility, erodibility_now
from pverosion.kernels.mesh.geometry import average_edge_length, point_areas
from pverosion.kernels.mesh.laplacian import laplacian_vectors
from pverosion.kernels.mesh.topology import vertex_face_incidence
from pverosion.kernels.solver.mesh_evolution import GuardedMeshSolver, volume_area
from pverosion.kernels.spatial.grid import bucket_points

__all__ = ["MODELS", "STAT_NAMES", "HydraulicSolver", "ShearParameters", "nearest_particle_distance"]

MODELS = ("curvature", "sediment")
"""Accepted values of the ``model`` option."""

STAT_NAMES = ("volume", "area", "particles", "colliding", "affected_vertices", "eroded", "deposited", "carried",
              "drained", "pending", "retries", "collapses")
"""Per-iteration statistics of :class:`HydraulicSolver` (one row per iteration, iteration 0 first)."""

_MAX_CELLS = 1 << 23


@dataclass(frozen=True)
class ShearParameters:
    """Constants of the shear-stress erosion/deposition model (thesis eqs. 8.2–8.4).

    Parameters
    ----------
    erosion_rate : float, default: 1e-3
        k of ε = k (τ - τ_c)^a, in model length per time per unit stress.
    critical_stress : float, default: 5.0
        τ_c: erosion above it, deposition below it.
    stress_constant : float, default: 1.0
        K of τ = K θ^m.
    stress_power : float, default: 1.0
        m of τ = K θ^m (the material's power-law index).
    rate_power : float, default: 1.0
        a of ε = k (τ - τ_c)^a.
    """

    erosion_rate: float = 1e-3
    critical_stress: float = 5.0
    stress_constant: float = 1.0
    stress_power: float = 1.0
    rate_power: float = 1.0

    def __post_init__(self) -> None:
        for name in ("erosion_rate", "critical_stress", "stress_constant", "stress_power", "rate_power"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0; got {value!r}")
        if self.stress_power == 0.0 or self.rate_power == 0.0:
            raise ValueError("stress_power and rate_power must be > 0")


# --- affected vertices ----------------------------------------------------------------------------------------


@njit(cache=True, parallel=True)
def _nearest(points, pos, lo, size, dims, start, order, radius):
    """Distance from every point to the nearest of ``pos`` when within ``radius`` (inf otherwise)."""
    out = np.full(points.shape[0], np.inf)
    r2 = radius * radius
    for i in prange(points.shape[0]):
        cx = math.floor((points[i, 0] - lo[0]) / size)
        cy = math.floor((points[i, 1] - lo[1]) / size)
        cz = math.floor((points[i, 2] - lo[2]) / size)
        if cx < -1 or cy < -1 or cz < -1 or cx > dims[0] or cy > dims[1] or cz > dims[2]:
            continue
        best = np.inf
        for z in range(max(cz - 1, 0), min(cz + 2, dims[2])):
            for y in range(max(cy - 1, 0), min(cy + 2, dims[1])):
                for x in range(max(cx - 1, 0), min(cx + 2, dims[0])):
                    c = x + dims[0] * (y + dims[1] * z)
                    for s in range(start[c], start[c + 1]):
                        j = order[s]
                        d2 = 0.0
                        for k in range(3):
                            e = points[i, k] - pos[j, k]
                            d2 += e * e
                        best = min(best, d2)
        if best <= r2:
            out[i] = math.sqrt(best)
    return out


def nearest_particle_distance(points: np.ndarray, particles: np.ndarray, radius: float) -> np.ndarray:
    """Distance from each point to the nearest particle, where it is at most ``radius``.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    particles : numpy.ndarray, shape (N, 3)
    radius : float
        Search radius (> 0).

    Returns
    -------
    numpy.ndarray, shape (V,)
        The distance, or ``inf`` where no particle is within ``radius``.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    particles = np.ascontiguousarray(particles, dtype=np.float64).reshape(-1, 3)
    if not radius > 0.0:
        raise ValueError(f"radius must be > 0; got {radius!r}")
    if len(particles) == 0:
        return np.full(len(points), np.inf)
    lo = particles.min(axis=0) - radius
    extent = particles.max(axis=0) + radius - lo
    size = float(radius)
    cells = np.prod(np.floor(extent / size) + 1.0)
    if cells > _MAX_CELLS:  # coarser cells still find every particle within the radius
        size *= float((cells / _MAX_CELLS) ** (1.0 / 3.0)) * 1.01
    dims = (np.floor(extent / size) + 1).astype(np.int64)
    start, order = bucket_points(particles, lo, size, dims)
    return _nearest(points, particles, lo, size, dims, start, order, float(radius))


# --- curvature model --------------------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy", parallel=True)
def _curvature_displace(points, normals, lap, h, h_norm, h_min, h_max, factor, scale, power, length, displacement):
    """Move every vertex with ``factor > 0`` (eqs. 6–7) by ``min(h_norm^power * factor, 1) * length * scale``
    (``factor``: distance falloff times erodibility; ``scale``: the guard's slowing down); returns the new
    points."""
    out = points.copy()
    for i in prange(points.shape[0]):
        if factor[i] <= 0.0 or scale[i] <= 0.0:
            continue
        w = 0.0
        if h[i] > 0.0 and h_max > 0.0:
            w = min(h[i] / h_max, 1.0)
        elif h[i] < 0.0 and h_min < 0.0:
            w = min(h[i] / h_min, 1.0)
        inward = v3.scale(v3.row(normals, i), -1.0)
        lvec = v3.row(lap, i)
        size = v3.norm(lvec)
        if size > 0.0:
            lvec = v3.scale(lvec, 1.0 / size)
        else:
            lvec = inward
        vec = v3.add(v3.scale(inward, 1.0 - w), v3.scale(lvec, w))
        size = v3.norm(vec)
        vec = v3.scale(vec, 1.0 / size) if size > 0.0 else inward
        step = v3.scale(vec, min((h_norm[i] ** power) * factor[i], 1.0) * length * scale[i])
        v3.store(out, i, v3.add(v3.row(points, i), step))
        for d in range(3):
            displacement[i, d] += step[d]
    return out


# --- sediment model ---------------------------------------------------------------------------------------------


@njit(cache=True, error_model="numpy")
def _footprint(points, faces, ring_ptr, ring_idx, areas, movable, f, centre, radius, stamp, mark, queue, weights):
    """Vertices sharing a particle's exchange and their weights; returns how many (stored in ``queue[:n]`` with
    ``weights[:n]``, summing to at most 1), 0 when none can move.

    The footprint is the surface within ``radius`` of ``centre`` (the particle's contact point, a point of face
    ``f``), walked from the face's corners along edges; a vertex's weight is its area times
    ``1 - (d / radius)²``. A footprint holding no vertex (a face longer than the fluid's kernel radius) falls
    back to the face's corners weighted by the contact point's barycentric coordinates. The shares of vertices
    that cannot
    move (fixed or frozen) are left out rather than handed to the others, so the particle exchanges less
    instead of drilling the movable vertices next to a frozen patch. ``stamp`` (V,) holds the last ``mark``
    that visited each vertex.
    """
    n_queue = 0
    for c in range(3):
        v = faces[f, c]
        if stamp[v] != mark:
            stamp[v] = mark
            queue[n_queue] = v
            n_queue += 1
    n_seeds = n_queue
    r2 = radius * radius
    n_in = 0
    head = 0
    while head < n_queue:
        v = queue[head]
        head += 1
        d2 = 0.0
        for d in range(3):
            e = points[v, d] - centre[d]
            d2 += e * e
        if d2 <= r2:
            # queue[:head] only holds visited vertices: keep the footprint's in front of them
            queue[head - 1] = queue[n_in]
            queue[n_in] = v
            weights[n_in] = areas[v] * (1.0 - d2 / r2)
            n_in += 1
        elif head > n_seeds:
            continue  # the walk goes on from the footprint and from the contact face's corners
        for q in range(ring_ptr[v], ring_ptr[v + 1]):
            u = ring_idx[q]
            if stamp[u] != mark:
                stamp[u] = mark
                queue[n_queue] = u
                n_queue += 1
    if n_in == 0:
        a = v3.row(points, faces[f, 0])
        b = v3.row(points, faces[f, 1])
        c = v3.row(points, faces[f, 2])
        nrm = v3.cross(v3.sub(b, a), v3.sub(c, a))
        full = v3.dot(nrm, nrm)
        for k in range(3):
            p0 = v3.row(points, faces[f, (k + 1) % 3])
            p1 = v3.row(points, faces[f, (k + 2) % 3])
            w = max(v3.dot(v3.cross(v3.sub(p0, centre), v3.sub(p1, centre)), nrm) / full, 0.0)
            v = faces[f, k]
            queue[k] = v
            weights[k] = w
        n_in = 3
    total = 0.0
    for t in range(n_in):
        total += weights[t]
    if not total > 0.0:
        return 0
    kept = 0
    for t in range(n_in):
        if movable[queue[t]] and weights[t] > 0.0:
            queue[kept] = queue[t]
            weights[kept] = weights[t] / total
            kept += 1
    return kept


@njit(cache=True, error_model="numpy")
def _exchange(points, faces, ring_ptr, ring_idx, areas, pos, vel, contact_face, contact_distance, sediment,
              pending, movable, erodibility, dt, radius, d_min, k, tau_c, big_k, m, a):
    """Erosion/deposition between colliding particles and the surface under them (in particle order).

    Each particle's exchange is spread over its contact footprint at the particle ``radius``, or at the
    contact face's longest edge when that is longer, up to the fluid's kernel radius ``4 radius``
    (:func:`_footprint`). Updates ``sediment`` (N,) and ``pending`` (V,) in place; returns (eroded, deposited)
    volumes.
    """
    eroded = 0.0
    deposited = 0.0
    n_vertices = points.shape[0]
    stamp = np.full(n_vertices, -1, np.int64)
    queue = np.empty(n_vertices, np.int64)
    weights = np.empty(n_vertices)
    area = math.pi * radius * radius
    for p in range(pos.shape[0]):
        f = contact_face[p]
        if f < 0:
            continue
        a0 = v3.row(points, faces[f, 0])
        nrm = v3.cross(v3.sub(v3.row(points, faces[f, 1]), a0), v3.sub(v3.row(points, faces[f, 2]), a0))
        size = v3.norm(nrm)
        if size == 0.0:
            continue
        nrm = v3.scale(nrm, 1.0 / size)
        x = v3.row(pos, p)
        b0, c0 = v3.row(points, faces[f, 1]), v3.row(points, faces[f, 2])
        if _over(x, a0, b0, c0, nrm):  # the contact point: the face's point nearest the particle
            centre = v3.sub(x, v3.scale(nrm, v3.dot(nrm, v3.sub(x, a0))))
        else:
            centre = _closest_on_boundary(x, a0, b0, c0)
        # a face longer than the particle cannot carry a dent as narrow as the particle: the footprint reaches as
        # far as the face's longest edge, up to the fluid's kernel radius 4 r (the scale over which the water
        # itself is smooth), so the exchange does not pile up on the corner it touches
        longest = 0.0
        for c in range(3):
            longest = max(longest, v3.norm(v3.sub(v3.row(points, faces[f, (c + 1) % 3]), v3.row(points, faces[f, c]))))
        reach = max(radius, min(longest, 4.0 * radius))
        nt = _footprint(points, faces, ring_ptr, ring_idx, areas, movable, f, centre, reach, stamp, p, queue,
                        weights)
        if nt == 0:
            continue
        u = v3.row(vel, p)
        tangential = v3.sub(u, v3.scale(nrm, v3.dot(u, nrm)))
        theta = v3.norm(tangential) / max(contact_distance[p], d_min)
        tau = big_k * theta**m
        if tau > tau_c:
            amount = k * (tau - tau_c) ** a * dt * area  # each vertex gives its share times its erodibility
            if amount <= 0.0:
                continue
            taken = 0.0
            for t in range(nt):
                part = amount * weights[t] * erodibility[queue[t]]
                pending[queue[t]] -= part
                taken += part
            sediment[p] += taken
            eroded += taken
        else:
            amount = min(sediment[p], k * (tau_c - tau) ** a * dt * area)
            if amount <= 0.0:
                continue
            given = 0.0
            for t in range(nt):
                part = amount * weights[t]
                pending[queue[t]] += part
                given += part
            if given > sediment[p]:  # the shares' rounding: never drop more than the particle carries
                pending[queue[nt - 1]] -= given - sediment[p]
                given = sediment[p]
            sediment[p] -= given
            deposited += given
    return eroded, deposited


@njit(cache=True, error_model="numpy")
def _apply_volumes(points, faces, indptr, face_ids, corners, pending, cap, displacement):
    """Move each vertex with pending volume along its fan normal so the enclosed volume changes by exactly it.

    Vertices are processed in index order; each move is capped at ``cap[v]``
    and the rest stays in ``pending``. Returns the number of vertices moved.
    """
    moved = 0
    for v in range(points.shape[0]):
        s = pending[v]
        if s == 0.0 or cap[v] <= 0.0:
            continue
        g = (0.0, 0.0, 0.0)
        p = v3.row(points, v)
        for q in range(indptr[v], indptr[v + 1]):
            f = face_ids[q]
            k = corners[q]
            b = v3.row(points, faces[f, (k + 1) % 3])
            c = v3.row(points, faces[f, (k + 2) % 3])
            g = v3.add(g, v3.cross(v3.sub(b, p), v3.sub(c, p)))
        size = v3.norm(g)
        if size == 0.0:
            continue
        t = 6.0 * s / size
        if abs(t) > cap[v]:
            t = math.copysign(cap[v], t)
            pending[v] -= t * size / 6.0
        else:
            pending[v] = 0.0
        step = v3.scale(g, t / size)
        v3.store(points, v, v3.add(p, step))
        for d in range(3):
            displacement[v, d] += step[d]
        moved += 1
    return moved


# --- solver -----------------------------------------------------------------------------------------------------


class HydraulicSolver(GuardedMeshSolver):
    """Particle fluid flowing over a closed mesh and eroding it, one iteration at a time.

    Parameters
    ----------
    points : array_like, shape (V, 3)
    faces : array_like, shape (F, 3)
        The terrain or model; oriented outward by default (the fluid flows on
        the outside).
    fluid : FluidParameters
        Particle radius, gravity, time step, substeps, solver iterations, viscosity.
    emitters, drains : sequence of Emitter / Drain
        Where water enters and leaves (:mod:`pverosion.kernels.fluid.particle_fluid`).
    domain : tuple of two array_like (3,), optional
        Box the particles live in; particles leaving it are drained. Default:
        the mesh's bounding box and the emitters, padded by 10 % of the
        diagonal (and 20 particle radii above).
    walls : bool, default: False
        Keep the particles inside the domain box (a tank) instead of draining
        those that leave it.
    model : {"curvature", "sediment"}, default: "curvature"
    power : float, default: 1.0
        n of the curvature model (H_s^n).
    normalization : {"scale_free", "paper"}, default: "scale_free"
        Curvature model: H_min and H_max are taken over the interior vertices
        (not fixed boundary vertices nor their one-ring), so an open scan's
        rim does not set them, or over all vertices as in the paper. Both are
        independent of the model's units.
    step_divisor : float, default: 10.0
        x: the largest displacement per iteration is ``e_avg / x`` (both models).
    influence : float, default: 1.0
        d_influence in units of the average edge length, measured from the
        surface of a colliding particle (its centre plus the radius r); the
        curvature model's reach (and ``f_distance``) only.
    shear : ShearParameters, optional
        Constants of the sediment model.
    erodibility : array_like (V,), callable, MaterialField or None
        Multiplier of the erosion (see :class:`~pverosion.kernels.weathering.model.WeatheringSolver`).
    min_edge_ratio, check_every, max_halvings, orientation, repair
        Mesh improvement and self-intersection guard
        (:class:`~pverosion.kernels.solver.mesh_evolution.GuardedMeshSolver`).
    seed : int, default: 0
        Seed of the fluid's random numbers (emission); the same seed gives bit-identical runs.

    Attributes
    ----------
    fluid : ParticleFluid
    f_distance : numpy.ndarray, shape (V',)
        f_distance of every vertex at the last iteration (0: not affected).
    colliding : numpy.ndarray, shape (C, 3)
        Positions of the particles that touched the mesh in the last iteration.
    pending : numpy.ndarray, shape (V',)
        Sediment volume waiting on each vertex (sediment model).
    eroded, deposited : float
        Total volumes taken from and given back to the mesh (sediment model).
    profile : dict or None
        Set it to ``{}`` to collect the seconds per part of each iteration:
        "fluid_total" (the fluid step; set ``fluid.profile = {}`` for its
        phases), "affected", "curvature" (with the Laplacian), "displacement"
        (with mesh improvement and the collision grid update), "guard".
    """

    STAT_NAMES = STAT_NAMES
    PROGRESS_LABEL = "hydraulic erosion"

    def __init__(
        self,
        points,
        faces,
        *,
        fluid: FluidParameters,
        emitters=(),
        drains=(),
        domain=None,
        walls: bool = False,
        model: str = "curvature",
        power: float = 1.0,
        normalization: str = "scale_free",
        step_divisor: float = 10.0,
        influence: float = 1.0,
        shear: ShearParameters | None = None,
        erodibility: Erodibility = None,
        min_edge_ratio: float = 0.1,
        check_every: int = 10,
        max_halvings: int = 4,
        orientation: str = "outward",
        repair: str = "retry",
        seed: int = 0,
    ) -> None:
        if model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}; got {model!r}")
        if not (np.isfinite(power) and power >= 1.0):
            raise ValueError(f"power must be a real number >= 1; got {power!r}")
        if not (np.isfinite(step_divisor) and step_divisor > 0.0):
            raise ValueError(f"step_divisor must be > 0; got {step_divisor!r}")
        if not (np.isfinite(influence) and influence > 0.0):
            raise ValueError(f"influence must be > 0; got {influence!r}")
        if normalization not in SOLVER_NORMALIZATIONS:
            raise ValueError(f"normalization must be one of {SOLVER_NORMALIZATIONS}; got {normalization!r}")
        if not isinstance(fluid, FluidParameters):
            raise TypeError(f"fluid must be FluidParameters; got {type(fluid).__name__}")
        emitters = tuple(emitters)
        super().__init__(points, faces, min_edge_ratio=min_edge_ratio, check_every=check_every,
                         max_halvings=max_halvings, orientation=orientation, repair=repair)
        self.model = model
        self.power = float(power)
        self.normalization = normalization
        self.step_divisor = float(step_divisor)
        self.influence = float(influence)
        self.shear = shear if shear is not None else ShearParameters()
        self._erodibility = check_erodibility(erodibility, len(self.points))
        box = self._domain(domain, emitters, fluid.radius)
        self.fluid = ParticleFluid(fluid, domain=box, emitters=emitters, drains=drains, walls=walls, seed=seed)
        self.fluid.set_mesh(self.points, self.faces)
        self.f_distance = np.zeros(len(self.points))
        self.colliding = np.empty((0, 3))
        self.pending = np.zeros(len(self.points))
        self.eroded = 0.0
        self.deposited = 0.0
        self._start()

    def _domain(self, domain, emitters, radius: float) -> tuple[np.ndarray, np.ndarray]:
        if domain is not None:
            lo, hi = (np.asarray(c, dtype=np.float64) for c in domain)
            if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo) & np.isfinite(hi)) or np.any(hi <= lo):
                raise ValueError(f"domain must be two corners (lo, hi) of a box with lo < hi; got {domain!r}")
            return lo, hi
        corners = [self.points]
        corners += [np.asarray(e.position, dtype=np.float64)[None, :] for e in emitters]
        pts = np.vstack(corners)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.1 * float(np.linalg.norm(hi - lo))
        lo, hi = lo - pad, hi + pad
        hi[2] += 20.0 * radius
        return lo, hi

    _curvature_estimator: ClassVar[type] = CurvatureTracker  # the water moves a small part of the mesh per iteration
    # the water tangles the surface where it pours, and most tangles come undone before the next check: every
    # rollback halves
    REPEAT_FACTOR: ClassVar[float] = 0.5

    def _build_topology(self) -> None:
        super()._build_topology()
        self._incidence = vertex_face_incidence(self.faces, len(self.points))

    def _after_collapse(self, kept: np.ndarray) -> None:
        self.pending = self.pending[kept]
        self.f_distance = self.f_distance[kept]

    def _after_repair(self, source: np.ndarray, donor: np.ndarray, heir: np.ndarray) -> None:
        # sediment owed to a vertex stays with it, that of a vertex cut away goes to the nearest one left; the new
        # vertices on the curves owe nothing
        gone = heir >= 0
        self.pending = (np.where(source >= 0, self.pending[donor], 0.0)
                        + np.bincount(heir[gone], weights=self.pending[gone], minlength=len(source)))
        self.f_distance = self.f_distance[donor]
        self.fluid.set_mesh(self.points, self.faces)

    def _extra_state(self):
        return (self.fluid.state(), self.pending.copy(), self.f_distance.copy(), self.colliding.copy(),
                self.eroded, self.deposited)

    def _restore_extra(self, extra) -> None:
        state, pending, f_distance, colliding, self.eroded, self.deposited = extra
        self.fluid.restore(state)
        self.pending = pending.copy()
        self.f_distance = f_distance.copy()
        self.colliding = colliding.copy()
        self.fluid.set_mesh(self.points, self.faces)

    def progress_postfix(self) -> dict:
        return {"particles": len(self.fluid.positions), "retries": self.retries}

    @property
    def d_influence(self) -> float:
        """Region of influence of a particle now, from its surface: ``influence * e_avg``."""
        return self.influence * average_edge_length(self.points, self.faces, edges=self._edges)

    def _row(self) -> tuple:
        volume, area = volume_area(self.points, self.faces, self._origin)
        return (float(volume), float(area), len(self.fluid.positions), len(self.colliding),
                int(np.count_nonzero(self.f_distance > 0.0)), self.eroded, self.deposited,
                float(self.fluid.sediment.sum()), float(self.fluid.drained_sediment), float(self.pending.sum()),
                self.retries, self.collapses)

    def _step(self) -> None:
        clock = time.perf_counter()
        fluid = self.fluid
        fluid.step()
        clock = self._lap("fluid_total", clock)
        touching = fluid.contact_face >= 0
        self.colliding = fluid.positions[touching]
        e_avg = average_edge_length(self.points, self.faces, edges=self._edges)
        reach = self.influence * e_avg
        r = fluid.params.radius
        d_part = np.maximum(nearest_particle_distance(self.points, self.colliding, reach + r) - r, 0.0)
        f = np.where(np.isfinite(d_part), (reach - d_part) / reach, 0.0)
        f[self._fixed] = 0.0
        self.f_distance = f
        clock = self._lap("affected", clock)
        scale = self._scale[self.ids]
        factor = f if self._erodibility is None else f * erodibility_now(self._erodibility, self.points, self.ids)
        if self.model == "curvature":
            curv = self._curvature(self.points)
            h = curv.mean
            lap = laplacian_vectors(self.points, self.faces, ring=self._ring)
            clock = self._lap("curvature", clock)
            over = None if self.normalization == "paper" else self._interior
            stats = h if over is None or not over.any() else h[over]
            self.points = _curvature_displace(self.points, curv.normals, lap, h, normalize_shifted(h, where=over),
                                              float(stats.min()), float(stats.max()), factor, scale, self.power,
                                              e_avg / self.step_divisor, self.displacement)
            moved = (factor > 0.0) & (scale > 0.0)
        else:
            moved = self._sediment_step(fluid, e_avg)
        if self.min_edge_ratio > 0.0:
            self._improve(self.min_edge_ratio * e_avg, movable=moved & (self.pending == 0.0))
        fluid.set_mesh(self.points, self.faces)
        self.step_count += 1
        self._stats.append(self._row())
        self._lap("displacement", clock)

    def _sediment_step(self, fluid: ParticleFluid, e_avg: float) -> np.ndarray:
        """Exchange sediment and move the vertices by their balances; returns the mask (V',) of moved vertices."""
        shear = self.shear
        erod = np.ones(len(self.points))
        if self._erodibility is not None:
            erod = erodibility_now(self._erodibility, self.points, self.ids)
        movable = ~self._fixed & (self._scale[self.ids] > 0.0)
        r = fluid.params.radius
        eroded, deposited = _exchange(
            self.points, self.faces, *self._ring, point_areas(self.points, self.faces), fluid.positions,
            fluid.velocities, fluid.contact_face, fluid.contact_distance, fluid.sediment, self.pending, movable, erod,
            fluid.dt, r, 0.25 * r, shear.erosion_rate, shear.critical_stress, shear.stress_constant,
            shear.stress_power, shear.rate_power)
        self.eroded += eroded
        self.deposited += deposited
        cap = (e_avg / self.step_divisor) * self._scale[self.ids] * movable
        before = self.points
        self.points = self.points.copy()
        _apply_volumes(self.points, self.faces, *self._incidence, self.pending, cap, self.displacement)
        return np.any(self.points != before, axis=1)

    def conservation_error(self) -> float:
        """``|eroded - carried - deposited - drained|`` of the sediment model (0 for exact bookkeeping)."""
        return abs(self.eroded - float(self.fluid.sediment.sum()) - self.deposited - float(self.fluid.drained_sediment))
