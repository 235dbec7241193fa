"""Input scenes for intersection repair and Booleans (Skorkovská's thesis, §10.3, Figures 10.11-10.15).

Every builder returns closed, outward-oriented triangle meshes (PyVista
PolyData), deterministic for its arguments and built without data files; the
twelve-object scene uses the bunny scan when the caller passes it.

- :func:`two_spheres`: two intersecting spheres of different size and
  resolution (Figure 10.11);
- :func:`rotated_cuboids`: the cuboids 2:2:2 and 4:1:1 meshed so that their
  intersection runs along mesh edges, rotated 1° about x (Figure 10.12,
  Table 10.1);
- :func:`crossed_tube`: a torus bent into a figure eight whose halves pass
  through each other, a single self-intersecting closed mesh (Figure 10.14);
- :func:`cube_and_sphere`: the Boolean operands of Figure 10.15;
- :func:`twelve_objects`: six bunnies and six procedural shapes at seeded
  random poses (Figure 10.13's scene, ~77k faces);
- :func:`fuzz_primitives` and :func:`fuzz_operands`: seeded rigid copies of
  small shapes (and the bunny), half of them on a grid of exact moves, for
  fuzzing the repair and the Booleans.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyvista as pv
from scipy.spatial.transform import Rotation

from pverosion.examples import load_rock
from pverosion.kernels.mesh.orientation import orient_faces
from pverosion.meshing import fill_holes

__all__ = ["SCENES", "combine", "crossed_tube", "cube_and_sphere", "fuzz_operands", "fuzz_primitives",
           "rotated_cuboids", "tube", "twelve_objects", "two_spheres"]


def _polydata(points: np.ndarray, faces: np.ndarray) -> pv.PolyData:
    faces = np.asarray(faces, dtype=np.int64)
    return pv.PolyData(np.asarray(points, dtype=np.float64), np.c_[np.full(len(faces), 3), faces].ravel())


def combine(meshes: list[pv.PolyData]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (V, 3), faces (F, 3) and the mesh index of every face (F,) of several meshes put together."""
    points, faces, group = [], [], []
    offset = 0
    for k, mesh in enumerate(meshes):
        points.append(np.asarray(mesh.points, dtype=np.float64))
        faces.append(mesh.regular_faces + offset)
        group.append(np.full(mesh.n_cells, k))
        offset += mesh.n_points
    return np.vstack(points), np.vstack(faces), np.concatenate(group)


def two_spheres() -> tuple[pv.PolyData, pv.PolyData]:
    """A unit icosphere (1280 faces) and a coarser sphere of radius 0.6 (320 faces) overlapping it."""
    a = pv.Icosphere(radius=1.0, nsub=3)
    b = pv.Icosphere(radius=0.6, nsub=2).rotate_z(17.0).translate((0.95, 0.2, 0.1))
    return a, b


def rotated_cuboids(n: int = 8, *, degrees: float = 1.0) -> tuple[pv.PolyData, pv.PolyData]:
    """The thesis' cuboids: 2 x 2 x 2 and 4 x 1 x 1 through it, ``n`` cells along every side of each.

    With ``n`` a multiple of 2, the 4:1:1 cuboid has vertex rings where it
    enters and leaves the other and the 2:2:2 cuboid has grid lines around
    them, so the intersection runs along edges of both; the rotation by
    ``degrees`` about x makes the coordinates inexact. Exact results: union
    10, intersection 2, differences 6 and 2.
    """
    if int(n) != n or n < 2 or n % 2:
        raise ValueError(f"n must be an even integer >= 2; got {n!r}")
    a = pv.Box(bounds=(-1, 1, -1, 1, -1, 1), level=int(n) - 1).triangulate()
    b = pv.Box(bounds=(-2, 2, -0.5, 0.5, -0.5, 0.5), level=int(n) - 1).triangulate()
    turn = Rotation.from_euler("x", degrees, degrees=True).as_matrix()
    return (_polydata(np.asarray(a.points, float) @ turn.T, a.regular_faces),
            _polydata(np.asarray(b.points, float) @ turn.T, b.regular_faces))


