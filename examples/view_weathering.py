"""Scrub through a weathering run in the viewer and export it as a movie (off-screen friendly)."""

# %%
import pverosion
from pverosion.examples import load_cube
from pverosion.filters.weathering import Weathering
from pverosion.io import TimeSeriesWriter
from pverosion.viewer import record_movie

with TimeSeriesWriter("weathering.pvd") as series:
    Weathering(iterations=40).step_through(load_cube(resolution=10), list(range(0, 41, 2)),
                                          on_output=lambda t, result: series.write(result, time=t))

# %%
plotter = pverosion.view("weathering.pvd", off_screen=True)  # drop off_screen for a window, then plotter.show()
plotter.set_step(10)
plotter.save_screenshot("weathering_step10.png")
record_movie(plotter, "weathering.gif", fps=8, orbit=True)
plotter.close()
