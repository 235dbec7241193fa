"""Implicit splitting surfaces F(x, y, z) = d for material fields (thesis §11.2–11.3, Fig. 11.12).

A point lies on the negative side of a surface for ``d < 0`` and on the
positive side for ``d > 0``; ``|d|`` grows with the distance from the
surface and drives gradual materials. Every built-in surface has a NumPy
:meth:`~ImplicitSurface.evaluate` and a kind code plus a parameter vector,
which the numba kernels of :mod:`pverosion.kernels.materials.bsp` evaluate with
:func:`surface_value`. ``UserSurface`` wraps any vectorised Python callable.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pverosion.kernels._jit import njit

__all__ = [
    "Cylinder",
    "Ellipsoid",
    "EllipticHyperboloid",
    "ImplicitSurface",
    "Paraboloid",
    "Plane",
    "SinSurface",
    "SincSurface",
    "Sphere",
    "UserSurface",
    "surface_from_dict",
    "surface_value",
]

N_PARAMS = 8
"""Length of every surface's parameter vector."""

PLANE, SPHERE, ELLIPSOID, PARABOLOID, HYPERBOLOID, CYLINDER, SIN, SINC, USER = range(9)


def _vec(value, name: str) -> tuple[float, float, float]:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be 3 finite numbers; got {value!r}")
    return tuple(float(v) for v in arr)


def _positive(value, name: str) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be > 0; got {value!r}")
    return value


@dataclass(frozen=True)
class ImplicitSurface:
    """Base class: ``evaluate(points (N, 3)) -> d (N,)``."""

    KIND = USER

    def evaluate(self, points) -> np.ndarray:
        """Signed value d of F at ``points`` (N, 3); negative side ``d < 0``."""
        raise NotImplementedError

    def params(self) -> np.ndarray:
        """Parameter vector (N_PARAMS,) of the numba evaluator."""
        raise NotImplementedError

    def to_dict(self) -> dict:
        """JSON-ready description (see :func:`surface_from_dict`)."""
        return {"type": type(self).__name__, **{k: list(v) if isinstance(v, tuple) else v
                                                 for k, v in self.__dict__.items()}}


@dataclass(frozen=True)
class Plane(ImplicitSurface):
    """Plane ``n · x + offset = 0``; ``normal`` is normalised, so ``|d|`` is the distance."""

    normal: tuple = (0.0, 0.0, 1.0)
    offset: float = 0.0
    KIND = PLANE

    def __post_init__(self):
        n = np.asarray(_vec(self.normal, "normal"))
        length = np.linalg.norm(n)
        if length == 0:
            raise ValueError("normal must not be zero")
        if abs(length - 1.0) < 1e-12:  # already unit: keep the bits (exact save/load round trip)
            length = 1.0
        object.__setattr__(self, "normal", tuple((n / length).tolist()))
        object.__setattr__(self, "offset", float(self.offset) / length)

    @classmethod
    def through(cls, point, normal) -> Plane:
        """The plane through ``point`` with ``normal``."""
        n = np.asarray(_vec(normal, "normal"))
        return cls(tuple(n), -float(n @ np.asarray(_vec(point, "point"))))

    def evaluate(self, points) -> np.ndarray:
        return np.asarray(points, dtype=np.float64) @ np.asarray(self.normal) + self.offset

    def params(self) -> np.ndarray:
        return np.array([*self.normal, self.offset, 0, 0, 0, 0], dtype=np.float64)


@dataclass(frozen=True)
class Sphere(ImplicitSurface):
    """Sphere: ``d = |x - centre| - radius`` (inside negative)."""

    centre: tuple = (0.0, 0.0, 0.0)
    radius: float = 1.0
    KIND = SPHERE

    def __post_init__(self):
        object.__setattr__(self, "centre", _vec(self.centre, "centre"))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def evaluate(self, points) -> np.ndarray:
        return np.linalg.norm(np.asarray(points, dtype=np.float64) - self.centre, axis=1) - self.radius

    def params(self) -> np.ndarray:
        return np.array([*self.centre, self.radius, 0, 0, 0, 0], dtype=np.float64)


