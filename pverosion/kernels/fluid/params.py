"""Parameters of the particle fluid: the fluid's constants, emitters, drains and saved states.

Part of :mod:`pverosion.kernels.fluid.particle_fluid` (its docstring describes the method).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["DRAIN_KINDS", "JACOBI_WEIGHT", "LAST_WEIGHT", "MAX_PLANES", "PHASES", "PLANE_REACH", "TENSILE_DISTANCE",
           "Drain", "Emitter", "FluidParameters", "FluidState"]


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
    last: object | None  # the last step's work (a ParticleFluid's _Work: its searches carry over)
    rows: np.ndarray
