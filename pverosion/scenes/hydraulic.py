"""Input scenes for hydraulic erosion on meshes: a closed mesh with emitters, drains and a particle radius.

Every builder returns a :class:`HydraulicScene`: a closed, 2-manifold,
outward-oriented triangle mesh without self-intersections, the emitters and
drains as option strings, the particle radius, the fluid's domain and a
suggested number of iterations. :data:`SCENES` maps a name to a builder;
all are deterministic for a seed and need no data files (the DEM and the
scan are used when the caller passes them).

Emitter strings are ``"x,y,z,dx,dy,dz,R,rate,speed"``: a disc of radius R at
(x, y, z) facing (dx, dy, dz) that releases ``rate`` particles per second at
``speed``; the rates fill the disc's cross-section at that speed with
particles packed at a spacing of one diameter. Drain strings are
``"plane:nx,ny,nz,d"`` (removes particles with n . x > d) or
``"box:xmin,ymin,zmin,xmax,ymax,zmax"``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import numpy as np
import pyvista as pv
from matplotlib.path import Path as Polygon
from scipy.ndimage import gaussian_filter, map_coordinates, uniform_filter1d
from scipy.spatial import cKDTree
from skimage.graph import route_through_array

from pverosion.examples import load_rock
from pverosion.kernels.fluid.particle_fluid import Emitter
from pverosion.kernels.mesh.orientation import orient_faces
from pverosion.kernels.mesh.terrain import height_field_solid
from pverosion.kernels.mesh.topology import edge_topology
from pverosion.kernels.validation import as_triangle_mesh
from pverosion.meshing import fill_holes, points_clear_of, resample, triangular_lattice, triangulate

__all__ = ["HELENS_WINDOW", "SCENES", "HydraulicScene", "canyon_scene", "fill_holes", "lake_scene", "pour_scene",
           "river_scene"]


@dataclass(frozen=True)
class HydraulicScene:
    """A closed mesh and the set-up of the particle fluid poured over it.

    Attributes
    ----------
    mesh : pyvista.PolyData
        Closed, 2-manifold, outward-oriented triangles (the fluid is outside).
    emitters : list of str
        ``"x,y,z,dx,dy,dz,R,rate,speed"`` each.
    drains : list of str
        ``"plane:nx,ny,nz,d"`` or ``"box:xmin,ymin,zmin,xmax,ymax,zmax"`` each.
    radius : float
        Particle radius.
    domain : tuple of two 3-tuples
        Corners (lo, hi) of the box the particles live in.
    iterations : int
        Suggested number of solver iterations.
    name : str
    """

    mesh: pv.PolyData
    emitters: list[str]
    drains: list[str]
    radius: float
    domain: tuple[tuple[float, float, float], tuple[float, float, float]]
    iterations: int
    name: str


def _emitter(position, direction, disc: float, radius: float, speed: float) -> str:
    """Emitter string of a disc that fills its cross-section at ``speed`` with particles one diameter apart.

    The rate is what the emitter's lattice of spacing 2r in the disc releases
    at that speed (a layer every 2r / speed seconds). Numbers are written in
    full (``repr``), so the emitter parsed back is exactly this one: a rate
    rounded to a few digits can exceed what the disc emits by the rounding.
    """
    spacing = 2.0 * radius
    layer = len(Emitter(position=tuple(position), direction=tuple(direction), radius=disc, rate=1.0).lattice(spacing))
    rate = layer * speed / spacing * (1.0 - 1e-9)
    values = [*np.asarray(position, dtype=float), *np.asarray(direction, dtype=float), disc, rate, speed]
    return ",".join(repr(float(v)) for v in values)


def _box(lo, hi) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    return tuple(float(v) for v in lo), tuple(float(v) for v in hi)


# ---------------------------------------------------------------- planar meshing

_QUANTUM = 2.0**-14
"""Grid the canyon's coordinates are rounded to (its coordinates lie within +-2)."""


def _snap(points: np.ndarray) -> np.ndarray:
    """Points rounded to multiples of :data:`_QUANTUM`.

    On coordinates of at most 2**16 quanta the orientation determinants of
    the self-intersection check are exact, so the many coplanar triangles of
    a vertical wall are recognised as coplanar rather than tested on the
    rounding noise of their plane (which reports false intersections).
    """
    return np.round(points / _QUANTUM) * _QUANTUM


