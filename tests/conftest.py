"""Shared fixtures: procedural surfaces and the real scans of ../shared/data."""

from __future__ import annotations

import itertools
import os
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
import numpy as np
import pytest
import pyvista as pv

from pverosion.examples import data_path

os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

DATA = data_path()

_DISPLAYS = itertools.count()


def one_and_all_threads(call: Callable[[], Any]) -> tuple[Any, Any]:
    """``call()`` with one numba thread, then with all ``NUMBA_NUM_THREADS``; skips the test when only one
    thread exists. The caller's thread count is restored."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs at least two threads to compare")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = call()
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = call()
    finally:
        numba.set_num_threads(before)
    return one, many


def assert_filter_equals_kernel(out: pv.PolyData, points: np.ndarray, faces: np.ndarray, orientation: str):
    """Assert that the curvature filter's output ``out`` holds, bit for bit, what ``orient_faces`` followed by
    ``principal_curvatures`` gives for the (n, 3) ``points`` and (m, 3) ``faces``; returns the orientation."""
    from pverosion.kernels import orient_faces, principal_curvatures

    oriented = orient_faces(points, faces, mode=orientation)
    expected = principal_curvatures(points, oriented.faces)
    for name, values in (("k1", expected.k1), ("k2", expected.k2), ("normals", expected.normals),
                         ("principal_direction_1", expected.direction1)):
        assert np.array_equal(out[name], values), name
    np.testing.assert_array_equal(out.regular_faces, oriented.faces)
    return oriented


def surface_defects(faces: np.ndarray) -> dict[str, int]:
    """Defects of a closed manifold triangle surface (F, 3): all zero for one."""
    ordered = np.sort(faces, axis=1)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, per_edge = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    _, per_directed = np.unique(directed, axis=0, return_counts=True)
    return {"repeated faces": len(faces) - len(np.unique(ordered, axis=0)),
            "faces repeating a vertex": int(np.count_nonzero((ordered[:, 0] == ordered[:, 1])
                                                              | (ordered[:, 1] == ordered[:, 2]))),
            "edges not in two faces": int(np.count_nonzero(per_edge != 2)),
            "edges wound alike by two faces": int(np.count_nonzero(per_directed > 1))}


def with_x_server(command: list[str], *, env: dict | None = None, screen: str = "1024x768x24") -> list[str]:
    """``command`` under an X server of its own (``xvfb-run``) when there is no display.

    Each call takes another display number: ``xvfb-run -a`` alone races with other runs
    starting at :99, and the previous call's X server may still hold its number while it exits.
    """
    if not shutil.which("xvfb-run") or (env if env is not None else os.environ).get("DISPLAY"):
        return command
    number = 100 + (os.getpid() % 800 + 37 * next(_DISPLAYS)) % 800
    while Path(f"/tmp/.X{number}-lock").exists() or Path(f"/tmp/.X11-unix/X{number}").exists():
        number = 100 + (number - 99) % 800
    return ["xvfb-run", "-a", "-n", str(number), "-s", f"-screen 0 {screen}", *command]


def run_pvbatch(command: list[str], *, env: dict | None = None, screen: str = "1024x768x24",
                **kwargs) -> subprocess.CompletedProcess:
    """Run a ``pvbatch`` command line (under :func:`with_x_server`); captured text output.

    Debian's ``pvbatch`` renders through X even off-screen, and under ``xvfb-run`` it
    sometimes fails to open the display although the X server answers other clients
    (``bad X server connection``, then SIGABRT). Only that failure is retried, twice, each
    time on a new X server; any other outcome is returned as it is.
    """
    for attempt in range(3):
        done = subprocess.run(with_x_server(command, env=env, screen=screen), capture_output=True, text=True,
                              env=env, stdin=subprocess.DEVNULL, **kwargs)
        if done.returncode == 0 or "bad X server connection" not in done.stderr:
            break
    return done


@pytest.fixture(scope="session")
def bunny() -> pv.PolyData:
    path = DATA / "bunny.ply"
    if not path.exists():
        pytest.skip(f"real data not found at {path}")
    return pv.read(path)


@pytest.fixture(scope="session")
def closed_bunny(bunny) -> tuple[np.ndarray, np.ndarray]:
    """The bunny scan with its holes filled and every part turned outward: points (V, 3) and faces (F, 3)."""
    from pverosion.kernels.repair.mesh_repair import outward_parts
    from pverosion.meshing import fill_holes

    points, faces = fill_holes(np.asarray(bunny.points, float), bunny.regular_faces)
    return points, outward_parts(points, faces)


def icosphere(radius: float, nsub: int) -> pv.PolyData:
    """Icosphere with float64 points exactly on the sphere."""
    s = pv.Icosphere(radius=1.0, nsub=nsub)
    p = np.asarray(s.points, dtype=np.float64)
    p = radius * p / np.linalg.norm(p, axis=1, keepdims=True)
    return pv.PolyData.from_regular_faces(p, s.regular_faces)


def touching_spheres(nsub: int = 2) -> tuple[pv.PolyData, int]:
    """Two closed unit icospheres side by side that share one vertex and no edge, and that vertex.

    The second is the mirror image of the first through the plane of its
    rightmost vertex, with its faces reversed (still outward); every point
    is used.
    """
    sphere = icosphere(1.0, nsub)
    p, f = np.asarray(sphere.points), sphere.regular_faces
    touch = int(np.argmax(p[:, 0]))
    others = np.delete(np.arange(len(p)), touch)
    index = np.full(len(p), touch)
    index[others] = len(p) + np.arange(len(others))
    mirrored = p[others] * [-1.0, 1.0, 1.0] + [2.0 * p[touch, 0], 0.0, 0.0]
    return pv.PolyData.from_regular_faces(np.vstack([p, mirrored]), np.vstack([f, index[f[:, ::-1]]])), touch


def height_field(fn, *, n: int = 81, half: float = 1.0) -> pv.PolyData:
    """Triangulated graph z = fn(x, y) on a square grid."""
    x = np.linspace(-half, half, n)
    xx, yy = np.meshgrid(x, x, indexing="ij")
    grid = np.stack([xx, yy, fn(xx, yy)], axis=-1)
    from pverosion.examples import periodic_grid_surface

    return periodic_grid_surface(grid, wrap_u=False, wrap_v=False)


def assert_pipeline_keeps_the_error(alg, mesh: pv.PolyData, message: str) -> None:
    """``alg`` given ``mesh`` in a plain VTK pipeline: ``Update()`` fails (VTK's warning muted), the filter keeps an
    ``InvalidMeshError`` matching ``message`` (a regex) in ``last_error``, and the mesh is unchanged."""
    import re

    from vtkmodules.vtkCommonCore import vtkObject

    from pverosion.kernels.validation import InvalidMeshError

    kept_points, kept_faces = np.array(mesh.points), np.array(mesh.faces)
    alg.SetInputDataObject(0, mesh)
    shown = vtkObject.GetGlobalWarningDisplay()
    vtkObject.GlobalWarningDisplayOff()
    try:
        alg.Update()  # the executive reports the failure; the filter keeps the error
    finally:
        vtkObject.SetGlobalWarningDisplay(shown)
    assert isinstance(alg.last_error, InvalidMeshError) and re.search(message, str(alg.last_error))
    np.testing.assert_array_equal(mesh.points, kept_points)
    np.testing.assert_array_equal(mesh.faces, kept_faces)


@numba.njit(parallel=True, cache=True)
def _winding_numbers(samples, points, faces):
    """Van Oosterom and Strackee's solid angles summed over the faces, for every sample point."""
    out = np.empty(samples.shape[0])
    for i in numba.prange(samples.shape[0]):
        total = 0.0
        for f in range(faces.shape[0]):
            u, v, w = faces[f, 0], faces[f, 1], faces[f, 2]
            px, py, pz = samples[i, 0], samples[i, 1], samples[i, 2]
            ax, ay, az = points[u, 0] - px, points[u, 1] - py, points[u, 2] - pz
            bx, by, bz = points[v, 0] - px, points[v, 1] - py, points[v, 2] - pz
            cx, cy, cz = points[w, 0] - px, points[w, 1] - py, points[w, 2] - pz
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            lc = np.sqrt(cx * cx + cy * cy + cz * cz)
            det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
            div = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la
                   + (cx * ax + cy * ay + cz * az) * lb)
            total += 2.0 * np.arctan2(det, div)
        out[i] = total / (4.0 * np.pi)
    return out


def winding_numbers(samples, points, faces):
    """Generalised winding numbers (S,) of a mesh at the sample points (S, 3)."""
    return _winding_numbers(np.ascontiguousarray(samples, dtype=float), np.ascontiguousarray(points, dtype=float),
                            np.ascontiguousarray(faces, dtype=np.int64))
