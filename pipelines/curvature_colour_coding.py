"""Skorkovská 2019, Figure 2: mean-curvature colour coding, on procedural shapes.

Writes <out>/curvature_<shape>.vtp and .png for a boulder, a torus and a cylinder.

    python pipelines/curvature_colour_coding.py [-o figures]
"""

import argparse
from pathlib import Path

import pverosion
from pverosion.examples import load_cylinder, load_rock, load_torus
from pverosion.io import write_atomic
from pverosion.plotting import render_scalars


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("figures"))
    args = parser.parse_args()
    shapes = {"rock": load_rock(seed=1), "torus": load_torus(), "cylinder": load_cylinder()}
    for name, mesh in shapes.items():
        out = pverosion.curvature(mesh, normalization="symmetric")
        write_atomic(out, args.output_dir / f"curvature_{name}.vtp")
        render_scalars(out, args.output_dir / f"curvature_{name}.png", scalars="mean_curvature_normalized")
        print(f"{name}: H in [{out['mean_curvature'].min():.3f}, {out['mean_curvature'].max():.3f}]")


if __name__ == "__main__":
    main()
