"""Batch scenario files (TOML): parsing, validation and expansion of the parameter sweep into jobs.

A scenario names one input, a pipeline of stages with their options, the
outputs to keep, and optionally a sweep whose value lists expand into the
cartesian product of jobs::

    name = "rocks"                 # optional; default: the file name
    seed = 0                       # default of every `seed` option left unset

    [input]
    example = "rock"               # a procedural example (pverosion.examples.EXAMPLES) ...
    subdivisions = 4               # ... with its keyword options
    # file = "meshes/rock.ply"     # or a mesh/volume file, relative to this scenario

    [[stages]]
    stage = "weather"              # a pverosion stage (CLI command name)
    iterations = 100               # its options (see `pverosion weather --help`)

    [[stages]]
    stage = "curvature"
    name = "final_curvature"       # optional label; default: the stage name, "-" read as "_"

    [sweep]
    "input.seed" = [1, 2, 3, 4]    # <input | stage label>.<option>, or seed
    "weather.power" = [1.0, 2.0, 4.0]

    [outputs]
    format = "vtp"                 # format of final.<ext>
    save_every = 50                # also keep every 50th step of time-dependent stages (0: none)
    screenshot = false             # render final.png

Every job is validated before any runs; errors name the file, the table
and the key.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import itertools
import json
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from PyPI
    import tomli as tomllib

from pverosion._stages import resolve_command
from pverosion.examples import EXAMPLES
from pverosion.filters import ALL_FILTERS
from pverosion.filters.base import ErosionFilter, Param

__all__ = ["IMAGE_SUFFIXES", "STAGES", "Job", "Scenario", "ScenarioError", "load_scenario", "parse_scenario"]

STAGES: dict[str, type[ErosionFilter]] = {
    cls.command_name(): cls for cls in ALL_FILTERS if len(cls.INPUT_PORTS) == 1
}
"""Stages a scenario may use, by CLI command name (the one-input stages: a job erodes one mesh)."""

IMAGE_SUFFIXES = (".vti", ".mhd", ".mha", ".nrrd", ".nhdr")
"""File suffixes read as volumes (ImageData); anything else is read as a surface."""

FORMATS = {"vtkPolyData": ("vtp", "vtk", "ply", "stl", "obj"), "vtkImageData": ("vti",),
           "vtkMultiBlockDataSet": ("vtm",)}
"""Formats of the final output, by its data type (the first is the default)."""
MAX_JOBS = 100_000
"""Largest sweep accepted unless ``PVEROSION_MAX_JOBS`` says otherwise (0: no limit)."""

EXAMPLE_BOUNDS = {"subdivisions": (0, 8), "resolution": (1, 1000), "n_around": (3, 100_000),
                  "n_along": (1, 100_000), "n_major": (3, 100_000), "n_minor": (3, 100_000), "n_bumps": (0, 10_000),
                  "seed": (0, None), "roughness": (0.0, None), "size": (1e-9, None), "radius": (1e-9, None),
                  "height": (1e-9, None), "major_radius": (1e-9, None), "minor_radius": (1e-9, None),
                  "finger_length": (1e-9, None), "finger_width": (1e-9, None)}
"""Inclusive bounds of the procedural examples' options (counts beyond them exhaust memory; sizes are positive)."""

_TOP_KEYS = ("name", "description", "seed", "input", "stages", "sweep", "outputs")
_OUTPUT_DEFAULTS = {"format": "", "save_every": 0, "screenshot": False}


class ScenarioError(ValueError):
    """A scenario file that cannot run; the message names the file, table and key."""


@dataclass(frozen=True)
class Job:
    """One fully specified run: input, stages with options, outputs.

    Attributes
    ----------
    index : int
        Position in the expanded sweep (0-based).
    id : str
        SHA-256 of the job's content (input, stages, outputs, and the bytes of
        an input file): the same job in a re-run has the same id, so completed
        jobs are recognised; a changed input file makes it another job.
    label : str
        The swept values, e.g. ``"input.seed=1, weather.power=2.0"``.
    input : dict
        ``{"example": name, "options": {...}}`` or ``{"file": absolute path}``.
    stages : tuple of dict
        ``{"stage": command, "name": label, "options": {...}}`` per stage.
    outputs : dict
        ``format``, ``save_every``, ``screenshot``.
    swept : dict
        The sweep key and value of this job for each swept key.
    """

    index: int
    id: str
    label: str
    input: dict
    stages: tuple
    outputs: dict
    swept: dict = field(default_factory=dict)

    @property
    def folder(self) -> str:
        """Name of the job's output folder: index and id prefix, e.g. ``0003-1a2b3c4d5e``."""
        return f"{self.index:04d}-{self.id[:10]}"

    def to_dict(self) -> dict:
        """JSON-ready description of the job."""
        return {"index": self.index, "id": self.id, "label": self.label, "folder": self.folder,
                "input": self.input, "stages": list(self.stages), "outputs": self.outputs, "swept": self.swept}


