"""
Curvature of your scan
======================

Per-vertex mean curvature of a scanned surface, coloured as in the papers: blue where the surface
is concave (H < 0), green where it is flat, red where it is convex (H > 0). The bunny scan is used
when ``../shared/data/bunny.ply`` (or ``$PVEROSION_DATA/bunny.ply``) is present: it has holes and
inward-wound faces, which are turned outward first. A procedural boulder otherwise.
"""

# %%
import os
from pathlib import Path

import pyvista as pv

import pverosion
from pverosion.examples import load_rock

DATA = Path(os.environ.get("PVEROSION_DATA", "../shared/data"))  # the scans, relative to the repository
scan = DATA / "bunny.ply"
mesh = pv.read(scan) if scan.exists() else load_rock(subdivisions=5, seed=3)
out = pverosion.curvature(mesh, normalization="symmetric")  # or mesh.erosion.curvature(...)
print(out.field_data["face_orientation"][0], "faces;", int(out.field_data["flipped_faces"][0]), "flipped")

# %%
# ``mean_curvature_normalized`` is H scaled into [-1, 1] keeping its sign (symmetric
# normalisation), so the colour limits are symmetric and green is exactly H = 0.
plotter = pv.Plotter()
plotter.add_mesh(out, scalars="mean_curvature_normalized", cmap=pverosion.CURVATURE_CMAP, clim=(-1, 1),
                 scalar_bar_args={"title": "normalised H"})
plotter.view_isometric()
plotter.show()
