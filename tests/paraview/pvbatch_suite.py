"""The plugin in a real ParaView: run with ``xvfb-run -a pvbatch tests/paraview/pvbatch_suite.py OUTDIR``.

The environment is the one ``pverosion paraview setup`` prints (``PYTHONPATH``
with pverosion and its dependencies, ``PV_PLUGIN_PATH`` with the plugin
folder), so ParaView loads the plugin by itself as the README says. Every
check raises ``AssertionError`` on failure; the last line printed is
``PVEROSION-PARAVIEW-OK`` when all passed. tests/test_paraview_real.py runs it.
"""

import sys
from pathlib import Path

import numpy as np
import paraview.simple as pvs
from paraview import servermanager
from vtkmodules.numpy_interface import dataset_adapter as dsa
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow
from vtkmodules.vtkCommonDataModel import vtkMultiBlockDataSet

OUT = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
FILTERS = {  # paraview.simple function of each filter, from its menu label
    "curvature": "pverosionCurvatureRusinkiewicz",
    "weather": "pverosionWeatheringcurvaturedriven",
    "hydraulic": "pverosionHydraulicerosionparticlefluid",
    "materials": "pverosionMaterialsfromvolumeBSP",
    "sample-materials": "pverosionMaterialfieldsampling",
    "voxel": "pverosionVoxelhydraulicerosion",
    "shard-graph": "pverosionVoronoishards",
    "freeze-thaw": "pverosionFreezethawweathering",
    "repair": "pverosionRepairselfintersections",
    "boolean": "pverosionBooleanoperation",
}


def check(condition, message):
    if not condition:
        raise AssertionError(message)


def fetch(proxy):
    """The output data object of ``proxy`` (pvbatch runs client and server in one process)."""
    return proxy.GetClientSideObject().GetOutputDataObject(0)


def block(data, name):
    """Block ``name`` of a multiblock output."""
    for i in range(data.GetNumberOfBlocks()):
        if data.GetMetaData(i).Get(vtkMultiBlockDataSet.NAME()) == name:
            return data.GetBlock(i)
    raise AssertionError(f"no block {name!r}")


def point_array(data, name, association="PointData"):
    arr = getattr(dsa.WrapDataObject(data), association)[name]
    check(isinstance(arr, np.ndarray), f"output has no {association} array {name!r}")
    return np.asarray(arr)


def messages_of(action):
    """Run ``action()`` with a string output window; return (its result, the text ParaView would show)."""
    window = vtkOutputWindow.GetInstance()
    capture = vtkStringOutputWindow()
    vtkOutputWindow.SetInstance(capture)
    try:
        result = action()
    finally:
        vtkOutputWindow.SetInstance(window)
    return result, capture.GetOutput()


def sphere(radius=1.0, centre=(0.0, 0.0, 0.0)):
    return pvs.Sphere(Radius=radius, Center=centre, ThetaResolution=24, PhiResolution=24)


