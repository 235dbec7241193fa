"""Batch overhead: a 12-job sweep on a 2-worker Dask LocalCluster against the same jobs run serially.

Weathers procedural rocks (three power modifiers x four seeds) with outputs
every 50 steps. Each repeat runs the sweep serially in this process (numba on
all cores) and on a fresh 2-worker LocalCluster (one numba thread per worker),
each into a new folder; cluster start-up and warm-up are timed apart and
excluded from the ratio. Prints JSON; the target is ratio <= 1.1.

Usage: python benchmarks/bench_batch.py [--repeat 3] [--subdivisions 5] [--iterations 100]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from pverosion.batch import parse_scenario, run_batch
from pverosion.batch.job import warm_up

SCENARIO = """
name = "bench"
[input]
example = "rock"
subdivisions = {subdivisions}
[[stages]]
stage = "weather"
iterations = {iterations}
[[stages]]
stage = "curvature"
[sweep]
"weather.power" = [1.0, 2.0, 4.0]
"input.seed" = [1, 2, 3, 4]
[outputs]
save_every = 50
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--subdivisions", type=int, default=5)
    parser.add_argument("--iterations", type=int, default=100)
    args = parser.parse_args()
    scenario = parse_scenario(SCENARIO.format(subdivisions=args.subdivisions, iterations=args.iterations))
    warm_up()
    serial, cluster, startup = [], [], []
    with tempfile.TemporaryDirectory() as folder:
        for k in range(args.repeat):
            start = time.perf_counter()
            report = run_batch(scenario, Path(folder) / f"serial{k}", serial=True, progress=False)
            serial.append(time.perf_counter() - start)
            assert len(report.ran) == 12 and report.failed == 0
            report = run_batch(scenario, Path(folder) / f"cluster{k}", workers=2, progress=False)
            assert len(report.ran) == 12 and report.failed == 0
            cluster.append(report.seconds)
            startup.append(report.seconds_startup)
    ratios = [c / s for c, s in zip(cluster, serial)]
    print(json.dumps({
        "jobs": len(scenario.jobs),
        "rock_vertices": 10 * 4 ** args.subdivisions + 2,
        "iterations": args.iterations,
        "cores": os.cpu_count(),
        "serial_s": [round(t, 3) for t in serial],
        "cluster_2_workers_s": [round(t, 3) for t in cluster],
        "cluster_startup_s": [round(t, 3) for t in startup],
        "ratio": [round(r, 3) for r in ratios],
        "median_ratio": round(statistics.median(ratios), 3),
        "target_ratio": 1.1,
    }, indent=2))


if __name__ == "__main__":
    main()
