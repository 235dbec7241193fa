"""Every stage exposes the same options, with the same defaults, in every front end.

The function (:mod:`pverosion.api`), the accessor method, the CLI
subcommand, the batch stage and the ParaView proxy are all checked against
the filter's :class:`~pverosion.filters.base.Param` metadata.
"""

from __future__ import annotations

import argparse
import inspect
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest

import pverosion
from pverosion import api
from pverosion._accessor import ErosionAccessor
from pverosion._frontend import StageFunction, param_entry
from pverosion._stages import STAGE_INDEX, load_stage
from pverosion.batch.scenario import STAGES, ScenarioError, _stage_options
from pverosion.cli import build_parser
from pverosion.filters.base import parse_numbers
from pverosion.filters.paraview import _convert, make_proxy

KEYWORD = inspect.Parameter.KEYWORD_ONLY
EMPTY = inspect.Parameter.empty


def _same(a, b) -> bool:
    """Equal values of one option (vectors by their numbers, so "0,0,0" is (0.0, 0.0, 0.0))."""
    if isinstance(a, str) and isinstance(b, str) and a and b and "," in a + b:
        try:
            a, b = parse_numbers(a, "a"), parse_numbers(b, "b")
        except ValueError:
            return a == b
    if isinstance(a, (tuple, list, np.ndarray)) or isinstance(b, (tuple, list, np.ndarray)):
        return np.shape(a) == np.shape(b) and bool(np.all(np.asarray(a) == np.asarray(b)))
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("stage", STAGE_INDEX, ids=lambda s: s.command)
def test_function_takes_every_option_with_its_default(stage):
    cls = load_stage(stage.command)
    function = getattr(api, stage.function)
    assert getattr(pverosion, stage.function) is function
    info: StageFunction = function.__pverosion_stage__
    assert info.filter_cls is cls
    parameters = inspect.signature(function).parameters
    options = {name: p for name, p in parameters.items() if name in {q.name for q in cls.PARAMS}}
    expected = {p.name for p in cls.PARAMS} - set(info.omitted)
    assert set(options) == expected, stage.command
    assert set(info.omitted) <= {p.name for p in cls.PARAMS}
    for p in cls.PARAMS:
        if p.name not in options:
            continue
        assert options[p.name].kind is KEYWORD or p.name in info.positional, (stage.command, p.name)
        if options[p.name].default is not EMPTY:  # a required positional has no default
            assert _same(options[p.name].default, p.python_default), (stage.command, p.name)
            p.validate(options[p.name].default)  # the Python default is a valid value of the option
    inputs = [name for name, q in parameters.items() if q.kind is not KEYWORD and name not in options]
    assert len(inputs) == info.inputs, (stage.function, inputs)  # the datasets (or field) come first
    extra = {name for name, q in parameters.items() if q.kind is KEYWORD} - expected - {"progress_bar"}
    assert extra <= set(info.python_only), (stage.command, extra)
    names = list(parameters)
    if stage.function != "materials_from_volume":  # builds the field directly; no pipeline runs
        assert names[-1] == "progress_bar" and parameters["progress_bar"].default is False
    doc = inspect.getdoc(function)
    assert "{options}" not in doc
    for name in (*options, *info.python_only):
        assert f"\n{name} : " in doc, (stage.function, name)  # numpydoc entry generated for every option
    for p in cls.PARAMS:  # an option's description and default are the filter's, written once
        if p.name in options and p.name not in info.python_only:
            assert param_entry(p, required=options[p.name].default is EMPTY) in doc, (stage.function, p.name)


@pytest.mark.parametrize("stage", [s for s in STAGE_INDEX if s.accessor], ids=lambda s: s.command)
def test_accessor_method_is_the_function_on_the_dataset(stage):
    assert stage.accessor == stage.command.replace("-", "_")
    method = getattr(ErosionAccessor, stage.accessor)
    function = getattr(api, stage.function)
    accessor_params = list(inspect.signature(method).parameters.values())
    function_params = list(inspect.signature(function).parameters.values())
    assert accessor_params[0].name == "self"
    assert accessor_params[1:] == function_params[1:]
    first = function_params[0].name
    assert f"\n{first} : " not in method.__doc__  # the dataset is not an option of the method


