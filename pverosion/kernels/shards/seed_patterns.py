"""Seed point patterns for Voronoi shard generation (Mateos et al. §4.1, Figure 4).

The shards of :func:`pverosion.kernels.shards.graph.build_shards` are the Voronoi
cells of a set of seeds clipped to a closed mesh, so the look of the shards
is chosen through the seed distribution: random points, jittered cubic
grids, hexagonal columns (columnar basalt), tilted strata (slabs), Poisson
discs with a graded radius, or the mesh's own vertices.

Every generator works in an axis-aligned box ``bounds = (lo, hi)`` and keeps
only the points inside the box (closed) and, when ``inside`` is given, the
points for which ``inside(points)`` is true. :func:`inside_mesh` builds such a
predicate for a closed triangle mesh.

All results are ``float64`` arrays of shape (n, 3) with distinct rows, in an
order fixed by the arguments. Random generators take ``seed`` (an int or a
:class:`numpy.random.Generator`, passed to :func:`numpy.random.default_rng`)
and give bit-identical results for the same seed and arguments. The grid
generators draw their jitter for every lattice site before culling, so the
points kept with an ``inside`` predicate are exactly the points of the
unculled pattern that satisfy it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numba import prange

from pverosion.kernels._jit import njit
from pverosion.kernels.mesh.topology import halfedge_twins
from pverosion.kernels.spatial.mesh_query import TriangleIndex, point_inside
from pverosion.kernels.validation import as_triangle_mesh

__all__ = [
    "hex_column_seeds",
    "inside_mesh",
    "jittered_grid_seeds",
    "mesh_vertex_seeds",
    "poisson_disc_seeds",
    "slab_seeds",
    "uniform_seeds",
]

InsideFn = Callable[[np.ndarray], np.ndarray]

_MAX_SITES = 50_000_000
"""Largest lattice a grid generator builds before culling (guards against a tiny spacing)."""
_MAX_CANDIDATES = 1 << 30
"""Largest number of candidates :func:`uniform_seeds` may need to draw."""
_FIRST_DARTS = 1 << 20
"""Candidates drawn to find a first point of the region before giving up."""
_DART_BATCH = 4096
_MAX_GRID_CELLS = 1 << 22


# ----------------------------------------------------------------------------- validation


def _bounds(bounds) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)`` as two float64 (3,) arrays; accepts ``(lo, hi)`` or a 6-tuple ``(x0, x1, y0, y1, z0, z1)``."""
    try:
        b = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"bounds must be (lo, hi) with lo and hi 3-vectors; got {bounds!r}") from exc
    if b.shape == (6,):
        b = b.reshape(3, 2).T
    if b.shape != (2, 3):
        raise ValueError(f"bounds must be (lo, hi) with lo and hi 3-vectors (or a 6-tuple x0, x1, y0, y1, z0, z1); "
                         f"got an array of shape {b.shape}")
    if not np.isfinite(b).all():
        raise ValueError(f"bounds must be finite; got lo={b[0].tolist()}, hi={b[1].tolist()}")
    if not (b[0] < b[1]).all():
        raise ValueError(f"bounds must have lo < hi on every axis; got lo={b[0].tolist()}, hi={b[1].tolist()}")
    return b[0].copy(), b[1].copy()


def _positive(value, name: str, dim: int) -> np.ndarray:
    """A positive finite scalar or ``dim``-vector, broadcast to shape (dim,)."""
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a positive number or a {dim}-vector; got {value!r}") from exc
    if v.ndim == 0:
        v = np.full(dim, float(v))
    if v.shape != (dim,):
        raise ValueError(f"{name} must be a positive number or a {dim}-vector; got an array of shape {v.shape}")
    if not np.isfinite(v).all() or not (v > 0).all():
        raise ValueError(f"{name} must be positive and finite; got {v.tolist()}")
    return v


