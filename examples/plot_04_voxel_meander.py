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
from pverosion.scenes.voxel import meander_grid

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
# The flow seen from above: water speed in the horizontal slice that holds the most water. The
# inflow on the left pushes the water into the channel and the drain on the right pulls it out; over
# a few hundred steps the flow fills the whole channel and the outer banks of the bends, where it
# runs faster, erode more than the inner ones.
speed = np.linalg.norm(state["velocity"], axis=1).reshape(shape, order="F")
water = state["water"].reshape(shape, order="F")
level = int(np.argmax((water > 0.5).sum(axis=(0, 1))))
fig, ax = plt.subplots(figsize=(7, 3.2))
image = ax.imshow(np.where(water[:, :, level] > 0.5, speed[:, :, level], np.nan).T, origin="lower", cmap="viridis")
ax.set(title=f"water speed at z = {level} (m/s)", xlabel="x (voxels)", ylabel="y (voxels)")
fig.colorbar(image, ax=ax, shrink=0.8)

# %%
# The eroded surface, cut open along the channel's middle, and the water in it.
plotter = pv.Plotter()
plotter.add_mesh(surface.clip(normal="z", origin=surface.center, invert=False), color="tan")
wet = state.threshold(0.5, scalars="water")
if wet.n_cells:
    plotter.add_mesh(wet, color="dodgerblue", opacity=0.4)
plotter.view_isometric()
plotter.show()

# sphinx_gallery_thumbnail_number = 2