def main():
    # 1. the plugin was loaded from PV_PLUGIN_PATH: the ten filters are in paraview.simple
    names = sorted(n for n in dir(pvs) if n.startswith("pverosion"))
    check(names == sorted(FILTERS.values()), f"expected the 10 pverosion filters, found {names}")
    print("filters:", ", ".join(names), flush=True)
    make = {command: getattr(pvs, name) for command, name in FILTERS.items()}

    # 2. every filter with its default options on small inputs (thresholds, emitter and tree file are required;
    #    fewer steps or cells keep the run short)
    ball = sphere(0.5)
    curv = make["curvature"](Input=ball)
    curv.UpdatePipeline()
    H = point_array(fetch(curv), "mean_curvature")
    check(abs(np.median(H) - 2.0) < 0.1, f"sphere of radius 0.5: median H {np.median(H)} != 2")

    rock = sphere(1.0)
    weather = make["weather"](Input=rock)
    check(list(weather.TimestepValues) == [float(t) for t in range(101)], "weathering publishes steps 0..100")
    weather.UpdatePipeline(100.0)
    depth = point_array(fetch(weather), "erosion_depth")
    check(np.all(depth >= -1e-9) and depth.max() > 0, "weathering a sphere erodes every vertex inward")

    hydraulic = make["hydraulic"](Input=sphere(1.0), Emitter="0,0,1.6,0,0,-1,0.4,200", Iterations=10)
    hydraulic.UpdatePipeline(10.0)
    particles = block(fetch(hydraulic), "particles")
    check(particles.GetNumberOfPoints() > 0, "the emitter adds particles")
    check(np.all(np.isfinite(point_array(block(fetch(hydraulic), "mesh"), "erosion_depth"))), "finite erosion")

    wavelet = pvs.Wavelet(WholeExtent=[-6, 6, -6, 6, -6, 6])
    materials = make["materials"](Input=wavelet, Thresholds="100,150", TreeFile=str(OUT / "tree.json"))
    materials.UpdatePipeline()
    mat = fetch(materials)
    ids = point_array(mat, "material_id")
    check(set(np.unique(ids)) <= {0, 1, 2} and len(np.unique(ids)) == 3, f"three materials; got {np.unique(ids)}")
    agreement = float(dsa.WrapDataObject(mat).FieldData["agreement"][0])
    check(agreement > 0.9, f"the tree reproduces the thresholded volume; agreement {agreement}")

    before = set(Path.cwd().iterdir())
    plain = make["materials"](Input=wavelet, Thresholds="100,150")  # TreeFile left empty: ParaView passes None
    plain.UpdatePipeline()
    check(np.array_equal(point_array(fetch(plain), "material_id"), ids), "materials without a tree file")
    check(set(Path.cwd().iterdir()) == before, f"an empty TreeFile wrote {set(Path.cwd().iterdir()) - before}")

    sampler = make["sample-materials"](Input=wavelet, TreeFile=str(OUT / "tree.json"))
    sampler.UpdatePipeline()
    check(np.array_equal(point_array(fetch(sampler), "material_id"), ids), "sampling the saved tree")

    floor = pvs.Calculator(Input=wavelet, Function="coordsZ < 0", ResultArrayName="material_amount")
    spring = pvs.Calculator(Input=floor, Function="(coordsZ > 3) and (coordsX < -4)", ResultArrayName="source")
    voxel = make["voxel"](Input=spring, Iterations=3)
    voxel.UpdatePipeline(3.0)
    state = block(fetch(voxel), "state")
    amount = point_array(state, "material_amount")
    check(amount.min() >= 0 and amount.max() <= 1 and amount.sum() > 0, "voxel state keeps material in [0, 1]")
    check(block(fetch(voxel), "surface").GetNumberOfPoints() > 0, "voxel erosion extracts the material surface")

    shards = make["shard-graph"](Input=sphere(1.0), Cells=30)
    shards.UpdatePipeline()
    cell_ids = point_array(block(fetch(shards), "shards"), "cell_id", "CellData")
    check(len(np.unique(cell_ids)) == 30, f"30 shards; got {len(np.unique(cell_ids))}")

    freeze = make["freeze-thaw"](Input=sphere(1.0), Cells=30)
    check(list(freeze.TimestepValues) == [float(t) for t in range(11)], "freeze-thaw publishes steps 0..10")
    freeze.UpdatePipeline(10.0)
    check(block(fetch(freeze), "surface").GetNumberOfPoints() > 0, "freeze-thaw leaves a surface")

    repair = make["repair"](Input=sphere(1.0))
    repair.UpdatePipeline()
    check(fetch(repair).GetNumberOfCells() == servermanager.Fetch(sphere(1.0)).GetNumberOfCells(),
          "repairing a clean sphere keeps its triangles")

    union = make["boolean"](InputA=sphere(1.0), InputB=sphere(1.0, (1.0, 0.1, 0.05)))
    union.UpdatePipeline()
    bounds = fetch(union).GetBounds()
    check(abs(bounds[0] + 1) < 0.05 and abs(bounds[1] - 2) < 0.05, f"union spans x in [-1, 2]; bounds {bounds}")
    print("every filter ran with its defaults", flush=True)

    # vector options are 3-element fields that reach the filter as x,y,z; tuning options are in the advanced panel
    panel = make["freeze-thaw"](Input=sphere(1.0), Cells=30)
    direction = panel.SMProxy.GetProperty("WaterDirection")
    check(direction.GetNumberOfElements() == 3 and list(panel.WaterDirection) == [0.0, 0.0, -1.0],
          f"WaterDirection widget: {direction.GetNumberOfElements()} elements, {list(panel.WaterDirection)}")
    panel.WaterDirection = [1.0, 0.5, -2.0]
    panel.UpdatePipelineInformation()
    received = [float(v) for v in panel.GetClientSideObject().GetWaterDirection().split(",")]
    check(received == [1.0, 0.5, -2.0], f"the filter received water direction {received}")
    visibility = {name: panel.SMProxy.GetProperty(name).GetPanelVisibility() for name in ("Seed", "KBreak", "Cells")}
    check(visibility == {"Seed": "advanced", "KBreak": "advanced", "Cells": "default"}, f"panels: {visibility}")
    pvs.Delete(panel)

    # 3. a bad option: its message in ParaView's output, and a failed update
    bad = make["weather"](Input=sphere(1.0), Iterations=2)
    (_, text) = messages_of(lambda: setattr(bad, "StepDivisor", -1.0))
    check("step_divisor must be >= 1.0; got -1.0" in text, f"bad option message missing; output: {text!r}")
    (_, text) = messages_of(lambda: bad.UpdatePipeline(2.0))
    check("step_divisor must be >= 1.0" in text and "ValueError" in text, f"update output: {text!r}")
    check(fetch(bad).GetNumberOfPoints() == 0, "the failed update left an empty output")
    bad.StepDivisor = 10.0
    bad.ErodibilityArray = "no_such_array"
    (_, text) = messages_of(lambda: bad.UpdatePipeline(2.0))
    check("erodibility_array 'no_such_array' is not a point array" in text and "Traceback" in text,
          f"execute error output: {text!r}")
    bad.ErodibilityArray = ""  # ParaView passes None for an empty string: back to uniform
    (_, text) = messages_of(lambda: bad.UpdatePipeline(2.0))
    check(fetch(bad).GetNumberOfPoints() > 0 and "Error" not in text, f"valid again: {text!r}")
    print("errors reach the output window", flush=True)

    # 4. animation: the TimeKeeper lists the weathering steps; the last step shows erosion_depth > 0
    scene = pvs.GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    keeper = pvs.GetTimeKeeper()
    steps = list(keeper.TimestepValues)
    check(set(map(float, range(101))) <= set(steps) and max(steps) == 100.0, f"TimeKeeper steps: {steps}")
    view = pvs.CreateView("RenderView")
    view.ViewSize = [400, 300]
    for proxy in list(pvs.GetSources().values()):
        pvs.Hide(proxy, view)
    display = pvs.Show(weather, view)
    pvs.ColorBy(display, ("POINTS", "erosion_depth"))
    scene.AnimationTime = 100.0  # the last step, as the animation toolbar's "Last Frame"
    pvs.Render(view)
    shown = display.GetRepresentedDataInformation().GetPointDataInformation().GetArrayInformation("erosion_depth")
    low, high = shown.GetComponentRange(0)
    check(high > 0, f"rendered erosion_depth at the last step is zero (range {low}, {high})")
    pvs.ResetCamera(view)
    shot = OUT / "weathering.png"
    pvs.SaveScreenshot(str(shot), view, ImageResolution=[400, 300])
    from vtkmodules.vtkIOImage import vtkPNGReader

    reader = vtkPNGReader()
    reader.SetFileName(str(shot))
    reader.Update()
    pixels = dsa.WrapDataObject(reader.GetOutput()).PointData[0]
    check(np.asarray(pixels).std(axis=0).max() > 10, "the screenshot is blank")
    print(f"animated to step 100: erosion_depth in [{low:.4g}, {high:.4g}]; screenshot {shot}", flush=True)

    # 5. mean_curvature gets the curvature colour map by default; the preset is registered
    pvs.Hide(weather, view)
    cdisplay = pvs.Show(curv, view)
    pvs.ColorBy(cdisplay, ("POINTS", "mean_curvature"))
    lut = pvs.GetColorTransferFunction("mean_curvature")
    rgb = np.asarray(lut.RGBPoints).reshape(-1, 4)[:, 1:]
    check(np.allclose(rgb, [[0, 0, 1], [0, 0.8, 0], [1, 0, 0]]), f"mean_curvature colour map: {rgb.tolist()}")
    from paraview.modules.vtkRemotingViews import vtkSMTransferFunctionPresets

    check(vtkSMTransferFunctionPresets.GetInstance().HasPreset("pverosion_curvature"), "preset not registered")
    print("PVEROSION-PARAVIEW-OK", flush=True)


main()