@dataclass(frozen=True)
class Scenario:
    """A parsed and validated scenario.

    Attributes
    ----------
    name : str
    path : pathlib.Path or None
        The scenario file (None when parsed from a string).
    text : str
        The TOML source, kept beside the results.
    jobs : tuple of Job
        The expanded sweep, every job validated.
    """

    name: str
    path: Path | None
    text: str
    jobs: tuple[Job, ...]


def load_scenario(path: str | os.PathLike) -> Scenario:
    """Read, validate and expand the scenario file ``path``.

    Relative input files are resolved against the scenario's folder.

    Raises
    ------
    ScenarioError
        If the file is missing or not TOML, or any job would be invalid.
    """
    path = Path(path)
    if path.is_dir():
        raise ScenarioError(f"{path} is a folder, not a scenario file (.toml)")
    if not path.is_file():
        raise ScenarioError(f"no such scenario file: {path}")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ScenarioError(f"{path}: not a TOML scenario (not UTF-8 text)") from None
    return parse_scenario(text, source=path)


def parse_scenario(text: str, *, source: str | os.PathLike | None = None, base: str | os.PathLike | None = None) -> Scenario:
    """Validate and expand a scenario given as TOML text.

    Parameters
    ----------
    text : str
        TOML source.
    source : path-like, optional
        The file it came from: names it in errors, and its folder is the
        default ``base``.
    base : path-like, optional
        Folder that relative input files are resolved against (default:
        the source's folder, else the current folder).

    Returns
    -------
    Scenario
    """
    where = str(source) if source is not None else "scenario"
    base = Path(base) if base is not None else (Path(source).parent if source is not None else Path.cwd())
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        hint = "; scenario files are TOML" if Path(where).suffix.lower() in (".json", ".yaml", ".yml") else ""
        raise ScenarioError(f"{where}: not valid TOML: {exc}{hint}") from None
    try:
        return _expand(doc, text=text, source=Path(source) if source is not None else None, base=base)
    except ScenarioError as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def _unknown(keys, known, where: str) -> None:
    extra = [k for k in keys if k not in known]
    if extra:
        raise ScenarioError(f"{where}: unknown key {extra[0]!r} (known: {', '.join(known)})")


def _table(doc: dict, key: str, where: str) -> dict:
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise ScenarioError(f"{where}: must be a table; got {value!r}")
    return value


