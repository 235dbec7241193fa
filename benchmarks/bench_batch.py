"""Batch overhead: a 12-job sweep on a 2-worker Dask LocalCluster against the same jobs run serially.

Runs pipelines/batch_rocks.toml: four procedural rocks (10,242 vertices) x three
power modifiers, 150 weathering steps, curvature, outputs every 50 steps. Each
repeat runs the sweep serially in this process (numba on all cores) and on a
fresh 2-worker LocalCluster (one numba thread per worker), each into a new
folder; cluster start-up and warm-up are timed apart and excluded from the ratio. Prints JSON; the target is ratio <= 1.1.

Usage: python benchmarks/bench_batch.py [--repeat 3] [--load N]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from _load import add_load_option, run

from pverosion.batch import load_scenario, run_batch
from pverosion.batch.job import warm_up

SCENARIO = Path(__file__).resolve().parents[1] / "pipelines" / "batch_rocks.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    add_load_option(parser)
    args = parser.parse_args()
    scenario = load_scenario(SCENARIO)
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
        "scenario": SCENARIO.name,
        "cores": os.cpu_count(),
        "serial_s": [round(t, 3) for t in serial],
        "cluster_2_workers_s": [round(t, 3) for t in cluster],
        "cluster_startup_s": [round(t, 3) for t in startup],
        "ratio": [round(r, 3) for r in ratios],
        "median_ratio": round(statistics.median(ratios), 3),
        "target_ratio": 1.1,
    }, indent=2))


if __name__ == "__main__":
    run(main, timings=("serial_s", "cluster_2_workers_s"))
