"""
Fracture a cliff into shards
============================

Freeze–thaw weathering (Mateos et al.): the volume of a closed mesh is split into Voronoi shards;
water paths run along the faces between them, freeze and weaken the bonds, and shards whose
bonds break fall away, from the outside in. Here a cone-shaped hill is eroded by water arriving
from one side.
"""

# %%
import os

import pyvista as pv

import pverosion
from pverosion.scenes.shards import hill_cone

QUICK = os.environ.get("PVEROSION_QUICK") == "1"  # set by the documentation build
hill = hill_cone()
cells, paths = (800, 30000) if QUICK else (3000, 120000)
out = pverosion.freeze_thaw(hill, iterations=1, paths_per_step=paths, cells=cells, pattern="grid",
                            water_direction=(-1, -1, -0.6), seed=0)
surface = out["surface"]
print(f"{int(surface.field_data['shard_cells'][0])} cells, "
      f"{int(surface.field_data['shard_solid_cells'][0])} left after {paths} paths, "
      f"{int(surface.field_data['shard_breaks'][0])} links broken")

# %%
# The shards that are left, in a categorical colour map, and the paths of the water.
plotter = pv.Plotter(shape=(1, 2))
plotter.add_text("shards left", font_size=10)
plotter.add_mesh(out["shards"], scalars="shard_colour", cmap="tab20", show_scalar_bar=False)
plotter.subplot(0, 1)
plotter.add_text("eroded surface", font_size=10)
plotter.add_mesh(surface, color="tan")
plotter.link_views()
plotter.view_vector((1, 1, 0.6))  # the side the water comes from
plotter.show()
