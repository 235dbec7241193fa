"""Batch example: weather four procedural rocks with three power modifiers on Dask (12 jobs).

Runs pipelines/batch_rocks.toml (a local cluster, or --scheduler ADDRESS), then renders the
final rocks in one figure (rows: power n = 1, 2, 3; columns: rock seeds) and prints the
volume lost per job. Re-running resumes: completed jobs are skipped.

    python pipelines/batch_rocks.py [-o batch_rocks] [--workers 2] [--scheduler tcp://host:8786]
"""

import argparse
from pathlib import Path

import pyvista as pv

from pverosion.batch import load_scenario, run_batch
from pverosion.plotting import render_strip

SCENARIO = Path(__file__).with_name("batch_rocks.toml")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("batch_rocks"))
    parser.add_argument("--workers", type=int, help="local cluster workers (default: one per core)")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler")
    args = parser.parse_args()
    scenario = load_scenario(SCENARIO)
    report = run_batch(scenario, args.output_dir, workers=args.workers, scheduler=args.scheduler)
    print(f"{len(report.ran)} jobs ran, {report.skipped} were already done, {report.failed} failed "
          f"({report.seconds:.1f} s on {report.workers} workers)")
    powers = sorted({row["weather.power"] for row in report.rows})
    rows, labels = [], []
    for power in powers:
        done = [row for row in report.rows if row["weather.power"] == power and row["status"] == "done"]
        rows.append([pv.read(args.output_dir / "jobs" / row["folder"] / "final.vtp") for row in done])
        labels.append([f"n = {power:g}, rock {row['input.seed']}" for row in done])
        for row in done:
            print(f"  n = {power:g}, rock {row['input.seed']}: volume {100 * row['volume_change']:+6.2f} %, "
                  f"mean |H| {row['mean_curvature_abs_mean']:.3f}")
    figure = render_strip(rows, args.output_dir / "batch_rocks.png", labels=labels)
    print(f"wrote {figure} and {args.output_dir / 'results.csv'}")


if __name__ == "__main__":
    main()
