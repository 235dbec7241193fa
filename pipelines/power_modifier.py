"""Skorkovská 2019, Figure 7: influence of the power modifier n on weathering (rows n = 1, 2, 3).

Uses the Stanford bunny scan from ../shared/data/bunny.ply when it is there (or --data FILE),
else a procedural boulder. Writes <out>/power_n<n>.pvd per row (steps 0, 20, 50, 100, 200),
power_modifier.png (rows of renders with the curvature colour coding) and
power_modifier_statistics.png.

    python pipelines/power_modifier.py [-o figures] [--data FILE]
"""

import argparse
from pathlib import Path

from pverosion.examples import data_path, load_rock
from pverosion.io import read_mesh
from pverosion.scenes.weathering import power_modifier

BUNNY = data_path("bunny.ply")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("figures"))
    parser.add_argument("--data", type=Path, default=BUNNY if BUNNY.exists() else None,
                        help="surface to weather (default: the bunny scan if present, else a procedural rock)")
    args = parser.parse_args()
    mesh = read_mesh(args.data) if args.data else load_rock(seed=2)
    runs = power_modifier(mesh, args.output_dir)
    for run in runs:
        eroded = run.statistics["eroded_volume"][-1] / run.statistics["volume"][0]
        print(f"{run.label}: {100 * eroded:5.2f} % of the volume eroded after {run.steps[-1]} steps, "
              f"{run.retries} guard retries")
    print(f"wrote the series and PNGs in {args.output_dir}")


if __name__ == "__main__":
    main()