def _chain(corners: np.ndarray, spacing: float) -> np.ndarray:
    """Points along the polyline ``corners`` (n, 2) at about ``spacing``, ends kept, every piece split evenly."""
    pieces = []
    for a, b in pairwise(corners):
        n = max(1, round(float(np.linalg.norm(b - a)) / spacing))
        pieces.append(a + np.linspace(0.0, 1.0, n + 1)[:-1, None] * (b - a))
    return np.vstack([*pieces, corners[-1:]])


def _directed_edges(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Directed edges (3m, 2) of counter-clockwise triangles, the triangle on the left of each (3m,) and the one
    on its right (3m,; -1: none)."""
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    owner = np.tile(np.arange(len(tri)), 3)
    n = int(tri.max()) + 1
    key = edges[:, 0] * n + edges[:, 1]
    order = np.argsort(key)
    reverse = edges[:, 1] * n + edges[:, 0]
    at = np.clip(np.searchsorted(key[order], reverse), 0, len(key) - 1)
    found = key[order][at] == reverse
    right = np.where(found, owner[order][at], -1)
    return edges, owner, right


# ---------------------------------------------------------------- canyon

_CANYON_LENGTH = 2.0
_CANYON_HALF_WIDTH = 0.35
_CANYON_HEIGHT = 0.5
_CANYON_WIDTH = 0.1
_CANYON_START = 0.25
_CANYON_FLOOR = (0.2, 0.1)
_CANYON_AMPLITUDE = 0.09


def _canyon_outline(seed: int) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]:
    """Dense wall polyline of the canyon (outlet right bank, back round the head, out along the left bank), centre line."""
    rng = np.random.default_rng(seed)
    amplitudes = _CANYON_AMPLITUDE * np.array([rng.uniform(-0.15, 0.15), rng.uniform(0.85, 1.15),
                                               rng.uniform(-0.15, 0.15)])
    waves = np.array([4.0, 5.0, 6.0])  # half waves along the channel; cosines keep the ends straight
    x0, x1 = _CANYON_START, _CANYON_LENGTH

    def centre(x):
        t = (np.asarray(x, dtype=float)[..., None] - x0) / (x1 - x0)
        return (amplitudes * np.cos(np.pi * waves * t)).sum(-1)

    def slope(x):
        t = (np.asarray(x, dtype=float)[..., None] - x0) / (x1 - x0)
        return (-amplitudes * np.pi * waves / (x1 - x0) * np.sin(np.pi * waves * t)).sum(-1)

    x = np.linspace(x0, x1, 4001)
    y, dy = centre(x), slope(x)
    normal = np.stack([-dy, np.ones_like(dy)], axis=1) / np.hypot(dy, 1.0)[:, None]
    line = np.stack([x, y], axis=1)
    half = 0.5 * _CANYON_WIDTH
    angle = np.linspace(1.5 * np.pi, 0.5 * np.pi, 201)
    head = np.stack([x0 + half * np.cos(angle), y[0] + half * np.sin(angle)], axis=1)
    outline = np.vstack([(line - half * normal)[::-1], head[1:-1], line + half * normal])
    outline[[0, -1]] = [[x1, y[-1] - half], [x1, y[-1] + half]]  # exactly on the end face
    return outline, centre


def _floor(x: np.ndarray) -> np.ndarray:
    """Height of the canyon floor: falling linearly from the head to the outlet."""
    (z0, z1), x0 = _CANYON_FLOOR, _CANYON_START
    return z0 + (z1 - z0) * (np.asarray(x) - x0) / (_CANYON_LENGTH - x0)


def _canyon_plan(outline: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planar mesh of the canyon block's top: points (n, 2), CCW triangles (m, 3), channel mask (m,)."""
    length, half = _CANYON_LENGTH, _CANYON_HALF_WIDTH
    wall = resample(outline, spacing)
    rim = np.array([[0.0, -half], [length, -half], outline[0], outline[-1], [length, half], [0.0, half], [0.0, -half]])
    frame = _chain(rim, spacing)[:-1]
    frame = frame[np.abs(frame[:, None, :] - wall[None, [0, -1], :]).sum(-1).min(axis=1) > 0.0]  # wall's ends
    inner = triangular_lattice((0.0, -half), (length, half), spacing)
    inside = (inner[:, 0] > 0.0) & (inner[:, 0] < length) & (np.abs(inner[:, 1]) < half)
    inner = inner[inside]
    inner = inner[points_clear_of(inner, [outline, rim], 0.6 * spacing)]
    points = np.vstack([wall, frame, inner])
    n_wall = len(wall)
    constraints = np.stack([np.arange(n_wall - 1), np.arange(1, n_wall)], axis=1)
    tri = triangulate(points, constraints)
    closed = np.vstack([outline, outline[:1]])
    channel = Polygon(closed).contains_points(points[tri].mean(axis=1))
    return points, tri, channel


def _canyon_solid(points: np.ndarray, tri: np.ndarray, channel: np.ndarray,
                  spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed block over the planar mesh: banks up to the top, channel down to the floor, vertical walls and sides.

    Vertex (i, k) stands over planar point i at level k: levels 0..nb span
    the base to the floor height at the point's x, levels nb..nb+nt the
    floor to the top, so every wall and side is cut into rows of about
    ``spacing``.
    """
    floor = _floor(points[:, 0])
    mean_floor = float(np.mean(_CANYON_FLOOR))
    nb = max(1, round(mean_floor / spacing))
    nt = max(2, round((_CANYON_HEIGHT - mean_floor) / spacing))
    top = nb + nt
    edges, left, right = _directed_edges(tri)
    bank = ~channel[left]
    walls = edges[bank & (right >= 0) & channel[np.maximum(right, 0)]]
    sides = edges[right < 0]
    side_top = np.where(bank[right < 0], top, nb)
    strips = [(walls, np.full(len(walls), nb), np.full(len(walls), top)),
              (sides, np.zeros(len(sides), np.int64), side_top)]
    used = np.zeros((len(points), top + 1), bool)
    used[tri[~channel], top] = True
    used[tri[channel], nb] = True
    used[:, 0] = True
    levels = np.arange(top + 1)[None, :]
    for e, k0, k1 in strips:
        for end in (0, 1):
            used[e[:, end]] |= (levels >= k0[:, None]) & (levels <= k1[:, None])
    ids = np.full(used.shape, -1, np.int64)
    ids[used] = np.arange(used.sum())
    vi, vk = np.nonzero(used)
    z = np.where(vk <= nb, vk / nb * floor[vi], floor[vi] + (vk - nb) / nt * (_CANYON_HEIGHT - floor[vi]))
    vertices = _snap(np.column_stack([points[vi], z]))
    faces = [ids[tri[~channel], top], ids[tri[channel], nb], ids[tri[:, ::-1], 0]]
    for e, k0, k1 in strips:  # quads (a, k) (b, k) (b, k + 1) (a, k + 1), facing right of a -> b
        which = np.repeat(np.arange(len(e)), k1 - k0)
        k = np.concatenate([np.arange(lo, hi) for lo, hi in zip(k0, k1)])
        a, b = e[which, 0], e[which, 1]
        faces += [np.stack([ids[a, k], ids[b, k], ids[b, k + 1]], axis=1),
                  np.stack([ids[a, k], ids[b, k + 1], ids[a, k + 1]], axis=1)]
    return vertices, np.concatenate(faces)


def canyon_scene(*, n_faces: int = 34_000, seed: int = 0) -> HydraulicScene:
    """A block with a narrow, meandering canyon: vertical walls, a floor falling towards the open outlet.

    The block spans x in [0, 2], y in [-0.35, 0.35], z in [0, 0.5]. The
    channel, 0.1 wide, starts with a rounded head at x = 0.25 and leaves the
    block through the end face x = 2; its centre line meanders (about five
    bends, the seed varies them) and its floor falls from z = 0.2 at the head to
    z = 0.1 at the outlet (depth 0.3 to 0.4). The walls are exactly vertical.
    Triangles are near equilateral on the top, floor and bottom (a planar
    Delaunay mesh), right-angled on the walls and sides.

    Parameters
    ----------
    n_faces : int, default: 34000
        Number of triangles wanted (the result is within a few per cent).
    seed : int, default: 0
        Varies the meanders.

    Returns
    -------
    HydraulicScene
        Emitter jetting down the channel from the canyon's head, a drain past the outlet,
        particles of radius 1/12 of the channel's width.
    """
    if int(n_faces) != n_faces or n_faces < 2000:
        raise ValueError(f"n_faces must be an integer >= 2000; got {n_faces!r}")
    outline, centre = _canyon_outline(seed)
    walls = np.linalg.norm(np.diff(outline, axis=0), axis=1).sum() * (_CANYON_HEIGHT - np.mean(_CANYON_FLOOR))
    area = (4.0 * _CANYON_LENGTH * _CANYON_HALF_WIDTH + walls
            + 2.0 * _CANYON_HEIGHT * (2.0 * _CANYON_LENGTH + 2.0 * _CANYON_HALF_WIDTH))
    spacing = np.sqrt(area / (np.sqrt(3.0) / 4.0 * n_faces))
    for _ in range(3):  # refine the estimate of the spacing on the face count it gives
        vertices, faces = _canyon_solid(*_canyon_plan(outline, spacing), spacing)
        if abs(len(faces) - n_faces) <= 0.01 * n_faces:
            break
        spacing *= np.sqrt(len(faces) / n_faces)
    mesh = pv.PolyData.from_regular_faces(vertices, faces)
    radius = _CANYON_WIDTH / 12.0
    x_head = _CANYON_START + 0.5 * _CANYON_WIDTH
    # a jet low in the canyon's head, down the channel, so the water runs through the whole canyon
    emitter = _emitter((x_head, float(centre(x_head)), _floor(np.array([x_head]))[0] + 0.08), (1.0, 0.0, -0.3),
                       0.35 * _CANYON_WIDTH, radius, 1.5)
    drain = f"plane:1,0,0,{_CANYON_LENGTH + 0.05:.6g}"
    domain = _box((-0.05, -_CANYON_HALF_WIDTH - 0.05, -0.1),
                  (_CANYON_LENGTH + 0.1, _CANYON_HALF_WIDTH + 0.05, _CANYON_HEIGHT + 0.2))
    length = float(np.linalg.norm(np.diff(outline, axis=0), axis=1).sum()) / 2.0
    return HydraulicScene(mesh, [emitter], [drain], radius, domain, _iterations(length, radius), "canyon")


# ---------------------------------------------------------------- river

HELENS_WINDOW = (76, 276, 168, 168)
"""Samples (i0, j0, ni, nj) of ``SainteHelens.dem`` taken by :func:`river_scene`: the crater floor and the breach."""

_RIVER_SOURCE = (0.5, 0.06)
"""Head of the river as fractions of the window along x and y (the crater floor of the St Helens window)."""

_RIVER_WIDTH = 5.0
_RIVER_DEPTH = 2.0
_RIVER_BANK = 2.0
_RIVER_SLOPE = 0.01


def _dem_window(dem: str | Path, window) -> tuple[np.ndarray, float]:
    """Heights (ni, nj) of a window of a DEM file (square samples) and its sample spacing."""
    image = pv.read(str(dem))
    if not isinstance(image, pv.ImageData) or image.dimensions[2] != 1 or image.active_scalars is None:
        raise ValueError(f"{dem} is not a DEM: expected a 2-D image of heights")
    dims = image.dimensions
    i0, j0, ni, nj = (int(v) for v in window)
    if i0 < 0 or j0 < 0 or ni < 2 or nj < 2 or i0 + ni > dims[0] or j0 + nj > dims[1]:
        raise ValueError(f"window {tuple(window)} does not fit the DEM's {dims[0]} x {dims[1]} samples")
    if not np.isclose(image.spacing[0], image.spacing[1]):
        raise ValueError(f"the DEM's samples must be square; got spacing {image.spacing[:2]}")
    heights = np.asarray(image.active_scalars, dtype=np.float64).reshape(dims[:2], order="F")
    return heights[i0:i0 + ni, j0:j0 + nj], float(image.spacing[0])


def _valley_terrain(shape, spacing: float, seed: int) -> np.ndarray:
    """Procedural heights (metres) like the St Helens window: a flank falling along y, rough hills across it."""
    rng = np.random.default_rng(seed)
    nx, ny = shape
    x = np.arange(nx)[:, None] * spacing
    y = np.arange(ny)[None, :] * spacing
    extent = max(nx, ny) * spacing
    heights = 1900.0 - 900.0 * (y / extent) ** 0.8 + 250.0 * ((x / extent - 0.5) * 2.0) ** 2
    for sigma, amplitude in ((12.0, 120.0), (4.0, 25.0)):
        noise = gaussian_filter(rng.standard_normal(shape), sigma, mode="reflect")
        heights = heights + amplitude * noise / np.abs(noise).max()
    return heights


def _river_line(heights: np.ndarray, seed: int) -> np.ndarray:
    """Centre line (n, 2) of the river in sample units: the cheapest route from the head to the lowest border
    sample through low ground, smoothed, with meanders added (none at the ends)."""
    nx, ny = heights.shape
    head = (round(_RIVER_SOURCE[0] * (nx - 1)), round(_RIVER_SOURCE[1] * (ny - 1)))
    border = np.ones(heights.shape, bool)
    border[1:-1, 1:-1] = False
    outlet = np.unravel_index(np.argmin(np.where(border, heights, np.inf)), heights.shape)
    cost = 1.0 + 50.0 * (heights - heights.min()) / max(float(np.ptp(heights)), 1e-12)
    route = np.array(route_through_array(cost, head, outlet, fully_connected=True, geometric=True)[0], dtype=float)
    line = resample(route, 0.25)
    line = uniform_filter1d(line, 33, axis=0, mode="nearest")
    line[0], line[-1] = route[0], route[-1]
    line = resample(line, 0.25)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))])
    tangent = np.gradient(line, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    rng = np.random.default_rng(seed)
    wavelength = rng.uniform(26.0, 34.0)
    amplitude = rng.uniform(2.5, 3.5) * np.clip(np.minimum(arc, arc[-1] - arc) / 12.0, 0.0, 1.0) ** 2
    offset = amplitude * np.sin(2.0 * np.pi * arc / wavelength + rng.uniform(0.0, 2.0 * np.pi))
    meander = line + offset[:, None] * np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    inside = np.clip(meander, 0.0, [nx - 1, ny - 1])
    return resample(inside, 0.25)


def _carve(heights: np.ndarray, line: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Heights with the river cut in (flat bed, steep banks) and the bed's height along the line (n,).

    The bed lies ``_RIVER_DEPTH`` samples below the ground at the head and
    falls at least ``_RIVER_SLOPE`` all the way, cutting a gorge where the
    line crosses higher ground.
    """
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(line, axis=0), axis=1))]) * spacing
    ground = map_coordinates(heights, line.T, order=1)
    drop = _RIVER_SLOPE * arc
    bed = np.minimum.accumulate(ground - _RIVER_DEPTH * spacing + drop) - drop
    nx, ny = heights.shape
    grid = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"), axis=-1).reshape(-1, 2)
    distance, nearest = cKDTree(line).query(grid)
    target = bed[nearest] + _RIVER_BANK * spacing * np.maximum(distance - 0.5 * _RIVER_WIDTH, 0.0)
    return np.minimum(heights, target.reshape(heights.shape)), bed


