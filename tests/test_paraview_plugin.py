"""The ParaView plugin file, loaded with a stand-in for paraview.util.vtkAlgorithm."""

import importlib.util
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

from pverosion.filters import ALL_FILTERS

PLUGIN = Path(__file__).resolve().parents[1] / "filters" / "pverosion_filters.py"


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


@pytest.fixture()
def plugin(monkeypatch):
    stub = types.ModuleType("paraview.util.vtkAlgorithm")
    stub.smproperty, stub.smdomain, stub.smhint, stub.smproxy = smproperty, smdomain, smhint, smproxy
    monkeypatch.setitem(sys.modules, "paraview", types.ModuleType("paraview"))
    monkeypatch.setitem(sys.modules, "paraview.util", types.ModuleType("paraview.util"))
    monkeypatch.setitem(sys.modules, "paraview.util.vtkAlgorithm", stub)
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


def test_proxy_runs_as_a_plain_vtk_algorithm(plugin):
    alg = plugin.PVErosionCurvature()
    alg.SetPVNormalization(2)  # as ParaView sets an enumeration: by index -> "shifted"
    assert alg.GetNormalization() == "shifted"
    alg.SetInputDataObject(0, pv.Sphere(radius=0.5))
    alg.Update()
    out = pv.wrap(alg.GetOutputDataObject(0))
    assert np.median(out["mean_curvature"]) == pytest.approx(2.0, rel=0.02)
    assert out["mean_curvature_normalized"].max() == pytest.approx(1.0)
