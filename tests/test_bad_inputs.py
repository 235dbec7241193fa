"""Bad input never passes silently: every front end refuses it with a message naming the problem.

Each case runs a CLI subcommand (in this process, so a traceback would fail the
test) and, where one exists, the matching Python function, and checks: a
non-zero exit, the message, the input files unchanged, and no output or hidden
leftover in the folder. The memory limit is fixed at 1 GiB so that the
absurd-size cases are refused the same way on any machine.
"""

from __future__ import annotations

import errno
import hashlib
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
from conftest import assert_pipeline_keeps_the_error, icosphere, touching_spheres

import pverosion
from pverosion.batch import ScenarioError, run_batch
from pverosion.cli import main
from pverosion.filters.base import output_times
from pverosion.io import read_mesh, write_atomic
from pverosion.kernels.validation import InvalidMeshError
from pverosion.limits import ResourceLimitError, check_memory, memory_limit

ROOT = Path(__file__).resolve().parents[1]
EMITTER = "0,0,2,0,0,-1,0.3,200"
TOUCH = touching_spheres()[1]
"""The vertex where the two spheres of :func:`touching_spheres` touch."""


@pytest.fixture(autouse=True)
def _limits(monkeypatch):
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "1G")
    monkeypatch.delenv("PVEROSION_WORK_LIMIT", raising=False)


def _sphere() -> pv.PolyData:
    return pv.Sphere(theta_resolution=12, phi_resolution=12)


def _grid() -> pv.ImageData:
    from pverosion.scenes.voxel import spring_grid

    return spring_grid(shape=(12, 10, 10))


