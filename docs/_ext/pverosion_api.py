"""What the API and CLI references must contain, computed from the package itself (no Sphinx needed).

Used by the Sphinx extension :mod:`pverosion_docs` to write the API pages and to check them, and by
``tests/test_docs.py``.
"""

from __future__ import annotations

import argparse
import ast
import functools
import importlib
import inspect
import pkgutil

PACKAGE = "pverosion"
#: Sections of the API reference, in order: (title, module-name prefixes).
GROUPS = (
    ("Functions and the accessor", ("pverosion", "pverosion.api", "pverosion.io", "pverosion.plotting")),
    ("Filters (VTK algorithms)", ("pverosion.filters",)),
    ("Kernels (arrays in, arrays out)", ("pverosion.kernels",)),
    ("Batch runs", ("pverosion.batch",)),
    ("Command line", ("pverosion.cli",)),
    ("Example data and scenes", ("pverosion.examples", "pverosion.scenes", "pverosion.meshing")),
)
ACCESSOR = "pverosion._accessor.ErosionAccessor"


@functools.lru_cache(maxsize=1)
def public_modules() -> tuple[str, ...]:
    """Names of the package's public modules (no component starting with ``_``), sorted."""
    package = importlib.import_module(PACKAGE)
    names = [PACKAGE]
    for info in pkgutil.walk_packages(package.__path__, prefix=PACKAGE + "."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            names.append(info.name)
    return tuple(sorted(names))


def public_names(module_name: str) -> list[str]:
    """The module's ``__all__`` (a module without one exports nothing documented)."""
    return list(getattr(importlib.import_module(module_name), "__all__", ()))


def _is_routine(obj) -> bool:
    """Functions, including numba dispatchers (which wrap a Python function as ``py_func``)."""
    return inspect.isroutine(obj) or inspect.isfunction(getattr(obj, "py_func", None))


def _assignments(module) -> dict[str, bool]:
    """Names bound by a top-level assignment in the module's source, and whether each one is documented.

    Documented means a ``#:`` comment on the line(s) just above the assignment or a string literal
    just below it (the conventions autodoc reads).
    """
    source = inspect.getsource(module)
    lines = source.splitlines()
    tree = ast.parse(source)
    found = {}
    # top-level statements, and those of top-level ``if`` blocks (``if TYPE_CHECKING:`` declares the
    # names a module's ``__getattr__`` creates lazily)
    body = [node for top in tree.body for node in ([top, *top.body, *top.orelse] if isinstance(top, ast.If) else [top])]
    for index, node in enumerate(body):
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
            node, ast.AnnAssign) else []
        if not targets:
            continue
        after = body[index + 1] if index + 1 < len(body) else None
        documented = (isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant)
                      and isinstance(after.value.value, str))
        documented |= node.lineno >= 2 and lines[node.lineno - 2].strip().startswith("#:")
        for target in targets:
            for name in ast.walk(target):
                if isinstance(name, ast.Name):
                    found[name.id] = documented
    return found


def _defined_here(module, name: str) -> bool:
    """Whether ``module.name`` is defined in ``module`` (not imported from elsewhere)."""
    obj = getattr(module, name)
    if inspect.isclass(obj) or _is_routine(obj):
        return getattr(obj, "__module__", None) == module.__name__
    return name in _assignments(module)


def _member_directive(module, name: str) -> str:
    full = f"{module.__name__}.{name}"
    obj = getattr(module, name)
    if inspect.isclass(obj):
        return f".. autoclass:: {full}\n   :members:\n   :show-inheritance:\n"
    if _is_routine(obj):
        return f".. autofunction:: {full}\n"
    if _assignments(module).get(name):
        return f".. autodata:: {full}\n   :no-value:\n"
    # No documentation of its own: autodoc would show the docstring of the value's type. The name is
    # relative to the module set by the page's automodule.
    value = repr(obj)
    return f".. py:data:: {name}\n" + (f"   :value: {value}\n" if len(value) <= 80 and "\n" not in value else "")


