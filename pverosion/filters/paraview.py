"""Generate ParaView proxies from a filter's :class:`~pverosion.filters.base.Param` metadata.

This module never imports ParaView: the plugin file
(``pverosion/paraview_plugin/pverosion_filters.py``) passes in the decorators
of ``paraview.util.vtkAlgorithm``. Each option becomes one property whose
command is a thin method of the generated subclass; string choices become an
enumeration, ``x,y,z`` options a 3-element vector, solver tuning options go to
the advanced panel (``Param.advanced``); each input port (``INPUT_PORTS``) becomes one input
property; a time-stepped filter exposes its steps as ``TimestepValues`` so the
TimeKeeper and the animation toolbar list them.

ParaView only prints ``returned failure for request`` when a Python algorithm
fails; the generated proxy writes the error's message and traceback to the
VTK output window (ParaView's Output Messages, stderr in pvpython/pvbatch).
An option set to an invalid value from ParaView does not raise inside the
property push: it is reported, and every update fails with its message until
the option gets a valid value.
"""

from __future__ import annotations

import json
import traceback
from types import SimpleNamespace
from xml.sax.saxutils import escape, quoteattr

from vtkmodules.vtkCommonCore import vtkOutputWindow

from pverosion.filters import ALL_FILTERS
from pverosion.filters.base import ErosionFilter, Param, TimeSteppedFilter
from pverosion.plotting import CURVATURE_CMAP, CURVATURE_COLOURS

__all__ = ["ADVANCED", "MENU_CATEGORY", "curvature_preset", "curvature_settings", "make_proxy", "report_error",
           "vector_size"]

MENU_CATEGORY = "pverosion"




ADVANCED: dict[str, frozenset[str]] = {
    cls.command_name(): frozenset(p.name for p in cls.PARAMS if p.advanced) for cls in ALL_FILTERS
}
"""Options shown only in ParaView's advanced panel (gear button), by command name (``Param.advanced``)."""


def vector_size(p: Param) -> int:
    """3 for an ``x,y,z`` vector option (``Param.numbers == 3``: a 3-element widget), else 1."""
    return 3 if p.numbers == 3 else 1


def _property_xml(p: Param, command: str, advanced: bool) -> str:
    doc = f"<Documentation>{escape(p.help)}</Documentation>"
    label = quoteattr(p.name.replace("_", " ").title())
    head = f'name="{p.camel}" label={label} command="{command}"' + (' panel_visibility="advanced"' if advanced else "")
    if p.choices is not None:
        entries = "".join(f"<Entry value={quoteattr(str(i))} text={quoteattr(c)}/>" for i, c in enumerate(p.choices))
        return (f'<IntVectorProperty {head} number_of_elements="1" default_values="{p.choices.index(p.default)}">'
                f'<EnumerationDomain name="enum">{entries}</EnumerationDomain>{doc}</IntVectorProperty>')
    if p.kind is bool:
        return (f'<IntVectorProperty {head} number_of_elements="1" default_values="{int(p.default)}">'
                f'<BooleanDomain name="bool"/>{doc}</IntVectorProperty>')
    if vector_size(p) == 3:
        values = " ".join(str(float(x)) for x in p.default.split(","))
        return (f'<DoubleVectorProperty {head} number_of_elements="3" default_values="{values}">{doc}'
                f"</DoubleVectorProperty>")
    tag = {int: "IntVectorProperty", float: "DoubleVectorProperty", str: "StringVectorProperty"}[p.kind]
    domain = ""
    if p.minimum is not None or p.maximum is not None:
        kind = "IntRangeDomain" if p.kind is int else "DoubleRangeDomain"
        limits = (("min", p.minimum), ("max", p.maximum))
        bounds = "".join(f" {k}={quoteattr(str(v))}" for k, v in limits if v is not None)
        domain = f'<{kind} name="range"{bounds}/>'
    return f"<{tag} {head} number_of_elements=\"1\" default_values={quoteattr(str(p.default))}>{domain}{doc}</{tag}>"


def _convert(p: Param, values: tuple):
    """The option value of what ParaView passes to the setter (one value, or three for a vector)."""
    if p.choices is not None:
        return p.choices[int(values[0])]
    if vector_size(p) == 3:
        return tuple(float(v) for v in values)  # a vector option takes its numbers (Param.validate)
    value = values[0]
    if p.kind is str:
        return "" if value is None else str(value)  # ParaView passes None for an empty string
    return p.kind(value)


def _setter(p: Param):
    def setter(self, *values):
        try:
            self.set_option(p.name, _convert(p, values))
        except (TypeError, ValueError) as exc:
            self._invalid_options[p.name] = exc
            report_error(exc, f"pverosion {type(self).LABEL}: option {p.camel}")
            self.Modified()
        else:
            if self._invalid_options.pop(p.name, None) is not None:
                self.Modified()
    return setter