def river_scene(*, dem: str | Path | None = None, stride: int = 2, window=HELENS_WINDOW, seed: int = 0) -> HydraulicScene:
    """A meandering river with steep banks cut into a terrain block: the St Helens DEM or a procedural flank.

    With ``dem`` (e.g. the path of ``SainteHelens.dem``) the window
    ``window`` of the DEM is taken, every ``stride``-th sample (the default
    window at stride 2 gives 84 x 84 samples and 14,774 faces, the paper's
    model has 14,782); without it a procedural flank of the same size and
    spacing stands in. Coordinates are metres from the window's corner. The
    river runs from a head near the middle of the window's low-y side (the
    crater floor) along the cheapest route through low ground to the lowest
    border sample, with meanders added (the seed varies them); it is 5
    samples wide with a flat bed 2 samples deep at the head, falling at
    least 1 %, and banks rising 2 : 1. The block is closed by
    :func:`~pverosion.kernels.mesh.terrain.height_field_solid`.

    Parameters
    ----------
    dem : str or pathlib.Path, optional
        A DEM file that PyVista reads as a 2-D image of heights.
    stride : int, default: 2
        Take every stride-th sample of the window.
    window : (4,) int, default: HELENS_WINDOW
        First samples and sample counts (i0, j0, ni, nj) of the DEM's window.
    seed : int, default: 0
        Varies the meanders (and the procedural terrain).

    Returns
    -------
    HydraulicScene
        Emitter pouring into the river's head, a drain box round its outlet,
        particles of radius 1/12 of the river's width.

    Raises
    ------
    ValueError
        A bad stride or window, a file that is not a DEM (or has samples
        that are not square), or fewer than 16 x 16 samples left.
    """
    if int(stride) != stride or stride < 1:
        raise ValueError(f"stride must be an integer >= 1; got {stride!r}")
    if len(window) != 4:
        raise ValueError(f"window must be (i0, j0, ni, nj); got {window!r}")
    if dem is None:
        spacing = 30.0
        heights = _valley_terrain(tuple(int(v) for v in window[2:]), spacing, seed)
    else:
        heights, spacing = _dem_window(dem, window)
    heights = heights[::stride, ::stride]
    cell = spacing * stride
    if min(heights.shape) < 16:
        raise ValueError(f"the river needs at least 16 x 16 samples; got {heights.shape}")
    line = _river_line(heights, seed)
    heights, bed = _carve(heights, line, cell)
    points, faces = height_field_solid(heights, spacing=(cell, cell))
    mesh = pv.PolyData.from_regular_faces(points, faces)
    width, depth = _RIVER_WIDTH * cell, _RIVER_DEPTH * cell
    radius = width / 12.0
    head, outlet = line[0] * cell, line[-1] * cell
    emitter = _emitter((*head, bed[0] + depth + 4.0 * radius), (0.0, 0.0, -1.0), 0.4 * width, radius, 10.0)
    lo, hi = points.min(axis=0), points.max(axis=0)
    reach = 2.0 * width
    drain = "box:" + ",".join(repr(float(v)) for v in (*(outlet - reach), lo[2] - depth, *(outlet + reach),
                                                        hi[2] + depth))
    domain = _box((*(lo[:2] - 2.0 * cell), lo[2] - depth), (*(hi[:2] + 2.0 * cell), hi[2] + depth))
    length = float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum()) * cell
    return HydraulicScene(mesh, [emitter], [drain], radius, domain, _iterations(length, radius), "river")