@pytest.mark.parametrize("stage", STAGE_INDEX, ids=lambda s: s.command)
def test_cli_subcommand_takes_every_option_with_its_default(stage):
    cls = load_stage(stage.command)
    parser = build_parser(stages={stage.command})
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[stage.command]
    flags = {a.dest: a for a in sub._actions if a.option_strings and a.dest in {p.name for p in cls.PARAMS}}
    assert set(flags) == {p.name for p in cls.PARAMS}
    for p in cls.PARAMS:
        assert flags[p.name].option_strings[0] == "--" + p.name.replace("_", "-")
        assert _same(flags[p.name].default, p.default), (stage.command, p.name)


@pytest.mark.parametrize("stage", [s for s in STAGE_INDEX if s.command in STAGES], ids=lambda s: s.command)
def test_batch_stage_takes_every_option_with_its_default(stage, tmp_path):
    cls = load_stage(stage.command)
    assert STAGES[stage.command] is cls
    table = {p.name: p.default for p in cls.PARAMS if p.path is None}
    for name in cls.REQUIRED:  # a required option at its (empty) default is refused; give it a value
        with pytest.raises(ScenarioError, match=f"{name} is required"):
            _stage_options(cls, table, seed=0, base=tmp_path, where="test")
        table[name] = {"emitter": "0,0,1,0,0,-1,0.2,50", "thresholds": "40,100"}[name]
    options = _stage_options(cls, table, seed=0, base=tmp_path, where="test")
    assert options == table



def _decorators():
    def recorder(key):
        def decorate(value=None, **kw):
            def tag(obj):
                setattr(obj, key, [*getattr(obj, key, []), value if value is not None else kw])
                return obj
            return tag
        return decorate

    return SimpleNamespace(
        smproperty=SimpleNamespace(xml=recorder("_xml"), doublevector=recorder("_info"), input=recorder("_input")),
        smdomain=SimpleNamespace(datatype=lambda **kw: (lambda c: c)),
        smhint=SimpleNamespace(xml=lambda text: (lambda c: c)),
        smproxy=SimpleNamespace(filter=lambda **kw: (lambda c: c)))


@pytest.mark.parametrize("stage", STAGE_INDEX, ids=lambda s: s.command)
def test_paraview_proxy_has_every_option_with_its_default(stage):
    cls = load_stage(stage.command)
    proxy = make_proxy(cls, _decorators(), __name__)
    properties = {}
    for value in vars(proxy).values():
        for text in getattr(value, "_xml", []):
            element = ET.fromstring(text)
            properties[element.get("name")] = element
    params = {p.camel: p for p in cls.PARAMS}
    assert set(properties) == set(params)
    for camel, element in properties.items():
        p = params[camel]
        values = tuple(element.get("default_values").split(" ")) if p.kind is not str or p.numbers == 3 else \
            (element.get("default_values"),)
        if p.kind is not str and p.choices is None:
            values = tuple(p.kind(float(v)) if p.kind is not bool else bool(int(v)) for v in values)
        shown = _convert(p, values)
        assert _same(p.validate(shown), p.validate(p.default)), (stage.command, p.name)
        assert (element.get("panel_visibility") == "advanced") == p.advanced


def test_deprecated_names_still_work_with_a_warning():
    import pyvista as pv

    from pverosion._stages import resolve_command

    with pytest.warns(DeprecationWarning, match="freeze-thaw"):
        assert load_stage("shards") is load_stage("freeze-thaw")
    assert resolve_command("shard-graph") == "shard-graph"
    sphere = pv.Icosphere(radius=1.0, nsub=2)
    with pytest.warns(DeprecationWarning, match="shard_graph"):
        old = sphere.erosion.shards(cells=12, seed=2)
    new = sphere.erosion.shard_graph(cells=12, seed=2)
    assert np.array_equal(old["surface"].points, new["surface"].points)


def test_deprecated_keywords_map_to_the_current_options():
    import pyvista as pv

    sphere = pv.Icosphere(radius=1.0, nsub=2)
    with pytest.warns(DeprecationWarning, match="emitters= is deprecated"), \
            pytest.raises(ValueError, match="needs water"):
        pverosion.hydraulic_erosion(sphere, emitters=[], iterations=1)
    with pytest.raises(TypeError, match="give emitter= only"):
        pverosion.hydraulic_erosion(sphere, emitter="0,0,2,0,0,-1,0.3,5", emitters="0,0,2,0,0,-1,0.3,5")
    with pytest.warns(DeprecationWarning, match="paths=N is deprecated"):
        old = pverosion.freeze_thaw(sphere, paths=40, cells=20, seed=1, record_paths=False)
    new = pverosion.freeze_thaw(sphere, iterations=1, paths_per_step=40, cells=20, seed=1, record_paths=False)
    assert np.array_equal(old["surface"].points, new["surface"].points)
    assert old["surface"].field_data["shard_paths"][0] == 40


