"""Intersection repair and Boolean scenes of Skorkovská's thesis, chapter 10: two spheres put together and repaired
into their union (Figure 10.11), the rotated cuboids 2:2:2 and 4:1:1 at growing resolution (Figure 10.12, Table
10.1), a self-intersecting tube (Figure 10.14), the four Booleans of a cube and a sphere (Figure 10.15) and twelve
overlapping objects repaired at once (Figure 10.13).

For each scene: builds the inputs (:mod:`pverosion.scenes.intersection`), finds the intersection curves, repairs
them or does the Booleans (:mod:`pverosion.kernels.repair.mesh_repair`) and writes under <out>/:

- <scene>_input.vtp: the input(s) put together, cell data ``source_mesh`` (which object a face comes from);
- <scene>_curves.vtp: the intersection curves as VTK polylines;
- <scene>.vtp: the result, with the arrays of the ``pverosion.repair`` / ``pverosion.boolean`` filters
  (``on_intersection``, ``source_face``, ``source_mesh``, the case table in field data); the cuboids write
  cuboids_16*.vtp (n = 16), the Booleans booleans_<operation>.vtp;
- <scene>.png: input | curves (blue dots) over the input | result, coloured by source object, and below the same
  cut open by a plane facing the camera (the walls inside that the repair removes); the self-intersection colours
  the input's intersecting faces and the result's pieces and shows the crossing close up; booleans.png shows the
  four results side by side.

and prints a JSON line of figures: faces, curve loops (traced polylines), the thesis' case table (the ten cases,
``valid`` and ``impossible``), output faces, volume, whether the output is closed (no open edges); the cuboids one
row per n with the union volume and its relative error to the exact 10; the twelve objects the detection and
repair times (ms, after a warm-up call so that numba compilation is excluded; the repair time includes its own
detection). The bunny is used when ../shared/data has it, rocks stand in otherwise.

    python pipelines/intersection_scenes.py [-o intersection_scenes]
        [--scene two_spheres|cuboids|self_intersection|booleans|twelve_objects|all] [--quick]
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pyvista as pv
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from vtkmodules.vtkCommonDataModel import vtkPolyData

from pverosion.examples import data_path
from pverosion.filters.repair import repair_output
from pverosion.io import write_atomic
from pverosion.kernels.exact.intersection_curves import (
    IntersectionCurves,
    intersection_curves,
    trace_polylines,
    unique_rows,
)
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.mesh.topology import boundary_edges
from pverosion.kernels.repair.mesh_repair import OPERATIONS, RepairResult, boolean_meshes, repair_intersections
from pverosion.plotting import render_strip
from pverosion.scenes.intersection import (
    combine,
    crossed_tube,
    cube_and_sphere,
    rotated_cuboids,
    twelve_objects,
    two_spheres,
)

DATA = data_path()
BUNNY = DATA / "bunny.ply"
EXACT_UNION = 10.0  # the cuboids 2 x 2 x 2 and 4 x 1 x 1 through it
CMAP = "Set3"  # twelve distinct light colours; the curves are drawn as saturated blue dots over them


# --- meshes and figures ------------------------------------------------------------------------------------------


def _polydata(points: np.ndarray, faces: np.ndarray, **cell_data) -> pv.PolyData:
    mesh = pv.PolyData.from_regular_faces(np.asarray(points, dtype=np.float64), np.asarray(faces, dtype=np.int64))
    for name, values in cell_data.items():
        mesh.cell_data[name] = values
    return mesh


def _input_mesh(meshes: list[pv.PolyData]) -> tuple[pv.PolyData, np.ndarray, np.ndarray]:
    """The meshes put together (cell data ``source_mesh``), their points and faces."""
    points, faces, group = combine(meshes)
    return _polydata(points, faces, source_mesh=group.astype(np.int32)), points, faces


def _result_mesh(result: RepairResult, sources: list[pv.PolyData]) -> pv.PolyData:
    """The result with the arrays the repair / Boolean filters give it."""
    out = vtkPolyData()
    repair_output(result, sources, out)
    return pv.wrap(out)


def _curve_lines(curves: IntersectionCurves) -> pv.PolyData:
    """The traced intersection curves as VTK polylines (a closed one repeats its first point)."""
    lines = trace_polylines(curves)
    cells = np.concatenate([np.r_[len(line), line] for line in lines]) if lines else np.zeros(0, np.int64)
    return pv.PolyData(np.asarray(curves.points, dtype=np.float64), lines=cells.astype(np.int64))


def _curve_dots(curves: IntersectionCurves, per_segment: int = 6) -> pv.PolyData:
    """Points along every intersection segment, to draw the curves as dotted lines over a mesh."""
    segments = unique_rows(np.sort(curves.segments, axis=1))[0] if len(curves.segments) else np.zeros((0, 2), int)
    t = np.linspace(0.0, 1.0, per_segment, endpoint=False)[None, :, None]
    a, b = curves.points[segments[:, 0]][:, None], curves.points[segments[:, 1]][:, None]
    return pv.PolyData((a + t * (b - a)).reshape(-1, 3))


def _coloured(mesh: pv.PolyData, values) -> pv.PolyData:
    """A copy of ``mesh`` with cell data ``colour`` (what the PNG panels are coloured by)."""
    shown = pv.PolyData(mesh.points, faces=mesh.faces)
    shown.cell_data["colour"] = np.asarray(values, dtype=np.float64)
    return shown


def _creased(mesh: pv.PolyData) -> pv.PolyData:
    """``mesh`` with its vertices split along sharp edges (the intersection creases), so that the smooth shading
    of :func:`render_strip` does not smear them (done last: clipping merges the split vertices again)."""
    return mesh.compute_normals(split_vertices=True, feature_angle=30.0, auto_orient_normals=False,
                                consistent_normals=False)


def _open_edges(faces: np.ndarray, n_points: int) -> int:
    return len(boundary_edges(np.asarray(faces, dtype=np.int64), n_points))


def _pieces(faces: np.ndarray, n_points: int) -> np.ndarray:
    """Connected component of every face (faces sharing a vertex are connected)."""
    faces = np.asarray(faces, dtype=np.int64)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_points, n_points))
    return connected_components(graph, directed=False)[1][faces[:, 0]]


def _figures(result: RepairResult) -> dict:
    """Loops, case table, output faces, volume, closed and pieces of a repair or Boolean result."""
    n_open = _open_edges(result.faces, len(result.points))
    pieces = _pieces(result.faces, len(result.points)) if len(result.faces) else np.zeros(0, np.int64)
    return {
        "loops": len(result.polylines), "segments": len(result.curves.segments),
        "cases": result.curves.case_table, "touching": result.curves.touching,
        "coplanar": len(result.curves.coplanar), "faces_out": len(result.faces),
        "volume": float(signed_volume(result.points, result.faces, origin=np.zeros(3))),
        "closed": n_open == 0, "open_edges": n_open, "pieces": len(np.unique(pieces)),
    }


def _strip(out: Path, name: str, shown: pv.PolyData, curves: IntersectionCurves, result: pv.PolyData,
           labels: list[str], crop: tuple | None = None) -> Path:
    """input | curves over the input | result, all coloured by their ``colour`` cell data; below, the same cut
    open by a plane through the curves' centre facing the camera (the near half removed), inside ``crop`` bounds
    if given, to show the walls inside that the repair removes."""
    dots = _curve_dots(curves)
    region = crop if crop is not None else shown.bounds
    centre = (curves.points.mean(axis=0) if crop is None and len(curves.points)
              else 0.5 * (np.array(region[::2]) + np.array(region[1::2])))
    normal = np.ones(3) / np.sqrt(3.0)  # towards the isometric camera

    def cut(mesh: pv.PolyData) -> pv.PolyData:
        if crop is not None:
            mesh = mesh.clip_box(crop, invert=False).extract_surface(algorithm="dataset_surface")
        return mesh.clip(normal=normal, origin=centre).extract_surface(algorithm="dataset_surface")

    far = pv.PolyData(dots.points[(dots.points - centre) @ normal <= 0.0])
    if crop is not None:
        lo, hi = np.array(crop[::2]), np.array(crop[1::2])
        far = pv.PolyData(far.points[((far.points >= lo) & (far.points <= hi)).all(axis=1)])
    rows = [[_creased(m) for m in row] for row in ([shown, shown, result], [cut(shown), cut(shown), cut(result)])]
    cut_labels = ["input, cut open", "curves, cut open", "result, cut open"]
    return render_strip(rows, out / f"{name}.png", labels=[labels, cut_labels], scalars="colour", cmap=CMAP,
                        particles=[[None, dots, None], [None, far, None]], panel_size=(400, 400))


def _write_scene(out: Path, stem: str, source: pv.PolyData, curves: IntersectionCurves,
                 mesh: pv.PolyData) -> list[Path]:
    """Write <stem>_input.vtp, <stem>_curves.vtp and <stem>.vtp (atomically); their paths."""
    return [write_atomic(source, out / f"{stem}_input.vtp"),
            write_atomic(_curve_lines(curves), out / f"{stem}_curves.vtp"),
            write_atomic(mesh, out / f"{stem}.vtp")]


def _repair_scene(name: str, out: Path, meshes: list[pv.PolyData], input_colour=None, labels=None,
                  crop=None) -> dict:
    """Put ``meshes`` together, repair, write <name>_input / _curves / .vtp and the PNG strip (``labels``: three
    format strings, filled with the input ``faces`` and the figures of :func:`_figures`)."""
    source, points, faces = _input_mesh(meshes)
    start = time.perf_counter()
    result = repair_intersections(points, faces)
    seconds = time.perf_counter() - start
    mesh = _result_mesh(result, [source])
    paths = _write_scene(out, name, source, result.curves, mesh)
    figures = _figures(result)
    colour = source["source_mesh"] if input_colour is None else input_colour(result)
    result_colour = mesh["source_mesh"] if len(meshes) > 1 else _pieces(result.faces, len(result.points))
    labels = [label.format(faces=len(faces), **figures) for label in labels or
              ["input: {faces} faces", "curve loops: {loops}", "repaired: {faces_out} faces"]]
    paths.append(_strip(out, name, _coloured(source, colour), result.curves, _coloured(mesh, result_colour),
                        labels, crop=crop))
    return {"scene": name, "objects": len(meshes), "faces": len(faces), **figures,
            "seconds": round(seconds, 3), "files": [str(p) for p in paths]}


# --- scenes ------------------------------------------------------------------------------------------------------


def scene_two_spheres(out: Path, quick: bool) -> dict:
    """Figure 10.11: two spheres put together, repaired into their union."""
    a, b = two_spheres()
    figures = _repair_scene("two_spheres", out, [a, b])
    figures["volumes_in"] = [float(signed_volume(np.asarray(m.points, float), m.regular_faces, origin=np.zeros(3)))
                             for m in (a, b)]
    # Figure 10.11e: the optional mesh improvement of the slivers along the curve
    source, points, faces = _input_mesh([a, b])
    plain, improved = (repair_intersections(points, faces, improve=flag) for flag in (False, True))
    path = write_atomic(_result_mesh(improved, [source]), out / "two_spheres_improved.vtp")
    figures["improved"] = {
        "faces_out": len(improved.faces), "closed": _open_edges(improved.faces, len(improved.points)) == 0,
        "volume": float(signed_volume(improved.points, improved.faces, origin=np.zeros(3))),
        "largest_angle_before": round(_largest_angle(plain), 2), "largest_angle_after": round(_largest_angle(improved), 2),
        "shortest_edge_before": _shortest_edge(plain), "shortest_edge_after": _shortest_edge(improved),
        "file": str(path),
    }
    return figures


def _shortest_edge(result: RepairResult) -> float:
    t = result.points[result.faces]
    return float(np.linalg.norm(t - np.roll(t, 1, axis=1), axis=2).min())


def _largest_angle(result: RepairResult) -> float:
    """Largest angle of any face (degrees)."""
    t = result.points[result.faces]
    cos = [np.einsum("ij,ij->i", t[:, (k + 1) % 3] - t[:, k], t[:, (k + 2) % 3] - t[:, k])
           / np.linalg.norm(t[:, (k + 1) % 3] - t[:, k], axis=1) / np.linalg.norm(t[:, (k + 2) % 3] - t[:, k], axis=1)
           for k in range(3)]
    return float(np.degrees(np.arccos(np.clip(np.min(cos), -1.0, 1.0))))


def scene_cuboids(out: Path, quick: bool) -> dict:
    """Figure 10.12 and Table 10.1: unions of the rotated cuboids, intersecting along mesh edges."""
    rows, paths = [], []
    for n in (4, 8, 16) if quick else (4, 8, 16, 32, 64):
        a, b = rotated_cuboids(n)
        start = time.perf_counter()
        result = boolean_meshes(a.points, a.regular_faces, b.points, b.regular_faces, "union")
        seconds = time.perf_counter() - start
        figures = _figures(result)
        rows.append({"n": n, "faces": a.n_cells + b.n_cells, **figures,
                     "relative_error": float(f"{abs(figures['volume'] - EXACT_UNION) / EXACT_UNION:.3g}"),
                     "seconds": round(seconds, 3)})
        if n == 16:
            source, _, _ = _input_mesh([a, b])
            mesh = _result_mesh(result, [a, b])
            paths += _write_scene(out, "cuboids_16", source, result.curves, mesh)
            paths.append(_strip(out, "cuboids", _coloured(source, source["source_mesh"]), result.curves,
                                _coloured(mesh, mesh["source_mesh"]),
                                [f"n = 16: {a.n_cells + b.n_cells} faces", f"curve loops: {figures['loops']}",
                                 f"union: volume {figures['volume']:.6f}"]))
    return {"scene": "cuboids", "exact_volume": EXACT_UNION, "rows": rows, "files": [str(p) for p in paths]}


def scene_self_intersection(out: Path, quick: bool) -> dict:
    """Figure 10.14: a closed tube passing through itself, repaired."""
    tube = crossed_tube()

    def intersecting(result: RepairResult) -> np.ndarray:
        colour = np.zeros(tube.n_cells)
        colour[result.curves.faces()] = 1.0
        return colour

    figures = _repair_scene("self_intersection", out, [tube], input_colour=intersecting,
                            labels=["input: faces crossing", "curve loops: {loops}", "repaired, pieces: {pieces}"],
                            crop=(-0.45, 0.45, -0.45, 0.45, -0.4, 0.4))  # the crossing
    figures["volume_in"] = float(signed_volume(np.asarray(tube.points, float), tube.regular_faces,
                                               origin=np.zeros(3)))
    return figures


def scene_booleans(out: Path, quick: bool) -> dict:
    """Figure 10.15: union, intersection and both differences of a cube and a sphere."""
    a, b = cube_and_sphere()
    source, _, _ = _input_mesh([a, b])
    paths = [write_atomic(source, out / "booleans_input.vtp")]
    results, shown, labels = {}, [], []
    for operation in OPERATIONS:
        start = time.perf_counter()
        result = boolean_meshes(a.points, a.regular_faces, b.points, b.regular_faces, operation)
        seconds = time.perf_counter() - start
        if not results:
            paths.append(write_atomic(_curve_lines(result.curves), out / "booleans_curves.vtp"))
        mesh = _result_mesh(result, [a, b])
        paths.append(write_atomic(mesh, out / f"booleans_{operation}.vtp"))
        figures = _figures(result)
        results[operation] = {key: figures[key] for key in ("faces_out", "volume", "closed", "pieces")}
        results[operation]["seconds"] = round(seconds, 3)
        shown.append(_creased(_coloured(mesh, mesh["source_mesh"])))
        labels.append(f"{operation.replace('_', ' ')}: {figures['volume']:.4f}")
    paths.append(render_strip([shown], out / "booleans.png", labels=[labels], scalars="colour", cmap=CMAP,
                              panel_size=(420, 420)))
    return {"scene": "booleans", "faces": [a.n_cells, b.n_cells], "loops": figures["loops"],
            "cases": figures["cases"], **results, "files": [str(p) for p in paths]}


def scene_twelve_objects(out: Path, quick: bool) -> dict:
    """Figure 10.13: six bunnies and six other shapes overlapping, repaired at once (timed)."""
    meshes = twelve_objects(bunny=BUNNY if BUNNY.exists() else None)
    source, points, faces = _input_mesh(meshes)
    intersection_curves(points, faces)  # warm-up: numba compilation and caches out of the timings
    repair_intersections(points, faces)
    start = time.perf_counter()
    intersection_curves(points, faces)
    detection = time.perf_counter() - start
    start = time.perf_counter()
    result = repair_intersections(points, faces)
    repair = time.perf_counter() - start
    mesh = _result_mesh(result, [source])
    figures = _figures(result)
    paths = _write_scene(out, "twelve_objects", source, result.curves, mesh)
    paths.append(_strip(out, "twelve_objects", _coloured(source, source["source_mesh"]), result.curves,
                        _coloured(mesh, mesh["source_mesh"]),
                        [f"twelve objects: {len(faces)} faces", f"curve loops: {figures['loops']}",
                         f"repaired: {figures['faces_out']} faces"]))
    return {"scene": "twelve_objects", "bunny": BUNNY.exists(), "objects": len(meshes), "faces": len(faces),
            **figures, "detection_ms": round(1e3 * detection, 1), "repair_ms": round(1e3 * repair, 1),
            "files": [str(p) for p in paths]}


SCENES = {
    "two_spheres": scene_two_spheres,
    "cuboids": scene_cuboids,
    "self_intersection": scene_self_intersection,
    "booleans": scene_booleans,
    "twelve_objects": scene_twelve_objects,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("intersection_scenes"))
    parser.add_argument("--scene", choices=[*SCENES, "all"], default="all")
    parser.add_argument("--quick", action="store_true", help="cuboids up to n = 16 only, for a quick look")
    args = parser.parse_args()
    args.output_dir.mkdir(parents=True, exist_ok=True)
    for name in SCENES if args.scene == "all" else [args.scene]:
        print(json.dumps(SCENES[name](args.output_dir, args.quick)), flush=True)


if __name__ == "__main__":
    main()