def canonical_name(module_name: str, name: str) -> str:
    """Full name under which ``module_name.name`` is documented: where it is defined."""
    module = importlib.import_module(module_name)
    if _defined_here(module, name):
        return f"{module_name}.{name}"
    obj = getattr(module, name)
    owner = getattr(obj, "__module__", None)
    if (inspect.isclass(obj) or _is_routine(obj)) and owner:
        return f"{owner}.{getattr(obj, '__qualname__', name)}"
    for other in public_modules():
        candidate = importlib.import_module(other)
        if getattr(candidate, name, None) is obj and _defined_here(candidate, name):
            return f"{other}.{name}"
    return f"{module_name}.{name}"


def module_page(module_name: str) -> str:
    """reStructuredText of one module's API page."""
    module = importlib.import_module(module_name)
    own, reexported = [], []
    for name in public_names(module_name):
        (own if _defined_here(module, name) else reexported).append(name)
    title = module_name
    lines = [title, "=" * len(title), "", f".. automodule:: {module_name}", "   :no-members:", ""]
    if own:
        lines += [".. rubric:: Defined here", "", ".. autosummary::", "   :nosignatures:", ""]
        lines += [f"   {name}" for name in own] + [""]
    if reexported:
        lines += [".. rubric:: Re-exported", ""]
        lines += [f"* :py:obj:`{name} <{canonical_name(module_name, name)}>`" for name in reexported] + [""]
    for name in own:
        lines.append(_member_directive(module, name))
    return "\n".join(lines) + "\n"


def index_page(modules: tuple[str, ...]) -> str:
    """reStructuredText of the API reference's table of contents, module pages grouped by layer."""
    lines = []
    placed = set()
    for title, prefixes in GROUPS:
        members = [m for m in modules if m not in placed
                   and any(m == p or (p != PACKAGE and m.startswith(p + ".")) for p in prefixes)]
        if not members:
            continue
        placed.update(members)
        lines += [".. rubric:: " + title, "", ".. toctree::", "   :maxdepth: 1", ""]
        lines += [f"   generated/{m}" for m in members] + [""]
    rest = [m for m in modules if m not in placed]
    if rest:
        lines += [".. rubric:: Other modules", "", ".. toctree::", "   :maxdepth: 1", ""]
        lines += [f"   generated/{m}" for m in rest] + [""]
    return "\n".join(lines)


def _subcommands(parser: argparse.ArgumentParser, prefix: str = "") -> dict[str, argparse.ArgumentParser]:
    """The subcommands of ``parser`` by name, each followed by its own (``"paraview setup"``)."""
    found = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found[prefix + name] = sub
                found.update(_subcommands(sub, f"{prefix}{name} "))
    return found


def cli_parsers() -> dict[str, argparse.ArgumentParser]:
    """Every ``pverosion`` subcommand's parser, nested ones too, by name, in the order of ``pverosion --help``."""
    from pverosion.cli import build_parser

    return _subcommands(build_parser())


def _documented(objects, module_name: str, name: str) -> bool:
    return f"{module_name}.{name}" in objects or canonical_name(module_name, name) in objects


def missing_from_reference(objects) -> list[str]:
    """Public names (``module.name``) and accessor methods that no page of the reference documents."""
    missing = [f"{m}.{n}" for m in public_modules() for n in public_names(m) if not _documented(objects, m, n)]
    accessor = importlib.import_module(ACCESSOR.rsplit(".", 1)[0]).ErosionAccessor
    missing += [f"{ACCESSOR}.{n}" for n, _ in inspect.getmembers(accessor, inspect.isfunction)
                if not n.startswith("_") and f"{ACCESSOR}.{n}" not in objects]
    return missing


__all__ = ["ACCESSOR", "GROUPS", "PACKAGE", "canonical_name", "cli_parsers", "index_page", "missing_from_reference",
           "module_page", "public_modules", "public_names"]
