"""The ParaView plugin file, loaded with a stand-in for paraview.util.vtkAlgorithm.

tests/test_paraview_real.py runs the plugin in a real ParaView.
"""

import importlib.util
import json
import subprocess
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow

from pverosion.filters import ALL_FILTERS
from pverosion.filters.paraview import ADVANCED, curvature_preset, vector_size
from pverosion.paraview_setup import PLUGIN_FILE, environment_lines, host_requirements, plugin_dir

PLUGIN = plugin_dir() / PLUGIN_FILE
ROOT = Path(__file__).resolve().parents[1]


class _Recorder:
    """Decorators that record what they were given, like ParaView's, and return the object."""

    @staticmethod
    def _tag(obj, key, value):
        setattr(obj, key, [*getattr(obj, key, []), value])
        return obj


class smproperty(_Recorder):
    @staticmethod
    def xml(text):
        return lambda f: smproperty._tag(f, "_stub_properties", text)

    @staticmethod
    def doublevector(**kw):
        return lambda f: smproperty._tag(f, "_stub_information", kw)

    @staticmethod
    def input(**kw):
        return lambda c: smproperty._tag(c, "_stub_inputs", kw)


class smdomain(_Recorder):
    @staticmethod
    def datatype(dataTypes, **kw):
        return lambda c: smdomain._tag(c, "_stub_datatypes", dataTypes)


class smhint(_Recorder):
    @staticmethod
    def xml(text):
        return lambda c: smhint._tag(c, "_stub_hints", text)


class smproxy(_Recorder):
    @staticmethod
    def filter(**kw):
        return lambda c: smproxy._tag(c, "_stub_proxy", kw)


class _Settings:
    collections: list = []

    @classmethod
    def GetInstance(cls):  # noqa: N802
        return cls()

    def AddCollectionFromString(self, text, priority):  # noqa: N802
        self.collections.append((text, priority))


class _Presets:
    imported: list = []

    @classmethod
    def GetInstance(cls):  # noqa: N802
        return cls()

    def HasPreset(self, name):  # noqa: N802
        return False

    def ImportPresets(self, path):  # noqa: N802
        self.imported.append(path)


@pytest.fixture()
def plugin(monkeypatch):
    stub = types.ModuleType("paraview.util.vtkAlgorithm")
    stub.smproperty, stub.smdomain, stub.smhint, stub.smproxy = smproperty, smdomain, smhint, smproxy
    server_manager = types.ModuleType("paraview.modules.vtkRemotingServerManager")
    server_manager.vtkSMSettings = _Settings
    views = types.ModuleType("paraview.modules.vtkRemotingViews")
    views.vtkSMTransferFunctionPresets = _Presets
    monkeypatch.setattr(_Settings, "collections", [])
    monkeypatch.setattr(_Presets, "imported", [])
    for name in ("paraview", "paraview.util", "paraview.modules"):
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    monkeypatch.setitem(sys.modules, "paraview.util.vtkAlgorithm", stub)
    monkeypatch.setitem(sys.modules, "paraview.modules.vtkRemotingServerManager", server_manager)
    monkeypatch.setitem(sys.modules, "paraview.modules.vtkRemotingViews", views)
    spec = importlib.util.spec_from_file_location("pverosion_filters", PLUGIN)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_filter_has_a_proxy_with_all_options(plugin):
    for cls in ALL_FILTERS:
        proxy = getattr(plugin, f"PVErosion{cls.__name__}")
        assert issubclass(proxy, cls)
        assert proxy._stub_proxy[0]["name"] == proxy.__name__
        assert proxy._stub_datatypes[0] == [cls.INPUT_TYPE]
        props = {}
        for attr, value in vars(proxy).items():
            for text in getattr(value, "_stub_properties", []):
                el = ET.fromstring(text)  # well-formed XML
                assert el.get("command") == attr
                props[el.get("name")] = el
        assert set(props) == {p.camel for p in cls.PARAMS}
        for p in cls.PARAMS:
            el = props[p.camel]
            if p.choices:
                entries = [e.get("text") for e in el.iter("Entry")]
                assert entries == list(p.choices)
                assert entries[int(el.get("default_values"))] == p.default
            advanced = p.name in ADVANCED.get(cls.command_name(), ())
            assert (el.get("panel_visibility") == "advanced") == advanced
        # information property listing the time steps, on the time-stepped filters only
        info = getattr(proxy, "GetTimestepValues", None)
        assert (info is not None) == cls.TIME_DEPENDENT
        if info is not None:
            assert info._stub_information == [{"name": "TimestepValues", "information_only": "1",
                                               "si_class": "vtkSITimeStepsProperty"}]
            assert proxy().GetTimestepValues() == [float(t) for t in range(proxy().GetIterations() + 1)]


def test_advanced_options_exist():
    commands = {cls.command_name(): cls for cls in ALL_FILTERS}
    for command, names in ADVANCED.items():
        assert names <= {p.name for p in commands[command].PARAMS}, command


