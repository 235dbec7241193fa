"""Material fields on the MR head volume: C-BSP, S-BSP and fitted build, size, agreement, location speed.

Prints one JSON object. Thresholds 40 / 100 / 160 split the 8-bit MR head into four materials
(air and noise | soft tissue | brain | the brightest tissue). Per tree (``c_bsp``: C-BSP of the voxels'
boundary faces, coplanar ones merged, the default of ``method="complete"``; ``c_bsp_isosurface`` and
``s_bsp``: C-BSP and S-BSP inserting the marching-cubes faces as in the thesis; ``fitted``: grown from
the voxels' materials): build time (median of --repeat builds; with --repeat above 1 a warm-up build
keeps numba compilation out), extracted and inserted faces, node count, height, and the tree's size
next to the volume's bytes:

- ``tree_bytes``: the build statistics' count (24 B/node for the isosurface trees as in the thesis;
  the real bytes of the arrays of the compact layout of the voxel C-BSP and of the fitted tree),
- ``in_memory_bytes``: the bytes of the arrays that define the tree as the package holds it,
- ``saved_bytes``: the size of the tree's JSON file,

each also divided by the volume's bytes (``*_to_volume``); then the agreement (%) of the tree's
material with the thresholded voxels at the voxel centres, and the classification rate for 1M
uniformly random points in the volume's box (median of --repeat).

    python benchmarks/bench_materials.py [--volume ../shared/data/HeadMRVolume.mhd] [--repeat 5] [--load N]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from _load import add_load_option, run

import pverosion
from pverosion.examples import data_path
from pverosion.io import read_image

DEFAULT = data_path("HeadMRVolume.mhd")
THRESHOLDS = (40.0, 100.0, 160.0)


def median_time(fn, repeat: int) -> tuple[float, object]:
    result, times = None, []
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--volume", type=Path, default=DEFAULT)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    add_load_option(parser)
    args = parser.parse_args()

    head = read_image(args.volume)
    nx, ny, nz = head.dimensions
    values = np.asarray(head.active_scalars).reshape(nz, ny, nx).transpose(2, 1, 0)
    reference = (values[..., None] > np.array(THRESHOLDS)).sum(axis=-1).transpose(2, 1, 0).ravel()
    centres = np.asarray(head.points)
    bounds = np.asarray(head.bounds).reshape(3, 2)
    rng = np.random.default_rng(args.seed)
    random_points = bounds[:, 0] + rng.random((1_000_000, 3)) * (bounds[:, 1] - bounds[:, 0])

    report = {"benchmark": "materials", "volume": args.volume.name, "dimensions": [nx, ny, nz],
              "thresholds": list(THRESHOLDS), "repeat": args.repeat}
    trees = {"c_bsp": ("complete", "voxels"), "c_bsp_isosurface": ("complete", "isosurface"),
             "s_bsp": ("simplified", "isosurface"), "fitted": ("fitted", None)}
    for key, (method, surface) in trees.items():
        def build(method=method, surface=surface):
            return pverosion.materials_from_volume(head, THRESHOLDS, method=method, surface=surface, seed=args.seed)

        if args.repeat > 1:
            build()  # warm-up
        build_s, field = median_time(build, args.repeat)
        if args.repeat > 1:
            field.sample(random_points)
        locate_s, _ = median_time(lambda field=field: field.sample(random_points), args.repeat)
        stats = field.stats
        with tempfile.TemporaryDirectory() as tmp:
            saved = field.tree.to_json(Path(tmp) / "tree.json").stat().st_size
        report[key] = {
            "build_ms": round(1e3 * build_s, 1),
            "extracted_faces": stats.extracted_faces,
            "inserted_faces": stats.inserted_faces,
            "nodes": stats.nodes,
            "height": stats.height,
            "tree_bytes": stats.tree_bytes,
            "volume_bytes": stats.volume_bytes,
            "in_memory_bytes": field.tree.nbytes,
            "saved_bytes": saved,
            "tree_to_volume": round(stats.tree_bytes / stats.volume_bytes, 3),
            "in_memory_to_volume": round(field.tree.nbytes / stats.volume_bytes, 3),
            "saved_to_volume": round(saved / stats.volume_bytes, 3),
            "agreement_percent": round(100.0 * float(np.mean(field.sample(centres).material_id == reference)), 3),
            "classify_1m_points_s": round(locate_s, 3),
            "points_per_s": round(1e6 / locate_s),
        }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    run(main, timings=("c_bsp.build_ms", "c_bsp.classify_1m_points_s", "c_bsp_isosurface.build_ms", "s_bsp.build_ms"))
