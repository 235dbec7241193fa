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
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._scatter import CHUNKS, chunk_range
from pverosion.kernels.random_streams import stream_state
from pverosion.kernels.tolerances import CROSSING_GROWTH
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["DRAIN_KINDS", "PHASES", "Drain", "Emitter", "FluidParameters", "FluidState", "ParticleFluid"]

DRAIN_KINDS = ("plane", "box")
"""Accepted values of :attr:`Drain.kind`."""

PHASES = ("neighbours", "solve", "collision", "emit_drain")
"""Parts of :meth:`ParticleFluid.step` timed in :attr:`ParticleFluid.profile`."""

TENSILE_DISTANCE = 0.2
"""dq of s_corr in units of the kernel radius h (n = 4)."""
JACOBI_WEIGHT = 0.7
"""w scaling every lambda: below 2 / 2.9, the limit of Jacobi convergence at 5 % compression."""
LAST_WEIGHT = 0.5
"""Fraction of the last iteration's correction that is applied."""
MAX_PLANES = 3
"""Boundary planes (mesh faces turned apart) that add solid density to a particle."""
PLANE_REACH = 2.5
"""Boundary planes are taken within this many radii (the solid's density there is below 0.2 % of rest)."""

_PLANE_COS = math.cos(math.radians(30.0))
"""Faces turned less than this from a boundary plane already taken are the same wall."""
_PAIRS = {"reassoc", "contract"}
"""Floating-point freedom of the particle-pair loops: their sums vectorise (same order for any thread count)."""
_LIMIT = 1 << 19
"""Particle grid cell coordinates are clamped to +-_LIMIT (far-away points only share cells)."""
_MESH_CELL = 2.0
"""Least edge of the mesh grid's cells, in radii (larger cells list more faces, smaller ones list each face in
more cells)."""
_MESH_CELLS = 4096
"""The mesh grid has at most this many cells along an axis (face boxes pack in 3 x 21 bits)."""
_REUSE = 0.5
"""Least slack, in radii, of a search for boundary planes: within a step, a particle whose substep starts and
ends within the slack of where the mesh was last searched (along each axis) reuses that search, which covered
PLANE_REACH r plus the slack."""
_CARRY = (PLANE_REACH - 1.0) / math.sqrt(3.0)
"""Slack, in radii, up to which a search carries over to the next steps: within it (along each axis), every
face within r of the particle is within PLANE_REACH r of the anchor, so its planes were found."""
_MARGIN = 0.1
"""Faces are listed in the cells of their boxes grown by this fraction of a cell: set_mesh refits the grid
instead of rebuilding it while the faces stay the same and no point has moved farther since the build."""
_SPHERE_GROWTH = 1e-6
"""Face bounding spheres are grown by this fraction of their radius and position (more than the crossing
test grows the triangles by, :data:`CROSSING_GROWTH`)."""
_BLOCK = 32
"""Rows per block of :func:`_spread`."""
_CELL_CHUNK = 64
"""Occupied cells per task of :func:`_neighbour_lists`."""
_GAP_ROUNDING = 1e-6
"""The gap of a search (:func:`_search`) is shrunk by this fraction and this many radii (rounding, and the
crossing test's growth of the triangles)."""
_SWEEP_ROUNDS = 3
"""Projections of a crossing segment before the particle is stopped at its first crossing."""
_STOP = 1e-3
"""A stopped particle ends at this fraction of its start's distance in front of the face it would cross."""


# --- parameters ------------------------------------------------------------------------------------------------


def _vector(value, name: str, *, nonzero: bool = False) -> tuple[float, float, float]:
    v = np.asarray(value, dtype=np.float64) if _is_numeric(value) else None
    if v is None or v.shape != (3,) or not np.all(np.isfinite(v)) or (nonzero and not np.any(v != 0.0)):
        kind = "finite non-zero" if nonzero else "finite"
        raise ValueError(f"{name} must be a {kind} 3-vector; got {value!r}")
    return (float(v[0]), float(v[1]), float(v[2]))


def _is_numeric(value) -> bool:
    try:
        np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return True


def _positive(value, name: str) -> float:
    if isinstance(value, bool) or not _is_numeric(value) or np.ndim(value) != 0 or not (
            math.isfinite(float(value)) and float(value) > 0.0):
        raise ValueError(f"{name} must be a finite number > 0; got {value!r}")
    return float(value)


def _count(value, name: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}; got {value!r}")
    return int(value)


def _poly6(r2: float, h: float) -> float:
    return 315.0 / (64.0 * math.pi * h**9) * (h * h - r2) ** 3 if r2 < h * h else 0.0


@dataclass(frozen=True)
class FluidParameters:
    """Parameters of :class:`ParticleFluid`.

    Attributes
    ----------
    radius : float
        Particle radius r (model units). Rest spacing 2r, kernel radius
        h = 4r, collision distance r.
    gravity : (3,) float, default: (0, 0, -9.81)
        Acceleration (model units per s²).
    time_step : float or None, default: None
        Seconds per :meth:`ParticleFluid.step`. None: ``0.4 sqrt(r / |g|)``
        (required when gravity is zero), i.e. substeps of ``0.2 sqrt(r / |g|)``
        at the default two: gravity then moves a resting particle 0.04 r per
        substep, a particle that has fallen 25 r moves about r per substep,
        and with 3 iterations a pool 10 particles deep settles about 2.5 %
        above rest density inside (4 % in bulk; 5 % and 8 % at 20 deep: the
        compression grows with the depth and the square of the substep).
    substeps : int, default: 2
    solver_iterations : int, default: 3
        Jacobi iterations of the density constraint per substep.
    viscosity : float, default: 0.01
        XSPH c in [0, 0.2]: every neighbour's velocity difference is blended
        in with weight ``c W_ij / W(0)`` per substep (the weights of a
        particle in the rest lattice sum to 4.2 c).
    friction : float, default: 0.0
        Fraction in [0, 1] of the tangential displacement removed at a mesh
        contact (per substep); 1 makes touching particles stick.
    relaxation : float, default: 0.1
        Constraint-force mixing epsilon of eq. 11 in units of S (the sum of
        the squared constraint gradients of a particle at rest in the
        lattice): it bounds lambda where a particle has few neighbours and
        costs 10 % of the correction in the bulk. (The under-relaxation that
        keeps the Jacobi iterations stable is :data:`JACOBI_WEIGHT`.)
    tensile : float, default: 0.0
        k of the tensile term s_corr (eq. 13, n = 4, dq = 0.2 h) in units of
        1 / S; the paper's 0.1 is a comparable strength. Off by default:
        with the unilateral constraint there is no negative pressure for it
        to counter, and it adds an artificial pressure that spreads free
        surfaces and thin jets apart.
    max_particles : int, default: 250000
        Emitters stop emitting at this count; :meth:`ParticleFluid.add_particles`
        refuses to exceed it.
    """

    radius: float
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    time_step: float | None = None
    substeps: int = 2
    solver_iterations: int = 3
    viscosity: float = 0.01
    friction: float = 0.0
    relaxation: float = 0.1
    tensile: float = 0.0
    max_particles: int = 250_000

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))
        object.__setattr__(self, "gravity", _vector(self.gravity, "gravity"))
        if self.time_step is None:
            if not any(self.gravity):
                raise ValueError("time_step is required when gravity is zero (the default scales with |g|)")
        else:
            object.__setattr__(self, "time_step", _positive(self.time_step, "time_step"))
        _count(self.substeps, "substeps", 1)
        _count(self.solver_iterations, "solver_iterations", 1)
        _count(self.max_particles, "max_particles", 1)
        for name, top in (("viscosity", 0.2), ("friction", 1.0), ("relaxation", math.inf), ("tensile", math.inf)):
            value = getattr(self, name)
            if (isinstance(value, bool) or not _is_numeric(value) or np.ndim(value) != 0
                    or not (0.0 <= float(value) <= top and math.isfinite(float(value)))):
                limit = f"in [0, {top:g}]" if math.isfinite(top) else ">= 0 and finite"
                raise ValueError(f"{name} must be a number {limit}; got {value!r}")
            object.__setattr__(self, name, float(value))

    @property
    def spacing(self) -> float:
        """Rest spacing 2r."""
        return 2.0 * self.radius

    @property
    def kernel_radius(self) -> float:
        """Kernel radius h = 4r."""
        return 4.0 * self.radius

    @property
    def dt(self) -> float:
        """Seconds per step: ``time_step``, or ``0.4 sqrt(r / |g|)`` when it is None."""
        if self.time_step is not None:
            return self.time_step
        return 0.4 * math.sqrt(self.radius / math.sqrt(sum(g * g for g in self.gravity)))

    @property
    def rest_density(self) -> float:
        """Poly6 kernel sum (mass 1) of a particle in a cubic lattice of spacing 2r."""
        return self._lattice()[0]

    def _lattice(self) -> tuple[float, float, float]:
        """Rest density, S = sum_k |grad_k C|² of a particle in the rest lattice, and the solid's scale.

        The solid's density at distance ``delta`` from a plane is
        ``kw ((h² - z²)⁴)`` summed over z = delta + r, delta + 3r (layers of
        virtual particles smeared over their planes); ``kw`` makes it equal to
        the lattice layers it replaces at delta = r, so a lattice resting on a
        wall is exactly at rest density.
        """
        h, d, r = self.kernel_radius, self.spacing, self.radius
        rho = 0.0
        grad2 = 0.0
        beyond = 0.0
        for i in range(-2, 3):
            for j in range(-2, 3):
                for k in range(-2, 3):
                    dist = d * math.sqrt(i * i + j * j + k * k)
                    rho += _poly6(dist * dist, h)
                    if 0.0 < dist < h:
                        grad2 += (45.0 / (math.pi * h**6) * (h - dist) ** 2) ** 2
                    if k > 0:
                        beyond += _poly6(dist * dist, h)
        smeared = sum((h * h - z * z) ** 4 for z in (2.0 * r, 4.0 * r) if z < h)
        # the gradients with respect to the particle itself cancel in the symmetric lattice
        return rho, grad2 / (rho * rho), beyond / smeared