def test_cli_runs_a_deprecated_stage_name_with_a_warning(tmp_path, capsys):
    import pyvista as pv

    from pverosion.cli import main

    pv.Icosphere(radius=1.0, nsub=2).save(tmp_path / "sphere.vtp")
    args = [str(tmp_path / "sphere.vtp"), "--cells", "20", "--iterations", "1", "--paths-per-step", "10"]
    assert main(["shards", *args, "-o", str(tmp_path / "old.vtm")]) == 0
    assert "stage 'shards' is deprecated; use 'freeze-thaw'" in capsys.readouterr().err
    assert main(["freeze-thaw", *args, "-o", str(tmp_path / "new.vtm")]) == 0
    assert "deprecated" not in capsys.readouterr().err
    old, new = pv.read(tmp_path / "old.vtm"), pv.read(tmp_path / "new.vtm")
    assert np.array_equal(old["surface"].points, new["surface"].points)


def test_structured_options_keep_python_objects():
    from pverosion.filters import HydraulicErosion
    from pverosion.filters.hydraulic import format_emitters, parse_emitters
    from pverosion.kernels.fluid.particle_fluid import Drain, Emitter

    emitter = Emitter((0.0, 0.0, 2.0), (0.0, 0.0, -1.0), 0.3, 5.0, 1.5)
    alg = HydraulicErosion(emitter=[emitter], drain=Drain("plane", (0, 0, 1, 5)))
    assert alg.structured_option("emitter")[0] is emitter  # passed through, not turned into text
    assert alg.structured_option("drain") == (Drain("plane", (0.0, 0.0, 1.0, 5.0)),)
    assert parse_emitters(format_emitters([emitter])) == [emitter]
    as_text = HydraulicErosion(emitter="0,0,2,0,0,-1,0.3,5,1.5")
    assert as_text.structured_option("emitter") == (emitter,)
    numbers = HydraulicErosion(emitter=[0, 0, 2, 0, 0, -1, 0.3, 5, 1.5])
    assert numbers.structured_option("emitter") == (emitter,)
    with pytest.raises(ValueError, match="emitter"):
        HydraulicErosion(emitter=[[1, 2, 3]])
    with pytest.raises(TypeError, match="drain"):
        HydraulicErosion(drain=[3.0])


def test_vector_options_take_sequences_and_none():
    from pverosion.filters import FreezeThaw

    p = FreezeThaw.param("water_direction")
    assert p.validate((1, 0.5, -2)) == "1.0,0.5,-2.0"
    assert p.python_default == (0.0, 0.0, -1.0)
    assert FreezeThaw.param("core_plane").validate(None) == ""
    with pytest.raises(ValueError, match="water_direction needs 3 numbers"):
        p.validate((1, 2))
    with pytest.raises(ValueError, match="finite"):
        p.validate((1, float("nan"), 2))
    with pytest.raises(TypeError, match="water_direction"):
        p.validate(3.0)


def test_progress_bar_shows_the_run(capsys):
    import pyvista as pv

    sphere = pv.Icosphere(radius=1.0, nsub=2)
    quiet = pverosion.curvature(sphere)
    assert "100%" not in capsys.readouterr().err
    shown = pverosion.curvature(sphere, progress_bar=True)
    assert "curvature: 100%" in capsys.readouterr().err
    assert np.array_equal(quiet["mean_curvature"], shown["mean_curvature"])


def test_batch_reads_an_old_stage_name_as_the_current_one():
    from pverosion.batch import parse_scenario

    text = """
[input]
example = "rock"
subdivisions = 1
[[stages]]
stage = "{stage}"
cells = 20
[sweep]
"{label}.paths_per_step" = [10, 20]
"""
    with pytest.warns(DeprecationWarning, match="freeze-thaw"):
        old = parse_scenario(text.format(stage="shards", label="shards"))
    new = parse_scenario(text.format(stage="freeze-thaw", label="freeze_thaw"))  # default label: "-" as "_"
    assert [job.stages[0]["stage"] for job in old.jobs] == ["freeze-thaw", "freeze-thaw"]
    assert [job.stages[0]["options"] for job in old.jobs] == [job.stages[0]["options"] for job in new.jobs]
    assert [job.stages[0]["options"]["paths_per_step"] for job in new.jobs] == [10, 20]
