"""Particle water: position-based fluids (Macklin & Müller 2013) colliding with a triangle mesh.

Method
------
- **Particles.** Spheres of radius ``r`` and mass 1; the rest spacing is
  ``2r`` and the kernel radius ``h = 4r`` (about 33 neighbours). Density
  uses the poly6 kernel, gradients the spiky kernel. The rest density
  ``rho0`` is the kernel sum of a particle in a cubic lattice of spacing
  ``2r``, so such a lattice is exactly at rest density.
- **A step** emits, runs ``substeps`` substeps of ``time_step / substeps``
  seconds, then drains. **A substep**: gravity and a predicted position
  ``p = x + v dt``; the mesh collision of ``x -> p`` (below); neighbour lists
  (grid of cell edge h); ``solver_iterations`` Jacobi iterations of the
  density constraint, each followed by the push-out from the particle's
  boundary planes and the walls; friction and a final swept test of the
  substep's whole motion; ``v = (p - x) / dt``; XSPH viscosity
  ``v_i += c sum_j (v_j - v_i) W_ij / W(0)``; at a contact, the velocity into
  the surface is removed.
- **Density constraint.** ``C_i = max(rho_i / rho0 - 1, 0)``, the unilateral
  form (particles only push each other apart, so the free surface does not
  clump), ``lambda_i = -w C_i / (sum_k |grad_k C_i|² + epsilon)`` (eq. 11)
  and the position change of eq. 14, with the tensile term ``s_corr`` of
  eq. 13 when ``tensile`` > 0. Jacobi iterations on this system diverge for
  the checkerboard modes of the lattice unless ``w`` is below 2 / 2.65
  (2.65 is the largest eigenvalue of the diagonally scaled constraint
  matrix of the rest lattice, 2.9 at 5 % compression): ``w`` is
  :data:`JACOBI_WEIGHT`. The last iteration applies half its correction,
  which keeps every mode's net response per substep non-negative: with an
  odd number of plain iterations, modes that flip sign each substep grow
  through the velocity update. ``epsilon`` and ``s_corr`` are in units of
  S, the sum of the squared constraint gradients of a particle at rest in
  the lattice, so the parameters mean the same at any particle size.
- **Walls and mesh in the density.** The solid behind a wall or mesh face
  counts as two layers of virtual particles (at ``delta + r`` and
  ``delta + 3r`` from a particle ``delta`` in front of it, each smeared over
  its plane), scaled to equal the lattice layers it replaces at
  ``delta = r``: fluid resting on a floor is at rest density instead of
  being squeezed into it. A particle's boundary planes are those of the
  faces it is over within :data:`PLANE_REACH` r (its projection falls inside
  the triangle), the tangent planes at the closest points of edges and
  corners within r, and the face it is less than r behind when no face it
  is over is nearer (the mesh moved over it); of faces turned less than 30
  degrees apart (one wall) only the nearest counts, up to
  :data:`MAX_PLANES` walls (a corner).
- **Mesh collision.** The fluid is on the front side of every face (the
  right-hand normal points into the fluid). A particle ends ``r`` in front
  of its boundary planes. The boundary planes are searched at the
  predicted position with some slack, and reused while the particle stays
  in it, into the next steps too (the slack shrinks by how far the mesh
  moved, and the planes follow their faces). The substep's start is pushed out first,
  carrying the predicted position along, so a mesh that moved over a
  particle gives it no velocity. The segment from the start to the
  predicted and to the final position is tested against the triangles
  (front-to-back crossings), unless both ends stay nearer to where the
  mesh was searched than every face it listed: a crossing particle is put back ``r`` in front
  of the first face it crossed, keeping its tangential motion, and stopped
  just before the crossing if that still crosses a face. So particles never
  pass through a closed surface, however fast. Faces are found through a
  uniform grid of cell size ``max(2r, mean edge)``, each face
  listed in the cells of its bounding box grown by a margin; while the
  faces stay the same and no point has moved farther than the margin,
  :meth:`ParticleFluid.set_mesh` only refreshes the face coordinates.
- **Grids** are hashed: cells are numbered linearly over the bounding box of
  what they hold and bucketed modulo a power of two, so building them costs
  O(items) whatever the extent, and cells next to each other along x stay
  next to each other in memory. The particles are processed in cell order.
- **Determinism.** Parallel loops write only their own particle's entries,
  sorts are counting sorts (in fixed chunks when parallel), ties between
  faces go to the lower face index, and random numbers come from
  SplitMix64 started from the seed's hash (:func:`~pverosion.kernels.random_streams.stream_state`),
  so the same inputs and seed give bit-identical states for any number of
  threads, and different seeds give independent streams.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from pverosion.kernels.fluid.collision import _carry, _collide, _drift_buckets, _plane_distances, _refresh
from pverosion.kernels.fluid.grids import (
    _density_sum,
    _empty_grid,
    _face_moves,
    _largest_move,
    _mesh_grid,
    _neighbour_lists,
    _particle_grid,
    _refit,
)
from pverosion.kernels.fluid.params import (
    _BLOCK,
    _CARRY,
    DRAIN_KINDS,
    JACOBI_WEIGHT,
    LAST_WEIGHT,
    MAX_PLANES,
    PHASES,
    PLANE_REACH,
    TENSILE_DISTANCE,
    Drain,
    Emitter,
    FluidParameters,
    FluidState,
    _is_numeric,
    _poly6,
)
from pverosion.kernels.fluid.pbf import (
    _corrections,
    _drained,
    _gather,
    _lambdas,
    _predict,
    _scatter,
    _uniforms,
    _velocities,
)
from pverosion.kernels.random_streams import stream_state
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["DRAIN_KINDS", "PHASES", "Drain", "Emitter", "FluidParameters", "FluidState", "ParticleFluid"]

# --- the fluid -----------------------------------------------------------------------------------------------------


def _spread(n: int) -> np.ndarray:
    """Order (N,) of the rows 0..n-1 in blocks of _BLOCK taken in bit-reversed block order.

    Any contiguous share of it (what one thread of a parallel loop gets)
    samples the whole range evenly, so work bunched in cell order (the
    particles near a mesh) is split between the threads.
    """
    blocks = -(-n // _BLOCK)
    bits = max(blocks - 1, 0).bit_length()
    index = np.arange(blocks)
    reversed_index = np.zeros(blocks, np.int64)
    for b in range(bits):
        reversed_index |= ((index >> b) & 1) << (bits - 1 - b)
    rows = (np.argsort(reversed_index, kind="stable")[:, None] * _BLOCK + np.arange(_BLOCK)).ravel()
    return rows[rows < n]


class _Buffers:
    """Arrays reused from step to step, handed out as views of their first rows.

    A fresh array of megabytes costs about a millisecond per megabyte of
    page faults on a virtual machine, and the particle count changes from
    step to step; so each array grows with some headroom and stays.
    """

    def __init__(self) -> None:
        self._store: dict[str, np.ndarray] = {}

    def get(self, name: str, n: int, tail: tuple = (), dtype=np.float64) -> np.ndarray:
        """Uninitialised array of shape ``(n, *tail)``: a view of the first ``n`` rows of the array ``name``."""
        store = self._store.get(name)
        if store is None or store.shape[0] < n or store.shape[1:] != tail or store.dtype != dtype:
            store = np.empty((n + n // 8 + 64, *tail), dtype)
            self._store[name] = store
        return store[:n]


class _Work:
    """Particle arrays of one step, in cell order (``order``: index of each row in the public arrays)."""

    def __init__(self, n: int, order: np.ndarray, carried: _Work | None = None, rows: np.ndarray | None = None,
                 buffers: _Buffers | None = None) -> None:
        """``carried``: the previous step's work, whose searches move along; ``rows[s]``: row of particle
        ``order[s]`` there (-1: none); ``buffers``: where the arrays live (not those of ``carried``)."""
        get = (buffers or _Buffers()).get
        self.order = order
        self.spread = _spread(n)
        self.x = get("x", n, (3,))
        self.v = get("v", n, (3,))
        self.touched = get("touched", n, (), np.int64)  # face of the latest contact in the step
        self.touched.fill(-1)
        self.anchor = get("anchor", n, (3,))  # where the mesh was last searched for boundary planes
        self.anchor.fill(np.nan)
        self.slack = get("slack", n)  # how far from the anchor, along each axis, that search holds
        self.slack.fill(0.0)
        self.gap = get("gap", n)  # no face nearer to the anchor (see _search)
        self.gap.fill(0.0)
        self.planes = get("planes", n, (MAX_PLANES, 6))  # unit normal, offset, distance, 1 for an edge or corner
        self.n_planes = get("n_planes", n, (), np.int64)
        self.n_planes.fill(0)
        self.plane_face = get("plane_face", n, (MAX_PLANES,), np.int64)
        if carried is not None:
            _carry(rows, *carried.searches(), *self.searches())

    def searches(self) -> tuple:
        """The search arrays, in the order the kernels take them."""
        return self.anchor, self.slack, self.gap, self.planes, self.n_planes, self.plane_face

    def forget(self) -> None:
        """Drop every search (the faces changed or went)."""
        self.anchor[:] = np.nan
        self.n_planes[:] = 0

    def copy(self) -> _Work:
        out = _Work(0, self.order)
        for name, value in vars(self).items():
            setattr(out, name, value.copy())
        return out


class ParticleFluid:
    """Position-based fluid in a box, with emitters, drains and a triangle mesh to flow over.

    Parameters
    ----------
    params : FluidParameters
    domain : tuple of two array_like (3,)
        Corners (lo, hi) of the box the particles live in.
    emitters : sequence of Emitter
    drains : sequence of Drain
    walls : bool, default: False
        False: particles leaving the domain are drained. True: the domain's
        sides are solid walls (frictionless) that keep particle centres ``r``
        inside.
    seed : int, default: 0
        Seed (>= 0) of the emitters' SplitMix64 generator, hashed so that
        different seeds give independent streams.

    Attributes
    ----------
    params : FluidParameters
    dt : float
        Seconds per step.
    positions, velocities : numpy.ndarray, shape (N, 3) float64
        Particles in increasing order of ``ids``.
    ids : numpy.ndarray, shape (N,) int64
        Unique particle numbers in order of creation.
    sediment : numpy.ndarray, shape (N,) float64
        Payload carried along (the caller sets it; drained particles add
        theirs to ``drained_sediment``).
    contact_face : numpy.ndarray, shape (N,) int64
        Mesh face of each particle's latest contact during the last step
        (-1: none).
    contact_distance : numpy.ndarray, shape (N,) float64
        Signed distance from the particle centre to the plane of its contact
        face after the last step (inf without a contact).
    emitted, drained : int
        Particles released by the emitters and removed by drains or by
        leaving the domain.
    drained_sediment : float
        Sum of the sediment of the drained particles.
    steps : int
    profile : dict or None
        Set it to ``{}`` to collect the seconds per step spent in each of
        :data:`PHASES`.
    on_substep : callable or None
        Called as ``on_substep(done, positions, velocities, ids)`` after
        every substep of a step but its last (after which the step ends and
        the attributes above hold the particles): ``done`` substeps of the
        step are done, and the particles come in the step's work order. The
        arrays are the fluid's work buffers: copy what you keep. A live view
        uses it to show the water between steps.

    Examples
    --------
    >>> fluid = ParticleFluid(FluidParameters(radius=0.1), domain=((0, 0, 0), (2, 2, 2)), walls=True)
    >>> fluid.add_particles([[1.0, 1.0, 1.0]])
    >>> fluid.step()
    >>> bool(fluid.positions[0, 2] < 1.0)
    True
    """

    def __init__(self, params: FluidParameters, *, domain, emitters=(), drains=(), walls: bool = False,
                 seed: int = 0) -> None:
        if not isinstance(params, FluidParameters):
            raise TypeError(f"params must be FluidParameters; got {type(params).__name__}")
        lo, hi = self._check_domain(domain, params.radius, bool(walls))
        emitters, drains = tuple(emitters), tuple(drains)
        for e in emitters:
            if not isinstance(e, Emitter):
                raise TypeError(f"emitters must be Emitter objects; got {type(e).__name__}")
        for d in drains:
            if not isinstance(d, Drain):
                raise TypeError(f"drains must be Drain objects; got {type(d).__name__}")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise TypeError(f"seed must be an integer; got {seed!r}")
        self.params = params
        self.dt = params.dt
        self.domain = (lo, hi)
        self.walls = bool(walls)
        self.emitters = emitters
        self.drains = drains
        self._plans = [self._plan(k, e) for k, e in enumerate(emitters)]
        self._planes = np.array([d.values for d in drains if d.kind == "plane"], np.float64).reshape(-1, 4)
        self._boxes = np.array([d.values for d in drains if d.kind == "box"], np.float64).reshape(-1, 6)
        rho0, grad2, kw = params._lattice()
        h = params.kernel_radius
        self._rho0 = rho0
        self._k6 = 315.0 / (64.0 * math.pi * h**9)
        # r, h, poly6 and spiky constants, 1 / rho0, epsilon, solid scale, 1 / W(dq), tensile k / S
        self._kern = np.array([params.radius, h, self._k6, 45.0 / (math.pi * h**6), 1.0 / rho0,
                               params.relaxation * grad2, kw, 1.0 / _poly6((TENSILE_DISTANCE * h) ** 2, h),
                               params.tensile / grad2, JACOBI_WEIGHT])
        self._rng = np.array([stream_state(seed, "particle_fluid")], np.uint64)
        self._advance = np.zeros(len(emitters))
        self._next_id = 0
        self._capacity = 64
        self._buffers = _Buffers()  # neighbour lists and substep arrays
        self._work_buffers = (_Buffers(), _Buffers())  # a step's work arrays and its predecessor's, in turn
        self._parity = 0
        self._grid = _empty_grid()
        self._mesh: tuple | None = None  # points, faces and margin of the last grid build
        self._entries: tuple = ()  # grid entries of every face (CSR) of the last grid build
        self._points: np.ndarray | None = None  # points of the last set_mesh
        self._last: _Work | None = None  # the last step's work, with its searches
        self._rows = np.zeros(0, np.int64)  # row of every particle in it (-1: none)
        self.positions = np.zeros((0, 3))
        self.velocities = np.zeros((0, 3))
        self.ids = np.zeros(0, np.int64)
        self.sediment = np.zeros(0)
        self.contact_face = np.zeros(0, np.int64)
        self.contact_distance = np.zeros(0)
        self.emitted = 0
        self.drained = 0
        self.drained_sediment = 0.0
        self.steps = 0
        self.profile: dict[str, list[float]] | None = None
        self.on_substep: Callable[[int, np.ndarray, np.ndarray, np.ndarray], None] | None = None

    @staticmethod
    def _check_domain(domain, radius: float, walls: bool) -> tuple[np.ndarray, np.ndarray]:
        try:
            lo, hi = (np.array(c, dtype=np.float64) for c in domain)
        except (TypeError, ValueError):
            raise ValueError(f"domain must be two corners (lo, hi) of a box; got {domain!r}") from None
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo) & np.isfinite(hi)) or np.any(hi <= lo):
            raise ValueError(f"domain must be two corners (lo, hi) of a box with lo < hi; got {domain!r}")
        if walls and np.any(hi - lo < 2.0 * radius):
            raise ValueError(f"domain {domain!r} is thinner than a particle (2r = {2.0 * radius}) and walls=True")
        return lo, hi

    def _plan(self, k: int, emitter: Emitter) -> tuple[np.ndarray, float, float]:
        """Lattice offsets, speed and emission probability of emitter ``k``."""
        spacing = self.params.spacing
        offsets = emitter.lattice(spacing)
        if emitter.speed is None:
            speed = spacing * emitter.rate / len(offsets)
            lo, hi = self.domain
            width = float(np.max(hi - lo))
            if speed * self.dt > width:  # each step's layers would reach past the domain: drained at once
                raise ValueError(
                    f"emitter {k}: rate {emitter.rate:g} particles/s without a speed sends the particles off at "
                    f"{speed:.3g} per second (the rate over the disc's {len(offsets)} lattice points), "
                    f"{speed * self.dt:.3g} per time step, farther than the domain is wide ({width:.3g}); lower the "
                    "rate, or give a speed and a radius that fit it"
                )
            return offsets, speed, 1.0
        top = len(offsets) * emitter.speed / spacing
        if emitter.rate > top * (1.0 + 1e-12):
            raise ValueError(
                f"emitter {k}: rate {emitter.rate:g} particles/s cannot fit; at speed {emitter.speed:g} a disc of "
                f"radius {emitter.radius:g} emits at most {top:g} particles/s ({len(offsets)} lattice points every "
                f"{spacing / emitter.speed:g} s); raise the speed or the radius, or leave the speed out"
            )
        return offsets, emitter.speed, min(emitter.rate / top, 1.0)

    # -- particles and mesh ------------------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Simulated seconds: ``steps * dt``."""
        return self.steps * self.dt

    def add_particles(self, positions, velocities=None) -> None:
        """Append particles (sediment 0) with the next ids.

        Parameters
        ----------
        positions : array_like, shape (M, 3)
        velocities : array_like, shape (M, 3), optional
            Default: at rest.
        """
        pos = self._block(positions, "positions")
        vel = np.zeros_like(pos) if velocities is None else self._block(velocities, "velocities")
        if vel.shape != pos.shape:
            raise ValueError(f"velocities must have the shape of positions {pos.shape}; got {vel.shape}")
        if len(self.positions) + len(pos) > self.params.max_particles:
            raise ValueError(f"{len(self.positions)} + {len(pos)} particles exceed max_particles "
                             f"({self.params.max_particles})")
        self._append(pos, vel)

    @staticmethod
    def _block(values, name: str) -> np.ndarray:
        if not _is_numeric(values):
            raise ValueError(f"{name} must be numeric")
        arr = np.array(values, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise ValueError(f"{name} must have shape (M, 3); got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} contain NaN or infinite values")
        return arr

    def _append(self, pos: np.ndarray, vel: np.ndarray) -> None:
        m = len(pos)
        self.positions = np.concatenate((self.positions, pos))
        self.velocities = np.concatenate((self.velocities, vel))
        self.ids = np.concatenate((self.ids, np.arange(self._next_id, self._next_id + m, dtype=np.int64)))
        self.sediment = np.concatenate((self.sediment, np.zeros(m)))
        self.contact_face = np.concatenate((self.contact_face, np.full(m, -1, np.int64)))
        self.contact_distance = np.concatenate((self.contact_distance, np.full(m, np.inf)))
        self._rows = np.concatenate((self._rows, np.full(m, -1, np.int64)))
        self._next_id += m

    def set_mesh(self, points, faces) -> None:
        """Set the collision mesh; the fluid is on the front side of every face. None or no faces clears it.

        Parameters
        ----------
        points : array_like, shape (V, 3) or None
        faces : array_like, shape (F, 3) or None
        """
        if points is None or faces is None or np.size(faces) == 0:
            self._grid = _empty_grid()
            self._mesh = self._points = None
            if self._last is not None:
                self._last.forget()
            return
        pts, fcs = as_triangle_mesh(points, faces)
        if self._mesh is None or pts.shape != self._mesh[0].shape or not np.array_equal(fcs, self._mesh[1]):
            self._grid, margin, self._entries = _mesh_grid(pts, fcs, self.params.radius)
            self._mesh = (pts.copy(), fcs.copy(), margin)
            if self._last is not None:
                self._last.forget()  # the faces are numbered anew
        else:
            face_move, drift = _face_moves(pts, self._points, fcs)
            if drift == 0.0:
                return
            if _largest_move(pts, self._mesh[0]) < self._mesh[2]:
                # refit: the faces are still in their cells; those that moved get new data and spheres
                _refit(pts, fcs, face_move, self._grid[0], self._grid[8], *self._entries)
            else:
                self._grid, margin, self._entries = _mesh_grid(pts, fcs, self.params.radius)
                self._mesh = (pts.copy(), fcs.copy(), margin)
            if self._last is not None:  # the same faces: the searches carry over, shrunk where faces moved
                last = self._last
                r = self.params.radius
                drift_buckets = _drift_buckets(self._grid, face_move, (PLANE_REACH + _CARRY) * r)
                _refresh(self._grid, drift_buckets, _CARRY * r, last.anchor, last.slack, last.gap, last.planes,
                         last.n_planes, last.plane_face)
        self._points = pts.copy()

    # -- stepping ------------------------------------------------------------------------------------------------

    def step(self) -> None:
        """Advance one time step: emission, ``substeps`` substeps with collisions, then drains."""
        self._check_arrays()
        times = dict.fromkeys(PHASES, 0.0)
        clock = time.perf_counter()
        self._emit()
        n = len(self.positions)
        self.contact_face = np.full(n, -1, np.int64)
        clock = self._lap(times, "emit_drain", clock)
        if n:
            # the particles in cell order for the whole step, for locality
            order = _particle_grid(self.positions, self.domain[0], self.params.kernel_radius)[0]
            self._parity ^= 1  # the other buffers than those of the last work, whose searches carry over
            work = _Work(n, order, self._last, self._rows[order], self._work_buffers[self._parity])
            _gather(self.positions, self.velocities, work.order, work.x, work.v)
            self._lap(times, "neighbours", clock)
            for k in range(self.params.substeps):
                self._substep(work, self.dt / self.params.substeps, times)
                if self.on_substep is not None and k + 1 < self.params.substeps:
                    self.on_substep(k + 1, work.x, work.v, self.ids[work.order])
            clock = time.perf_counter()
            _scatter(work.order, work.x, work.v, work.touched, self.positions, self.velocities, self.contact_face)
            # the searches go on to the next step as far as their planes cover every face within r
            np.minimum(work.slack, _CARRY * self.params.radius, out=work.slack)
            self._last = work
            self._rows = np.empty(n, np.int64)
            self._rows[work.order] = np.arange(n)
            clock = self._lap(times, "solve", clock)
        self._drain()
        clock = self._lap(times, "emit_drain", clock)
        self.contact_distance = np.empty(len(self.positions))
        _plane_distances(self.positions, self.contact_face, self._grid[0], self.contact_distance)
        self._lap(times, "collision", clock)
        self.steps += 1
        if self.profile is not None:
            for name in PHASES:
                self.profile.setdefault(name, []).append(times[name])

    def _check_arrays(self) -> None:
        n = len(self.positions)
        for name, shape, dtype in (("positions", (n, 3), np.float64), ("velocities", (n, 3), np.float64),
                                   ("ids", (n,), np.int64), ("sediment", (n,), np.float64)):
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) or value.shape != shape:
                raise ValueError(f"{name} must be an array of shape {shape}; got {np.shape(value)}")
            setattr(self, name, np.ascontiguousarray(value, dtype=dtype))

    def _emit(self) -> None:
        spacing = self.params.spacing
        blocks = []
        room = self.params.max_particles - len(self.positions)
        for k, (emitter, (offsets, speed, chance)) in enumerate(zip(self.emitters, self._plans)):
            self._advance[k] += speed * self.dt
            direction = np.array(emitter.direction)
            while self._advance[k] >= spacing:
                if room <= 0:  # paused at max_particles: skip the layers that no longer fit without building them
                    self._advance[k] %= spacing
                    break
                self._advance[k] -= spacing
                layer = np.array(emitter.position) + direction * self._advance[k] + offsets
                if chance < 1.0:
                    layer = layer[_uniforms(self._rng, len(layer)) < chance]
                layer = layer[:max(room, 0)]
                room -= len(layer)
                blocks.append((layer, np.broadcast_to(direction * speed, layer.shape)))
        if blocks:
            pos = np.concatenate([b[0] for b in blocks])
            self._append(pos, np.concatenate([b[1] for b in blocks]))
            self.emitted += len(pos)

    def _substep(self, work: _Work, dt: float, times: dict[str, float]) -> None:
        prm = self.params
        r, h = prm.radius, prm.kernel_radius
        lo, hi = self.domain
        n = len(work.x)
        clock = time.perf_counter()
        # positions: three buffers in turn, work.x being one of them after the first substep
        ps, buffer = [b for b in (self._buffers.get(f"positions{k}", n, (3,)) for k in range(3))
                      if not np.may_share_memory(b, work.x)][:2]
        _predict(work.x, work.v, np.array(prm.gravity), dt, ps)
        contact = self._buffers.get("contact", n, (), np.int64)
        contact.fill(-1)
        normal = self._buffers.get("normal", n, (3,))
        normal.fill(0.0)
        clock = self._lap(times, "solve", clock)
        _collide(ps, work.x, r, self._grid, 0.0, True, self.walls, lo, hi, contact, normal, work.anchor, work.slack,
                 work.gap, work.planes, work.n_planes, work.plane_face, work.spread)
        clock = self._lap(times, "collision", clock)
        nbr, count = self._neighbours(ps)
        clock = self._lap(times, "neighbours", clock)
        lam = self._buffers.get("lambda", n)
        for it in range(prm.solver_iterations):
            fraction = LAST_WEIGHT if it == prm.solver_iterations - 1 else 1.0
            _lambdas(ps, nbr, count, self._kern, work.planes, work.n_planes, self.walls, lo, hi, lam)
            _corrections(ps, nbr, count, lam, self._kern, fraction, work.planes, work.n_planes, work.plane_face,
                         self.walls, lo, hi, contact, normal, buffer)
            ps, buffer = buffer, ps
        clock = self._lap(times, "solve", clock)
        _collide(ps, work.x, r, self._grid, prm.friction, False, self.walls, lo, hi, contact, normal, work.anchor,
                 work.slack, work.gap, work.planes, work.n_planes, work.plane_face, work.spread)
        clock = self._lap(times, "collision", clock)
        _velocities(ps, work.x, nbr, count, dt, h, self._k6, prm.viscosity / (self._k6 * h**6), contact, normal, buffer,
                    work.v)
        work.x = ps
        np.copyto(work.touched, contact, where=contact >= 0)
        self._lap(times, "solve", clock)

    def _neighbours(self, ps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Neighbour lists (N, capacity) int32 and counts (N,) of the points ``ps``, in buffers reused by the next call."""
        h = self.params.kernel_radius
        grid = _particle_grid(ps, self.domain[0], h)
        count = self._buffers.get("count", len(ps), (), np.int64)
        while True:
            nbr = self._buffers.get("nbr", len(ps), (self._capacity,), np.int32)
            _neighbour_lists(ps, grid, h, nbr, count)
            most = int(count.max())
            if most <= self._capacity:
                return nbr, count
            self._capacity = 16 * (most // 16 + 1)

    @staticmethod
    def _lap(times: dict[str, float], name: str, start: float) -> float:
        now = time.perf_counter()
        times[name] += now - start
        return now

    def _drain(self) -> None:
        lo, hi = self.domain
        gone = np.empty(len(self.positions), np.bool_)
        _drained(self.positions, lo, hi, not self.walls, self._planes, self._boxes, gone)
        if not gone.any():
            return
        keep = ~gone
        self.drained += int(np.count_nonzero(gone))
        self.drained_sediment += float(self.sediment[gone].sum())
        for name in ("positions", "velocities", "ids", "sediment", "contact_face", "_rows"):
            setattr(self, name, getattr(self, name)[keep])

    def density(self) -> np.ndarray:
        """SPH density of the fluid particles over the rest density (N,) at the current positions.

        Walls and the mesh are not counted, so particles next to them read low.
        """
        n = len(self.positions)
        out = np.empty(n)
        if n == 0:
            return out
        nbr, count = self._neighbours(self.positions)
        _density_sum(self.positions, nbr, count, self.params.kernel_radius, self._k6, 1.0 / self._rho0, out)
        return out

    # -- snapshots -------------------------------------------------------------------------------------------------

    def state(self) -> FluidState:
        """Copy of everything :meth:`step` changes (not the mesh or the parameters)."""
        return FluidState(self.positions.copy(), self.velocities.copy(), self.ids.copy(), self.sediment.copy(),
                          self.contact_face.copy(), self.contact_distance.copy(), self._advance.copy(),
                          self._rng.copy(), self._next_id, self.emitted, self.drained, self.drained_sediment,
                          self.steps, None if self._last is None else self._last.copy(), self._rows.copy())

    def restore(self, state: FluidState) -> None:
        """Return to a snapshot taken by :meth:`state` (of this fluid); the snapshot stays usable."""
        if not isinstance(state, FluidState):
            raise TypeError(f"state must come from ParticleFluid.state(); got {type(state).__name__}")
        if state.advance.shape != self._advance.shape:
            raise ValueError("state comes from a fluid with a different number of emitters")
        self.positions = state.positions.copy()
        self.velocities = state.velocities.copy()
        self.ids = state.ids.copy()
        self.sediment = state.sediment.copy()
        self.contact_face = state.contact_face.copy()
        self.contact_distance = state.contact_distance.copy()
        self._advance = state.advance.copy()
        self._rng = state.rng.copy()
        self._next_id = state.next_id
        self.emitted = state.emitted
        self.drained = state.drained
        self.drained_sediment = state.drained_sediment
        self.steps = state.steps
        self._last = None if state.last is None else state.last.copy()
        self._rows = state.rows.copy()
