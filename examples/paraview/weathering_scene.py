"""ParaView Python trace: a sphere weathered by curvature (Skorkovská et al. 2019, Figures 2 and 5).

Needs the environment of ``pverosion paraview setup`` (the plugin loads from
PV_PLUGIN_PATH). Run ``xvfb-run -a pvbatch weathering_scene.py [OUTDIR]``, or
in the GUI: View > Python Shell > Run Script. Writes
``weathering_step_<n>.png`` for a few steps and ``weathering_curvature.png``.
"""

import sys
from pathlib import Path

from paraview.simple import (
    ColorBy,
    CreateView,
    GetAnimationScene,
    GetColorTransferFunction,
    Hide,
    Render,
    ResetCamera,
    SaveScreenshot,
    Show,
    Sphere,
    pverosionCurvatureRusinkiewicz,
    pverosionWeatheringcurvaturedriven,
)

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
rock = Sphere(Radius=1.0, ThetaResolution=48, PhiResolution=48)
weathering = pverosionWeatheringcurvaturedriven(Input=rock, Iterations=100, Power=1.0, StepDivisor=10.0)

view = CreateView("RenderView")
view.ViewSize = [800, 600]
display = Show(weathering, view)
ColorBy(display, ("POINTS", "erosion_depth"))
display.SetScalarBarVisibility(view, True)
ResetCamera(view)

scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()  # the 101 steps of the weathering, as in the GUI's toolbar
for step in (0, 25, 50, 100):
    scene.AnimationTime = float(step)
    GetColorTransferFunction("erosion_depth").RescaleTransferFunction(0.0, 0.1)
    Render(view)
    SaveScreenshot(str(out / f"weathering_step_{step}.png"), view, ImageResolution=[800, 600])

# the curvature of the weathered rock, in the curvature colour map (the default for mean_curvature)
curvature = pverosionCurvatureRusinkiewicz(Input=weathering)
Hide(weathering, view)
shown = Show(curvature, view)
ColorBy(shown, ("POINTS", "mean_curvature"))
GetColorTransferFunction("mean_curvature").RescaleTransferFunction(-2.0, 2.0)  # symmetric: green is flat
shown.SetScalarBarVisibility(view, True)
Render(view)
SaveScreenshot(str(out / "weathering_curvature.png"), view, ImageResolution=[800, 600])
print("wrote", ", ".join(sorted(p.name for p in out.glob("weathering_*.png"))))
