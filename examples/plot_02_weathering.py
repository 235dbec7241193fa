"""
Weather a rock
==============

Curvature-driven weathering moves every convex vertex inward by ``H^n * e_avg / x`` per step:
sharp ridges and corners wear away first and the rock rounds off. The power modifier ``n``
decides how strongly the most convex parts are preferred.
"""

# %%
import os

import pyvista as pv

import pverosion
from pverosion.examples import load_rock

QUICK = os.environ.get("PVEROSION_QUICK") == "1"  # set by the documentation build
rock = load_rock(subdivisions=4 if QUICK else 5, seed=1)
steps = 40 if QUICK else 150
results = {n: pverosion.weather(rock, iterations=steps, power=n) for n in (1.0, 3.0)}  # or rock.erosion.weather

# %%
# Per-step statistics are in the output's field data, step 0 first.
for n, out in results.items():
    volume = out.field_data["weathering_volume"]
    print(f"n = {n}: volume {volume[0]:.4f} -> {volume[-1]:.4f} after {steps} steps")

# %%
plotter = pv.Plotter(shape=(1, 3))
plotter.add_text("input", font_size=10)
plotter.add_mesh(rock, color="tan")
for column, (n, out) in enumerate(results.items(), start=1):
    plotter.subplot(0, column)
    plotter.add_text(f"{steps} steps, n = {n:g}", font_size=10)
    plotter.add_mesh(out, scalars="erosion_depth", cmap="viridis", show_scalar_bar=False)
plotter.link_views()
plotter.view_isometric()
plotter.show()