def _files(folder: Path) -> dict[str, str]:
    """Every file and folder under ``folder`` (hidden ones included) with the checksum of each file."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(folder.rglob("*"))}


@pytest.fixture
def inputs(tmp_path) -> Path:
    """A folder of good and bad input files."""
    _sphere().save(tmp_path / "sphere.vtp")
    open_mesh = _sphere().remove_cells([0, 1, 2])
    open_mesh.save(tmp_path / "open.vtp")
    nan = _sphere()
    nan.points[3] = np.nan
    nan.save(tmp_path / "nan.vtp")
    inf = _sphere()
    inf.points[5, 1] = np.inf
    inf.save(tmp_path / "inf.vtp")
    pv.Plane(i_resolution=3, j_resolution=3).save(tmp_path / "quads.vtp")
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]])
    pv.PolyData.from_regular_faces(points, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])).save(tmp_path / "fan.vtp")
    _grid().save(tmp_path / "grid.vti")
    flat = _grid()
    flat.spacing = (2.0, 1.0, 1.0)
    flat.save(tmp_path / "flat.vti")
    pv.ImageData().save(tmp_path / "empty.vti")
    (tmp_path / "zero.vtp").write_bytes(b"")
    (tmp_path / "garbage.ply").write_bytes(np.random.default_rng(0).bytes(2000))
    (tmp_path / "folder.vtp").mkdir()
    ramp = pv.ImageData(dimensions=(6, 6, 6))
    ramp["value"] = np.linspace(0.0, 1.0, ramp.n_points)
    ramp.save(tmp_path / "ramp.vti")
    (tmp_path / "garbage.json").write_bytes(np.random.default_rng(1).bytes(300))
    for name, binary in (("cut.ply", True), ("cut_text.ply", False)):  # a PLY file cut off in its data
        _sphere().save(tmp_path / name, binary=binary)
        data = (tmp_path / name).read_bytes()
        (tmp_path / name).write_bytes(data[:len(data) * 3 // 10])
    faces = _sphere().regular_faces
    degenerate = faces.copy()
    degenerate[:4, 2] = degenerate[:4, 1]
    pv.PolyData.from_regular_faces(_sphere().points, degenerate).save(tmp_path / "degenerate.vtp")
    pv.PolyData.from_regular_faces(_sphere().points, np.vstack([faces, faces[:3, ::-1]])).save(
        tmp_path / "duplicate.vtp")
    pv.PolyData.from_regular_faces(_sphere().points * [1.0, 1.0, 0.0], faces).save(tmp_path / "flat.vtp")
    pv.PolyData.from_regular_faces(np.zeros_like(_sphere().points), faces).save(tmp_path / "collapsed.vtp")
    flat_face = np.array(_sphere().points, dtype=np.float64)
    flat_face[faces[7, 2]] = 0.5 * (flat_face[faces[7, 0]] + flat_face[faces[7, 1]])  # face 7 without area
    pv.PolyData.from_regular_faces(flat_face, faces).save(tmp_path / "flat_face.vtp")
    tangled = np.array(_sphere().points, dtype=np.float64)
    tangled += np.random.default_rng(2).normal(scale=0.15, size=tangled.shape)  # about an edge: faces cross
    pv.PolyData.from_regular_faces(tangled, faces).save(tmp_path / "tangled.vtp")
    pv.Plane(i_resolution=4, j_resolution=4).triangulate().save(tmp_path / "sheet.vtp")
    soup = _sphere().points[faces].reshape(-1, 3)  # every triangle with its own three points, as an STL file holds them
    pv.PolyData.from_regular_faces(soup, np.arange(len(soup)).reshape(-1, 3)).save(tmp_path / "soup.vtp")
    (tmp_path / "other.json").write_text('{"format": "something else"}')
    touching = touching_spheres()[0]
    touching.save(tmp_path / "touching.vtp")
    apart = np.flatnonzero(~(touching.regular_faces == TOUCH).any(axis=1))[0]  # a face away from the touching point
    pv.PolyData.from_regular_faces(touching.points, np.delete(touching.regular_faces, apart, axis=0)).save(
        tmp_path / "touching_open.vtp")
    return tmp_path


# (CLI arguments, expected message (regex), Python call or None)
CASES = {
    "missing file": (["weather", "missing.vtp", "-o", "out.vtp"], r"no such file", None),
    "empty file": (["weather", "zero.vtp", "-o", "out.vtp"], r"zero.vtp is empty", None),
    "garbage file": (["curvature", "garbage.ply", "-o", "out.vtp"], r"garbage.ply", None),
    "truncated binary PLY": (["curvature", "cut.ply", "-o", "out.vtp"], r"cut.ply: the file is truncated",
                             lambda d: read_mesh(d / "cut.ply")),
    "truncated text PLY": (["weather", "cut_text.ply", "-o", "out.vtp"], r"cut_text.ply: the file is truncated",
                           lambda d: read_mesh(d / "cut_text.ply")),
    "degenerate faces, weather": (["weather", "degenerate.vtp", "-o", "out.vtp"],
                                  r"4 degenerate faces that use a vertex twice",
                                  lambda d: pverosion.weather(pv.read(d / "degenerate.vtp"))),
    "duplicate faces, repair": (["repair", "duplicate.vtp", "-o", "out.vtp"],
                                r"3 faces that repeat the vertices of another face",
                                lambda d: pverosion.repair(pv.read(d / "duplicate.vtp"))),
    "open mesh, shards": (["shard-graph", "open.vtp", "-o", "out.vtm", "--cells", "5"],
                          r"must be closed: it has \d+ boundary edges",
                          lambda d: pverosion.shard_graph(pv.read(d / "open.vtp"), cells=5)),
    "face of zero area, shards": (["shard-graph", "flat_face.vtp", "-o", "out.vtm", "--cells", "5"],
                                  r"faces of zero area, whose corners lie on a line \(first faces: \[7",
                                  lambda d: pverosion.shard_graph(pv.read(d / "flat_face.vtp"), cells=5)),
    "face of zero area, freeze-thaw": (["freeze-thaw", "flat_face.vtp", "-o", "out.vtm", "--cells", "5"],
                                       r"faces of zero area",
                                       lambda d: pverosion.freeze_thaw(pv.read(d / "flat_face.vtp"), cells=5)),
    "self-intersecting mesh, shards": (["shard-graph", "tangled.vtp", "-o", "out.vtm", "--cells", "5"],
                                       r"mesh intersects itself: \d+ faces meet faces they share no vertex with .*"
                                       r"pverosion repair",
                                       lambda d: pverosion.shard_graph(pv.read(d / "tangled.vtp"), cells=5)),
    "self-intersecting mesh, freeze-thaw": (["freeze-thaw", "tangled.vtp", "-o", "out.vtm", "--cells", "5"],
                                            r"mesh intersects itself",
                                            lambda d: pverosion.freeze_thaw(pv.read(d / "tangled.vtp"), cells=5)),
    "open sheet with close_holes": (["hydraulic", "sheet.vtp", "-o", "out.vtm", "--emitter", EMITTER,
                                     "--close-holes"],
                                    r"closing the input's \d+ boundary edges did not give a closed surface to erode "
                                    r"\(.*\): an open sheet has no inside",
                                    lambda d: pverosion.hydraulic_erosion(pv.read(d / "sheet.vtp"), emitter=EMITTER,
                                                                          close_holes=True)),
    "voxels that are not cubes": (["voxel", "flat.vti", "-o", "out.vtm"],
                                  r"needs cubic voxels; the grid's spacing is \(2\.0, 1\.0, 1\.0\)$",
                                  lambda d: pverosion.voxel_erosion(pv.read(d / "flat.vti"))),
    "zero slab thickness": (["shard-graph", "sphere.vtp", "-o", "out.vtm", "--pattern", "slabs", "--layers", "1,0"],
                            r"--layers must be positive thicknesses",
                            lambda d: pverosion.shard_graph(_sphere(), pattern="slabs", layers=(1.0, 0.0))),
    "core window of negative radius": (["freeze-thaw", "sphere.vtp", "-o", "out.vtm", "--core-window", "0,0,0,-1"],
                                       r"--core-window needs a positive radius",
                                       lambda d: pverosion.freeze_thaw(_sphere(), core_window=(0, 0, 0, -1))),
    "demo into a file": (["demo", "-o", "sphere.vtp"], r"-o sphere.vtp/cube_to_sphere.pvd: sphere.vtp is not a folder",
                         None),
    "output onto the input": (["curvature", "sphere.vtp", "-o", "sphere.vtp"], r"names the input file", None),
    "output onto input B": (["boolean", "grid.vti", "sphere.vtp", "-o", "./sphere.vtp"], r"names the input B", None),
    "image to a mesh stage": (["weather", "grid.vti", "-o", "out.vtp"], r"holds an image .*not a surface", None),
    "mesh to a volume stage": (["voxel", "sphere.vtp", "-o", "out.vtm"], r"not an image|needs an ImageData",
                               lambda d: pverosion.voxel_erosion(pv.read(d / "sphere.vtp"))),
    "empty image to sample-materials": (["sample-materials", "empty.vti", "-o", "out.vti", "--tree-file", "t.json"],
                                        r"the grid is empty", None),
    "empty image to voxel": (["voxel", "empty.vti", "-o", "out.vtm"], r"the voxel grid is empty",
                             lambda d: pverosion.voxel_erosion(pv.read(d / "empty.vti"))),
    "NaN points, weather": (["weather", "nan.vtp", "-o", "out.vtp"], r"NaN or infinite coordinates at 1 vertices",
                            lambda d: pverosion.weather(pv.read(d / "nan.vtp"))),
    "inf points, hydraulic": (["hydraulic", "inf.vtp", "-o", "out.vtm", "--emitter", EMITTER],
                              r"NaN or infinite coordinates",
                              lambda d: pverosion.hydraulic_erosion(pv.read(d / "inf.vtp"), emitter=EMITTER)),
    "NaN points, shards": (["shard-graph", "nan.vtp", "-o", "out.vtm"], r"NaN or infinite coordinates",
                           lambda d: pverosion.shard_graph(pv.read(d / "nan.vtp"))),
    "non-triangles": (["curvature", "quads.vtp", "-o", "out.vtp"], r"not triangles",
                      lambda d: pverosion.curvature(pv.read(d / "quads.vtp"))),
    "non-manifold": (["weather", "fan.vtp", "-o", "out.vtp"], r"non-manifold edges",
                     lambda d: pverosion.weather(pv.read(d / "fan.vtp"))),
    "non-manifold vertex, weather": (["weather", "touching.vtp", "-o", "out.vtp"],
                                     (rf"1 non-manifold vertex \(.*the first is vertex {TOUCH}\): repair it first "
                                      r"\(pverosion repair"),
                                     lambda d: pverosion.weather(pv.read(d / "touching.vtp"), iterations=2)),
    "non-manifold vertex, hydraulic": (["hydraulic", "touching.vtp", "-o", "out.vtm", "--emitter", EMITTER],
                                       rf"1 non-manifold vertex \(.*the first is vertex {TOUCH}\)",
                                       lambda d: pverosion.hydraulic_erosion(pv.read(d / "touching.vtp"),
                                                                             emitter=EMITTER)),
    "non-manifold vertex of an open mesh": (["weather", "touching_open.vtp", "-o", "out.vtp"],
                                            (rf"1 non-manifold vertex \(.*vertex {TOUCH}\): split each into one "
                                             r"vertex per fan first \(pverosion repair does so for a closed mesh only"),
                                            lambda d: pverosion.weather(pv.read(d / "touching_open.vtp"))),
    "collapsed mesh, curvature": (["curvature", "collapsed.vtp", "-o", "out.vtp"], r"mesh has no area",
                                  lambda d: pverosion.curvature(pv.read(d / "collapsed.vtp"))),
    "triangle soup, curvature": (["curvature", "soup.vtp", "-o", "out.vtp"], r"share a vertex.*mesh\.clean\(\)",
                                 lambda d: pverosion.curvature(pv.read(d / "soup.vtp"))),
    "triangle soup, weather": (["weather", "soup.vtp", "-o", "out.vtp"], r"unwelded triangle soup",
                               lambda d: pverosion.weather(pv.read(d / "soup.vtp"), iterations=2)),
    "triangle soup, shards": (["shard-graph", "soup.vtp", "-o", "out.vtm"], r"unwelded triangle soup",
                              lambda d: pverosion.shard_graph(pv.read(d / "soup.vtp"), cells=10)),
    "open mesh, hydraulic": (["hydraulic", "open.vtp", "-o", "out.vtm", "--emitter", EMITTER],
                             r"needs a closed mesh.*--close-holes",
                             lambda d: pverosion.hydraulic_erosion(pv.read(d / "open.vtp"), emitter=EMITTER)),
    "NaN option": (["weather", "sphere.vtp", "-o", "out.vtp", "--power", "nan"], r"--power must be finite",
                   lambda d: pverosion.weather(_sphere(), power=float("nan"))),
    "inf option": (["voxel", "grid.vti", "-o", "out.vtm", "--time-step", "inf"], r"--time-step must be finite",
                   lambda d: pverosion.voxel_erosion(_grid(), time_step=float("inf"))),
    "negative option": (["weather", "sphere.vtp", "-o", "out.vtp", "--iterations", "-1"], r"--iterations must be >= 0",
                        lambda d: pverosion.weather(_sphere(), iterations=-1)),
    "step divisor that inverts the mesh": (["weather", "sphere.vtp", "-o", "out.vtp", "--step-divisor", "0.1"],
                                           r"--step-divisor must be >= 1",
                                           lambda d: pverosion.weather(_sphere(), step_divisor=0.1)),
    "NaN vector component": (["voxel", "grid.vti", "-o", "out.vtm", "--source-velocity", "1,nan,0"],
                             r"--source-velocity must be finite",
                             lambda d: pverosion.voxel_erosion(_grid(), source_velocity=(1.0, float("nan"), 0.0))),
    "short vector": (["hydraulic", "sphere.vtp", "-o", "out.vtm", "--emitter", EMITTER, "--gravity", "0,0"],
                     r"--gravity needs 3 numbers", None),
    "malformed emitter": (["hydraulic", "sphere.vtp", "-o", "out.vtm", "--emitter", "1,2"], r"8 or 9 numbers",
                          lambda d: pverosion.hydraulic_erosion(_sphere(), emitter="1,2")),
    "bad output extension": (["weather", "sphere.vtp", "-o", "out.yi8"], r"-o out.yi8: .*got '.yi8'", None),
    "output is a folder": (["weather", "sphere.vtp", "-o", "folder.vtp"], r"is a folder", None),
    "output under a file": (["weather", "sphere.vtp", "-o", "sphere.vtp/out.vtp"], r"is not a folder", None),
    "MultiBlock to .vtp": (["hydraulic", "sphere.vtp", "-o", "out.vtp", "--emitter", EMITTER],
                           r"MultiBlockDataSet result is written as .vtm", None),
    "series not .pvd": (["weather", "sphere.vtp", "-o", "out.vtp", "--save-every", "1", "--series", "s.txt"],
                        r"a time series is a .pvd file", None),
    "absurd iterations": (["weather", "sphere.vtp", "-o", "out.vtp", "--iterations", "1000000000"],
                          r"--iterations: the list of 1000000001 time steps would need about 22.4 GiB",
                          lambda d: pverosion.weather(_sphere(), iterations=10**9)),
    "absurd hydraulic time step": (["hydraulic", "sphere.vtp", "-o", "out.vtm", "--iterations", "3", "--emitter",
                                    EMITTER, "--time-step", "1e6"], r"--time-step: a substep of 5e\+05 s", None),
    "absurd substeps": (["hydraulic", "sphere.vtp", "-o", "out.vtm", "--emitter", EMITTER, "--substeps", "1000000000"],
                        r"--substeps: 1000000000 substeps", None),
    "absurd max particles": (["hydraulic", "sphere.vtp", "-o", "out.vtm", "--emitter", EMITTER, "--max-particles",
                              "1000000000"], r"--max-particles: a fluid of up to 1000000000 particles", None),
    "absurd voxel time step": (["voxel", "grid.vti", "-o", "out.vtm", "--iterations", "2", "--time-step", "1e9"],
                               r"--time-step: a time step of 1e\+09 s",
                               lambda d: pverosion.voxel_erosion(_grid(), iterations=2, time_step=1e9)),
    "absurd viscosity": (["voxel", "grid.vti", "-o", "out.vtm", "--viscosity", "1e9"], r"--viscosity: viscosity 1e\+09",
                         None),
    "absurd source velocity": (["voxel", "grid.vti", "-o", "out.vtm", "--source-velocity", "1e9,0,0"],
                               r"--source-velocity: a time step", None),
    "absurd cells": (["shard-graph", "sphere.vtp", "-o", "out.vtm", "--cells", "1000000000"],
                     r"--cells: a graph of 1000000000 shards would need",
                     lambda d: pverosion.shard_graph(_sphere(), cells=10**9)),
    "absurd paths per step": (["freeze-thaw", "sphere.vtp", "-o", "out.vtm", "--cells", "20", "--iterations", "1",
                               "--paths-per-step", "1000000000000"], r"--paths-per-step: 1000000000000 water paths",
                              None),
    # materials, sample-materials, repair, boolean
    "mesh to materials": (["materials", "sphere.vtp", "-o", "out.vti", "--thresholds", "0.5"],
                          r"sphere.vtp holds a PolyData, not an image", None),
    "image without scalars to materials": (["materials", "empty.vti", "-o", "out.vti", "--thresholds", "0.5"],
                                           r"no point scalars", None),
    "no such array": (["materials", "ramp.vti", "-o", "out.vti", "--thresholds", "0.5", "--array", "nosuch"],
                      r"no point array 'nosuch'",
                      lambda d: pverosion.materials_from_volume(pv.read(d / "ramp.vti"), [0.5], array="nosuch")),
    "NaN threshold": (["materials", "ramp.vti", "-o", "out.vti", "--thresholds", "nan"],
                      r"--thresholds must be finite", None),
    "threshold outside the values": (["materials", "ramp.vti", "-o", "out.vti", "--thresholds", "5"],
                                     r"thresholds must lie strictly inside the value range",
                                     lambda d: pverosion.materials_from_volume(pv.read(d / "ramp.vti"), [5.0])),
    "equal thresholds": (["materials", "ramp.vti", "-o", "out.vti", "--thresholds", "0.5,0.5"],
                         r"thresholds must be one or more distinct numbers",
                         lambda d: pverosion.materials_from_volume(pv.read(d / "ramp.vti"), [0.5, 0.5])),
    "NaN hardness": (["materials", "ramp.vti", "-o", "out.vti", "--thresholds", "0.5", "--hardness", "1,nan"],
                     r"--hardness must be finite", None),
    "more hardness values than materials": (["materials", "ramp.vti", "-o", "out.vti", "--thresholds", "0.5",
                                             "--hardness", "1,2,3"],
                                            r"hardness needs one value per material: 1 thresholds make 2 materials; "
                                            r"got 3 values",
                                            lambda d: pverosion.materials_from_volume(pv.read(d / "ramp.vti"), [0.5],
                                                                                      hardness=[1.0, 2.0, 3.0])),
    "image result to .vtp": (["materials", "ramp.vti", "-o", "out.vtp", "--thresholds", "0.5"],
                             r"-o out.vtp: an ImageData result is written as .vti", None),
    "missing tree file": (["sample-materials", "grid.vti", "-o", "out.vti", "--tree-file", "missing.json"],
                          r"no such file: missing.json", None),
    "garbage tree file": (["sample-materials", "grid.vti", "-o", "out.vti", "--tree-file", "garbage.json"],
                          r"garbage.json is not a pverosion BSP file", None),
    "foreign tree file": (["sample-materials", "grid.vti", "-o", "out.vti", "--tree-file", "other.json"],
                          r"other.json is not a pverosion BSP file", None),
    "image to repair": (["repair", "grid.vti", "-o", "out.vtp"], r"holds an image .*not a surface", None),
    "NaN points, repair": (["repair", "nan.vtp", "-o", "out.vtp"], r"NaN or infinite coordinates at 1 vertices",
                           lambda d: pverosion.repair(pv.read(d / "nan.vtp"))),
    "non-triangles, repair": (["repair", "quads.vtp", "-o", "out.vtp"], r"not triangles",
                              lambda d: pverosion.repair(pv.read(d / "quads.vtp"))),
    "open mesh, repair": (["repair", "open.vtp", "-o", "out.vtp"], r"must be closed",
                          lambda d: pverosion.repair(pv.read(d / "open.vtp"))),
    "negative tolerance": (["repair", "sphere.vtp", "-o", "out.vtp", "--tolerance", "-1"], r"--tolerance must be >= 0",
                           lambda d: pverosion.repair(_sphere(), tolerance=-1.0)),
    "missing second mesh": (["boolean", "sphere.vtp", "missing.vtp", "-o", "out.vtp"], r"no such file: missing.vtp",
                            None),
    "flat closed mesh, repair": (["repair", "flat.vtp", "-o", "out.vtp"], r"encloses no volume",
                                 lambda d: pverosion.repair(pv.read(d / "flat.vtp"))),
    "flat closed mesh B": (["boolean", "sphere.vtp", "flat.vtp", "-o", "out.vtp"], r"mesh B encloses no volume",
                           lambda d: pverosion.boolean(_sphere(), pv.read(d / "flat.vtp"))),
    "non-manifold mesh B": (["boolean", "sphere.vtp", "fan.vtp", "-o", "out.vtp"], r"mesh B must be closed",
                            lambda d: pverosion.boolean(_sphere(), pv.read(d / "fan.vtp"))),
    "NaN points, mesh B": (["boolean", "sphere.vtp", "nan.vtp", "-o", "out.vtp"], r"mesh B: .*NaN or infinite",
                           lambda d: pverosion.boolean(_sphere(), pv.read(d / "nan.vtp"))),
    "infinite tolerance": (["boolean", "sphere.vtp", "sphere.vtp", "-o", "out.vtp", "--tolerance", "inf"],
                           r"--tolerance must be finite",
                           lambda d: pverosion.boolean(_sphere(), _sphere(), tolerance=float("inf"))),
}


@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_cli_refuses_bad_input_and_leaves_no_trace(case, inputs, capsys):
    argv, message, _ = CASES[case]
    before = _files(inputs)
    cwd = os.getcwd()
    os.chdir(inputs)
    try:
        status = main(argv)
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err
    assert status == 2, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"pverosion {argv[0]}: error: "), err
    import re

    assert re.search(message, last), last
    assert _files(inputs) == before  # inputs unchanged, no output, no hidden leftovers


@pytest.mark.filterwarnings("ignore:The VTK reader")  # VTK's note on the inf file's array range
@pytest.mark.parametrize("case", [c for c in CASES if CASES[c][2] is not None],
                         ids=[c for c in CASES if CASES[c][2] is not None])
def test_python_function_refuses_the_same_input(case, inputs):
    argv, message, call = CASES[case]
    before = _files(inputs)
    plain = message.replace("--", "").replace("-", "[-_]")  # the Python spelling of the option names
    with pytest.raises((ValueError, TypeError)) as info:
        call(inputs)
    import re

    assert re.search(plain, str(info.value)), str(info.value)
    assert _files(inputs) == before


def test_absurd_sizes_are_refused_before_anything_is_allocated(monkeypatch):
    # the estimate alone decides: far beyond any memory, the request never reaches an allocation
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "0")
    assert memory_limit() == float("inf")
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "2G")
    assert memory_limit() == 2 * 1024**3
    with pytest.raises(ResourceLimitError, match=r"cells: the graph would need about 3.0 GiB.*PVEROSION_MEMORY_LIMIT"):
        check_memory(3 * 1024**3, option="cells", what="the graph")
    check_memory(1024**3, option="cells", what="the graph")
    with pytest.raises(ResourceLimitError, match="inf PiB"):  # an estimate beyond a float is still refused
        check_memory(10**400, option="cells", what="the graph")
    with pytest.raises(ValueError, match="PVEROSION_MEMORY_LIMIT must be a number of bytes"):
        monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "lots")
        memory_limit()


@pytest.mark.parametrize("value, error, message", [
    (float("inf"), ValueError, "iterations must be finite; got inf"),
    (float("nan"), ValueError, "iterations must be finite; got nan"),
    (2**63 - 1, ResourceLimitError, "iterations: the list of 9223372036854775808 time steps"),  # exact, not rounded
    (2**63, ValueError, "iterations must be a 64-bit integer"),
    (10**400, ValueError, "iterations must be a 64-bit integer"),
    (2.5, TypeError, "iterations must be an integer; got 2.5"),
], ids=["inf", "nan", "2**63-1", "2**63", "10**400", "2.5"])
def test_non_finite_and_huge_counts_are_named(value, error, message):
    """inf/NaN/a count beyond 64 bits each get the option's name, not an OverflowError or a wrong 'not an integer'."""
    with pytest.raises(error, match=re.escape(message)):
        pverosion.weather(pv.Sphere(), iterations=value)


