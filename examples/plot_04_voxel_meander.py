"""
Carve a meander in voxels
=========================

Water flows through a sinuous channel cut into a block of voxels (Beneš et al. 2006): a
Navier–Stokes solver on the voxel grid moves the water, which dissolves material where it
flows fast and deposits it where it slows down. Because the material is a voxel field, caves
and undercut banks need no special treatment. The result holds the grid (``state``) and the
material's closed isosurface (``surface``).
"""

# %%
import os

import matplotlib.pyplot as plt
import numpy as np
import pyvista as pv

import pverosion
from pverosion.voxel_scenes import meander_grid

QUICK = os.environ.get("PVEROSION_QUICK") == "1"  # set by the documentation build
shape = (64, 32, 24) if QUICK else (128, 64, 64)
grid, meander = meander_grid(shape, depth=6 if QUICK else 10, half_width=2.5 if QUICK else 4.0)
steps = 30 if QUICK else 300
out = pverosion.voxel_erosion(grid, iterations=steps, time_step=0.01, source_velocity=(1.0, 0.0, 0.0),
                              advection="maccormack")
state, surface = out["state"], out["surface"]
print(f"{steps} steps: material eroded {state.field_data['voxel_eroded'][-1]:.3f}, "
      f"deposited {state.field_data['voxel_deposited'][-1]:.3f} voxel volumes; "
      f"balance error {state.field_data['mass_error'][0]:.1e}")

# %%
# Material lost per voxel column, seen from above: the channel's banks.
before = grid["material_amount"].reshape(shape, order="F").sum(axis=2)
after = state["material_amount"].reshape(shape, order="F").sum(axis=2)
fig, ax = plt.subplots(figsize=(7, 3.2))
image = ax.imshow((before - after).T, origin="lower", cmap="magma", vmin=0)
ax.set(title="material removed per column (voxels)", xlabel="x", ylabel="y")
fig.colorbar(image, ax=ax, shrink=0.8)

# %%
# The eroded surface, cut open along the channel's middle.
plotter = pv.Plotter()
plotter.add_mesh(surface.clip(normal="z", origin=surface.center, invert=False), color="tan")
water = state.threshold(0.5, scalars="water")
if water.n_cells:
    plotter.add_mesh(water, color="dodgerblue", opacity=0.4)
plotter.view_isometric()
plotter.show()