@dataclass(frozen=True)
class Ellipsoid(ImplicitSurface):
    """Axis-aligned ellipsoid: ``d = sqrt(sum(((x - c) / r)^2)) - 1`` (inside negative)."""

    centre: tuple = (0.0, 0.0, 0.0)
    radii: tuple = (1.0, 1.0, 1.0)
    KIND = ELLIPSOID

    def __post_init__(self):
        object.__setattr__(self, "centre", _vec(self.centre, "centre"))
        radii = _vec(self.radii, "radii")
        for r in radii:
            _positive(r, "radii")
        object.__setattr__(self, "radii", radii)

    def evaluate(self, points) -> np.ndarray:
        q = (np.asarray(points, dtype=np.float64) - self.centre) / self.radii
        return np.linalg.norm(q, axis=1) - 1.0

    def params(self) -> np.ndarray:
        return np.array([*self.centre, *self.radii, 0, 0], dtype=np.float64)


@dataclass(frozen=True)
class Paraboloid(ImplicitSurface):
    """Elliptic paraboloid opening along +z: ``d = (x-cx)^2/a^2 + (y-cy)^2/b^2 - (z - cz)``."""

    apex: tuple = (0.0, 0.0, 0.0)
    a: float = 1.0
    b: float = 1.0
    KIND = PARABOLOID

    def __post_init__(self):
        object.__setattr__(self, "apex", _vec(self.apex, "apex"))
        object.__setattr__(self, "a", _positive(self.a, "a"))
        object.__setattr__(self, "b", _positive(self.b, "b"))

    def evaluate(self, points) -> np.ndarray:
        q = np.asarray(points, dtype=np.float64) - self.apex
        return q[:, 0] ** 2 / self.a**2 + q[:, 1] ** 2 / self.b**2 - q[:, 2]

    def params(self) -> np.ndarray:
        return np.array([*self.apex, self.a, self.b, 0, 0, 0], dtype=np.float64)


@dataclass(frozen=True)
class EllipticHyperboloid(ImplicitSurface):
    """Hyperboloid of one sheet around z: ``d = (x-cx)^2/a^2 + (y-cy)^2/b^2 - (z-cz)^2/c^2 - 1``."""

    centre: tuple = (0.0, 0.0, 0.0)
    a: float = 1.0
    b: float = 1.0
    c: float = 1.0
    KIND = HYPERBOLOID

    def __post_init__(self):
        object.__setattr__(self, "centre", _vec(self.centre, "centre"))
        for name in ("a", "b", "c"):
            object.__setattr__(self, name, _positive(getattr(self, name), name))

    def evaluate(self, points) -> np.ndarray:
        q = np.asarray(points, dtype=np.float64) - self.centre
        return q[:, 0] ** 2 / self.a**2 + q[:, 1] ** 2 / self.b**2 - q[:, 2] ** 2 / self.c**2 - 1.0

    def params(self) -> np.ndarray:
        return np.array([*self.centre, self.a, self.b, self.c, 0, 0], dtype=np.float64)


@dataclass(frozen=True)
class Cylinder(ImplicitSurface):
    """Infinite cylinder: ``d = distance to the axis - radius`` (inside negative)."""

    point: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)
    radius: float = 1.0
    KIND = CYLINDER

    def __post_init__(self):
        object.__setattr__(self, "point", _vec(self.point, "point"))
        u = np.asarray(_vec(self.axis, "axis"))
        length = np.linalg.norm(u)
        if not length > 0:
            raise ValueError("axis must not be zero")
        if abs(length - 1.0) < 1e-12:
            length = 1.0
        object.__setattr__(self, "axis", tuple((u / length).tolist()))
        object.__setattr__(self, "radius", _positive(self.radius, "radius"))

    def evaluate(self, points) -> np.ndarray:
        q = np.asarray(points, dtype=np.float64) - self.point
        u = np.asarray(self.axis)
        return np.linalg.norm(q - np.outer(q @ u, u), axis=1) - self.radius

    def params(self) -> np.ndarray:
        return np.array([*self.point, *self.axis, self.radius, 0], dtype=np.float64)