def _expand(doc: dict, *, text: str, source: Path | None, base: Path) -> Scenario:
    _unknown(doc, _TOP_KEYS, "top level")
    name = doc.get("name", source.stem if source is not None else "scenario")
    if not isinstance(name, str) or not name:
        raise ScenarioError(f"name: must be a non-empty string; got {name!r}")
    if name in (".", "..") or name.startswith(".") or any(c in name for c in "/\\\0:"):
        raise ScenarioError(f"name: must be a plain name (it names the output folder), without '/', '\\', ':' "
                            f"or a leading '.'; got {name!r}")
    if "input" not in doc:
        raise ScenarioError("[input]: missing (give example = NAME or file = PATH)")
    stages = doc.get("stages")
    if not isinstance(stages, list) or not stages:
        raise ScenarioError("[[stages]]: missing; give at least one [[stages]] table with stage = NAME")
    labels = []
    for k, stage in enumerate(stages):
        if not isinstance(stage, dict):
            raise ScenarioError(f"[[stages]] #{k + 1}: must be a table")
        if "stage" not in stage:
            raise ScenarioError(f"[[stages]] #{k + 1}: missing key 'stage' (one of {', '.join(STAGES)})")
        command = stage["stage"]
        label = stage.get("name", command.replace("-", "_") if isinstance(command, str) else command)
        if isinstance(command, str):  # an old stage name keeps its label, so its sweep keys still work
            stages[k] = {**stage, "stage": resolve_command(command, stacklevel=5)}
        if not isinstance(label, str) or not label.isidentifier():
            raise ScenarioError(f"[[stages]] #{k + 1}: name must be an identifier; got {label!r}")
        if label in labels or label in ("input", "seed", "outputs"):
            raise ScenarioError(f"[[stages]] #{k + 1}: name {label!r} is taken; give each stage a distinct name")
        labels.append(label)
    sweep = _table(doc, "sweep", "[sweep]")
    for key, values in sweep.items():
        head = key.split(".", 1)[0]
        if key != "seed" and (head not in ("input", *labels) or "." not in key):
            raise ScenarioError(f"[sweep] {key!r}: keys are seed, input.OPTION or STAGE.OPTION "
                                f"with STAGE one of {', '.join(labels)}")
        if not isinstance(values, list) or not values:
            raise ScenarioError(f"[sweep] {key!r}: must be a non-empty list of values; got {values!r}")
    size = math.prod(len(values) for values in sweep.values())
    limit = max_jobs()
    if size > limit:
        raise ScenarioError(f"[sweep]: {' x '.join(str(len(v)) for v in sweep.values())} = {size} jobs, more than "
                            f"the limit of {limit} (PVEROSION_MAX_JOBS); sweep fewer values")
    jobs = []
    keys = list(sweep)
    for index, combo in enumerate(itertools.product(*(sweep[k] for k in keys))):
        swept = dict(zip(keys, combo))
        context = f"[sweep] {', '.join(f'{k} = {v!r}' for k, v in swept.items())}: " if swept else ""
        try:
            jobs.append(_job(doc, stages, labels, swept, index=index, base=base))
        except ScenarioError as exc:
            raise ScenarioError(f"{context}{exc}") from None
    first: dict[str, Job] = {}
    for job in jobs:
        if job.id in first:
            raise ScenarioError(f"[sweep]: jobs {first[job.id].index} and {job.index} are identical "
                                f"({first[job.id].label} / {job.label}); list each value once")
        first[job.id] = job
    return Scenario(name=name, path=source, text=text, jobs=tuple(jobs))


def max_jobs() -> float:
    """The most jobs a sweep may expand into: ``PVEROSION_MAX_JOBS`` (0: no limit) or :data:`MAX_JOBS`."""
    text = os.environ.get("PVEROSION_MAX_JOBS", "").strip()
    if not text:
        return MAX_JOBS
    try:
        value = int(text)
    except ValueError:
        raise ScenarioError(f"PVEROSION_MAX_JOBS must be an integer; got {text!r}") from None
    return math.inf if value <= 0 else value


def _set_swept(table: dict, swept: dict, prefix: str) -> dict:
    table = dict(table)
    for key, value in swept.items():
        if key.startswith(prefix + "."):
            table[key[len(prefix) + 1:]] = value
    return table