def _iterations(length: float, radius: float) -> int:
    """Suggested iterations: the water crossing ``length`` about four times at half a particle radius per iteration."""
    return int(max(500, round(8.0 * length / radius, -2)))


# ---------------------------------------------------------------- lake

_LAKE_SIZE = (2.5, 1.5)
_LAKE_CENTRE = (0.8, 0.75)
_LAKE_RADIUS = 0.4


def _lake_terrain(shape, seed: int) -> tuple[np.ndarray, float]:
    """Heights over the lake scene's grid and its spacing: a slope falling along x, a basin, a rim notched downhill,
    a spillway from the notch to the low edge."""
    nx, ny = shape
    spacing = _LAKE_SIZE[0] / (nx - 1)
    x = np.arange(nx)[:, None] * spacing
    y = np.arange(ny)[None, :] * spacing
    (cx, cy), rb = _LAKE_CENTRE, _LAKE_RADIUS
    r = np.hypot(x - cx, y - cy)
    angle = np.arctan2(y - cy, x - cx)
    heights = 0.5 - 0.12 * x
    heights = heights - 0.2 * np.clip(1.0 - (r / rb) ** 2, 0.0, None) ** 2
    notch = 1.0 - 0.85 * np.exp(-((angle / 0.3) ** 2))
    heights = heights + 0.08 * np.exp(-(((r - 1.05 * rb) / 0.08) ** 2)) * notch
    t = np.clip((x - cx - 0.2) / 0.3, 0.0, 1.0)
    heights = heights - 0.03 * np.exp(-(((y - cy) / 0.07) ** 2)) * t * t * (3.0 - 2.0 * t)
    noise = gaussian_filter(np.random.default_rng(seed).standard_normal((nx, ny)), 4.0, mode="reflect")
    return heights + 0.005 * noise / np.abs(noise).max(), spacing


