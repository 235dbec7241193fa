"""Freeze–thaw speed on a cone like Hill3D (Mateos et al. Table 1): shard generation and ms per water path.

For 100, 1k, 5k and 10k cells from uniform random seeds inside the cone:
generation time (Voronoi cells clipped to the mesh plus both graphs, median
of ``--repeat`` runs after a warm-up) and the mean time per water path
including detachment (1000 paths, run ``--repeat`` times from the same
fresh graph as in the paper, median of the runs), next to the paper's
figures. Targets: <= 1.0 s generation for 10k cells, <= 0.1 ms per path,
and per-path time growing by <= 2x from 1k to 10k cells.

Then the same on a large non-convex model: 10k cells from uniform random
seeds inside the bunny (holes filled, Loop-subdivided to about 100k faces),
against SciPy's (Qhull's) unclipped Voronoi diagram of the same seeds, timed
alternately in the same run (median of ``--repeat``). Target: <= 2x SciPy.
Prints JSON.

Usage: python benchmarks/bench_shards.py [--repeat 5] [--paths 1000] [--statue-faces 100000] [--load N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from _load import add_load_option, run
from bench_scale import DEFAULT as BUNNY
from bench_scale import subdivided_bunny
from scipy.spatial import Voronoi

from pverosion.filters.base import polydata_triangles
from pverosion.kernels.shards.freeze_thaw import FreezeThawSimulation
from pverosion.kernels.shards.graph import build_shards
from pverosion.kernels.shards.seed_patterns import inside_mesh, uniform_seeds
from pverosion.scenes.shards import hill_cone

PAPER = {  # cells: (interior links, exterior links, generation s, ms per path)
    100: (504, 123, 0.015, 0.245),
    1000: (5236, 433, 0.141, 0.461),
    5000: (18201, 1407, 1.281, 1.265),
    10000: (32535, 2493, 2.469, 2.202),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--paths", type=int, default=1000)
    parser.add_argument("--statue-faces", type=int, default=100_000)
    add_load_option(parser)
    args = parser.parse_args()
    points, faces = polydata_triangles(hill_cone())
    inside = inside_mesh(points, faces)
    bounds = (points.min(axis=0), points.max(axis=0))
    warm = build_shards(uniform_seeds(200, bounds=bounds, inside=inside, seed=1), points, faces)
    FreezeThawSimulation(warm, seed=1).run(100)
    rows = []
    for cells, (p_int, p_ext, p_gen, p_path) in PAPER.items():
        seeds = uniform_seeds(cells, bounds=bounds, inside=inside, seed=0)
        gen = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            graph = build_shards(seeds, points, faces)
            gen.append(time.perf_counter() - start)
        per_path = []
        detached = []
        for k in range(args.repeat):
            sim = FreezeThawSimulation(graph, seed=k)
            start = time.perf_counter()
            sim.run(args.paths)
            per_path.append((time.perf_counter() - start) / args.paths)
            detached.append(int(graph.n_cells - sim.solid.sum()))
        rows.append({
            "cells": graph.n_cells, "interior_links": int((graph.link_cells[:, 1] >= 0).sum()),
            "exterior_links": int(graph.exterior.sum()), "generation_s": round(statistics.median(gen), 3),
            "ms_per_path": round(1000 * statistics.median(per_path), 4),
            "cells_detached_per_run": statistics.median(detached),
            "paper": {"interior_links": p_int, "exterior_links": p_ext, "generation_s": p_gen, "ms_per_path": p_path},
        })
    by_cells = {row["cells"]: row for row in rows}
    growth = by_cells[10000]["ms_per_path"] / by_cells[1000]["ms_per_path"]
    print(json.dumps({"mesh_triangles": len(faces), "paths_per_run": args.paths, "runs": args.repeat,
                      "results": rows, "path_time_growth_1k_to_10k": round(growth, 2),
                      "statue": statue(args.statue_faces, args.repeat),
                      "targets": {"generation_s_10k": 1.0, "ms_per_path": 0.1, "growth_1k_to_10k": 2.0,
                                  "statue_vs_scipy": 2.0}}, indent=2))


def statue(n_faces: int, repeat: int, cells: int = 10_000) -> dict:
    """10k cells clipped to the subdivided bunny, and SciPy's unclipped Voronoi of the same seeds, alternately."""
    points, faces = polydata_triangles(subdivided_bunny(BUNNY, n_faces))
    inside = inside_mesh(points, faces)
    seeds = uniform_seeds(cells, bounds=(points.min(axis=0), points.max(axis=0)), inside=inside, seed=0)
    build_shards(seeds[:200], points, faces)
    ours, scipy = [], []
    for _ in range(repeat):
        start = time.perf_counter()
        graph = build_shards(seeds, points, faces)
        ours.append(time.perf_counter() - start)
        start = time.perf_counter()
        Voronoi(seeds)
        scipy.append(time.perf_counter() - start)
    return {"mesh_triangles": len(faces), "cells": graph.n_cells, "links": graph.n_links,
            "generation_s": round(statistics.median(ours), 3), "scipy_voronoi_s": round(statistics.median(scipy), 3),
            "ratio_vs_scipy": round(statistics.median(ours) / statistics.median(scipy), 2)}


if __name__ == "__main__":
    run(main, timings=("results.0.generation_s", "results.0.ms_per_path", "results.-1.generation_s",
                       "statue.generation_s"))