@dataclass(frozen=True)
class SinSurface(ImplicitSurface):
    """Corrugated height surface: ``d = z - (height + amplitude sin(kx x) cos(ky y))``."""

    height: float = 0.0
    amplitude: float = 1.0
    kx: float = 1.0
    ky: float = 1.0
    KIND = SIN

    def evaluate(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        return p[:, 2] - (self.height + self.amplitude * np.sin(self.kx * p[:, 0]) * np.cos(self.ky * p[:, 1]))

    def params(self) -> np.ndarray:
        return np.array([self.height, self.amplitude, self.kx, self.ky, 0, 0, 0, 0], dtype=np.float64)


@dataclass(frozen=True)
class SincSurface(ImplicitSurface):
    """Hill: ``d = z - (height + amplitude sinc(r / width))``, r the distance from (cx, cy),
    sinc the normalised ``sin(pi t) / (pi t)``."""

    centre: tuple = (0.0, 0.0)
    height: float = 0.0
    amplitude: float = 1.0
    width: float = 1.0
    KIND = SINC

    def __post_init__(self):
        c = np.asarray(self.centre, dtype=np.float64)
        if c.shape != (2,):
            raise ValueError(f"centre must be 2 numbers (x, y); got {self.centre!r}")
        object.__setattr__(self, "centre", tuple(c.tolist()))
        object.__setattr__(self, "width", _positive(self.width, "width"))

    def evaluate(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        r = np.hypot(p[:, 0] - self.centre[0], p[:, 1] - self.centre[1])
        return p[:, 2] - (self.height + self.amplitude * np.sinc(r / self.width))

    def params(self) -> np.ndarray:
        return np.array([*self.centre, self.height, self.amplitude, self.width, 0, 0, 0], dtype=np.float64)


@dataclass(frozen=True)
class UserSurface(ImplicitSurface):
    """Any vectorised callable ``F(points (N, 3)) -> d (N,)``; evaluated in Python, not in numba."""

    function: object = field(default=None)
    KIND = USER

    def __post_init__(self):
        if not callable(self.function):
            raise TypeError(f"function must be callable; got {self.function!r}")

    def evaluate(self, points) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64)
        d = np.asarray(self.function(points), dtype=np.float64)
        if d.shape != (len(points),):
            raise ValueError(f"surface function must return shape ({len(points)},); got {d.shape}")
        return d

    def params(self) -> np.ndarray:
        return np.zeros(N_PARAMS)

    def to_dict(self) -> dict:
        raise TypeError("a UserSurface (Python callable) cannot be saved; use the built-in surfaces")


_TYPES = {cls.__name__: cls for cls in (Plane, Sphere, Ellipsoid, Paraboloid, EllipticHyperboloid, Cylinder,
                                         SinSurface, SincSurface)}


def surface_from_dict(data: dict) -> ImplicitSurface:
    """Rebuild a built-in surface from :meth:`ImplicitSurface.to_dict`."""
    data = dict(data)
    kind = data.pop("type", None)
    if kind not in _TYPES:
        raise ValueError(f"unknown surface type {kind!r}; known: {sorted(_TYPES)}")
    return _TYPES[kind](**data)


@njit(cache=True, error_model="numpy")
def surface_value(kind, p, x, y, z):
    """Value d of the built-in surface ``kind`` with parameters ``p`` at (x, y, z)."""
    if kind == PLANE:
        return p[0] * x + p[1] * y + p[2] * z + p[3]
    if kind == SPHERE:
        return np.sqrt((x - p[0]) ** 2 + (y - p[1]) ** 2 + (z - p[2]) ** 2) - p[3]
    if kind == ELLIPSOID:
        return np.sqrt(((x - p[0]) / p[3]) ** 2 + ((y - p[1]) / p[4]) ** 2 + ((z - p[2]) / p[5]) ** 2) - 1.0
    if kind == PARABOLOID:
        return (x - p[0]) ** 2 / p[3] ** 2 + (y - p[1]) ** 2 / p[4] ** 2 - (z - p[2])
    if kind == HYPERBOLOID:
        return (x - p[0]) ** 2 / p[3] ** 2 + (y - p[1]) ** 2 / p[4] ** 2 - (z - p[2]) ** 2 / p[5] ** 2 - 1.0
    if kind == CYLINDER:
        qx, qy, qz = x - p[0], y - p[1], z - p[2]
        t = qx * p[3] + qy * p[4] + qz * p[5]
        return np.sqrt((qx - t * p[3]) ** 2 + (qy - t * p[4]) ** 2 + (qz - t * p[5]) ** 2) - p[6]
    if kind == SIN:
        return z - (p[0] + p[1] * np.sin(p[2] * x) * np.cos(p[3] * y))
    if kind == SINC:
        t = np.sqrt((x - p[0]) ** 2 + (y - p[1]) ** 2) / p[4]
        s = 1.0 if t == 0.0 else np.sin(np.pi * t) / (np.pi * t)
        return z - (p[2] + p[3] * s)
    return np.nan
