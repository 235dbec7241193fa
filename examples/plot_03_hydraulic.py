"""
Pour water on a model
=====================

A particle fluid poured from a disc emitter flows over a closed mesh, and the surface erodes
where the water touches it. :func:`pverosion.scenes.hydraulic.pour_scene` sets up the emitter
over the model, a drain plane under it and the particle size; here on a procedural rock.
"""

# %%
import os

import pyvista as pv

import pverosion
from pverosion.scenes.hydraulic import pour_scene

QUICK = os.environ.get("PVEROSION_QUICK") == "1"  # set by the documentation build
scene = pour_scene()  # pour_scene(mesh=pv.read(...)) for your own model
iterations = 40 if QUICK else scene.iterations
out = pverosion.hydraulic_erosion(scene.mesh, emitter=scene.emitters, drain=scene.drains,
                                  radius=scene.radius, iterations=iterations, seed=0)
mesh, particles = out["mesh"], out["particles"]
print(f"{particles.n_points} particles; volume {mesh.field_data['hydraulic_volume'][0]:.4f} -> "
      f"{mesh.field_data['hydraulic_volume'][-1]:.4f}")

# %%
# The mesh carries ``erosion_depth``; the particles carry their ``speed``.
plotter = pv.Plotter()
plotter.add_mesh(mesh, scalars="erosion_depth", cmap="magma_r", scalar_bar_args={"title": "erosion depth"})
if particles.n_points:
    plotter.add_mesh(particles, color="dodgerblue", point_size=4, render_points_as_spheres=True)
plotter.view_isometric()
plotter.show()