def report_error(error: BaseException, context: str) -> None:
    """Write ``context``, the error's message and its traceback to the VTK output window.

    ParaView shows the output window's text in Output Messages; pvpython
    and pvbatch print it to stderr.
    """
    text = "".join(traceback.format_exception(type(error), error, error.__traceback__))
    vtkOutputWindow.GetInstance().DisplayErrorText(f"{context}: {type(error).__name__}: {error}\n{text}")


def _request_data(filter_cls: type[ErosionFilter]):
    def RequestData(self, request, in_info, out_info):  # noqa: N802 - VTK's name
        if self._invalid_options:
            name, error = next(iter(self._invalid_options.items()))
            report_error(error, f"pverosion {filter_cls.LABEL}: invalid option {filter_cls.param(name).camel}")
            return 0
        status = filter_cls.RequestData(self, request, in_info, out_info)
        if not status and self.last_error is not None:
            report_error(self.last_error, f"pverosion {filter_cls.LABEL} failed")
        return status
    return RequestData


def _init(filter_cls: type[ErosionFilter]):
    def __init__(self, **options):
        self._invalid_options: dict[str, Exception] = {}
        filter_cls.__init__(self, **options)
    return __init__


def _timestep_values():
    def GetTimestepValues(self) -> list[float]:  # noqa: N802 - ParaView's name
        return [float(t) for t in range(self.get_option("iterations") + 1)]
    return GetTimestepValues  # a new function per proxy: ParaView keeps the property XML on the function


def make_proxy(filter_cls: type[ErosionFilter], decorators: SimpleNamespace, module: str) -> type:
    """Build the ParaView-decorated subclass of ``filter_cls``.

    Parameters
    ----------
    filter_cls : type
        A :class:`~pverosion.filters.base.ErosionFilter` subclass.
    decorators : namespace
        ``smproxy``, ``smproperty``, ``smdomain`` and ``smhint`` from
        ``paraview.util.vtkAlgorithm``.
    module : str
        ``__name__`` of the plugin module the class will live in.

    Returns
    -------
    type
        The proxy class, named ``PVErosion<Filter>``; assign it to a module global.
    """
    name = f"PVErosion{filter_cls.__name__}"
    namespace = {"__module__": module, "__qualname__": name, "__doc__": filter_cls.__doc__,
                 "__init__": _init(filter_cls), "RequestData": _request_data(filter_cls)}
    for p in filter_cls.PARAMS:
        method = f"SetPV{p.camel}"
        func = _setter(p)
        func.__name__ = method
        namespace[method] = decorators.smproperty.xml(_property_xml(p, method, p.advanced))(func)
    if issubclass(filter_cls, TimeSteppedFilter):
        getter = decorators.smproperty.doublevector(name="TimestepValues", information_only="1",
                                                    si_class="vtkSITimeStepsProperty")
        namespace["GetTimestepValues"] = getter(_timestep_values())
    cls = type(name, (filter_cls,), namespace)
    # decorators apply bottom-up in ParaView: each port's data type domain first, then its input property
    for port, port_name in enumerate(filter_cls.INPUT_PORTS):
        cls = decorators.smdomain.datatype(dataTypes=[filter_cls.INPUT_TYPE], composite_data_supported=False)(cls)
        cls = decorators.smproperty.input(name=port_name, port_index=port)(cls)
    cls = decorators.smhint.xml(f'<ShowInMenu category="{MENU_CATEGORY}"/>')(cls)
    return decorators.smproxy.filter(name=name, label=f"pverosion {filter_cls.LABEL}")(cls)


def _rgb_points(low: float, high: float) -> list[float]:
    n = len(CURVATURE_COLOURS) - 1
    return [v for i, rgb in enumerate(CURVATURE_COLOURS) for v in (low + (high - low) * i / n, *rgb)]


def curvature_preset() -> list[dict]:
    """The curvature colour map as a ParaView colour-map preset (the JSON of Import Presets).

    Blue for H < 0, green for H = 0, red for H > 0 over [-1, 1]; rescale it
    symmetrically about zero so that green marks flat regions.
    """
    return [{"Name": CURVATURE_CMAP, "ColorSpace": "RGB", "NanColor": [0.5, 0.5, 0.5],
             "RGBPoints": _rgb_points(-1.0, 1.0)}]


def curvature_settings(arrays: tuple[str, ...] = ("mean_curvature",)) -> str:
    """ParaView settings JSON making the curvature colour map the default for the named point arrays."""
    table = {"RGBPoints": _rgb_points(-1.0, 1.0), "ColorSpace": 0}  # ColorSpace 0: RGB
    return json.dumps({"array_lookup_tables": {name: {"PVLookupTable": table} for name in arrays}})