@dataclass(frozen=True)
class Emitter:
    """A disc that releases particles.

    Layers of a square lattice of spacing 2r, clipped to the disc (centred on
    ``position``, perpendicular to ``direction``), are released each time the
    stream has advanced by 2r, moving at ``speed`` along ``direction``.

    Attributes
    ----------
    position : (3,) float
        Centre of the disc.
    direction : (3,) float
        Direction of the stream (normalised on creation).
    radius : float
        Radius of the disc; a disc smaller than 2r holds one lattice point.
    rate : float
        Particles per second.
    speed : float or None, default: None
        None: the speed at which ``rate`` particles per second leave at rest
        spacing. Given: every lattice point of a layer is emitted with the
        probability that makes ``rate`` the average; ``rate`` must not exceed
        the lattice points times ``speed / 2r``.
    """

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    radius: float
    rate: float
    speed: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _vector(self.position, "emitter position"))
        d = np.array(_vector(self.direction, "emitter direction", nonzero=True))
        d /= np.linalg.norm(d)
        object.__setattr__(self, "direction", (float(d[0]), float(d[1]), float(d[2])))
        object.__setattr__(self, "radius", _positive(self.radius, "emitter radius"))
        object.__setattr__(self, "rate", _positive(self.rate, "emitter rate"))
        if self.speed is not None:
            object.__setattr__(self, "speed", _positive(self.speed, "emitter speed"))

    @classmethod
    def parse(cls, text: str) -> Emitter:
        """Emitter from ``"x,y,z,dx,dy,dz,radius,rate[,speed]"``."""
        values = _numbers(text, "emitter")
        if len(values) not in (8, 9):
            raise ValueError(f"an emitter is 'x,y,z,dx,dy,dz,radius,rate[,speed]' (8 or 9 numbers); got {text!r}")
        return cls(tuple(values[0:3]), tuple(values[3:6]), values[6], values[7], values[8] if len(values) == 9 else None)

    def lattice(self, spacing: float) -> np.ndarray:
        """Offsets (M, 3) from ``position`` of the lattice points of one layer."""
        d = np.array(self.direction)
        helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(d, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(d, e1)
        m = int(self.radius // spacing)
        i, j = np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1), indexing="ij")
        i, j = i.ravel(), j.ravel()
        keep = (i * i + j * j) * spacing * spacing <= self.radius * self.radius * (1.0 + 1e-12)
        return spacing * (i[keep, None] * e1 + j[keep, None] * e2)


@dataclass(frozen=True)
class Drain:
    """A region that removes particles.

    Attributes
    ----------
    kind : {"plane", "box"}
    values : tuple of float
        ``"plane"``: ``(nx, ny, nz, d)``, removing particles with
        ``n . x > d``. ``"box"``: ``(xmin, ymin, zmin, xmax, ymax, zmax)``,
        removing particles inside the box.
    """

    kind: str
    values: tuple

    def __post_init__(self) -> None:
        if self.kind not in DRAIN_KINDS:
            raise ValueError(f"drain kind must be one of {DRAIN_KINDS}; got {self.kind!r}")
        if not _is_numeric(self.values) or np.ndim(self.values) != 1:
            raise ValueError(f"drain values must be a sequence of numbers; got {self.values!r}")
        values = tuple(float(v) for v in np.asarray(self.values, dtype=np.float64))
        expected = 4 if self.kind == "plane" else 6
        if len(values) != expected or not all(math.isfinite(v) for v in values):
            layout = "(nx, ny, nz, d)" if self.kind == "plane" else "(xmin, ymin, zmin, xmax, ymax, zmax)"
            raise ValueError(f"a {self.kind} drain takes {expected} finite numbers {layout}; got {self.values!r}")
        if self.kind == "plane" and not any(values[:3]):
            raise ValueError(f"a plane drain needs a non-zero normal; got {self.values!r}")
        if self.kind == "box" and any(values[a] > values[a + 3] for a in range(3)):
            raise ValueError(f"a box drain needs min <= max on every axis; got {self.values!r}")
        object.__setattr__(self, "values", values)

    @classmethod
    def parse(cls, text: str) -> Drain:
        """Drain from ``"plane:nx,ny,nz,d"`` or ``"box:xmin,ymin,zmin,xmax,ymax,zmax"``."""
        kind, sep, rest = str(text).partition(":")
        if not sep:
            raise ValueError(f"a drain is 'plane:nx,ny,nz,d' or 'box:xmin,ymin,zmin,xmax,ymax,zmax'; got {text!r}")
        return cls(kind.strip(), tuple(_numbers(rest, "drain")))


def _numbers(text: str, what: str) -> list[float]:
    try:
        return [float(part) for part in str(text).split(",")]
    except ValueError:
        raise ValueError(f"{what} specification must be comma-separated numbers; got {text!r}") from None


@dataclass(frozen=True)
class FluidState:
    """Snapshot of a :class:`ParticleFluid` (see :meth:`ParticleFluid.state`)."""

    positions: np.ndarray
    velocities: np.ndarray
    ids: np.ndarray
    sediment: np.ndarray
    contact_face: np.ndarray
    contact_distance: np.ndarray
    advance: np.ndarray
    rng: np.ndarray
    next_id: int
    emitted: int
    drained: int
    drained_sediment: float
    steps: int
    last: _Work | None  # the last step's work (its searches carry over)
    rows: np.ndarray


# --- grids -----------------------------------------------------------------------------------------------------


@njit(cache=True)
def _cell(x, lo, size):
    """Grid coordinate of ``x`` along one axis, clamped to +-_LIMIT."""
    return int(np.floor(min(max((x - lo) / size, -_LIMIT), _LIMIT)))


@njit(cache=True)
def _table_size(n):
    """Power of two >= n (at least 64)."""
    t = 64
    while t < n:
        t *= 2
    return t


