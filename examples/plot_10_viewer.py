"""
View a run and export a movie
=============================

Write a weathering run as a ``.pvd`` time series, open it in the viewer (:func:`pverosion.view`,
or ``pverosion view weathering.pvd`` from the shell), go to a step, and export a screenshot and a
GIF movie with the camera turning once around the model. Everything here works off-screen; drop
``off_screen=True`` and call ``plotter.show()`` for a window with the step slider and array buttons.
"""

# %%
import os
import tempfile
from pathlib import Path

import pverosion
from pverosion.examples import load_cube
from pverosion.filters.weathering import Weathering
from pverosion.io import TimeSeriesWriter
from pverosion.viewer import record_movie

QUICK = os.environ.get("PVEROSION_QUICK") == "1"  # set by the documentation build
steps = 20 if QUICK else 100
folder = Path(tempfile.mkdtemp())  # the series, screenshot and movie go here
with TimeSeriesWriter(folder / "weathering.pvd") as series:
    Weathering(iterations=steps).step_through(load_cube(resolution=10), list(range(0, steps + 1, 2)),
                                              on_output=lambda t, result: series.write(result, time=t))

# %%
# The viewer is a :class:`pyvista.Plotter`: every widget calls a public method, so a script
# drives it the same way a click does.
plotter = pverosion.view(folder / "weathering.pvd", off_screen=True, scalars="erosion_depth")
record_movie(plotter, folder / "weathering.gif", fps=8, orbit=True)
plotter.set_step(len(plotter.series) - 1)
plotter.save_screenshot(folder / "weathering_last.png")
print(sorted(path.name for path in folder.iterdir()))
plotter.show()
