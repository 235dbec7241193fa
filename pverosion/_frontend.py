"""Shared plumbing of the Python front ends: options, docstrings and runs generated from the filter metadata.

Each public function of :mod:`pverosion.api` is written with its real
keyword-only signature (so ``help()``, IDEs and sphinx show every option)
and decorated with :func:`stage_function`, which builds the numpydoc of its
options from the filter's :class:`~pverosion.filters.base.Param` metadata: an
option's default and description are written once, in the filter.
``tests/test_frontend_consistency.py`` checks that every function, accessor
method, CLI subcommand, batch stage and ParaView proxy exposes the same
option names and defaults.
"""

from __future__ import annotations

import functools
import inspect
import textwrap
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import pyvista as pv
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData

from pverosion._progress import filter_bar
from pverosion.filters.base import ErosionFilter, Param
from pverosion.kernels.validation import InvalidMeshError

__all__ = ["PROGRESS_BAR_DOC", "StageFunction", "accessor_method", "apply_filter", "param_entry", "renamed",
           "run_filter", "stage_function"]

PROGRESS_BAR_DOC = "Show a progress bar (tqdm) of the run."


@dataclass(frozen=True)
class StageFunction:
    """What a public function exposes of its filter, kept on the function as ``__pverosion_stage__``."""

    filter_cls: type[ErosionFilter]
    """The filter the function runs."""
    python_only: dict[str, tuple[str, str]] = field(default_factory=dict)
    """Options only Python can give (functions, arrays, images): name -> (type, description)."""
    omitted: tuple[str, ...] = ()
    """Filter options the function does not take, each for a reason given in its docstring."""
    inputs: int = 1
    """Positional inputs before the options."""
    positional: tuple[str, ...] = ()
    """Options also taken by position (after the inputs), e.g. ``boolean(a, b, "difference")``."""


def _type_text(p: Param) -> str:
    if p.python_type:
        return p.python_type
    if p.choices is not None:
        return "{" + ", ".join(f'"{c}"' for c in p.choices) + "}"
    if p.numbers is not None:
        return f"sequence of {p.numbers} float" if p.numbers else "sequence of float"
    return p.kind.__name__


def _default_text(p: Param) -> str:
    value = p.python_default
    return "None" if value is None else (f'"{value}"' if isinstance(value, str) else repr(value))


def _entry(name: str, kind: str, doc: str) -> str:
    doc = doc.replace("|", "\\|")  # |H| and |u| are absolute values, not reST substitutions
    body = textwrap.fill(doc, width=100, initial_indent="    ", subsequent_indent="    ")
    return f"{name} : {kind}\n{body}"


def param_entry(p: Param, *, required: bool = False) -> str:
    """The numpydoc entry of option ``p``: type, default (unless ``required``), description and units."""
    return _entry(p.name, _type_text(p) if required else f"{_type_text(p)}, default: {_default_text(p)}", p.help)


def stage_function(filter_cls: type[ErosionFilter], *, python_only: dict[str, tuple[str, str]] | None = None,
                   omitted: tuple[str, ...] = (), inputs: int = 1, positional: tuple[str, ...] = ()) -> Callable:
    """Decorator: fill the ``{options}`` line of a public function's docstring from ``filter_cls.PARAMS``.

    The keyword-only parameters of the function are documented in their
    order: a filter option from its :class:`Param`, a ``python_only`` one
    from that mapping, ``progress_bar`` from :data:`PROGRESS_BAR_DOC`.

    Raises
    ------
    TypeError
        At import, if a keyword-only parameter is neither an option of the
        filter nor declared Python-only.
    """
    python_only = dict(python_only or {})

    def decorate(function: Callable) -> Callable:
        params = {p.name: p for p in filter_cls.PARAMS}
        entries = []
        for name, parameter in inspect.signature(function).parameters.items():
            if parameter.kind is not inspect.Parameter.KEYWORD_ONLY and name not in params:
                continue
            if name in python_only:
                entries.append(_entry(name, *python_only[name]))
            elif name in params:
                entries.append(param_entry(params[name], required=parameter.default is inspect.Parameter.empty))
            elif name == "progress_bar":
                entries.append(_entry(name, "bool, default: False", PROGRESS_BAR_DOC))
            else:
                raise TypeError(f"{function.__name__}: keyword {name!r} is not an option of {filter_cls.__name__}")
        indent = " " * 4
        text = textwrap.indent("\n".join(entries), indent)
        function.__doc__ = function.__doc__.replace(f"{indent}{{options}}", text)
        function.__pverosion_stage__ = StageFunction(filter_cls, python_only, tuple(omitted), inputs,
                                                     tuple(positional))
        return function

    return decorate


