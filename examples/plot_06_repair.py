"""
Repair a scan
=============

A mesh whose parts overlap, or whose surface passes through itself, is cut along the exact
intersection curves and only the outer boundary of the solid is kept (every point where the
input's winding number is at least 1). The curves are marked in ``on_intersection``.
"""

# %%
import pyvista as pv

import pverosion
from pverosion.scenes.intersection import crossed_tube

tube = crossed_tube(n_around=80, n_tube=12)  # a tube bent into a figure eight that passes through itself
fixed = pverosion.repair(tube, improve=True)
print(f"{tube.n_cells} faces in, {fixed.n_cells} out; "
      f"{int(fixed.field_data['intersection_loops'][0])} intersection curves")

# %%
plotter = pv.Plotter(shape=(1, 2))
plotter.add_text("self-intersecting input", font_size=10)
plotter.add_mesh(tube, color="lightgrey", opacity=0.6)
plotter.subplot(0, 1)
plotter.add_text("repaired: curves in red", font_size=10)
plotter.add_mesh(fixed, scalars="on_intersection", cmap="coolwarm", show_scalar_bar=False)
plotter.link_views()
plotter.view_isometric()
plotter.show()
