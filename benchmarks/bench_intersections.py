"""Intersection detection, repair and Booleans: milliseconds per scene, against manifold3d and VTK in the same run.

Scenes (:mod:`pverosion.scenes.intersection`, the thesis' chapter 10):

- two spheres (Figure 10.11), the rotated cuboids at n = 16 (Figure 10.12),
  the cube and sphere (Figure 10.15): two-mesh unions, timed for pverosion
  (detection alone, and the whole union), manifold3d's union, and VTK's
  ``vtkBooleanOperationPolyDataFilter`` union;
- the self-intersecting tube (Figure 10.14): repair only (the other tools
  take no self-intersecting input);
- the twelve objects (Figure 10.13, six bunnies from ``../shared/data/bunny.ply``
  when present): detection and repair of all of them as one mesh, against
  manifold3d's batch union of the twelve.

Every figure is the median of ``--repeats`` runs after one warm-up run
(numba compilation excluded); a two-mesh union and manifold3d's run
alternately, so that both see the same machine load; VTK runs once per scene, in a child process
stopped after ``--vtk-limit`` seconds (it takes minutes on the larger scenes).
The targets: twelve objects detected and repaired in <= 500 ms; two-mesh
unions within 4x of manifold3d's time.

Usage: ``python benchmarks/bench_intersections.py [--repeats 15] [--scene NAME|all] [--vtk-limit 60] [--load N]``
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import time

import numpy as np
import pyvista as pv
from _load import add_load_option, run

from pverosion.examples import data_path
from pverosion.kernels.exact.intersection_curves import intersection_curves, trace_polylines
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.repair.mesh_repair import boolean_meshes, repair_intersections
from pverosion.scenes.intersection import (
    combine,
    crossed_tube,
    cube_and_sphere,
    rotated_cuboids,
    twelve_objects,
    two_spheres,
)

DATA = data_path()
TWELVE_TARGET_MS = 500.0
UNION_RATIO_TARGET = 4.0


def _median_ms(run, repeats: int) -> float:
    run()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return round(1e3 * float(np.median(times)), 2)


def _paired_median_ms(ours, peer, repeats: int) -> tuple[float, float]:
    """Medians in ms of two callables timed alternately (one warm-up run each), so that a change of
    load during the run reaches both alike."""
    ours()
    peer()
    times = np.empty((repeats, 2))
    for r in range(repeats):
        for column, call in enumerate((ours, peer)):
            start = time.perf_counter()
            call()
            times[r, column] = time.perf_counter() - start
    ms = np.median(times, axis=0) * 1e3
    return round(float(ms[0]), 2), round(float(ms[1]), 2)


def _manifold(mesh: pv.PolyData):
    import manifold3d

    return manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(mesh.points, np.float32),
                                               tri_verts=np.asarray(mesh.regular_faces, np.uint32)))


def _vtk_union(a: pv.PolyData, b: pv.PolyData, queue) -> None:
    from vtkmodules.vtkFiltersGeneral import vtkBooleanOperationPolyDataFilter

    flt = vtkBooleanOperationPolyDataFilter()
    flt.SetOperationToUnion()
    flt.SetInputData(0, a)
    flt.SetInputData(1, b)
    start = time.perf_counter()
    flt.Update()
    elapsed = time.perf_counter() - start
    out = pv.wrap(flt.GetOutput())
    queue.put((round(1e3 * elapsed, 1), float(out.volume) if out.n_cells else float("nan")))


def _vtk_union_ms(a: pv.PolyData, b: pv.PolyData, limit: float) -> tuple[float | str, float | None]:
    """VTK's Boolean union in a child process: milliseconds of one run and the result's volume, or
    ``"over <limit> s"`` when it has not finished by then."""
    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    child = context.Process(target=_vtk_union, args=(pv.PolyData(a), pv.PolyData(b), queue))
    child.start()
    child.join(limit)
    if child.is_alive():
        child.terminate()
        child.join()
        return f"over {limit:g} s", None
    return queue.get()


def two_mesh_union(name: str, a: pv.PolyData, b: pv.PolyData, repeats: int, vtk: float) -> dict:
    points, faces, group = combine([a, b])
    pa, fa, pb, fb = np.asarray(a.points, float), a.regular_faces, np.asarray(b.points, float), b.regular_faces
    result = boolean_meshes(pa, fa, pb, fb, "union")
    figures = {
        "scene": name,
        "faces": len(faces),
        "detection_ms": _median_ms(lambda: intersection_curves(points, faces, group=group), repeats),
        "loops": len(trace_polylines(result.curves)),
        "impossible_cases": result.curves.case_table["impossible"],
        "volume": round(signed_volume(result.points, result.faces), 9),
    }
    try:
        ma, mb = _manifold(a), _manifold(b)
    except ImportError:
        figures["union_ms"] = _median_ms(lambda: boolean_meshes(pa, fa, pb, fb, "union"), repeats)
        figures["manifold3d_union_ms"] = None
    else:
        figures["union_ms"], figures["manifold3d_union_ms"] = _paired_median_ms(
            lambda: boolean_meshes(pa, fa, pb, fb, "union"), lambda: (ma + mb).to_mesh(), repeats)
        figures["manifold3d_volume"] = round((ma + mb).volume(), 9)
        figures["union_ratio"] = round(figures["union_ms"] / figures["manifold3d_union_ms"], 2)
        figures["meets_ratio_target"] = figures["union_ratio"] <= UNION_RATIO_TARGET
    if vtk > 0:
        figures["vtk_union_ms"], figures["vtk_volume"] = _vtk_union_ms(a, b, vtk)
    return figures


def self_intersection(repeats: int) -> dict:
    tube = crossed_tube()
    points, faces = np.asarray(tube.points, float), tube.regular_faces
    result = repair_intersections(points, faces)
    return {
        "scene": "self_intersection",
        "faces": len(faces),
        "detection_ms": _median_ms(lambda: intersection_curves(points, faces), repeats),
        "repair_ms": _median_ms(lambda: repair_intersections(points, faces), repeats),
        "loops": len(trace_polylines(result.curves)),
        "volume_before": round(signed_volume(points, faces), 6),
        "volume_after": round(signed_volume(result.points, result.faces), 6),
    }


def twelve(repeats: int) -> dict:
    bunny = DATA / "bunny.ply"
    objects = twelve_objects(bunny=bunny if bunny.exists() else None)
    points, faces, _ = combine(objects)
    result = repair_intersections(points, faces)
    figures = {
        "scene": "twelve_objects",
        "bunny": bunny.exists(),
        "faces": len(faces),
        "detection_ms": _median_ms(lambda: intersection_curves(points, faces), repeats),
        "detection_and_repair_ms": _median_ms(lambda: repair_intersections(points, faces), repeats),
        "target_ms": TWELVE_TARGET_MS,
        "loops": len(trace_polylines(result.curves)),
        "case_table": result.curves.case_table,
        "output_faces": len(result.faces),
        "volume": round(signed_volume(result.points, result.faces), 6),
        "thesis_ms": {"search": 7631, "fix": 476},
    }
    figures["meets_target"] = figures["detection_and_repair_ms"] <= TWELVE_TARGET_MS
    try:
        import manifold3d

        parts = [_manifold(mesh) for mesh in objects]
        figures["manifold3d_union_ms"] = _median_ms(
            lambda: manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add).to_mesh(), repeats)
        figures["manifold3d_volume"] = round(manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add).volume(),
                                             6)
    except ImportError:
        figures["manifold3d_union_ms"] = None
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--scene", default="all",
                        choices=["all", "two_spheres", "cuboids", "cube_sphere", "self_intersection", "twelve_objects"])
    parser.add_argument("--vtk-limit", type=float, default=60.0,
                        help="seconds VTK's Boolean filter may take per scene (0: skip it)")
    add_load_option(parser)
    args = parser.parse_args()
    scenes = {
        "two_spheres": lambda: two_mesh_union("two_spheres", *two_spheres(), args.repeats, args.vtk_limit),
        "cuboids": lambda: two_mesh_union("cuboids_16", *rotated_cuboids(16), args.repeats, args.vtk_limit),
        "cube_sphere": lambda: two_mesh_union("cube_sphere", *cube_and_sphere(), args.repeats, args.vtk_limit),
        "self_intersection": lambda: self_intersection(args.repeats),
        "twelve_objects": lambda: twelve(args.repeats),
    }
    names = list(scenes) if args.scene == "all" else [args.scene]
    print(json.dumps({name: scenes[name]() for name in names}, indent=2))


if __name__ == "__main__":
    run(main, timings=("two_spheres.union_ms", "cuboids.union_ms", "cube_sphere.union_ms", "self_intersection.repair_ms", "twelve_objects.detection_and_repair_ms"))