def tube(centre: np.ndarray, radius: float, n_around: int) -> pv.PolyData:
    """A closed tube of ``radius`` around the closed curve ``centre`` (N, 3): 2 N ``n_around`` outward faces."""
    centre = np.asarray(centre, dtype=np.float64)
    n = len(centre)
    tangent = np.roll(centre, -1, axis=0) - np.roll(centre, 1, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    helper = np.where(np.abs(tangent[:, 2:3]) < 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    normal = np.cross(tangent, helper)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    binormal = np.cross(normal, tangent)
    v = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    ring = np.cos(v)[None, :, None] * normal[:, None] + np.sin(v)[None, :, None] * binormal[:, None]
    points = (centre[:, None] + radius * ring).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n_around), indexing="ij")
    a, b = i * n_around + j, ((i + 1) % n) * n_around + j
    c, d = ((i + 1) % n) * n_around + (j + 1) % n_around, i * n_around + (j + 1) % n_around
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return _polydata(points, orient_faces(points, faces, mode="outward").faces)


def crossed_tube(n_around: int = 160, n_tube: int = 16) -> pv.PolyData:
    """A torus bent into a figure eight whose halves pass through each other where they cross (centre lines
    0.24 apart there, the tube 0.3 wide): a closed self-intersecting mesh of ``2 n_around n_tube`` faces."""
    u = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    centre = np.stack([1.2 * np.sin(u), 0.9 * np.sin(2.0 * u), 0.12 * np.cos(u)], axis=1)
    return tube(centre, 0.15, n_tube)


def cube_and_sphere() -> tuple[pv.PolyData, pv.PolyData]:
    """A cube of side 1.6 (8112 faces) and a unit sphere (5120 faces) whose caps stick out of its faces."""
    a = pv.Box(bounds=(-0.8, 0.8, -0.8, 0.8, -0.8, 0.8), level=25).triangulate()
    b = pv.Icosphere(radius=1.0, nsub=4).translate((0.05, 0.03, 0.02))
    return a, b


def _shapes(rng: np.random.Generator) -> list[pv.PolyData]:
    """Six procedural closed shapes of about 6000 faces and unit size."""
    u = np.linspace(0.0, 2.0 * np.pi, 200, endpoint=False)
    trefoil = np.stack([np.sin(u) + 2 * np.sin(2 * u), np.cos(u) - 2 * np.cos(2 * u), -np.sin(3 * u)], axis=1) / 3
    ring = np.stack([np.cos(u[::2]), np.sin(u[::2]), 0.0 * u[::2]], axis=1)
    blob = pv.Icosphere(radius=1.0, nsub=4)
    bumps = 1.0 + 0.15 * np.sin(3 * blob.points[:, 0] + rng.uniform(0, 6)) * np.cos(2 * blob.points[:, 1])
    blob.points = blob.points * bumps[:, None]
    return [
        pv.Icosphere(radius=1.0, nsub=4).scale((1.0, 0.6, 0.4)),
        tube(ring * 0.8, 0.25, 32),
        pv.Box(bounds=(-0.7, 0.7, -0.5, 0.5, -0.4, 0.4), level=21).triangulate(),
        load_rock(subdivisions=4, seed=int(rng.integers(1 << 30))).scale(0.8),
        tube(trefoil, 0.12, 16),
        blob,
    ]


def _bunny(path: str | Path | None, faces: int) -> pv.PolyData:
    """The bunny scan decimated to about ``faces`` faces, holes filled, outward, scaled to unit size; a rock
    when no scan is given."""
    if path is None:
        return load_rock(subdivisions=4, seed=7)
    scan = pv.read(path).triangulate().clean()
    coarse = scan.decimate(1.0 - faces / scan.n_cells)
    points, tris = fill_holes(np.asarray(coarse.points, dtype=np.float64), coarse.regular_faces)
    tris = orient_faces(points, tris, mode="outward").faces
    points = (points - points.mean(axis=0)) / (0.5 * np.ptp(points, axis=0).max())
    return _polydata(points, tris)