@njit(cache=True)
def _particle_grid(pos, lo, size):
    """Counting sort of points into hashed cells of edge ``size``.

    Returns
    -------
    order : (N,) int64
        Points in bucket order, the cells of a bucket in order of their
        linear index (each cell's points contiguous, in increasing index).
    start : (T + 1,) int64
        CSR offsets of the T buckets into the sorted points.
    keys : (N,) int64
        Linear cell index of every sorted point (to tell apart cells sharing a bucket).
    cells : (N, 3) int64
        Cell coordinates of every sorted point, relative to the lowest cell.
    dims : (3,) int64
        Cells along each axis of the box of occupied cells.
    runs : (M + 1,) int64
        Offsets of the M occupied cells into the sorted points.
    """
    n = pos.shape[0]
    cell = np.empty((n, 3), np.int64)
    cmin = np.full(3, _LIMIT, np.int64)
    cmax = np.full(3, -_LIMIT, np.int64)
    for i in range(n):
        for a in range(3):
            c = _cell(pos[i, a], lo[a], size)
            cell[i, a] = c
            cmin[a] = min(cmin[a], c)
            cmax[a] = max(cmax[a], c)
    dims = np.maximum(cmax - cmin + 1, 1)
    table = _table_size(2 * n)
    mask = table - 1
    key = np.empty(n, np.int64)
    start = np.zeros(table + 1, np.int64)
    for i in range(n):
        for a in range(3):
            cell[i, a] -= cmin[a]
        key[i] = cell[i, 0] + dims[0] * (cell[i, 1] + dims[1] * cell[i, 2])
        start[(key[i] & mask) + 1] += 1
    for b in range(table):
        start[b + 1] += start[b]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        b = key[i] & mask
        order[fill[b]] = i
        fill[b] += 1
    for b in range(table):  # cells sharing a bucket: stable insertion sort by cell (buckets are small)
        for q in range(start[b] + 1, start[b + 1]):
            item = order[q]
            p = q - 1
            while p >= start[b] and key[order[p]] > key[item]:
                order[p + 1] = order[p]
                p -= 1
            order[p + 1] = item
    keys = key[order]
    runs = np.empty(n + 1, np.int64)
    m = 0
    for q in range(n):
        if q == 0 or keys[q] != keys[q - 1]:
            runs[m] = q
            m += 1
    runs[m] = n
    return order, start, keys, cell[order], dims, runs[:m + 1]


@njit(cache=True, inline="always")
def _row(i0, i1, base, mask, start):
    """Sorted ranges (two when the buckets wrap) and key bounds of cells i0..i1 of the row at key ``base``."""
    k0 = base + i0
    k1 = base + i1
    b0 = k0 & mask
    b1 = k1 & mask
    if b0 <= b1:
        return k0, k1, start[b0], start[b1 + 1], 0, 0
    return k0, k1, start[b0], start[mask + 1], start[0], start[b1 + 1]


@njit(cache=True, inline="always")
def _around(cells, dims, s):
    """Cell ranges (i0, i1, j0, j1, k0, k1) of the 27 cells around the cell of sorted point ``s``."""
    return (max(cells[s, 0] - 1, 0), min(cells[s, 0] + 1, dims[0] - 1), max(cells[s, 1] - 1, 0),
            min(cells[s, 1] + 1, dims[1] - 1), max(cells[s, 2] - 1, 0), min(cells[s, 2] + 1, dims[2] - 1))


@njit(cache=True)
def _candidates(start, cells, dims, s, mask):
    """Upper bound of the points in the 27 cells around the cell of sorted point ``s`` (whole buckets)."""
    i0, i1, j0, j1, k0, k1 = _around(cells, dims, s)
    total = 0
    for ck in range(k0, k1 + 1):
        for cj in range(j0, j1 + 1):
            _, _, a0, a1, w0, w1 = _row(i0, i1, dims[0] * (cj + dims[1] * ck), mask, start)
            total += a1 - a0 + w1 - w0
    return total


@njit(cache=True, fastmath=_PAIRS)
def _cell_lists(pos, grid, s0, s1, h2, nbr, count, bx, by, bz, d2, bj, kept):
    """Neighbour lists of the points of one cell (sorted points s0..s1), with buffers of :func:`_candidates` size.

    The points of the 27 cells around are copied into the buffers; every
    point of the cell keeps those within h, in buffer order. The compaction
    is branch-free: in a moving fluid, "within h" is a coin toss for the
    branch predictor.
    """
    order, start, keys, cells, dims, _ = grid
    mask = start.shape[0] - 2
    last = nbr.shape[1] - 1
    i0, i1, j0, j1, k0, k1 = _around(cells, dims, s0)
    m = 0
    for ck in range(k0, k1 + 1):
        for cj in range(j0, j1 + 1):
            key0, key1, a0, a1, w0, w1 = _row(i0, i1, dims[0] * (cj + dims[1] * ck), mask, start)
            for part in range(2):
                lo_q, hi_q = (a0, a1) if part == 0 else (w0, w1)
                for q in range(lo_q, hi_q):
                    if key0 <= keys[q] <= key1:
                        j = order[q]
                        bx[m], by[m], bz[m] = pos[j, 0], pos[j, 1], pos[j, 2]
                        bj[m] = j
                        m += 1
    for s in range(s0, s1):
        i = order[s]
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        for b in range(m):
            dx, dy, dz = px - bx[b], py - by[b], pz - bz[b]
            d2[b] = dx * dx + dy * dy + dz * dz
        n = 0
        for b in range(m):
            kept[n] = bj[b]
            n += (d2[b] < h2) & (bj[b] != i)
        for q in range(min(n, last + 1)):
            nbr[i, q] = kept[q]
        count[i] = n