def _fraction(value, name: str, upper: float = 0.5) -> float:
    """A number in [0, upper)."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a number in [0, {upper}); got {value!r}") from exc
    if not (0.0 <= v < upper):
        raise ValueError(f"{name} must be in [0, {upper}) so that jittered points stay distinct; got {v}")
    return v


def _count(value, name: str, minimum: int = 1) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= {minimum}; got {value!r}")  # noqa: TRY004 - the API raises ValueError
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}; got {value}")
    return int(value)


def _axis(value, name: str, allowed: Sequence[int]) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or int(value) not in allowed:
        names = ", ".join(f"{a} ({'xyz'[a]})" for a in allowed)
        raise ValueError(f"{name} must be one of {names}; got {value!r}")
    return int(value)


def _check_inside(inside) -> InsideFn | None:
    if inside is not None and not callable(inside):
        raise ValueError(f"inside must be None or a callable mapping (n, 3) points to (n,) booleans; "
                         f"got {type(inside).__name__}")
    return inside


def _eval_inside(inside: InsideFn, pts: np.ndarray) -> np.ndarray:
    """``inside(pts)`` checked to be an (n,) boolean-like array."""
    if len(pts) == 0:
        return np.zeros(0, dtype=bool)
    mask = np.asarray(inside(pts))
    if mask.shape != (len(pts),):
        raise ValueError(f"inside must return an array of shape ({len(pts)},) for {len(pts)} points; "
                         f"got shape {mask.shape}")
    return mask.astype(bool, copy=False)


def _keep(pts: np.ndarray, lo: np.ndarray, hi: np.ndarray, inside: InsideFn | None) -> np.ndarray:
    """The rows of ``pts`` inside the closed box and accepted by ``inside``, in order."""
    pts = pts[((pts >= lo) & (pts <= hi)).all(axis=1)]
    if inside is not None:
        pts = pts[_eval_inside(inside, pts)]
    return np.ascontiguousarray(pts, dtype=np.float64)


def _guard_sites(n: float, what: str) -> None:
    if n > _MAX_SITES:
        raise ValueError(f"{what} would generate about {int(n):,} lattice sites (more than {_MAX_SITES:,}); "
                         "increase the spacing or shrink the bounds")


def _centred(center: float, extent: float, step: float) -> np.ndarray:
    """``ceil(extent / step)`` (at least 1) positions ``step`` apart, centred on ``center``.

    When ``extent`` is a multiple of ``step`` they are the centres of the
    ``extent / step`` intervals, half a step from the ends.
    """
    n = max(math.ceil(extent / step * (1.0 - 1e-12)), 1)
    return center + (np.arange(n) - 0.5 * (n - 1)) * step


# ----------------------------------------------------------------------------- inside a mesh


@njit(cache=True, parallel=True)
def _inside_many(q, points, faces, lo, size, dims, start2, items2):
    out = np.zeros(q.shape[0], dtype=np.bool_)
    for i in prange(q.shape[0]):
        out[i] = point_inside(q[i], points, faces, lo, size, dims, start2, items2)
    return out


def inside_mesh(points: np.ndarray, faces: np.ndarray) -> InsideFn:
    """A predicate telling which points are inside a closed triangle mesh.

    Parameters
    ----------
    points : numpy.ndarray, shape (m, 3)
        Mesh vertices.
    faces : numpy.ndarray, shape (k, 3), int
        Triangles of a closed (watertight, manifold) mesh; orientation does
        not matter (the test is the parity of a +z ray's crossings).

    Returns
    -------
    callable
        ``inside(q)`` with ``q`` of shape (n, 3) returns a boolean array of
        shape (n,); points with NaN or infinite coordinates are outside.

    Raises
    ------
    ValueError
        Bad shapes, non-finite vertices, indices out of range, or an open or
        non-manifold mesh.
    """
    points, faces = as_triangle_mesh(points, faces)
    _, others = halfedge_twins(faces, len(points))
    if (others != 1).any():
        raise ValueError(f"inside_mesh needs a closed, manifold mesh: {int((others != 1).sum())} half-edges are on "
                         "the boundary or shared by more than two faces")
    index = TriangleIndex.build(points, faces)
    args = (index.points, index.faces, index.lo, index.size, index.dims, index.start2, index.items2)

    def inside(q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3); got {q.shape}")
        finite = np.isfinite(q).all(axis=1)
        out = np.zeros(len(q), dtype=bool)
        if finite.any():
            out[finite] = _inside_many(np.ascontiguousarray(q[finite]), *args)
        return out

    return inside


# ----------------------------------------------------------------------------- uniform


def uniform_seeds(n: int, *, bounds, inside: InsideFn | None = None,
                  seed: int | np.random.Generator = 0) -> np.ndarray:
    """``n`` points uniformly distributed in the region (rejection sampling).

    Candidates are drawn uniformly in ``bounds`` in batches sized from the
    acceptance rate seen so far; the first ``n`` accepted (in drawing order)
    are returned.

    Parameters
    ----------
    n : int
        Number of points, >= 1.
    bounds : (lo, hi)
        Box where candidates are drawn; ``lo`` and ``hi`` are 3-vectors with
        ``lo < hi`` (a 6-tuple ``(x0, x1, y0, y1, z0, z1)`` is accepted too).
    inside : callable, optional
        Maps (m, 3) points to (m,) booleans; only accepted points are kept.
    seed : int or numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n, 3), float64

    Raises
    ------
    ValueError
        Bad arguments, or a region that accepts too few candidates: none of
        the first 2**20, or so few that more than 2**30 would be needed.
    """
    n = _count(n, "n")
    lo, hi = _bounds(bounds)
    inside = _check_inside(inside)
    rng = np.random.default_rng(seed)
    chunks: list[np.ndarray] = []
    kept = drawn = 0
    batch = max(1024, 2 * n)
    while kept < n:
        cand = _keep(rng.uniform(lo, hi, size=(batch, 3)), lo, hi, inside)
        drawn += batch
        if len(cand):
            chunks.append(cand)
            kept += len(cand)
        if kept >= n:
            pts = _unique_in_order(np.concatenate(chunks))
            if len(pts) >= n:
                return np.ascontiguousarray(pts[:n])
            chunks, kept = [pts], len(pts)  # a repeated point (practically never): draw more
        if kept == 0:
            if drawn >= _FIRST_DARTS:
                raise ValueError(f"uniform_seeds: inside accepted none of {drawn:,} points drawn in bounds; "
                                 "does the region overlap the bounds?")
            batch = min(2 * batch, _FIRST_DARTS - drawn)
            continue
        rate = kept / drawn
        need = (n - kept) / rate
        if drawn + need > _MAX_CANDIDATES:
            raise ValueError(f"uniform_seeds: inside accepts only {kept:,} of {drawn:,} points drawn in bounds "
                             f"(rate {rate:.2e}); {n:,} points would need about {int(drawn + need):,} candidates. "
                             "Use bounds closer to the region.")
        batch = int(min(max(1.25 * need, 1024), 1 << 24))
    raise AssertionError("unreachable")  # pragma: no cover


def _unique_in_order(pts: np.ndarray) -> np.ndarray:
    """Rows of ``pts`` without repeats, first occurrences in their original order."""
    _, first = np.unique(pts, axis=0, return_index=True)
    if len(first) == len(pts):
        return pts
    return pts[np.sort(first)]


# ----------------------------------------------------------------------------- jittered cubic grid


def jittered_grid_seeds(spacing, *, bounds, jitter: float = 0.25, inside: InsideFn | None = None,
                        seed: int | np.random.Generator = 0) -> np.ndarray:
    """A cubic (rectilinear) grid, each point moved at random by up to ``jitter * spacing`` per axis.

    Along each axis the grid has ``ceil(extent / spacing)`` sites ``spacing``
    apart, centred in the box: when the extent is a multiple of the spacing,
    the sites are the centres of the grid's cells and no jittered point
    leaves the box. Points jittered out of the box, or rejected by
    ``inside``, are dropped.

    Parameters
    ----------
    spacing : float or array_like, shape (3,)
        Distance between neighbouring sites (per axis), > 0.
    bounds : (lo, hi)
        Box covered by the grid, ``lo < hi`` (or a 6-tuple).
    jitter : float
        Maximum displacement as a fraction of the spacing, uniform in
        ``[-jitter * spacing, jitter * spacing]`` independently per axis;
        in [0, 0.5) so points stay distinct.
    inside : callable, optional
        Maps (m, 3) points to (m,) booleans; only accepted points are kept.
    seed : int or numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n, 3), float64
        Sites in x-fastest order (then y, then z), culled.
    """
    spacing = _positive(spacing, "spacing", 3)
    lo, hi = _bounds(bounds)
    jitter = _fraction(jitter, "jitter")
    inside = _check_inside(inside)
    rng = np.random.default_rng(seed)
    center, extent = 0.5 * (lo + hi), hi - lo
    _guard_sites(float(np.prod(np.ceil(extent / spacing))), "jittered_grid_seeds")
    xs, ys, zs = (_centred(center[a], extent[a], spacing[a]) for a in range(3))
    zz, yy, xx = np.meshgrid(zs, ys, xs, indexing="ij")
    sites = np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)
    pts = sites + rng.uniform(-1.0, 1.0, size=sites.shape) * (jitter * spacing)
    return _keep(pts, lo, hi, inside)


# ----------------------------------------------------------------------------- hexagonal columns


def _plane_axes(axis: int) -> tuple[int, int]:
    return ((1, 2), (2, 0), (0, 1))[axis]


def hex_column_seeds(spacing: float, *, bounds, axis: int = 2, jitter: float = 0.1, layer_spacing: float | None = None,
                     inside: InsideFn | None = None, seed: int | np.random.Generator = 0) -> np.ndarray:
    """Columnar jointing (basalt columns): a hexagonal pattern of columns along ``axis``.

    Column centres form a triangular lattice in the plane perpendicular to
    ``axis`` (rows ``spacing * sqrt(3) / 2`` apart, every other row shifted by
    half a spacing), one lattice point at the centre of the box, so their
    Voronoi cells are regular hexagons of area ``sqrt(3) / 2 * spacing**2``
    when ``jitter == 0``. By default each column has one seed, at the middle
    of the box along ``axis``: its Voronoi cell is a prism running the full
    height. With ``layer_spacing``, every column gets seeds at the same
    heights (``ceil(height / layer_spacing)`` layers centred in the box), so
    the cells are hexagonal prisms ``layer_spacing`` high, cut by planes
    perpendicular to ``axis``.

    Parameters
    ----------
    spacing : float
        Distance between neighbouring column centres, > 0.
    bounds : (lo, hi)
        Box covered, ``lo < hi`` (or a 6-tuple).
    axis : int
        Column direction: 0 (x), 1 (y) or 2 (z).
    jitter : float
        In-plane displacement of each column, uniform in a disc of radius
        ``jitter * spacing`` (all layers of a column move together, so cells
        stay prisms); in [0, 0.5) so points stay distinct.
    layer_spacing : float, optional
        Distance between seeds along a column, > 0.
    inside : callable, optional
        Maps (m, 3) points to (m,) booleans; only accepted points are kept.
    seed : int or numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n, 3), float64
        Layer by layer (along ``axis``), rows then columns within a layer.
    """
    s = float(_positive(spacing, "spacing", 1)[0])
    lo, hi = _bounds(bounds)
    axis = _axis(axis, "axis", (0, 1, 2))
    jitter = _fraction(jitter, "jitter")
    if layer_spacing is not None:
        layer_spacing = float(_positive(layer_spacing, "layer_spacing", 1)[0])
    inside = _check_inside(inside)
    rng = np.random.default_rng(seed)
    u, v = _plane_axes(axis)
    center, extent = 0.5 * (lo + hi), hi - lo
    row = s * math.sqrt(3.0) / 2.0
    nj = math.floor(0.5 * extent[v] / row) + 1
    ni = math.ceil(0.5 * extent[u] / s) + 1
    heights = (np.array([center[axis]]) if layer_spacing is None
               else _centred(center[axis], extent[axis], layer_spacing))
    _guard_sites(float(2 * nj + 1) * (2 * ni + 2) * len(heights), "hex_column_seeds")
    j = np.arange(-nj, nj + 1)
    i = np.arange(-ni - 1, ni + 1)
    jj, ii = np.meshgrid(j, i, indexing="ij")
    pu = center[u] + (ii + 0.5 * (jj % 2)) * s
    pv = center[v] + jj * row
    cols = np.stack([pu.ravel(), pv.ravel()], axis=1)
    cols = cols[(cols[:, 0] >= lo[u]) & (cols[:, 0] <= hi[u]) & (cols[:, 1] >= lo[v]) & (cols[:, 1] <= hi[v])]
    angle = 2.0 * math.pi * rng.random(len(cols))
    radius = jitter * s * np.sqrt(rng.random(len(cols)))
    cols = cols + np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    pts = np.empty((len(heights) * len(cols), 3))
    pts[:, u] = np.tile(cols[:, 0], len(heights))
    pts[:, v] = np.tile(cols[:, 1], len(heights))
    pts[:, axis] = np.repeat(heights, len(cols))
    return _keep(pts, lo, hi, inside)


# ----------------------------------------------------------------------------- slabs (strata)


def _layer_midplanes(thickness: np.ndarray, base: float, below: float, above: float) -> np.ndarray:
    """Mid-planes, bottom to top, of layers stacked from ``base`` with the cycled thicknesses.

    Layer 0 sits on ``base`` with ``thickness[0]``, layer 1 above it with
    ``thickness[1 % L]``, ...; layers below ``base`` continue the cycle
    backwards (``thickness[-1]``, ``thickness[-2]``, ...). Layers are made
    until they reach below ``below`` and above ``above``.
    """
    cycle = float(thickness.sum())
    _guard_sites((above - below) / float(thickness.min()) + 2, "slab_seeds (layers)")
    ups, downs = [], []
    b, k = base, 0
    while b < above:
        t = thickness[k % len(thickness)]
        ups.append(b + 0.5 * t)
        b, k = b + t, k + 1
        if k % len(thickness) == 0:  # re-anchor on whole cycles to keep the rounding from drifting
            b = base + cycle * (k // len(thickness))
    b, k = base, -1
    while b > below:
        t = thickness[k % len(thickness)]
        downs.append(b - 0.5 * t)
        b, k = b - t, k - 1
        if k % len(thickness) == len(thickness) - 1:
            b = base - cycle * ((-k - 1) // len(thickness))
    return np.array(downs[::-1] + ups, dtype=np.float64)


def _rotation(tilt_deg: float, tilt_axis: int) -> np.ndarray:
    c, s = math.cos(math.radians(tilt_deg)), math.sin(math.radians(tilt_deg))
    if tilt_axis == 0:
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def slab_seeds(layer_thickness, *, bounds, spacing, tilt: float = 0.0, tilt_axis: int = 0, jitter: float = 0.0,
               inside: InsideFn | None = None, seed: int | np.random.Generator = 0) -> np.ndarray:
    """Strata: rectilinear grids stacked in layers along z, optionally tilted.

    In the pattern frame, layer 0 lies on the bottom of the box (``z =
    lo[2]``) and the layers above it take the thicknesses in turn, cycling
    through ``layer_thickness`` (the cycle continues downwards below the
    base when the tilted pattern needs layers there). Each layer gets a 2-D
    grid of seeds on its mid-plane; the grids of all layers line up, at
    ``spacing`` apart and centred on the box like :func:`jittered_grid_seeds`.
    The pattern is then rotated by ``tilt`` degrees about the ``tilt_axis``
    axis through the centre of the box; enough layers and rows are made to
    cover the box after rotation, then points are culled to the box and
    ``inside``.

    With aligned grids the Voronoi faces between two layers lie on the
    plane halfway between their mid-planes: exactly the layer boundary when
    the two layers are equally thick, shifted by a quarter of the thickness
    difference towards the thinner one otherwise.

    Parameters
    ----------
    layer_thickness : float or sequence of float
        Thickness of every layer, or of the layers from the bottom up
        (cycled), all > 0.
    bounds : (lo, hi)
        Box covered, ``lo < hi`` (or a 6-tuple).
    spacing : float or array_like, shape (2,)
        Distance between seeds within a layer along the pattern's x and y, > 0.
    tilt : float
        Rotation of the pattern in degrees (right-handed about ``tilt_axis``).
    tilt_axis : int
        0 (x) or 1 (y).
    jitter : float
        In-plane displacement, uniform in ``[-jitter * spacing, jitter *
        spacing]`` per in-plane axis of the pattern frame (seeds stay on their
        layer's mid-plane); in [0, 0.5).
    inside : callable, optional
        Maps (m, 3) points to (m,) booleans; only accepted points are kept.
    seed : int or numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n, 3), float64
        Layer by layer from the bottom of the pattern, x-fastest within a layer.
    """
    try:
        thickness = np.atleast_1d(np.asarray(layer_thickness, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"layer_thickness must be a positive number or a sequence of them; "
                         f"got {layer_thickness!r}") from exc
    if thickness.ndim != 1 or len(thickness) == 0:
        raise ValueError(f"layer_thickness must be a positive number or a non-empty sequence of them; "
                         f"got {layer_thickness!r}")
    if not np.isfinite(thickness).all() or not (thickness > 0).all():
        raise ValueError(f"layer_thickness must be positive and finite; got {thickness.tolist()}")
    lo, hi = _bounds(bounds)
    sp = _positive(spacing, "spacing", 2)
    try:
        tilt = float(tilt)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"tilt must be a number of degrees; got {tilt!r}") from exc
    if not math.isfinite(tilt):
        raise ValueError(f"tilt must be finite; got {tilt}")
    tilt_axis = _axis(tilt_axis, "tilt_axis", (0, 1))
    jitter = _fraction(jitter, "jitter")
    inside = _check_inside(inside)
    rng = np.random.default_rng(seed)
    center, extent = 0.5 * (lo + hi), hi - lo
    reach = 0.5 * float(np.linalg.norm(extent))  # the rotated box stays in this ball around the centre
    if tilt == 0.0:
        below, above, reach_xy = lo[2], hi[2], 0.5 * extent[:2]
    else:
        below, above, reach_xy = center[2] - reach, center[2] + reach, np.array([reach, reach])
    mids = _layer_midplanes(thickness, lo[2], below, above)
    axes = []
    for a in range(2):
        base = _centred(center[a], extent[a], sp[a])
        first = base[0]
        k0 = math.floor((center[a] - reach_xy[a] - sp[a] - first) / sp[a])
        k1 = math.ceil((center[a] + reach_xy[a] + sp[a] - first) / sp[a])
        _guard_sites(float(k1 - k0 + 1) ** 2 * len(mids), "slab_seeds")
        axes.append(first + np.arange(k0, k1 + 1) * sp[a])
    _guard_sites(float(len(axes[0])) * len(axes[1]) * len(mids), "slab_seeds")
    zz, yy, xx = np.meshgrid(mids, axes[1], axes[0], indexing="ij")
    pts = np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)
    if jitter > 0.0:
        pts[:, :2] += rng.uniform(-1.0, 1.0, size=(len(pts), 2)) * (jitter * sp)
    if tilt != 0.0:
        pts = center + (pts - center) @ _rotation(tilt, tilt_axis).T
    return _keep(pts, lo, hi, inside)


# ----------------------------------------------------------------------------- Poisson disc


@njit(cache=True)
def _conflict(x, rx, reach, pts, rad, nxt, head, lo, h, dims):
    """True when an accepted point ``q`` lies closer to ``x`` than ``max(rx, rad[q])``, looking ``reach`` around."""
    ci = min(max(int((x[0] - lo[0]) / h), 0), dims[0] - 1)
    cj = min(max(int((x[1] - lo[1]) / h), 0), dims[1] - 1)
    ck = min(max(int((x[2] - lo[2]) / h), 0), dims[2] - 1)
    m = int(reach / h) + 1
    for k in range(max(ck - m, 0), min(ck + m, dims[2] - 1) + 1):
        dz = max(lo[2] + k * h - x[2], x[2] - (lo[2] + (k + 1) * h), 0.0)
        if dz >= reach:
            continue
        for j in range(max(cj - m, 0), min(cj + m, dims[1] - 1) + 1):
            dy = max(lo[1] + j * h - x[1], x[1] - (lo[1] + (j + 1) * h), 0.0)
            if dy * dy + dz * dz >= reach * reach:
                continue
            base = dims[0] * (j + dims[1] * k)
            for i in range(max(ci - m, 0), min(ci + m, dims[0] - 1) + 1):
                q = head[base + i]
                while q >= 0:
                    ex = pts[q, 0] - x[0]
                    ey = pts[q, 1] - x[1]
                    ez = pts[q, 2] - x[2]
                    rr = max(rx, rad[q])
                    if ex * ex + ey * ey + ez * ez < rr * rr:
                        return True
                    q = nxt[q]
    return False


@njit(cache=True)
def _accept(cand, cand_r, cand_ok, first_only, pts, rad, nxt, head, n, lo, h, dims, rmax):
    """Try the candidates of each group in order; add the first that fits (or all that fit, unless ``first_only``).

    ``cand`` (g, c, 3), ``cand_r`` and ``cand_ok`` (g, c). Returns the new
    point count, which groups added a point, the indices of the added points
    and the largest accepted radius.
    """
    g, c = cand_ok.shape
    hit = np.zeros(g, dtype=np.bool_)
    added = np.empty(g * c if not first_only else g, dtype=np.int64)
    na = 0
    for a in range(g):
        for b in range(c):
            if not cand_ok[a, b]:
                continue
            x = cand[a, b]
            rx = cand_r[a, b]
            if _conflict(x, rx, rx, pts, rad, nxt, head, lo, h, dims):
                continue
            if rmax > rx and _conflict(x, rx, rmax, pts, rad, nxt, head, lo, h, dims):
                continue
            pts[n] = x
            rad[n] = rx
            cell = (min(max(int((x[0] - lo[0]) / h), 0), dims[0] - 1)
                    + dims[0] * (min(max(int((x[1] - lo[1]) / h), 0), dims[1] - 1)
                                 + dims[1] * min(max(int((x[2] - lo[2]) / h), 0), dims[2] - 1)))
            nxt[n] = head[cell]
            head[cell] = n
            rmax = max(rmax, rx)
            added[na] = n
            na += 1
            n += 1
            hit[a] = True
            if first_only:
                break
    return n, hit, added[:na], rmax


def poisson_disc_seeds(radius: float | Callable[[np.ndarray], np.ndarray], *, bounds, radius_gradient=None,
                       inside: InsideFn | None = None, seed: int | np.random.Generator = 0,
                       attempts: int = 30) -> np.ndarray:
    """Poisson-disc points with a spatially varying radius (Bridson's algorithm in 3-D).

    Every point ``p`` carries its local radius ``r(p)``; two points ``p`` and
    ``q`` are never closer than ``max(r(p), r(q))``, i.e. no point lies in
    another point's disc (ball) of radius ``r``. So the density follows
    ``1 / r**3``: more points where the radius is small.

    The sampler follows Bridson (2007): an active list, initially one point
    drawn uniformly in the region; in rounds, every active point ``a`` draws
    ``attempts`` candidates uniformly (by volume) in the shell between
    ``r(a)`` and ``2 r(a)`` around it and adds the first valid one (in the
    box, accepted by ``inside``, no conflict), or leaves the active list if
    none is valid. Conflicts are found on a background grid of cells
    ``r_min / sqrt(3)`` wide (each holding a linked list of points), looking
    ``max(r(x), r_max)`` around a candidate. When the active list is empty,
    a batch of uniform darts over the box restarts the growth in any part of
    the region it did not reach (another component of a disconnected
    region, or large holes); sampling stops when a batch of darts adds
    nothing.

    Parameters
    ----------
    radius : float or callable
        The radius, > 0, or a function mapping (m, 3) points to (m,) local
        radii (positive, finite); it is called only with points in the box.
    bounds : (lo, hi)
        Box of the samples, ``lo < hi`` (or a 6-tuple).
    radius_gradient : array_like, shape (3,), optional
        With a float ``radius``: ``r(x) = radius + radius_gradient . (x - lo)``,
        which must be positive over the whole box.
    inside : callable, optional
        Maps (m, 3) points to (m,) booleans; only accepted points are kept.
    seed : int or numpy.random.Generator
    attempts : int
        Candidates per active point and round (Bridson's k), >= 1.

    Returns
    -------
    numpy.ndarray, shape (n, 3), float64
        In the order the points were accepted.

    Raises
    ------
    ValueError
        Bad arguments; a radius that is not positive on the box; a radius so
        small the box would hold more than about 5e7 points; no point of the
        region found among 2**20 uniform darts.
    """
    lo, hi = _bounds(bounds)
    attempts = _count(attempts, "attempts")
    inside = _check_inside(inside)
    extent = hi - lo
    corners = lo + extent * np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], dtype=np.float64)
    if callable(radius):
        if radius_gradient is not None:
            raise ValueError("radius_gradient needs a float radius; fold the gradient into the radius callable")
        user = radius

        def radius_at(x: np.ndarray) -> np.ndarray:
            r = np.asarray(user(x), dtype=np.float64)
            if r.shape != (len(x),):
                raise ValueError(f"radius callable must return an array of shape ({len(x)},); got shape {r.shape}")
            if not (np.isfinite(r) & (r > 0)).all():
                bad = np.flatnonzero(~(np.isfinite(r) & (r > 0)))[0]
                raise ValueError(f"radius callable returned {r[bad]} at {x[bad].tolist()}; radii must be positive "
                                 "and finite")
            return r

        probe = np.stack(np.meshgrid(*(np.linspace(lo[a], hi[a], 9) for a in range(3)), indexing="ij"), -1)
        r_probe = radius_at(probe.reshape(-1, 3))
        r_min = float(r_probe.min())
    else:
        r0 = float(_positive(radius, "radius", 1)[0])
        if radius_gradient is None:
            grad = np.zeros(3)
        else:
            try:
                grad = np.asarray(radius_gradient, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"radius_gradient must be a 3-vector; got {radius_gradient!r}") from exc
            if grad.shape != (3,) or not np.isfinite(grad).all():
                raise ValueError(f"radius_gradient must be a finite 3-vector; got {radius_gradient!r}")
        r_corner = r0 + (corners - lo) @ grad
        if not (r_corner > 0).all():
            bad = int(np.argmin(r_corner))
            raise ValueError(f"radius + radius_gradient . (x - lo) must stay positive over the bounds; it is "
                             f"{r_corner[bad]:.6g} at the corner {corners[bad].tolist()}")
        r_min = float(r_corner.min())

        def radius_at(x: np.ndarray) -> np.ndarray:
            return r0 + (x - lo) @ grad if radius_gradient is not None else np.full(len(x), r0)

    estimate = float(np.prod(extent + r_min)) / r_min**3
    if estimate > _MAX_SITES:
        raise ValueError(f"poisson_disc_seeds: a radius of {r_min:.3g} in a box of size {extent.tolist()} would give "
                         f"up to about {int(estimate):,} points (more than {_MAX_SITES:,}); increase the radius")
    h = r_min / math.sqrt(3.0)
    h = max(h, (float(np.prod(extent)) / _MAX_GRID_CELLS) ** (1.0 / 3.0))
    dims = np.maximum(np.ceil(extent / h).astype(np.int64), 1)
    head = np.full(int(np.prod(dims)), -1, dtype=np.int64)
    capacity = 1024
    pts = np.empty((capacity, 3))
    rad = np.empty(capacity)
    nxt = np.empty(capacity, dtype=np.int64)
    n, rmax = 0, 0.0
    rng = np.random.default_rng(seed)

    def evaluate(cand: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Radii and validity of candidates of shape (g, c, 3)."""
        flat = cand.reshape(-1, 3)
        ok = ((flat >= lo) & (flat <= hi)).all(axis=1)
        idx = np.flatnonzero(ok)
        if inside is not None and len(idx):
            idx = idx[_eval_inside(inside, flat[idx])]
            ok[:] = False
            ok[idx] = True
        r = np.ones(len(flat))
        if len(idx):
            r[idx] = radius_at(flat[idx])
        return r.reshape(cand.shape[:2]), ok.reshape(cand.shape[:2])

    def grow(extra: int) -> None:
        nonlocal pts, rad, nxt, capacity
        if n + extra <= capacity:
            return
        capacity = max(2 * capacity, n + extra)
        pts = np.concatenate([pts, np.empty((capacity - len(pts), 3))])
        rad = np.concatenate([rad, np.empty(capacity - len(rad))])
        nxt = np.concatenate([nxt, np.empty(capacity - len(nxt), dtype=np.int64)])

    def darts(first_only: bool) -> np.ndarray:
        """Uniform darts over the box; the indices of the points they add."""
        nonlocal n, rmax
        cand = rng.uniform(lo, hi, size=(1 if first_only else _DART_BATCH, _DART_BATCH if first_only else 1, 3))
        r, ok = evaluate(cand)
        grow(cand.shape[0] * cand.shape[1])
        n, _, added, rmax = _accept(cand, r, ok, first_only, pts, rad, nxt, head, n, lo, h, dims, rmax)
        return added

    active = np.zeros(0, dtype=np.int64)
    for _ in range(_FIRST_DARTS // _DART_BATCH):
        active = darts(first_only=True)
        if len(active):
            break
    else:
        raise ValueError(f"poisson_disc_seeds: inside accepted none of {_FIRST_DARTS:,} points drawn in bounds; "
                         "does the region overlap the bounds?")
    while len(active):
        while len(active):
            g = len(active)
            ra = rad[active]
            direction = rng.standard_normal((g, attempts, 3))
            direction /= np.maximum(np.linalg.norm(direction, axis=2, keepdims=True), 1e-300)
            shell = np.cbrt(1.0 + 7.0 * rng.random((g, attempts)))  # r..2r, uniform by volume
            cand = pts[active][:, None, :] + direction * (shell * ra[:, None])[:, :, None]
            r, ok = evaluate(cand)
            grow(g)
            n, hit, added, rmax = _accept(cand, r, ok, True, pts, rad, nxt, head, n, lo, h, dims, rmax)
            active = np.concatenate([active[hit], added])
        active = darts(first_only=False)
    return np.ascontiguousarray(pts[:n])


# ----------------------------------------------------------------------------- mesh vertices


def mesh_vertex_seeds(points: np.ndarray, *, fraction: float = 1.0, count: int | None = None,
                      seed: int | np.random.Generator = 0) -> np.ndarray:
    """A random subset of a mesh's distinct vertices.

    Parameters
    ----------
    points : numpy.ndarray, shape (m, 3)
        Mesh vertices; repeated rows count once.
    fraction : float
        Share of the distinct vertices to keep, in (0, 1]; the number kept is
        ``round(fraction * m_distinct)``, at least 1.
    count : int, optional
        Number of vertices to keep instead of ``fraction`` (1 to the number
        of distinct vertices).
    seed : int or numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (n, 3), float64
        The chosen vertices in their input order (first occurrence).
    """
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise ValueError(f"points must have shape (m, 3) with m >= 1; got {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number):
        raise ValueError(f"points must be numeric; got dtype {pts.dtype}")
    pts = np.asarray(pts, dtype=np.float64)
    if not np.isfinite(pts).all():
        raise ValueError("points contain NaN or infinite coordinates")
    distinct = _unique_in_order(pts)
    m = len(distinct)
    if count is not None:
        if fraction != 1.0:
            raise ValueError("give either fraction or count, not both")
        count = _count(count, "count")
        if count > m:
            raise ValueError(f"count must be at most the number of distinct vertices ({m}); got {count}")
    else:
        try:
            fraction = float(fraction)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"fraction must be a number in (0, 1]; got {fraction!r}") from exc
        if not (0.0 < fraction <= 1.0):
            raise ValueError(f"fraction must be in (0, 1]; got {fraction}")
        count = min(max(round(fraction * m), 1), m)
    rng = np.random.default_rng(seed)
    chosen = np.sort(rng.choice(m, size=count, replace=False))
    return np.ascontiguousarray(distinct[chosen])