def lake_scene(*, shape=(101, 61), seed: int = 0) -> HydraulicScene:
    """Procedural terrain with a lake basin whose rim has one low notch leading down a slope.

    The terrain spans x in [0, 2.5], y in [0, 1.5] and falls along x. The
    basin (radius 0.4 round (0.8, 0.75)) is closed by a rim that is lowest
    at a notch on its downhill side (+x), where a shallow spillway leads
    down to the edge x = 2.5; the emitter above the basin fills it until it
    overflows through the notch.

    Parameters
    ----------
    shape : (2,) int, default: (101, 61)
        Height samples along x and y (2 (nx - 1)(ny - 1) + 3 * 2 (nx + ny - 2) faces).
    seed : int, default: 0
        Seed of the small roughness.

    Returns
    -------
    HydraulicScene
        Emitter over the basin's centre, a drain plane at the low edge.
    """
    if len(shape) != 2 or int(shape[0]) < 21 or int(shape[1]) < 13:
        raise ValueError(f"shape must be two sample counts of at least (21, 13); got {shape!r}")
    nx, ny = int(shape[0]), int(shape[1])
    heights, spacing = _lake_terrain((nx, ny), seed)
    points, faces = height_field_solid(heights, spacing=spacing)
    mesh = pv.PolyData.from_regular_faces(points, faces)
    radius = 0.01
    (cx, cy), top = _LAKE_CENTRE, float(heights.max())
    emitter = _emitter((cx, cy, top + 0.1), (0.0, 0.0, -1.0), 0.05, radius, 0.5)
    drain = f"plane:1,0,0,{_LAKE_SIZE[0] - 2.0 * spacing:.6g}"
    domain = _box((-0.05, -0.05, points[:, 2].min() - 0.1), (_LAKE_SIZE[0] + 0.05, _LAKE_SIZE[1] + 0.05, top + 0.3))
    return HydraulicScene(mesh, [emitter], [drain], radius, domain, _iterations(_LAKE_SIZE[0], radius), "lake")