@njit(cache=True, parallel=True)
def _neighbour_lists(pos, grid, h, nbr, count):
    """Neighbours closer than h of every point (itself excluded), up to nbr.shape[1] each; count gets all.

    ``grid`` is :func:`_particle_grid` of the points with cell edge h. The
    occupied cells go in chunks of :data:`_CELL_CHUNK` to the threads, each
    chunk with buffers as large as its largest cell needs.
    """
    start, cells, dims, runs = grid[1], grid[3], grid[4], grid[5]
    mask = start.shape[0] - 2
    n_cells = runs.shape[0] - 1
    for c in prange((n_cells + _CELL_CHUNK - 1) // _CELL_CHUNK):
        r0, r1 = c * _CELL_CHUNK, min((c + 1) * _CELL_CHUNK, n_cells)
        size = 0
        for r in range(r0, r1):
            size = max(size, _candidates(start, cells, dims, runs[r], mask))
        bx, by, bz, d2 = np.empty(size), np.empty(size), np.empty(size), np.empty(size)
        bj, kept = np.empty(size, np.int32), np.empty(size, np.int32)
        for r in range(r0, r1):
            _cell_lists(pos, grid, runs[r], runs[r + 1], h * h, nbr, count, bx, by, bz, d2, bj, kept)


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _density_sum(pos, nbr, count, h, k6, inv_rho0, out):
    """rho / rho0 of every point from its neighbour list (fluid only)."""
    h2 = h * h
    for i in prange(pos.shape[0]):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        rho = k6 * h2 * h2 * h2
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = px - pos[j, 0], py - pos[j, 1], pz - pos[j, 2]
            q = max(h2 - dx * dx - dy * dy - dz * dz, 0.0)
            rho += k6 * q * q * q
        out[i] = rho * inv_rho0


@njit(cache=True, inline="always")
def _store_face(points, faces, f, data):
    """Row ``f`` of :func:`_face_data`."""
    a, b, c = v3.row(points, faces[f, 0]), v3.row(points, faces[f, 1]), v3.row(points, faces[f, 2])
    n = v3.cross(v3.sub(b, a), v3.sub(c, a))
    length = v3.norm(n)
    n = v3.scale(n, 1.0 / length) if length > 0.0 else (0.0, 0.0, 0.0)
    for m in range(3):
        data[f, m] = a[m]
        data[f, 3 + m] = b[m]
        data[f, 6 + m] = c[m]
        data[f, 9 + m] = n[m]


@njit(cache=True, parallel=True)
def _face_data(points, faces):
    """Vertices a, b, c and unit normal n (right-hand rule, zero if degenerate) of every face: (F, 12)."""
    data = np.empty((faces.shape[0], 12))
    for f in prange(faces.shape[0]):
        _store_face(points, faces, f, data)
    return data


@njit(cache=True, parallel=True)
def _face_cells(data, lo, size, dims, margin):
    """Cell range (F, 6) of every face's bounding box grown by ``margin`` and its number of cells (F,)."""
    n = data.shape[0]
    box = np.empty((n, 6), np.int64)
    cnt = np.empty(n, np.int64)
    for f in prange(n):
        total = 1
        for a in range(3):
            x0, x1, x2 = data[f, a], data[f, 3 + a], data[f, 6 + a]
            c0 = min(max(int(np.floor((min(x0, min(x1, x2)) - margin - lo[a]) / size)), 0), dims[a] - 1)
            c1 = min(max(int(np.floor((max(x0, max(x1, x2)) + margin - lo[a]) / size)), 0), dims[a] - 1)
            box[f, a] = c0
            box[f, a + 3] = c1
            total *= c1 - c0 + 1
        cnt[f] = total
    return box, cnt


@njit(cache=True, parallel=True)
def _face_entries(box, offset, dims, mask, bucket, key, face, first):
    """Bucket, linear cell index, face and packed lowest cell of the face's box for every (face, cell) pair."""
    for f in prange(box.shape[0]):
        q = offset[f]
        low = box[f, 0] | (box[f, 1] << 21) | (box[f, 2] << 42)
        for k in range(box[f, 2], box[f, 5] + 1):
            for j in range(box[f, 1], box[f, 4] + 1):
                for i in range(box[f, 0], box[f, 3] + 1):
                    key[q] = i + dims[0] * (j + dims[1] * k)
                    bucket[q] = key[q] & mask
                    face[q] = f
                    first[q] = low
                    q += 1


@njit(cache=True, parallel=True)
def _bucket_sort(bucket, key, face, first, table):
    """Stable counting sort of the entries by bucket: (start (T + 1,), keys, faces, firsts).

    The entries are split in CHUNKS fixed chunks, counted and placed in parallel.
    """
    n = bucket.shape[0]
    counts = np.zeros((CHUNKS, table), np.int64)
    for c in prange(CHUNKS):
        lo, hi = chunk_range(n, c)
        for q in range(lo, hi):
            counts[c, bucket[q]] += 1
    start = np.zeros(table + 1, np.int64)
    for b in range(table):  # counts become each chunk's first slot in the bucket
        total = start[b]
        for c in range(CHUNKS):
            count = counts[c, b]
            counts[c, b] = total
            total += count
        start[b + 1] = total
    keys = np.empty(n, np.int64)
    items = np.empty(n, np.int64)
    firsts = np.empty(n, np.int64)
    for c in prange(CHUNKS):
        lo, hi = chunk_range(n, c)
        for q in range(lo, hi):
            b = bucket[q]
            slot = counts[c, b]
            keys[slot] = key[q]
            items[slot] = face[q]
            firsts[slot] = first[q]
            counts[c, b] = slot + 1
    return start, keys, items, firsts


@njit(cache=True, inline="always")
def _face_sphere(data, f):
    """Bounding sphere (x, y, z, radius) of face ``f``, grown by :data:`_SPHERE_GROWTH` for rounding."""
    c = v3.scale(v3.add(v3.add(_corner(data, f, 0), _corner(data, f, 1)), _corner(data, f, 2)), 1.0 / 3.0)
    radius = 0.0
    for m in range(3):
        radius = max(radius, v3.norm(v3.sub(_corner(data, f, m), c)))
    return c[0], c[1], c[2], radius + _SPHERE_GROWTH * (radius + abs(c[0]) + abs(c[1]) + abs(c[2]))


@njit(cache=True, parallel=True)
def _entry_spheres(data, items):
    """Bounding sphere (centre, radius) of the face of every grid entry, in entry order, and where each face's
    entries are: (E, 4) spheres and the CSR (F + 1,), (E,) of the entries of every face.

    The collision queries test the spheres before touching a face, reading
    them in the order they scan the entries.
    """
    n_faces = data.shape[0]
    first = np.zeros(n_faces + 1, np.int64)
    for q in range(items.shape[0]):
        first[items[q] + 1] += 1
    for f in range(n_faces):
        first[f + 1] += first[f]
    fill = first[:-1].copy()
    entries = np.empty(items.shape[0], np.int64)
    for q in range(items.shape[0]):
        entries[fill[items[q]]] = q
        fill[items[q]] += 1
    out = np.empty((items.shape[0], 4))
    for f in prange(n_faces):
        sphere = _face_sphere(data, f)
        for q in range(first[f], first[f + 1]):
            for m in range(4):
                out[entries[q], m] = sphere[m]
    return out, first, entries


@njit(cache=True, parallel=True)
def _face_moves(points, before, faces):
    """Largest coordinate change of the vertices of every face (F,) from ``before`` to ``points``, and of any point."""
    moved = np.empty(points.shape[0])
    for i in prange(points.shape[0]):
        moved[i] = max(abs(points[i, 0] - before[i, 0]), abs(points[i, 1] - before[i, 1]),
                       abs(points[i, 2] - before[i, 2]))
    out = np.empty(faces.shape[0])
    for f in prange(faces.shape[0]):
        out[f] = max(moved[faces[f, 0]], moved[faces[f, 1]], moved[faces[f, 2]])
    return out, moved.max() if points.shape[0] else 0.0


@njit(cache=True, parallel=True)
def _refit(points, faces, face_move, data, spheres, first, entries):
    """Update the face data and entry spheres of the faces that moved (``face_move > 0``), in place."""
    for f in prange(faces.shape[0]):
        if face_move[f] > 0.0:
            _store_face(points, faces, f, data)
            sphere = _face_sphere(data, f)
            for q in range(first[f], first[f + 1]):
                for m in range(4):
                    spheres[entries[q], m] = sphere[m]


@njit(cache=True)
def _bounds(points, data):
    """Lower and upper corners of ``points`` and the mean length of the faces' first edges."""
    lo = points[0].copy()
    hi = points[0].copy()
    for i in range(points.shape[0]):
        for a in range(3):
            lo[a] = min(lo[a], points[i, a])
            hi[a] = max(hi[a], points[i, a])
    total = 0.0
    for f in range(data.shape[0]):
        total += v3.norm(v3.sub(_corner(data, f, 1), _corner(data, f, 0)))
    return lo, hi, total / max(data.shape[0], 1)


@njit(cache=True, parallel=True)
def _largest_move(points, before):
    """Largest coordinate change of any point (deterministic: a maximum)."""
    moved = np.zeros(points.shape[0])
    for i in prange(points.shape[0]):
        moved[i] = max(abs(points[i, 0] - before[i, 0]), abs(points[i, 1] - before[i, 1]),
                       abs(points[i, 2] - before[i, 2]))
    return moved.max() if points.shape[0] else 0.0


def _mesh_grid(points: np.ndarray, faces: np.ndarray, radius: float) -> tuple[tuple, float, tuple]:
    """Face data and hashed bounding-box grid of a mesh, as the tuple the collision kernels take, its margin, and
    the grid entries of every face (CSR offsets (F + 1,) and entries (E,)) for refits.

    Faces are listed in the cells of their bounding boxes grown by the margin
    (:data:`_MARGIN` of a cell), so the grid stays valid while no point moves farther.
    The tuple is (face data, lower corner, cell size, cells per axis, bucket
    offsets, cell keys, faces and packed lowest cells of the entries, entry
    spheres).
    """
    data = _face_data(points, faces)
    lo, hi, edge = _bounds(points, data)
    size = max(_MESH_CELL * radius, edge, float((hi - lo).max()) / (_MESH_CELLS - 2))
    margin = _MARGIN * size
    lo = lo - margin
    dims = np.floor((hi + margin - lo) / size).astype(np.int64) + 1
    box, cnt = _face_cells(data, lo, size, dims, margin)
    offset = np.zeros(len(faces) + 1, np.int64)
    np.cumsum(cnt, out=offset[1:])
    table = int(_table_size(int(offset[-1]) // 4))
    bucket, key, face, first = (np.empty(offset[-1], np.int64) for _ in range(4))
    _face_entries(box, offset, dims, table - 1, bucket, key, face, first)
    start, keys, items, firsts = _bucket_sort(bucket, key, face, first, table)
    spheres, face_first, face_entries = _entry_spheres(data, items)
    return (data, lo, size, dims, start, keys, items, firsts, spheres), margin, (face_first, face_entries)


def _empty_grid() -> tuple:
    """The grid tuple of no mesh (same types as :func:`_mesh_grid`)."""
    return (np.zeros((0, 12)), np.zeros(3), 1.0, np.ones(3, np.int64), np.zeros(65, np.int64),
            np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)))


@njit(cache=True, inline="always")
def _cell_box(lo_box, hi_box, lo, size, dims):
    """Mesh-grid cell range (i0, j0, k0, i1, j1, k1) of the box [lo_box, hi_box]; i0 > i1 when outside."""
    i0 = max(int(np.floor((lo_box[0] - lo[0]) / size)), 0)
    j0 = max(int(np.floor((lo_box[1] - lo[1]) / size)), 0)
    k0 = max(int(np.floor((lo_box[2] - lo[2]) / size)), 0)
    i1 = min(int(np.floor((hi_box[0] - lo[0]) / size)), dims[0] - 1)
    j1 = min(int(np.floor((hi_box[1] - lo[1]) / size)), dims[1] - 1)
    k1 = min(int(np.floor((hi_box[2] - lo[2]) / size)), dims[2] - 1)
    if j0 > j1 or k0 > k1:
        i0 = i1 + 1
    return i0, j0, k0, i1, j1, k1


@njit(cache=True, inline="always")
def _first_visit(first, key, base, i0, j, k, j0, k0):
    """Whether the cell at ``key`` is the first cell of the query range the face's box meets (visit it once)."""
    return (key - base == max(i0, first & 0x1FFFFF) and j == max(j0, (first >> 21) & 0x1FFFFF)
            and k == max(k0, first >> 42))


# --- mesh collision --------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _corner(data, f, m):
    return (data[f, 3 * m], data[f, 3 * m + 1], data[f, 3 * m + 2])


@njit(cache=True, inline="always")
def _over(p, a, b, c, n):
    """Whether the projection of ``p`` on the plane of triangle (a, b, c) with unit normal ``n`` falls inside it."""
    return (v3.dot(v3.cross(v3.sub(b, a), v3.sub(p, a)), n) >= 0.0
            and v3.dot(v3.cross(v3.sub(c, b), v3.sub(p, b)), n) >= 0.0
            and v3.dot(v3.cross(v3.sub(a, c), v3.sub(p, c)), n) >= 0.0)


@njit(cache=True)
def _closest_on_boundary(p, a, b, c):
    """Closest point to ``p`` on the three edges of triangle (a, b, c)."""
    best = a
    best2 = np.inf
    for m in range(3):
        u, w = (a, b) if m == 0 else ((b, c) if m == 1 else (c, a))
        e = v3.sub(w, u)
        ee = v3.dot(e, e)
        t = 0.0 if ee == 0.0 else min(max(v3.dot(v3.sub(p, u), e) / ee, 0.0), 1.0)
        q = v3.add(u, v3.scale(e, t))
        d = v3.sub(p, q)
        if v3.dot(d, d) < best2:
            best2 = v3.dot(d, d)
            best = q
    return best


@njit(cache=True, inline="always")
def _nearer(dist, f, other_dist, other_face):
    """Whether (dist, f) comes before (other_dist, other_face): nearer, or as near with a lower face index."""
    return dist < other_dist or (dist == other_dist and f < other_face)


@njit(cache=True)
def _keep_plane(planes, plane_face, i, taken, data, f, u, offset, dist, edge):
    """Offer face ``f`` (plane ``u . x = offset`` at ``dist``; ``edge``: of an edge or corner) as a boundary plane
    of particle ``i``.

    A face turned less than 30 degrees from a plane already kept replaces it
    when nearer; otherwise it takes a free slot, or the farthest one's when
    nearer (ties go to the lower face index; the visiting order is fixed by
    the grid, and :func:`_sort_planes` orders the result). Returns the
    number of planes kept.
    """
    n = _corner(data, f, 3)
    slot = -1
    for k in range(taken):
        if v3.dot(n, _corner(data, plane_face[i, k], 3)) > _PLANE_COS:
            if not _nearer(dist, f, planes[i, k, 4], plane_face[i, k]):
                return taken
            slot = k
            break
    if slot < 0:
        if taken < MAX_PLANES:
            slot = taken
            taken += 1
        else:
            slot = 0
            for k in range(1, MAX_PLANES):
                if _nearer(planes[i, slot, 4], plane_face[i, slot], planes[i, k, 4], plane_face[i, k]):
                    slot = k
            if not _nearer(dist, f, planes[i, slot, 4], plane_face[i, slot]):
                return taken
    planes[i, slot, 0], planes[i, slot, 1], planes[i, slot, 2] = u
    planes[i, slot, 3] = offset
    planes[i, slot, 4] = dist
    planes[i, slot, 5] = 1.0 if edge else 0.0
    plane_face[i, slot] = f
    return taken


@njit(cache=True)
def _sort_planes(planes, plane_face, i, taken):
    """Order the first ``taken`` boundary planes of particle ``i`` by face (the order the faces were met in
    depends on the search box; the push-out and the solid's density sum the planes in order)."""
    for k in range(1, taken):
        m = k
        while m > 0 and plane_face[i, m - 1] > plane_face[i, m]:
            plane_face[i, m - 1], plane_face[i, m] = plane_face[i, m], plane_face[i, m - 1]
            for c in range(planes.shape[2]):
                planes[i, m - 1, c], planes[i, m, c] = planes[i, m, c], planes[i, m - 1, c]
            m -= 1


@njit(cache=True, inline="always")
def _covered(planes, plane_face, i, taken, data, f, n, s):
    """Whether a plane kept for particle ``i`` on the same wall as face ``f`` (normal ``n``) beats distance ``s``.

    ``s``, the distance to a face's plane, bounds the distance to the face
    from below, so such a face cannot replace the kept plane.
    """
    for k in range(taken):
        if ((planes[i, k, 4] < s or (planes[i, k, 4] == s and plane_face[i, k] < f))
                and v3.dot(n, _corner(data, plane_face[i, k], 3)) > _PLANE_COS):
            return True
    return False


@njit(cache=True)
def _listed(lo_box, hi_box, grid):
    """Whether any face is listed in the mesh-grid cells of the box [lo_box, hi_box]."""
    lo, size, dims, start, keys = grid[1], grid[2], grid[3], grid[4], grid[5]
    i0, j0, k0, i1, j1, k1 = _cell_box(lo_box, hi_box, lo, size, dims)
    mask = start.shape[0] - 2
    for k in range(k0, k1 + 1 if i0 <= i1 else k0):
        for j in range(j0, j1 + 1):
            key0, key1, a0, a1, w0, w1 = _row(i0, i1, dims[0] * (j + dims[1] * k), mask, start)
            for part in range(2):
                lo_q, hi_q = (a0, a1) if part == 0 else (w0, w1)
                for q in range(lo_q, hi_q):
                    if key0 <= keys[q] <= key1:
                        return True
    return False


@njit(cache=True)
def _search(p, r, slack, grid, planes, plane_face, i):
    """Boundary planes of particle ``i`` at ``p``: faces it is over within PLANE_REACH r, edges and corners
    within r, and the face it is less than r behind (when no face it is over is nearer).

    Returns the number of planes kept and the gap: a lower bound of the
    distance from ``p`` to every face listed within PLANE_REACH r + ``slack``
    of ``p`` along any axis (inf when there is none; faces farther along an
    axis are not listed). A motion that stays within ``slack`` along every
    axis and nearer than the gap to ``p`` cannot meet a face.
    """
    data, lo, size, dims, start, keys, items, firsts, spheres = grid
    reach = PLANE_REACH * r
    # only faces in the cells within reach can give planes or bound the gap below reach; the rest of the box
    # within reach + slack matters only when those cells are empty (gap reach, or inf when it is empty too)
    i0, j0, k0, i1, j1, k1 = _cell_box(v3.sub(p, (reach, reach, reach)), v3.add(p, (reach, reach, reach)), lo, size,
                                       dims)
    mask = start.shape[0] - 2
    gap = np.inf
    taken = 0
    nearest = r  # the face it is over with the smallest |distance| below r, for the behind rule
    over_face = -1
    over_s = 0.0
    for k in range(k0, k1 + 1 if i0 <= i1 else k0):
        for j in range(j0, j1 + 1):
            base = dims[0] * (j + dims[1] * k)
            key0, key1, a0, a1, w0, w1 = _row(i0, i1, base, mask, start)
            for part in range(2):
                lo_q, hi_q = (a0, a1) if part == 0 else (w0, w1)
                for q in range(lo_q, hi_q):
                    if keys[q] < key0 or keys[q] > key1:
                        continue
                    # a face it is over within reach, or an edge within r, lies within reach of p
                    dx, dy, dz = p[0] - spheres[q, 0], p[1] - spheres[q, 1], p[2] - spheres[q, 2]
                    if dx * dx + dy * dy + dz * dz > (reach + spheres[q, 3]) ** 2:
                        gap = min(gap, reach)  # outside the sphere grown by reach
                        continue
                    if not _first_visit(firsts[q], keys[q], base, i0, j, k, j0, k0):
                        continue
                    f = items[q]
                    n = _corner(data, f, 3)
                    a = _corner(data, f, 0)
                    s = v3.dot(n, v3.sub(p, a))
                    gap = min(gap, abs(s))  # the distance to a face's plane bounds the distance to the face
                    if (s <= -r or s >= reach or (n[0] == 0.0 and n[1] == 0.0 and n[2] == 0.0)
                            or (s >= 0.0 and _covered(planes, plane_face, i, taken, data, f, n, s))):
                        continue
                    b, c = _corner(data, f, 1), _corner(data, f, 2)
                    if _over(p, a, b, c, n):
                        if _nearer(abs(s), f, nearest, over_face if over_face >= 0 else data.shape[0]):
                            nearest = abs(s)
                            over_face = f
                            over_s = s
                        if s >= 0.0:
                            taken = _keep_plane(planes, plane_face, i, taken, data, f, n, v3.dot(n, a), s, False)
                    elif 0.0 <= s < r:
                        e = _closest_on_boundary(p, a, b, c)
                        d = v3.sub(p, e)
                        dist = v3.norm(d)
                        if 0.0 < dist < r:
                            u = v3.scale(d, 1.0 / dist)
                            taken = _keep_plane(planes, plane_face, i, taken, data, f, u, v3.dot(u, e), dist, True)
    box = reach + slack
    if gap == np.inf and _listed(v3.sub(p, (box, box, box)), v3.add(p, (box, box, box)), grid):
        gap = reach
    if over_face >= 0 and over_s < 0.0:  # behind the nearest face it is over: to its front
        n = _corner(data, over_face, 3)
        taken = _keep_plane(planes, plane_face, i, taken, data, over_face, n, v3.dot(n, _corner(data, over_face, 0)),
                            0.0, False)
    _sort_planes(planes, plane_face, i, taken)
    return taken, gap * (1.0 - _GAP_ROUNDING) - _GAP_ROUNDING * r


@njit(cache=True)
def _plane_push(p, r, planes, taken, plane_face, i):
    """Move ``p`` to ``r`` in front of the first ``taken`` boundary planes of particle ``i``.

    Returns the new position, the face of the last plane that moved it (-1: none) and that plane's direction.
    """
    contact = -1
    push = (0.0, 0.0, 0.0)
    for k in range(taken):
        u = (planes[i, k, 0], planes[i, k, 1], planes[i, k, 2])
        delta = v3.dot(u, p) - planes[i, k, 3]
        if delta < r:
            p = v3.add(p, v3.scale(u, r - delta))
            contact = plane_face[i, k]
            push = u
    return p, contact, push


@njit(cache=True)
def _drift_buckets(grid, face_move, box):
    """Largest move of a face within ``box`` (along every axis) of the cells of each bucket of the mesh grid: (T,).

    A point's bucket holds at least the largest move of any face that is now
    within ``box`` of it (more, where cells share a bucket). Whichever costs
    less: every moved face writes its move into the cells its bounding box
    grown by ``box`` meets, or it writes into the cells of its own box in a
    dense grid, which is then dilated by ``box`` rounded up to whole cells.
    """
    data, lo, size, dims, start = grid[0], grid[1], grid[2], grid[3], grid[4]
    mask = start.shape[0] - 2
    out = np.zeros(mask + 1)
    reach = math.ceil(box / size)
    moved = 0
    for f in range(data.shape[0]):
        moved += face_move[f] > 0.0
    n_cells = dims[0] * dims[1] * dims[2]
    dense = n_cells * (6 * reach + 4) < moved * (2 * reach + 2) ** 3
    cells = np.zeros((dims[2], dims[1], dims[0]) if dense else (0, 0, 0))
    grow = 0.0 if dense else box
    for f in range(data.shape[0]):
        move = face_move[f]
        if move <= 0.0:
            continue
        a, b, c = _corner(data, f, 0), _corner(data, f, 1), _corner(data, f, 2)
        low = (min(a[0], b[0], c[0]) - grow, min(a[1], b[1], c[1]) - grow, min(a[2], b[2], c[2]) - grow)
        high = (max(a[0], b[0], c[0]) + grow, max(a[1], b[1], c[1]) + grow, max(a[2], b[2], c[2]) + grow)
        i0, j0, k0, i1, j1, k1 = _cell_box(low, high, lo, size, dims)
        for k in range(k0, k1 + 1 if i0 <= i1 else k0):
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    if dense:
                        cells[k, j, i] = max(cells[k, j, i], move)
                    else:
                        q = (i + dims[0] * (j + dims[1] * k)) & mask
                        out[q] = max(out[q], move)
    if dense:
        for axis in range(3):  # running maximum over 2 reach + 1 cells, one axis after the other
            source = cells.copy()
            for k in range(dims[2]):
                for j in range(dims[1]):
                    for i in range(dims[0]):
                        at = (k, j, i)[2 - axis]
                        top = dims[axis] - 1
                        best = 0.0
                        for m in range(max(at - reach, 0), min(at + reach, top) + 1):
                            best = max(best, source[(m if axis == 2 else k), (m if axis == 1 else j),
                                                    (m if axis == 0 else i)])
                        cells[k, j, i] = best
        for k in range(dims[2]):
            for j in range(dims[1]):
                for i in range(dims[0]):
                    q = (i + dims[0] * (j + dims[1] * k)) & mask
                    out[q] = max(out[q], cells[k, j, i])
    return out


@njit(cache=True, parallel=True)
def _refresh(grid, drift, most_slack, anchor, slack, gap, planes, n_planes, plane_face):
    """Carry the searches over a mesh move, in place; ``drift`` is :func:`_drift_buckets` for a box of
    PLANE_REACH r + ``most_slack``.

    Around a search point whose bucket holds a move ``d`` > 0, the slack
    shrinks by ``d`` (the faces may have come that much nearer; a negative
    slack forces a new search), the gap by sqrt(3) ``d`` (the same, as a
    distance), and every boundary plane is recomputed from its face's new
    position: the face's plane, or for an edge or corner the direction from
    its closest point to the anchor. A search with more slack than
    ``most_slack`` is dropped (the drift does not cover it).
    """
    data, lo, size, dims, start = grid[0], grid[1], grid[2], grid[3], grid[4]
    mask = start.shape[0] - 2
    for i in prange(anchor.shape[0]):
        if slack[i] > most_slack:
            slack[i] = -1.0
        if slack[i] < 0.0:
            continue
        key = 0
        for m in range(2, -1, -1):  # the anchor's cell, clamped into the grid like the faces' cell ranges
            c = min(max(int(np.floor(min(max((anchor[i, m] - lo[m]) / size, -_LIMIT), _LIMIT))), 0), dims[m] - 1)
            key = key * dims[m] + c
        d = drift[key & mask]
        if d <= 0.0:
            continue  # no face within box moved, nor any of its planes' faces
        slack[i] -= d
        gap[i] -= math.sqrt(3.0) * d
        for k in range(n_planes[i]):
            f = plane_face[i, k]
            a = _corner(data, f, 0)
            u = _corner(data, f, 3)
            offset = v3.dot(u, a)
            if planes[i, k, 5] > 0.0:
                e = _closest_on_boundary(v3.row(anchor, i), a, _corner(data, f, 1), _corner(data, f, 2))
                dv = v3.sub(v3.row(anchor, i), e)
                dist = v3.norm(dv)
                if dist > 0.0:
                    u = v3.scale(dv, 1.0 / dist)
                    offset = v3.dot(u, e)
            planes[i, k, 0], planes[i, k, 1], planes[i, k, 2] = u
            planes[i, k, 3] = offset


@njit(cache=True, parallel=True)
def _carry(rows, anchor, slack, gap, planes, n_planes, plane_face, to_anchor, to_slack, to_gap, to_planes,
           to_n_planes, to_plane_face):
    """Row ``s`` of the ``to_`` arrays = row ``rows[s]`` of the others (-1: never searched)."""
    for s in prange(rows.shape[0]):
        q = rows[s]
        if q < 0:
            to_anchor[s, 0] = np.nan
            to_n_planes[s] = 0
            continue
        for a in range(3):
            to_anchor[s, a] = anchor[q, a]
        to_slack[s] = slack[q]
        to_gap[s] = gap[q]
        to_n_planes[s] = n_planes[q]
        for k in range(n_planes[q]):
            to_plane_face[s, k] = plane_face[q, k]
            for c in range(planes.shape[2]):
                to_planes[s, k, c] = planes[q, k, c]


@njit(cache=True)
def _first_crossing(x0, x1, grid):
    """Earliest front-to-back crossing of the segment x0 -> x1 with a face: (parameter t, face or -1)."""
    data, lo, size, dims, start, keys, items, firsts, spheres = grid
    mask = start.shape[0] - 2
    seg = v3.sub(x1, x0)
    seg2 = v3.dot(seg, seg)
    pieces = max(1, int(np.ceil(v3.norm(seg) / size)))
    margin = 1e-9 * size
    best_t = 2.0
    best_f = -1
    for piece in range(pieces):
        u = v3.add(x0, v3.scale(seg, piece / pieces))
        w = v3.add(x0, v3.scale(seg, (piece + 1) / pieces))
        i0, j0, k0, i1, j1, k1 = _cell_box(
            (min(u[0], w[0]) - margin, min(u[1], w[1]) - margin, min(u[2], w[2]) - margin),
            (max(u[0], w[0]) + margin, max(u[1], w[1]) + margin, max(u[2], w[2]) + margin), lo, size, dims)
        for k in range(k0, k1 + 1 if i0 <= i1 else k0):
            for j in range(j0, j1 + 1):
                base = dims[0] * (j + dims[1] * k)
                key0, key1, a0, a1, b0, b1 = _row(i0, i1, base, mask, start)
                for part in range(2):
                    lo_q, hi_q = (a0, a1) if part == 0 else (b0, b1)
                    for q in range(lo_q, hi_q):
                        if keys[q] < key0 or keys[q] > key1:
                            continue
                        centre = (spheres[q, 0], spheres[q, 1], spheres[q, 2])
                        e = v3.sub(centre, x0)
                        t = min(max(v3.dot(e, seg) / seg2, 0.0), 1.0) if seg2 > 0.0 else 0.0
                        e = v3.sub(e, v3.scale(seg, t))  # from the segment's closest point to the centre
                        if (v3.dot(e, e) > spheres[q, 3] ** 2
                                or not _first_visit(firsts[q], keys[q], base, i0, j, k, j0, k0)):
                            continue
                        f = items[q]
                        n = _corner(data, f, 3)
                        a = _corner(data, f, 0)
                        s0 = v3.dot(n, v3.sub(x0, a))
                        s1 = v3.dot(n, v3.sub(x1, a))
                        if not (s0 >= 0.0 and s1 < 0.0):
                            continue
                        t = s0 / (s0 - s1)
                        if not _nearer(t, f, best_t, best_f if best_f >= 0 else data.shape[0]):
                            continue
                        b, c = _corner(data, f, 1), _corner(data, f, 2)
                        y = v3.add(x0, v3.scale(seg, t))
                        tol = -CROSSING_GROWTH * v3.norm(v3.cross(v3.sub(b, a), v3.sub(c, a)))
                        if (v3.dot(v3.cross(v3.sub(b, a), v3.sub(y, a)), n) >= tol
                                and v3.dot(v3.cross(v3.sub(c, b), v3.sub(y, b)), n) >= tol
                                and v3.dot(v3.cross(v3.sub(a, c), v3.sub(y, c)), n) >= tol):
                            best_t = t
                            best_f = f
        if best_t <= (piece + 1) / pieces:
            break
    return best_t, best_f


@njit(cache=True)
def _sweep(x0, p, r, grid):
    """Keep the motion x0 -> p on the front side of every face it would cross.

    Returns the new end point, the face it hit (-1: none) and that face's normal.
    """
    data = grid[0]
    contact = -1
    push = (0.0, 0.0, 0.0)
    for _ in range(_SWEEP_ROUNDS):
        t, f = _first_crossing(x0, p, grid)
        if f < 0:
            return p, contact, push
        n = _corner(data, f, 3)
        p = v3.add(p, v3.scale(n, r - v3.dot(n, v3.sub(p, _corner(data, f, 0)))))
        contact = f
        push = n
    t, f = _first_crossing(x0, p, grid)
    if f >= 0:  # still crossing: stop just before the first crossing
        p = v3.add(x0, v3.scale(v3.sub(p, x0), t * (1.0 - _STOP)))
        contact = f
        push = _corner(data, f, 3)
    return p, contact, push


@njit(cache=True, inline="always")
def _clamp(p, r, wlo, whi):
    """``p`` clamped into the box [wlo + r, whi - r]."""
    return (min(max(p[0], wlo[0] + r), whi[0] - r), min(max(p[1], wlo[1] + r), whi[1] - r),
            min(max(p[2], wlo[2] + r), whi[2] - r))


@njit(cache=True, inline="always")
def _near(p, anchor, slack):
    """Whether ``p`` is within ``slack`` of ``anchor`` along every axis (False for a NaN anchor)."""
    return abs(p[0] - anchor[0]) <= slack and abs(p[1] - anchor[1]) <= slack and abs(p[2] - anchor[2]) <= slack


@njit(cache=True, parallel=True)
def _collide(pos, start, r, grid, friction, boundary, walls, wlo, whi, contact, normal, anchor, slack, gap,
             planes, n_planes, plane_face, spread):
    """Mesh collision and walls for every particle, in place.

    In order: ``friction`` (at the particles that touched the mesh this
    substep); when ``boundary``, the boundary planes (searched afresh at
    ``pos`` by :func:`_search` unless ``start`` and ``pos`` lie within
    ``slack`` of the last search's ``anchor``; then ``slack`` becomes
    ``max(_REUSE r, 1.5 |pos - start|)``, enough for the next substep too)
    and the push-out of ``start`` itself, moving ``pos`` along (a mesh that
    moved over a particle gives it no velocity); the swept test from
    ``start`` (skipped when both ends lie within the slack of the last
    search and nearer to its anchor than its ``gap``); when ``boundary``, the push-out of ``pos``; the clamp
    into the walls. ``contact`` and ``normal`` receive the face and
    direction of the latest contact. Particles are visited in the order
    ``spread`` (:func:`_spread`), so the threads share the particles near
    the mesh.
    """
    has_mesh = grid[0].shape[0] > 0
    for t in prange(pos.shape[0]):
        i = spread[t]
        p = v3.row(pos, i)
        x0 = v3.row(start, i)
        a = v3.row(anchor, i)
        if friction > 0.0 and contact[i] >= 0:
            n = v3.row(normal, i)
            move = v3.sub(p, x0)
            p = v3.sub(p, v3.scale(v3.sub(move, v3.scale(n, v3.dot(n, move))), friction))
        if has_mesh and boundary:
            if not (_near(x0, a, slack[i]) and _near(p, a, slack[i])):
                move = v3.sub(p, x0)
                slack[i] = max(_REUSE * r, 1.5 * max(abs(move[0]), abs(move[1]), abs(move[2])))
                a = p
                v3.store(anchor, i, a)
                n_planes[i], gap[i] = _search(p, r, slack[i], grid, planes, plane_face, i)
            y, f, n = _plane_push(x0, r, planes, n_planes[i], plane_face, i)
            if f >= 0:
                p = v3.add(p, v3.sub(y, x0))
                x0 = y
                v3.store(start, i, y)
                contact[i] = f
                v3.store(normal, i, n)
        if has_mesh and not (_near(x0, a, slack[i]) and _near(p, a, slack[i]) and v3.norm(v3.sub(x0, a)) < gap[i]
                             and v3.norm(v3.sub(p, a)) < gap[i]):
            p, f, n = _sweep(x0, p, r, grid)
            if f >= 0:
                contact[i] = f
                v3.store(normal, i, n)
        if has_mesh and boundary:
            p, f, n = _plane_push(p, r, planes, n_planes[i], plane_face, i)
            if f >= 0:
                contact[i] = f
                v3.store(normal, i, n)
        if walls:
            p = _clamp(p, r, wlo, whi)
        v3.store(pos, i, p)


@njit(cache=True, parallel=True)
def _plane_distances(pos, contact, data, out):
    """Signed distance of every particle to the plane of its contact face (inf without one)."""
    for i in prange(pos.shape[0]):
        f = contact[i]
        out[i] = np.inf if f < 0 else v3.dot(_corner(data, f, 3), v3.sub(v3.row(pos, i), _corner(data, f, 0)))


# --- position-based fluid ----------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _solid(delta, r, h2, kw):
    """Density of the solid beyond a plane at distance ``delta`` and its derivative along the plane's normal."""
    rho = 0.0
    slope = 0.0
    z = max(delta, 0.0) + r
    for _ in range(2):
        q = h2 - z * z
        if q > 0.0:
            rho += kw * q**4
            slope -= 8.0 * kw * z * q**3
        z += 2.0 * r
    return rho, slope


@njit(cache=True)
def _boundary_density(p, i, r, h2, kw, planes, n_planes, walls, wlo, whi):
    """Density of the boundary planes and walls at particle ``i`` at ``p`` and its gradient with respect to ``p``."""
    rho = 0.0
    gx, gy, gz = 0.0, 0.0, 0.0
    for k in range(n_planes[i]):
        ux, uy, uz = planes[i, k, 0], planes[i, k, 1], planes[i, k, 2]
        w, slope = _solid(ux * p[0] + uy * p[1] + uz * p[2] - planes[i, k, 3], r, h2, kw)
        rho += w
        gx += slope * ux
        gy += slope * uy
        gz += slope * uz
    if walls:
        reach = PLANE_REACH * r
        for a in range(3):
            for side in range(2):
                delta = p[a] - wlo[a] if side == 0 else whi[a] - p[a]
                if delta < reach:
                    w, slope = _solid(delta, r, h2, kw)
                    rho += w
                    g = slope if side == 0 else -slope
                    if a == 0:
                        gx += g
                    elif a == 1:
                        gy += g
                    else:
                        gz += g
    return rho, (gx, gy, gz)


@njit(cache=True, parallel=True)
def _gather(pos, vel, order, x, v):
    """x = pos[order], v = vel[order]."""
    for s in prange(order.shape[0]):
        v3.store(x, s, v3.row(pos, order[s]))
        v3.store(v, s, v3.row(vel, order[s]))


@njit(cache=True, parallel=True, error_model="numpy")
def _predict(pos, vel, gravity, dt, out):
    """out = x + (v + g dt) dt."""
    for i in prange(pos.shape[0]):
        v3.store(out, i, v3.add(v3.row(pos, i), v3.scale(v3.add(v3.row(vel, i), v3.scale(gravity, dt)), dt)))


@njit(cache=True, parallel=True)
def _scatter(order, x, v, touched, pos, vel, contact_face):
    """pos[order] = x, vel[order] = v, contact_face[order] = touched."""
    for s in prange(order.shape[0]):
        i = order[s]
        v3.store(pos, i, v3.row(x, s))
        v3.store(vel, i, v3.row(v, s))
        contact_face[i] = touched[s]


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _lambdas(pos, nbr, count, kern, planes, n_planes, walls, wlo, whi, lam):
    """lambda_i = -w C_i / (sum_k |grad_k C_i|² + eps) of the unilateral density constraint.

    ``kern`` is (r, h, k6, ks, 1 / rho0, eps, kw, 1 / W(dq), tensile k / S, w).
    """
    r, h, k6, ks, inv_rho0, eps, kw, weight = kern[0], kern[1], kern[2], kern[3], kern[4], kern[5], kern[6], kern[9]
    h2 = h * h
    floor = 1e-24 * h2  # coincident particles: zero offset times a finite factor
    for i in prange(pos.shape[0]):
        p = v3.row(pos, i)
        rho, grad = _boundary_density(p, i, r, h2, kw, planes, n_planes, walls, wlo, whi)
        rho += k6 * h2 * h2 * h2
        gx, gy, gz = grad[0] * inv_rho0, grad[1] * inv_rho0, grad[2] * inv_rho0
        sum2 = 0.0
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = p[0] - pos[j, 0], p[1] - pos[j, 1], p[2] - pos[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            q = max(h2 - r2, 0.0)
            rho += k6 * q * q * q
            dist = math.sqrt(max(r2, floor))
            t = max(h - dist, 0.0)
            s = -ks * t * t / dist * inv_rho0  # grad_i W_ij / rho0 = s * d
            gx += s * dx
            gy += s * dy
            gz += s * dz
            sum2 += s * s * r2
        c = rho * inv_rho0 - 1.0
        lam[i] = -weight * c / (sum2 + gx * gx + gy * gy + gz * gz + eps) if c > 0.0 else 0.0


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _corrections(pos, nbr, count, lam, kern, fraction, planes, n_planes, plane_face, walls, wlo, whi, contact,
                 normal, out):
    """out = pos + fraction * (sum_j (lambda_i + lambda_j + s_corr) grad W_ij + lambda_i grad rho_solid) / rho0,
    then pushed to ``r`` in front of the particle's boundary planes and clamped into the walls."""
    r, h, k6, ks, inv_rho0, kw, inv_wdq, tensile = kern[0], kern[1], kern[2], kern[3], kern[4], kern[6], kern[7], kern[8]
    h2 = h * h
    floor = 1e-24 * h2
    for i in prange(pos.shape[0]):
        p = v3.row(pos, i)
        _, grad = _boundary_density(p, i, r, h2, kw, planes, n_planes, walls, wlo, whi)
        li = lam[i]
        dx_sum, dy_sum, dz_sum = grad[0] * li, grad[1] * li, grad[2] * li
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = p[0] - pos[j, 0], p[1] - pos[j, 1], p[2] - pos[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            dist = math.sqrt(max(r2, floor))
            t = max(h - dist, 0.0)
            both = li + lam[j]
            if tensile > 0.0:  # loop-invariant: the loop is compiled both ways
                q = max(h2 - r2, 0.0)
                w = k6 * q * q * q * inv_wdq
                w2 = w * w
                both -= tensile * w2 * w2
            s = -both * ks * t * t / dist
            dx_sum += s * dx
            dy_sum += s * dy
            dz_sum += s * dz
        scale = fraction * inv_rho0
        p, f, u = _plane_push((p[0] + dx_sum * scale, p[1] + dy_sum * scale, p[2] + dz_sum * scale), r, planes,
                              n_planes[i], plane_face, i)
        if f >= 0:
            contact[i] = f
            v3.store(normal, i, u)
        if walls:
            p = _clamp(p, r, wlo, whi)
        v3.store(out, i, p)


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _velocities(pos, start, nbr, count, dt, h, k6, xsph, contact, normal, vel, out):
    """v = (pos - start) / dt (into ``vel``), then XSPH and no into-surface velocity at contacts (into ``out``)."""
    inv_dt = 1.0 / dt
    for i in prange(pos.shape[0]):
        v3.store(vel, i, v3.scale(v3.sub(v3.row(pos, i), v3.row(start, i)), inv_dt))
    h2 = h * h
    for i in prange(pos.shape[0]):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
        ax, ay, az = 0.0, 0.0, 0.0
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = px - pos[j, 0], py - pos[j, 1], pz - pos[j, 2]
            q = max(h2 - dx * dx - dy * dy - dz * dz, 0.0)
            w = k6 * q * q * q
            ax += (vel[j, 0] - vx) * w
            ay += (vel[j, 1] - vy) * w
            az += (vel[j, 2] - vz) * w
        v = (vx + ax * xsph, vy + ay * xsph, vz + az * xsph)
        if contact[i] >= 0:
            n = v3.row(normal, i)
            vn = v3.dot(v, n)
            if vn < 0.0:
                v = v3.sub(v, v3.scale(n, vn))
        v3.store(out, i, v)


@njit(cache=True, parallel=True)
def _drained(pos, lo, hi, outside, planes, boxes, out):
    """Which particles leave: outside [lo, hi] (when ``outside``), past a plane, inside a box, or not finite."""
    for i in prange(pos.shape[0]):
        x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
        gone = not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z))
        if outside and not (lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]):
            gone = True
        for k in range(planes.shape[0]):
            if planes[k, 0] * x + planes[k, 1] * y + planes[k, 2] * z > planes[k, 3]:
                gone = True
        for k in range(boxes.shape[0]):
            if boxes[k, 0] <= x <= boxes[k, 3] and boxes[k, 1] <= y <= boxes[k, 4] and boxes[k, 2] <= z <= boxes[k, 5]:
                gone = True
        out[i] = gone


@njit(cache=True)
def _uniforms(rng, n):
    """``n`` doubles in [0, 1) from the SplitMix64 state ``rng[0]`` (advanced in place)."""
    out = np.empty(n)
    for k in range(n):
        z = rng[0] + np.uint64(0x9E3779B97F4A7C15)
        rng[0] = z
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
        out[k] = np.float64(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return out


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
            return offsets, spacing * emitter.rate / len(offsets), 1.0
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
            for _ in range(self.params.substeps):
                self._substep(work, self.dt / self.params.substeps, times)
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
