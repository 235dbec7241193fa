"""Generate ParaView proxies from a filter's :class:`~pverosion.filters.base.Param` metadata.

This module never imports ParaView: the plugin file in the top-level
``filters/`` folder passes in the decorators of ``paraview.util.vtkAlgorithm``.
Each option becomes one property whose command is a thin method of the
generated subclass; string choices become an enumeration; each input port
(``INPUT_PORTS``) becomes one input property.
"""

from __future__ import annotations

from types import SimpleNamespace
from xml.sax.saxutils import escape, quoteattr

from pverosion.filters.base import ErosionFilter, Param

__all__ = ["MENU_CATEGORY", "make_proxy"]

MENU_CATEGORY = "pverosion"


def _property_xml(p: Param, command: str) -> str:
    doc = f"<Documentation>{escape(p.doc)}</Documentation>"
    label = quoteattr(p.name.replace("_", " ").title())
    if p.choices is not None:
        entries = "".join(f"<Entry value={quoteattr(str(i))} text={quoteattr(c)}/>" for i, c in enumerate(p.choices))
        return (f'<IntVectorProperty name="{p.camel}" label={label} command="{command}" number_of_elements="1" '
                f'default_values="{p.choices.index(p.default)}"><EnumerationDomain name="enum">{entries}'
                f"</EnumerationDomain>{doc}</IntVectorProperty>")
    if p.kind is bool:
        return (f'<IntVectorProperty name="{p.camel}" label={label} command="{command}" number_of_elements="1" '
                f'default_values="{int(p.default)}"><BooleanDomain name="bool"/>{doc}</IntVectorProperty>')
    tag = {int: "IntVectorProperty", float: "DoubleVectorProperty", str: "StringVectorProperty"}[p.kind]
    domain = ""
    if p.minimum is not None or p.maximum is not None:
        kind = "IntRangeDomain" if p.kind is int else "DoubleRangeDomain"
        bounds = "".join(f" {k}={quoteattr(str(v))}" for k, v in (("min", p.minimum), ("max", p.maximum)) if v is not None)
        domain = f'<{kind} name="range"{bounds}/>'
    return (f'<{tag} name="{p.camel}" label={label} command="{command}" number_of_elements="1" '
            f"default_values={quoteattr(str(p.default))}>{domain}{doc}</{tag}>")


def _setter(p: Param):
    if p.choices is not None:
        def setter(self, index):
            self.set_option(p.name, p.choices[int(index)])
    else:
        def setter(self, value):
            self.set_option(p.name, p.kind(value))
    return setter


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
    namespace = {"__module__": module, "__qualname__": name, "__doc__": filter_cls.__doc__}
    for p in filter_cls.PARAMS:
        method = f"SetPV{p.camel}"
        func = _setter(p)
        func.__name__ = method
        namespace[method] = decorators.smproperty.xml(_property_xml(p, method))(func)
    cls = type(name, (filter_cls,), namespace)
    # decorators apply bottom-up in ParaView: each port's data type domain first, then its input property
    for port, port_name in enumerate(filter_cls.INPUT_PORTS):
        cls = decorators.smdomain.datatype(dataTypes=[filter_cls.INPUT_TYPE], composite_data_supported=False)(cls)
        cls = decorators.smproperty.input(name=port_name, port_index=port)(cls)
    cls = decorators.smhint.xml(f'<ShowInMenu category="{MENU_CATEGORY}"/>')(cls)
    return decorators.smproxy.filter(name=name, label=f"pverosion {filter_cls.LABEL}")(cls)