def test_output_times_are_lazy():
    steps = output_times(10**12, 1)
    assert len(steps) == 10**12 + 1 and steps[-1] == 10**12
    assert list(output_times(10, 4)) == [0, 4, 8, 10]
    assert list(output_times(8, 4)) == [0, 4, 8]
    assert list(output_times(7, None)) == [7]


def test_open_mesh_is_closed_on_request(inputs):
    mesh = pv.read(inputs / "open.vtp")
    with pytest.raises(InvalidMeshError, match="close_holes=True"):
        pverosion.hydraulic_erosion(mesh, emitter=EMITTER, iterations=0)
    result = pverosion.hydraulic_erosion(mesh, emitter=EMITTER, iterations=0, close_holes=True)
    closed = result["mesh"]
    assert closed.n_cells > mesh.n_cells
    assert closed.extract_feature_edges(boundary_edges=True, feature_edges=False, manifold_edges=False,
                                        non_manifold_edges=False).n_cells == 0


def test_a_run_that_emits_nothing_warns(inputs):
    with pytest.warns(UserWarning, match=r"no particle was emitted in 2 iterations"):
        pverosion.hydraulic_erosion(_sphere(), emitter="0,0,2,0,0,-1,0.3,0.001", iterations=2)


# --- the error path of the VTK pipeline ----------------------------------------------------------------------