def _job(doc: dict, stages: list, labels: list, swept: dict, *, index: int, base: Path) -> Job:
    seed = swept.get("seed", doc.get("seed", 0))
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"seed: must be an integer >= 0; got {seed!r}")
    spec_input = _input(_set_swept(_table(doc, "input", "[input]"), swept, "input"), seed=seed, base=base)
    kind = "vtkImageData" if "file" in spec_input and spec_input["file"].lower().endswith(IMAGE_SUFFIXES) \
        else "vtkPolyData"
    spec_stages = []
    for k, (stage, label) in enumerate(zip(stages, labels)):
        where = f"[[stages]] #{k + 1} ({label})"
        table = _set_swept({key: v for key, v in stage.items() if key not in ("stage", "name")}, swept, label)
        cls = STAGES.get(stage["stage"]) if isinstance(stage["stage"], str) else None
        if cls is None:
            raise ScenarioError(f"{where}: unknown stage {stage['stage']!r} (stages: {', '.join(STAGES)})")
        if cls.INPUT_TYPE != kind:
            raise ScenarioError(f"{where}: stage {stage['stage']!r} takes {cls.INPUT_TYPE[3:]} but gets {kind[3:]} "
                                "from the step before")
        kind = cls.OUTPUT_TYPE
        spec_stages.append({"stage": stage["stage"], "name": label,
                            "options": _stage_options(cls, table, seed=seed, base=base, where=where)})
    outputs = dict(_OUTPUT_DEFAULTS)
    given = _table(doc, "outputs", "[outputs]")
    _unknown(given, tuple(_OUTPUT_DEFAULTS), "[outputs]")
    outputs.update(given)
    formats = FORMATS[kind]
    fmt = outputs["format"] or formats[0]
    if fmt not in formats:
        raise ScenarioError(f"[outputs] format: {fmt!r} cannot hold the final {kind[3:]} (one of {', '.join(formats)})")
    outputs["format"] = fmt
    outputs["save_every"] = _check(Param("save_every", 0, "", minimum=0), outputs["save_every"], "[outputs]")
    outputs["screenshot"] = _check(Param("screenshot", False, ""), outputs["screenshot"], "[outputs]")
    content = {"input": spec_input, "stages": spec_stages, "outputs": outputs}
    if "file" in spec_input:  # a changed input file is another job: a re-run computes it instead of keeping the old
        content["input_sha256"] = _file_digest(Path(spec_input["file"]))
    digest = hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()
    label = ", ".join(f"{k}={v}" for k, v in swept.items())
    return Job(index=index, id=digest, label=label, input=spec_input, stages=tuple(spec_stages), outputs=outputs,
               swept=swept)


def _check(param: Param, value: Any, where: str) -> Any:
    try:
        return param.validate(value)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def _file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes, read once per state of the file (path, size, modification time)."""
    stat = path.stat()
    return _digest_of(str(path), stat.st_size, stat.st_mtime_ns)


@functools.lru_cache(maxsize=64)
def _digest_of(path: str, size: int, mtime_ns: int) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _input(table: dict, *, seed: int, base: Path) -> dict:
    if ("example" in table) == ("file" in table):
        raise ScenarioError("[input]: give exactly one of example = NAME or file = PATH")
    if "file" in table:
        _unknown(table, ("file",), "[input]")
        path = table["file"]
        if not isinstance(path, str):
            raise ScenarioError(f"[input] file: must be a path string; got {path!r}")
        full = (base / path).resolve()
        if not full.is_file():
            raise ScenarioError(f"[input] file: no such file {path!r} (looked for {full})")
        return {"file": str(full)}
    name = table["example"]
    loader = EXAMPLES.get(name) if isinstance(name, str) else None
    if loader is None:
        raise ScenarioError(f"[input] example: unknown example {name!r} (examples: {', '.join(EXAMPLES)})")
    defaults = {p.name: p.default for p in inspect.signature(loader).parameters.values()}
    options = {k: v for k, v in table.items() if k != "example"}
    _unknown(options, tuple(defaults), f"[input] example {name!r}")
    checked = {}
    for k, v in options.items():
        low, high = EXAMPLE_BOUNDS.get(k, (None, None))
        checked[k] = _check(Param(k, defaults[k], "", minimum=low, maximum=high), v, f"[input] example {name!r}")
    if "seed" in defaults and "seed" not in checked:
        checked["seed"] = seed
    return {"example": name, "options": checked}


def _stage_options(cls: type[ErosionFilter], table: dict, *, seed: int, base: Path, where: str) -> dict:
    options = {}
    for key, value in table.items():
        try:
            param = cls.param(key)
        except TypeError as exc:
            raise ScenarioError(f"{where}: {exc}") from None
        value = _check(param, value, where)
        if param.convert is not None:  # emitters, drains given as TOML arrays: kept as their text (JSON records)
            value = param.text(value)
        if param.path == "input" and value:
            full = (base / value).resolve()
            if not full.is_file():
                raise ScenarioError(f"{where} {key}: no such file {value!r} (looked for {full})")
            value = str(full)
        elif param.path == "output" and value and (Path(value).is_absolute() or len(Path(value).parts) != 1):
            raise ScenarioError(f"{where} {key}: give a plain file name; it is written into the job's folder")
        options[key] = value
    for key, example in cls.REQUIRED.items():
        if not options.get(key):
            raise ScenarioError(f"{where}: {key} is required, e.g. {key} = {example!r}")
    if "seed" not in options and any(p.name == "seed" for p in cls.PARAMS):
        options["seed"] = _check(cls.param("seed"), seed, f"seed (the default of {where})")
    return options
