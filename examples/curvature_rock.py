"""Curvature of a procedural boulder, coloured as in the papers (blue < 0 < red)."""

# %%
import pyvista as pv

import pverosion
from pverosion.examples import load_rock

rock = load_rock(subdivisions=5, seed=3)
out = rock.erosion.curvature(normalization="symmetric")
print(out["mean_curvature_normalized"].min(), out["mean_curvature_normalized"].max())

# %%
plotter = pv.Plotter(off_screen=True)
plotter.add_mesh(out, scalars="mean_curvature_normalized", cmap=pverosion.CURVATURE_CMAP, clim=(-1, 1))
plotter.screenshot("curvature_rock.png")