def twelve_objects(*, bunny: str | Path | None = None, seed: int = 0, spread: float = 1.6) -> list[pv.PolyData]:
    """Six bunnies and six procedural shapes at seeded random poses, overlapping (about 77k faces).

    Parameters
    ----------
    bunny : str or Path, optional
        The Stanford bunny scan (``bunny.ply``); it is decimated to about
        6500 faces and its holes are closed. Without it, rocks stand in.
    seed : int, default: 0
        Poses and shapes; the same seed gives the same scene.
    spread : float, default: 1.6
        Side of the cube the objects' centres are drawn from (objects are
        about 2 across, so they overlap).
    """
    rng = np.random.default_rng(seed)
    model = _bunny(bunny, 6200)
    objects = [model.copy() for _ in range(6)] + _shapes(rng)
    placed = []
    for mesh in objects:
        turn = Rotation.random(random_state=int(rng.integers(1 << 30))).as_matrix()
        shift = rng.uniform(-0.5 * spread, 0.5 * spread, 3)
        placed.append(_polydata(np.asarray(mesh.points, dtype=np.float64) @ turn.T + shift, mesh.regular_faces))
    return placed


def fuzz_primitives(*, bunny: str | Path | None = None, bunny_faces: int = 2000) -> list[pv.PolyData]:
    """Small closed outward meshes for fuzzing the repair and the Booleans, coordinates exact in float32 (so
    that manifold3d, which reads float32, sees the same meshes).

    Two boxes (one with subdivided sides), two icospheres, a 9-sided
    cylinder, and with ``bunny`` the scan decimated to about ``bunny_faces``
    faces (holes filled, unit size).
    """
    shapes = [pv.Box(bounds=(-0.5, 0.5, -0.5, 0.5, -0.5, 0.5)).triangulate(),
              pv.Box(bounds=(-0.6, 0.6, -0.3, 0.3, -0.4, 0.4), level=1).triangulate(),
              pv.Icosphere(radius=0.55, nsub=1), pv.Icosphere(radius=0.55, nsub=2),
              pv.Cylinder(radius=0.4, height=1.0, resolution=9).triangulate()]
    if bunny is not None:
        shapes.append(_bunny(bunny, bunny_faces).scale(0.6))
    out = []
    for mesh in shapes:
        mesh = mesh.clean()
        out.append(_polydata(np.asarray(mesh.points, np.float32).astype(np.float64), mesh.regular_faces))
    return out


def fuzz_operands(rng: np.random.Generator, shapes: list[pv.PolyData], count: int = 2) -> list[pv.PolyData]:
    """``count`` rigid copies of randomly chosen ``shapes``: the first as it is, each further one with
    probability 1/2 turned by multiples of 90 degrees and moved by multiples of 1/2 (exactly shared planes,
    edges and vertices, touching and nested parts), else turned and moved at random; float32-exact."""
    picked = [shapes[k] for k in rng.integers(len(shapes), size=count)]
    out = [picked[0].copy()]
    for mesh in picked[1:]:
        if rng.random() < 0.5:
            turn = Rotation.from_euler("xyz", 90.0 * rng.integers(4, size=3), degrees=True).as_matrix().round()
            shift = 0.5 * rng.integers(-2, 3, size=3)
        else:
            turn = Rotation.random(random_state=int(rng.integers(1 << 31))).as_matrix()
            shift = rng.uniform(-0.8, 0.8, size=3)
        points = (np.asarray(mesh.points, np.float64) @ turn.T + shift).astype(np.float32).astype(np.float64)
        out.append(_polydata(points, mesh.regular_faces))
    return out


SCENES = {
    "two_spheres": two_spheres,
    "cuboids": rotated_cuboids,
    "self_intersection": crossed_tube,
    "cube_sphere": cube_and_sphere,
    "twelve_objects": twelve_objects,
}
"""Scene name -> builder."""
