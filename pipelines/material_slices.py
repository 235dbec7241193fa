"""Thesis Figures 11.11–11.13 and 11.18: 2-D slices through material fields.

Writes into <out>:
  slices_sphere.png      a sphere splitting space, constant and gradual hardness (Fig. 11.11)
  slices_surfaces.png    ellipsoid, paraboloid, hyperboloid, cylinder, sin, sinc with gradual hardness (Fig. 11.12)
  slices_tree.png        a BSP tree of three implicit surfaces (Fig. 11.13)
  slices_head_cbsp.png / slices_head_sbsp.png   isosurface BSP trees built from the MR head volume (Fig. 11.18),
                         when ../shared/data/HeadMRVolume.mhd is present (or --volume FILE)

    python pipelines/material_slices.py [-o figures] [--volume FILE] [--thresholds 40,100,160]
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import pverosion
from pverosion.examples import data_path
from pverosion.kernels.materials.bsp import BSPNode, BSPTree
from pverosion.kernels.materials.field import BSPMaterials, Gradual
from pverosion.kernels.materials.surfaces import (
    Cylinder,
    Ellipsoid,
    EllipticHyperboloid,
    Paraboloid,
    Plane,
    SincSurface,
    SinSurface,
    Sphere,
)
from pverosion.plotting import save_figure

HEAD = data_path("HeadMRVolume.mhd")


def middle_slice(field, n=160):
    """Hardness on the y = 0 plane of [-1, 1]^3, shape (n, n) (z up)."""
    image = pverosion.sample_materials(field, dimensions=(n, 1, n), bounds=(-1, 1, 0, 0, -1, 1))
    return np.asarray(image["hardness"]).reshape(n, n)


def panels(fields: dict, path: Path) -> Path:
    fig, axes = plt.subplots(1, len(fields), figsize=(3.2 * len(fields), 3.4), constrained_layout=True)
    for ax, (title, field) in zip(np.atleast_1d(axes), fields.items()):
        ax.imshow(middle_slice(field), origin="lower", cmap="copper_r", extent=(-1, 1, -1, 1))
        ax.set_title(title)
        ax.set_xlabel("x")
        ax.set_ylabel("z")
    return save_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output-dir", type=Path, default=Path("figures"))
    parser.add_argument("--volume", type=Path, default=HEAD if HEAD.exists() else None)
    parser.add_argument("--thresholds", default="40,100,160")
    args = parser.parse_args()
    out = args.output_dir
    out.mkdir(parents=True, exist_ok=True)
    gradual = Gradual(scale=0.25, floor=0.2)
    sphere = Sphere((0.0, 0.0, 0.0), 0.6)
    print(panels({"sphere, constant": BSPMaterials.split(sphere, 0, 1, [4.0, 1.0]),
                  "sphere, gradual": BSPMaterials.split(sphere, 0, 1, [4.0, 2.0], gradual=gradual)},
                 out / "slices_sphere.png"))
    surfaces = {"ellipsoid": Ellipsoid((0, 0, 0), (0.8, 0.5, 0.5)), "paraboloid": Paraboloid((0, 0, -0.6), 0.6, 0.6),
                "hyperboloid": EllipticHyperboloid((0, 0, 0), 0.3, 0.3, 0.5),
                "cylinder": Cylinder((0, 0, 0), (1, 0, 1), 0.4), "sin": SinSurface(0.0, 0.3, 6.0, 1.0),
                "sinc": SincSurface((0.0, 0.0), -0.4, 0.9, 0.35)}
    print(panels({name: BSPMaterials.split(s, 0, 1, [3.0, 1.5], gradual=gradual) for name, s in surfaces.items()},
                 out / "slices_surfaces.png"))
    tree = BSPTree.from_nodes(BSPNode(Plane((0.2, 0.0, 1.0), 0.3),
                                      BSPNode(Sphere((-0.4, 0.0, -0.5), 0.35), 0, 1),
                                      BSPNode(SincSurface((0.4, 0.0), 0.0, 0.5, 0.3), 2, 3)))
    print(panels({"3 implicit surfaces": BSPMaterials(tree, [6.0, 3.0, 2.0, 1.0])}, out / "slices_tree.png"))
    if args.volume is not None:
        from pverosion.io import read_image
        from pverosion.plotting import plot_slices

        head = read_image(args.volume)
        thresholds = [float(t) for t in args.thresholds.split(",")]
        for method in ("complete", "simplified"):
            field = pverosion.materials_from_volume(head, thresholds, method=method, surface="isosurface", seed=0)
            bounds = np.asarray(head.bounds)
            image = pverosion.sample_materials(field, dimensions=(96, 124, 84), bounds=tuple(bounds))
            tag = "cbsp" if method == "complete" else "sbsp"
            plot_slices(image, out / f"slices_head_{tag}.png",
                        title=f"{method} BSP: {field.stats.nodes} nodes, height {field.stats.height}")
            print(out / f"slices_head_{tag}.png")


if __name__ == "__main__":
    main()