def renamed(**old_names: str) -> Callable:
    """Decorator: accept the keywords ``old=new`` too, with a ``DeprecationWarning`` (for one release)."""
    def decorate(function: Callable) -> Callable:
        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            for old, new in old_names.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"{function.__name__}: give {new}= only ({old}= is its deprecated name)")
                    warnings.warn(f"{function.__name__}: {old}= is deprecated; use {new}=", DeprecationWarning,
                                  stacklevel=2)
                    kwargs[new] = kwargs.pop(old)
            return function(*args, **kwargs)

        return wrapper

    return decorate


def accessor_method(function: Callable, summary: str) -> Callable:
    """A method of the ``dataset.erosion`` accessor running ``function`` on the dataset, with its signature and doc."""
    @functools.wraps(function)
    def method(self, *args, **kwargs):
        return function(self._dataset, *args, **kwargs)

    signature = inspect.signature(function)
    parameters = list(signature.parameters.values())
    self_parameter = inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)
    method.__signature__ = signature.replace(parameters=[self_parameter, *parameters[1:]])
    del method.__wrapped__  # help() shows the signature above, without the dataset the accessor supplies
    doc = inspect.getdoc(function) or ""
    options = doc.partition("Parameters\n----------\n")[2]
    first = parameters[0].name
    lines = options.splitlines()
    if lines and lines[0].startswith(f"{first} :"):  # drop the entry of the dataset the accessor supplies
        lines = lines[1:]
        while lines and lines[0].startswith("    "):
            lines = lines[1:]
    method.__doc__ = f"{summary}; see :func:`pverosion.{function.__name__}`.\n\nParameters\n----------\n" + \
        "\n".join(lines)
    return method


def run_filter(alg: ErosionFilter, *inputs, progress_bar: bool = False) -> pv.DataSet:
    """Run the configured filter ``alg`` on ``inputs`` (one per port); a new PyVista dataset."""
    with filter_bar(alg, enabled=progress_bar):
        return pv.wrap(alg.run(*inputs))


def _check_input(filter_cls: type[ErosionFilter], mesh) -> None:
    if filter_cls.INPUT_TYPE == "vtkPolyData" and not isinstance(mesh, vtkPolyData):
        hint = " (call .extract_surface() first)" if isinstance(mesh, pv.DataSet) else ""
        raise TypeError(f"{filter_cls.__name__} needs a PolyData surface{hint}; got {type(mesh).__name__}")
    if filter_cls.INPUT_TYPE == "vtkImageData" and not isinstance(mesh, vtkImageData):
        raise TypeError(f"{filter_cls.__name__} needs an ImageData volume; got {type(mesh).__name__}")
    if isinstance(mesh, vtkPolyData) and mesh.GetNumberOfPoints() == 0:
        raise InvalidMeshError("mesh is empty: it has no points")


def apply_filter(filter_cls: type[ErosionFilter], mesh, *, progress_bar: bool = False, **options: Any) -> pv.DataSet:
    """Run ``filter_cls`` with ``options`` on ``mesh`` and return a new PyVista dataset.

    Raises
    ------
    TypeError
        If ``mesh`` is not the data type the filter takes, or an option is unknown.
    InvalidMeshError
        If the mesh cannot be processed.
    """
    _check_input(filter_cls, mesh)
    return run_filter(filter_cls(**options), mesh, progress_bar=progress_bar)
