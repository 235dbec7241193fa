"""
Curvature of your scan
======================

Per-vertex mean curvature of a scanned surface, coloured as in the papers: blue where the surface
is concave (H < 0), green where it is flat, red where it is convex (H > 0). The bunny scan is used
when ``../shared/data/bunny.ply`` (or ``$PVEROSION_DATA/bunny.ply``) is present: it has holes and
inward-wound faces, which are turned outward first. A procedural boulder otherwise.
"""

# %%
import numpy as np
import pyvista as pv

import pverosion
from pverosion.examples import data_path, load_rock

DATA = data_path()  # the real scans ($PVEROSION_DATA, else ../shared/data)
scan = DATA / "bunny.ply"
mesh = pv.read(scan) if scan.exists() else load_rock(subdivisions=5, seed=3)
out = pverosion.curvature(mesh)  # or mesh.erosion.curvature()
print(out.field_data["face_orientation"][0], "faces;", int(out.field_data["flipped_faces"][0]), "flipped")

# %%
# Scans have a few extreme values at noise spikes, so the colour limits are set symmetrically at
# the 98th percentile of ``|H|`` rather than at the maximum: green is exactly H = 0.
limit = float(np.percentile(np.abs(out["mean_curvature"]), 98))
plotter = pv.Plotter()
plotter.add_mesh(out, scalars="mean_curvature", cmap=pverosion.CURVATURE_CMAP, clim=(-limit, limit),
                 scalar_bar_args={"title": "mean curvature H"})
plotter.view_xy()  # the bunny scan stands along +y
plotter.show()