def test_vectors_get_three_element_widgets(plugin):
    from pverosion.filters import FreezeThaw

    assert {p.name for p in FreezeThaw.PARAMS if vector_size(p) == 3} == {"radius_gradient", "water_direction",
                                                                          "gravity"}
    proxy = plugin.PVErosionFreezeThaw
    el = ET.fromstring(proxy.SetPVWaterDirection._stub_properties[0])
    assert el.tag == "DoubleVectorProperty" and el.get("number_of_elements") == "3"
    assert [float(v) for v in el.get("default_values").split()] == [0.0, 0.0, -1.0]
    alg = proxy()
    alg.SetPVWaterDirection(1, 0.5, -2)
    assert [float(v) for v in alg.GetWaterDirection().split(",")] == [1.0, 0.5, -2.0]


def test_empty_strings_from_paraview_are_empty(plugin):
    alg = plugin.PVErosionWeathering()
    alg.SetPVErodibilityArray("h")
    alg.SetPVErodibilityArray(None)  # what ParaView passes for an empty text field
    assert alg.GetErodibilityArray() == ""
    sampler = plugin.PVErosionMaterialsFromVolume()
    sampler.SetPVTreeFile(None)
    assert sampler.GetTreeFile() == ""


def _captured(action):
    window = vtkOutputWindow.GetInstance()
    capture = vtkStringOutputWindow()
    vtkOutputWindow.SetInstance(capture)
    try:
        result = action()
    finally:
        vtkOutputWindow.SetInstance(window)
    return result, capture.GetOutput()


def test_bad_option_is_reported_and_fails_every_update_until_fixed(plugin):
    alg = plugin.PVErosionWeathering()
    alg.SetInputDataObject(0, pv.Sphere())
    _, text = _captured(lambda: alg.SetPVStepDivisor(-1.0))
    assert "StepDivisor" in text and "step_divisor must be >= 1.0; got -1.0" in text
    for iterations in (2, 3):  # another option changed: the update still fails
        alg.SetPVIterations(iterations)
        status, text = _captured(alg.Update)
        assert "invalid option StepDivisor" in text and "step_divisor must be >= 1.0" in text
        assert alg.GetOutputDataObject(0).GetNumberOfPoints() == 0
    alg.SetPVStepDivisor(5.0)
    _, text = _captured(alg.Update)
    assert text == "" and alg.GetOutputDataObject(0).GetNumberOfPoints() > 0


def test_execute_errors_print_message_and_traceback(plugin):
    alg = plugin.PVErosionWeathering()
    alg.SetPVIterations(1)
    alg.SetPVErodibilityArray("missing")
    alg.SetInputDataObject(0, pv.Sphere())
    _, text = _captured(alg.Update)
    assert "pverosion Weathering (curvature-driven) failed: ValueError: erodibility_array 'missing'" in text
    assert "Traceback (most recent call last)" in text


def test_loading_registers_the_curvature_preset_for_mean_curvature(plugin):
    assert _Presets.imported == [str(plugin_dir() / "pverosion_curvature.json")]
    shipped = json.loads((plugin_dir() / "pverosion_curvature.json").read_text())
    assert shipped == curvature_preset()
    import matplotlib

    cmap = matplotlib.colormaps[shipped[0]["Name"]]
    points = np.reshape(shipped[0]["RGBPoints"], (-1, 4))
    for x, *rgb in points:  # the preset is the matplotlib colour map of the papers
        assert np.allclose(cmap((x + 1) / 2)[:3], rgb, atol=1 / 255)
    (text, _), = _Settings.collections
    table = json.loads(text)["array_lookup_tables"]["mean_curvature"]["PVLookupTable"]
    assert table["RGBPoints"] == shipped[0]["RGBPoints"]


def test_host_requirements_never_bring_vtk():
    old = host_requirements({"numpy": "1.24.2", "vtk": "9.2.20230111"})
    assert not [r for r in old if r.split(">")[0].split("=")[0].strip().lower() == "vtk"]
    assert "numpy==1.24.2" in old and "pyvista>=0.48,<0.49" in old
    new = host_requirements({"numpy": "2.1.0", "vtk": "9.4.2"})
    assert "numpy==2.1.0" in new and any(r.startswith("pyvista") and "<0.49" not in r for r in new)


def test_environment_lines_and_plugin_path(tmp_path):
    lines = environment_lines(tmp_path)
    assert lines[0].startswith(f'export PYTHONPATH="{tmp_path}')
    assert f"{tmp_path}/pverosion/paraview_plugin" in lines[1]
    out = subprocess.run([sys.executable, "-m", "pverosion", "paraview", "plugin-path"], capture_output=True,
                         text=True, check=True, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}).stdout
    assert Path(out.strip()) == PLUGIN and PLUGIN.is_file()


def test_proxy_runs_as_a_plain_vtk_algorithm(plugin):
    alg = plugin.PVErosionCurvature()
    alg.SetPVNormalization(2)  # as ParaView sets an enumeration: by index -> "shifted"
    assert alg.GetNormalization() == "shifted"
    alg.SetInputDataObject(0, pv.Sphere(radius=0.5))
    alg.Update()
    out = pv.wrap(alg.GetOutputDataObject(0))
    assert np.median(out["mean_curvature"]) == pytest.approx(2.0, rel=0.02)
    assert out["mean_curvature_normalized"].max() == pytest.approx(1.0)
