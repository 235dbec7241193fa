"""
Booleans
========

Union, intersection and differences of two closed meshes, cut along exact intersection curves.
Each output face remembers the input it comes from (``source_mesh``: 0 for A, 1 for B).
"""

# %%
import pyvista as pv

import pverosion
from pverosion.scenes.intersection import cube_and_sphere

cube, sphere = cube_and_sphere()
operations = ("union", "intersection", "difference", "reverse_difference")
results = {op: pverosion.boolean(cube, sphere, op) for op in operations}  # or cube.erosion.boolean(sphere, ...)
for op, out in results.items():
    print(f"{op:>18}: {out.n_cells} faces, volume {out.volume:.4f}")

# %%
plotter = pv.Plotter(shape=(1, 4), window_size=(1200, 350))
for column, (op, out) in enumerate(results.items()):
    plotter.subplot(0, column)
    plotter.add_text(op.replace("_", " "), font_size=9)
    plotter.add_mesh(out, scalars="source_mesh", cmap="coolwarm", clim=(0, 1), show_scalar_bar=False)
plotter.link_views()
plotter.view_vector((1, 0.6, 0.8))
plotter.show()