def test_an_error_in_request_information_reaches_the_caller_and_nothing_is_written(tmp_path):
    from pverosion.filters.weathering import Weathering

    alg = Weathering(iterations=10**9)
    with pytest.raises(ResourceLimitError, match="iterations"):
        alg.run(_sphere())
    assert isinstance(alg.last_error, ResourceLimitError)  # kept for the ParaView layer
    alg.SetIterations(2)
    out = pv.wrap(alg.run(_sphere()))  # the filter recovers once the option is fixed
    assert out.n_points == _sphere().n_points and alg.last_error is None


@pytest.mark.parametrize("stage", ["Weathering", "HydraulicErosion"])
def test_a_non_manifold_vertex_is_refused_in_a_vtk_pipeline(stage):
    from pverosion import filters

    touching = touching_spheres()[0]
    message = rf"1 non-manifold vertex \(.*the first is vertex {TOUCH}\): repair it first"
    alg = getattr(filters, stage)(iterations=2, **({"emitter": EMITTER} if stage == "HydraulicErosion" else {}))
    with pytest.raises(InvalidMeshError, match=message):
        alg.run(touching)
    assert_pipeline_keeps_the_error(alg, touching, message)


def _fin() -> tuple[np.ndarray, np.ndarray]:
    """Three triangles on one edge."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]])
    return points, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])


@pytest.mark.parametrize("solver", ["WeatheringSolver", "HydraulicSolver"])
def test_the_solvers_called_from_python_refuse_what_their_filters_refuse(solver):
    from pverosion.kernels.fluid.params import FluidParameters
    from pverosion.kernels.hydraulic.erosion import HydraulicSolver
    from pverosion.kernels.weathering.model import WeatheringSolver

    make = {"WeatheringSolver": WeatheringSolver,
            "HydraulicSolver": lambda p, f: HydraulicSolver(p, f, fluid=FluidParameters(radius=0.05))}[solver]
    touching = touching_spheres()[0]
    sphere = icosphere(1.0, 2)
    repeated = np.vstack([sphere.regular_faces, sphere.regular_faces[[7]]])
    cases = [((touching.points, touching.regular_faces), rf"1 non-manifold vertex .*vertex {TOUCH}\): repair it"),
             (_fin(), r"1 non-manifold edges .*repair it first"),
             ((sphere.points, repeated), r"1 faces that repeat the vertices of another face \(first copies: \[320\]"),
             ((sphere.points, np.vstack([sphere.regular_faces, [[3, 3, 5]]])), r"1 degenerate faces that use a vertex")]
    for (points, faces), message in cases:
        with pytest.raises(InvalidMeshError, match=message):
            make(np.asarray(points, float), faces)


# the two spheres still touch where the split vertices coincide: the guard takes that contact for the input's
# own, not for a self-intersection (a warning, and a baseline that would let steps push those faces through)
@pytest.mark.filterwarnings("error:the input mesh already has")
def test_the_repair_named_for_a_non_manifold_vertex_splits_it_and_weathering_then_runs():
    from pverosion.kernels.mesh.topology import vertex_fan_counts

    touching = touching_spheres()[0]
    with pytest.raises(InvalidMeshError, match=r"repair it first \(pverosion repair, or pverosion.repair"):
        pverosion.weather(touching, iterations=2)
    repaired = pverosion.repair(touching)
    assert repaired.n_points == touching.n_points + 1 and repaired.n_cells == touching.n_cells
    assert np.all(vertex_fan_counts(repaired.regular_faces, repaired.n_points) == 1)
    out = pverosion.weather(repaired, iterations=2)
    assert out.n_points == repaired.n_points and np.all(np.isfinite(out["mean_curvature"]))


def test_manifold_surfaces_closed_and_open_are_accepted_with_one_fan_per_vertex():
    from pverosion.kernels.mesh.topology import boundary_vertices, vertex_fan_counts

    sphere = pv.Icosphere(nsub=2)
    holes = pv.PolyData.from_regular_faces(sphere.points, np.delete(sphere.regular_faces, [0, 40, 200], axis=0))
    for mesh in (sphere, holes):
        assert np.all(vertex_fan_counts(mesh.regular_faces, mesh.n_points) == 1)
        out = pverosion.weather(mesh, iterations=2)
        assert out.n_points == mesh.n_points
    assert boundary_vertices(holes.regular_faces, holes.n_points).sum() == 9  # three holes of three vertices each
    hydraulic = pverosion.hydraulic_erosion(sphere, emitter=EMITTER, iterations=2)
    assert hydraulic["mesh"].n_cells == sphere.n_cells


def test_keyboard_interrupt_inside_a_pass_is_reraised(monkeypatch):
    from pverosion.filters.weathering import Weathering

    alg = Weathering(iterations=3)

    def interrupted(self, info):
        raise KeyboardInterrupt

    monkeypatch.setattr(Weathering, "information", interrupted)
    with pytest.raises(KeyboardInterrupt):
        alg.run(_sphere())


# --- outputs ----------------------------------------------------------------------------------------------------


def test_vtm_blocks_are_named_after_the_output_and_replaced(tmp_path):
    blocks = pv.MultiBlock({"a": pv.Sphere(), "b": pv.Cube()})
    old = os.umask(0o022)
    try:
        write_atomic(blocks, tmp_path / "out.vtm")
        write_atomic(pv.MultiBlock({"a": pv.Cube()}), tmp_path / "out.vtm")
    finally:
        os.umask(old)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.vtm", "out_blocks"]
    assert sorted(p.name for p in (tmp_path / "out_blocks").iterdir()) == ["out_0.vtp"]
    again = pv.read(tmp_path / "out.vtm")
    assert again.n_blocks == 1 and again[0].n_cells == 6
    assert (tmp_path / "out.vtm").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "out_blocks" / "out_0.vtp").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "out_blocks").stat().st_mode & 0o777 == 0o755


def test_files_honour_the_umask(tmp_path):
    old = os.umask(0o027)
    try:
        write_atomic(pv.Sphere(), tmp_path / "a.vtp")
    finally:
        os.umask(old)
    assert (tmp_path / "a.vtp").stat().st_mode & 0o777 == 0o640


# --- Ctrl-C --------------------------------------------------------------------------------------------------


def _pvd_entries(path: Path) -> int:
    try:
        return path.read_text().count("<DataSet ")
    except OSError:
        return 0


@pytest.mark.parametrize("after_steps", [1, 3])
def test_ctrl_c_stops_a_series_run_cleanly(tmp_path, after_steps):
    pv.Sphere(theta_resolution=60, phi_resolution=60).save(tmp_path / "ball.vtp")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    command = [sys.executable, "-m", "pverosion", "weather", "ball.vtp", "-o", "out.vtp", "--iterations", "1000000",
               "--save-every", "2", "--series", "s.pvd", "--check-every", "0"]
    proc = subprocess.Popen(command, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 600
        while _pvd_entries(tmp_path / "s.pvd") < after_steps and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not (tmp_path / "out.vtp").exists()
    reader = pv.get_reader(tmp_path / "s.pvd")
    assert len(reader.time_values) >= after_steps
    for t in reader.time_values:  # every listed step is complete
        reader.set_active_time_value(t)
        step = reader.read()[0]
        assert step.n_cells > 6000 and {"mean_curvature", "displacement"} <= set(step.point_data.keys())
    listed = {f"s/s_{k:06d}.vtp" for k in range(len(reader.time_values))}
    on_disk = {str(p.relative_to(tmp_path)) for p in (tmp_path / "s").iterdir()}
    assert on_disk == listed  # no temporary or unlisted step files
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ball.vtp", "s", "s.pvd"]


# --- batch ---------------------------------------------------------------------------------------------------


def _scenario(folder: Path, text: str, name: str = "scenario.toml") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('name = "../../evil"\n[input]\nexample = "rock"\n[[stages]]\nstage = "curvature"\n',
         r"name: must be a plain name"),
        ('[input]\nexample = "rock"\nsubdivisions = -3\n[[stages]]\nstage = "curvature"\n',
         r"\[input\] example 'rock': subdivisions must be >= 0"),
        ('[input]\nexample = "rock"\nsubdivisions = 30\n[[stages]]\nstage = "curvature"\n',
         r"subdivisions must be <= 8"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "hydraulic"\nemitter = "0,0,2,0,0,-1,0.3,200"\n[sweep]\n'
         '"hydraulic.emitter" = ["0,0,2,0,0,-1,0.3,200", "0,0,2"]\n', r"emitter = '0,0,2'.*8 or 9 numbers"),
        ('[input]\nexample = "rock"\n[[stages]]\nstage = "weather"\n[sweep]\n'
         + "".join(f'"weather.power" = [{", ".join(str(1.0 + k) for k in range(40))}]\n'.replace("power", p)
                   for p in ("power", "step_divisor", "min_edge_ratio"))
         + '"seed" = [' + ", ".join(str(k) for k in range(60)) + "]\n",
         r"40 x 40 x 40 x 60 = 3840000 jobs, more than the limit of 100000"),
    ],
    ids=["path escape", "negative subdivisions", "huge subdivisions", "late emitter", "huge sweep"],
)
def test_bad_batch_fails_before_any_job_runs(tmp_path, text, message):
    path = _scenario(tmp_path, text)
    start = time.perf_counter()
    with pytest.raises(ScenarioError, match=message):
        run_batch(path, tmp_path / "out", serial=True, progress=False)
    assert time.perf_counter() - start < 60  # validated in O(size), long before any job
    assert not (tmp_path / "out").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scenario.toml"]


def test_a_folder_holds_one_scenario(tmp_path):
    pv.Sphere().save(tmp_path / "ball.vtp")
    first = _scenario(tmp_path, '[input]\nfile = "ball.vtp"\n[[stages]]\nstage = "curvature"\n', "a.toml")
    second = _scenario(tmp_path, '[input]\nfile = "ball.vtp"\n[[stages]]\nstage = "curvature"\n'
                                 'normalization = "shifted"\n', "b.toml")
    run_batch(first, tmp_path / "out", serial=True, progress=False)
    before = _files(tmp_path / "out")
    with pytest.raises(ScenarioError, match="holds the results of another scenario"):
        run_batch(second, tmp_path / "out", serial=True, progress=False)
    assert _files(tmp_path / "out") == before
    # the same scenario, re-laid out with a comment, resumes
    _scenario(tmp_path, "# again\n" + first.read_text(), "a.toml")
    assert run_batch(first, tmp_path / "out", serial=True, progress=False).skipped == 1


@pytest.mark.parametrize("options", [["-o", "locked/out.vtp"], ["-o", "out.vtp", "--screenshot", "locked/shot.png"]],
                         ids=["output", "screenshot"])
def test_a_folder_that_takes_no_new_file_is_refused_before_the_run(options, inputs, monkeypatch, capsys):
    """A folder where no file can be made (read-only file system; permission bits do not bind root) is found
    by trying, before any work: nothing is written, not even the output when only the screenshot is refused."""
    import tempfile

    (inputs / "locked").mkdir()
    real = tempfile.mkstemp

    def mkstemp(*args, dir=None, **kwargs):
        if dir is not None and Path(dir).resolve() == (inputs / "locked").resolve():
            raise OSError(errno.EROFS, "Read-only file system")
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    before = _files(inputs)
    monkeypatch.chdir(inputs)
    status = main(["curvature", "sphere.vtp", *options])
    err = capsys.readouterr().err
    assert status == 2, err
    assert re.search(r"error: --?\w+ locked/\w+\.\w+: cannot write in locked \(Read-only file system\)", err), err
    assert _files(inputs) == before


def test_cli_messages_use_cli_syntax():
    from pverosion.cli import _cli_message
    from pverosion.filters import HydraulicErosion, RepairIntersections

    assert _cli_message("faces point inwards (use orientation='outward' or reverse them)", RepairIntersections) \
        == "faces point inwards (use --orientation outward or reverse them)"
    assert _cli_message("the input has holes: set close_holes=True to close them", HydraulicErosion) \
        == "the input has holes: set --close-holes to close them"
    assert _cli_message("time_step: a substep of 5 s; lower time_step", HydraulicErosion) \
        == "--time-step: a substep of 5 s; lower --time-step"
    assert _cli_message("iterations must be >= 0; the particle radius is 0", HydraulicErosion) \
        == "--iterations must be >= 0; the particle radius is 0"  # 'radius' in prose stays a word


def test_a_run_whose_water_drains_at_once_warns():
    with pytest.warns(UserWarning, match=r"all \d+ emitted particles were drained or left the domain .* at once"):
        pverosion.hydraulic_erosion(_sphere(), emitter=EMITTER, drain="box:-1,-1,1.5,1,1,2.5", iterations=3)


def test_a_run_whose_water_never_reaches_the_mesh_warns_and_one_that_erodes_does_not():
    with pytest.warns(UserWarning, match=r"the water eroded nothing in 2 iterations \(\d+ particles emitted\): none "
                                         r"reached the mesh"):
        out = pverosion.hydraulic_erosion(_sphere(), emitter="0,0,5,0,0,-1,0.3,200", iterations=2)
    assert not out["mesh"]["displacement"].any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = pverosion.hydraulic_erosion(_sphere(), emitter="0,0,0.9,0,0,-1,0.3,400", iterations=8)
    assert out["mesh"]["displacement"].any()


@pytest.mark.parametrize("rate", ["1e5", "1e12"])
def test_a_rate_without_a_speed_that_sends_the_water_out_of_the_domain_is_refused(rate):
    """Without a speed the rate sets it: 1e5 particles/s from a disc of 9 lattice points leave at about 2000 per
    second, far past the domain in one step; the run drained every particle at once and blamed the emitter's
    place (1e12 ran for minutes first)."""
    shown = re.escape(f"{float(rate):g}")
    with pytest.raises(ValueError, match=rf"emitter 0: rate {shown} particles/s without a speed sends the particles "
                                         r"off at .* farther than the domain is wide"):
        pverosion.hydraulic_erosion(_sphere(), emitter=f"0,0,0.9,0,0,-1,0.3,{rate}", iterations=3)


def test_a_voxel_run_that_ends_without_material_warns_that_its_surface_is_empty():
    empty = _grid()
    empty.point_data["material_amount"] = np.zeros(empty.n_points)
    with pytest.warns(UserWarning, match=r"after 1 iterations no voxel's material_amount reaches 0.5.*the surface "
                                         r"is empty"):
        out = pverosion.voxel_erosion(empty, iterations=1)
    assert out["surface"].n_points == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert pverosion.voxel_erosion(_grid(), iterations=1)["surface"].n_points > 0


def test_a_grid_too_large_for_memory_is_refused(monkeypatch):
    monkeypatch.setenv("PVEROSION_MEMORY_LIMIT", "100K")
    with pytest.raises(ResourceLimitError, match=r"input grid: the solver of 1200 voxels .* use coarser voxels"):
        pverosion.voxel_erosion(_grid(), iterations=1)


def test_absurd_paths_per_step_are_refused_before_the_graph_is_built(monkeypatch):
    # building the graph (and compiling its kernels on a first run) can take minutes: the estimate comes first
    from pverosion.filters import shards

    def never(*args, **kwargs):
        raise AssertionError("the shard graph was built before the request was checked")

    monkeypatch.setattr(shards, "build_shards", never)
    with pytest.raises(ResourceLimitError, match=r"paths_per_step: 1000000000000 water paths"):
        shards.FreezeThaw(cells=20, iterations=1, paths_per_step=10**12).run(_sphere())