# ---------------------------------------------------------------- pouring over a model


def pour_scene(*, mesh: pv.PolyData | None = None, up=(0.0, 0.0, 1.0)) -> HydraulicScene:
    """Water poured over a model from above: the given mesh (its holes filled) or a procedural rock.

    Parameters
    ----------
    mesh : pyvista.PolyData, optional
        A triangle mesh, e.g. the bunny scan (``up=(0, 1, 0)``); its faces
        are made consistent, holes closed with :func:`fill_holes`, unused
        points dropped and the faces turned outward. Default:
        :func:`pverosion.examples.load_rock`.
    up : (3,) float, default: (0, 0, 1)
        The model's up direction; the model is rotated so that it points
        along +z.

    Returns
    -------
    HydraulicScene
        An emitter over the model's centroid, a fifth of its width across,
        and a drain plane below it.

    Raises
    ------
    TypeError
        A mesh that is not a PolyData.
    ValueError
        A bad ``up``, or holes :func:`fill_holes` cannot close.
    """
    source = load_rock() if mesh is None else mesh
    if not isinstance(source, pv.PolyData):
        raise TypeError(f"mesh must be a pyvista.PolyData; got {type(source).__name__}")
    if not source.is_all_triangles:
        source = source.triangulate()
    points, faces = as_triangle_mesh(source.points, source.regular_faces)
    points, faces = fill_holes(points, orient_faces(points, faces).faces)  # holes need consistent faces
    used = np.zeros(len(points), bool)
    used[faces] = True
    points, faces = points[used], (np.cumsum(used) - 1)[faces]
    if edge_topology(faces, len(points)).n_boundary_edges:
        raise ValueError("the mesh could not be closed")
    faces = orient_faces(points, faces).faces
    points = points @ _rotation_to_z(up).T
    mesh = pv.PolyData.from_regular_faces(points, faces)
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = float(np.max(hi - lo))
    radius = size / 60.0
    tri = points[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    centroid = (tri.mean(axis=1) * area[:, None]).sum(axis=0) / area.sum()
    width = float(np.min(hi[:2] - lo[:2]))
    emitter = _emitter((centroid[0], centroid[1], hi[2] + 0.2 * size), (0.0, 0.0, -1.0), 0.1 * width, radius, 0.5)
    drain = f"plane:0,0,-1,{float(0.05 * size - lo[2])!r}"
    domain = _box(lo - 0.25 * size, hi + [0.25 * size, 0.25 * size, 0.4 * size])
    return HydraulicScene(mesh, [emitter], [drain], radius, domain, _iterations(size, radius), "pour")


def _rotation_to_z(up) -> np.ndarray:
    """Rotation matrix (3, 3) taking the direction ``up`` to +z (the shortest rotation)."""
    u = np.asarray(up, dtype=np.float64)
    if u.shape != (3,) or not np.isfinite(u).all() or not np.linalg.norm(u) > 0.0:
        raise ValueError(f"up must be a non-zero 3-vector; got {up!r}")
    u = u / np.linalg.norm(u)
    axis = np.cross(u, [0.0, 0.0, 1.0])
    s, c = np.linalg.norm(axis), u[2]
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * skew + (1.0 - c) * skew @ skew


SCENES = {"canyon": canyon_scene, "river": river_scene, "lake": lake_scene, "pour": pour_scene}
"""Scene builders by name; each takes keyword arguments only and works without data files."""
