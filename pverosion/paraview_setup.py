"""Set pverosion up for a ParaView's own Python (``pverosion paraview setup`` / ``plugin-path``).

ParaView embeds its own Python and VTK. A second VTK in that process (pip's
``vtk`` wheel) crashes it, so the setup never installs ``vtk``: it asks the
given ``pvpython`` for its Python version, platform, numpy and VTK, then
installs pverosion's pure-Python and binary dependencies for that interpreter
into a separate folder with ``pip install --target`` (numpy pinned to
ParaView's own, which is not installed again; PyVista in a version that
accepts ParaView's VTK), copies the pverosion package there, and writes the
``PYTHONPATH`` / ``PV_PLUGIN_PATH`` lines that make ParaView find both.
Optionally it runs every filter once in ``pvpython`` so that numba's
compiled kernels are cached before the first use in the GUI.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path

__all__ = ["PLUGIN_FILE", "add_parser", "environment_lines", "host_requirements", "plugin_dir", "probe", "setup"]

PLUGIN_FILE = "pverosion_filters.py"
_PACKAGE = Path(__file__).resolve().parent
_MARKER = "PVEROSION-PROBE "
_PROBE = f"""
import inspect, json, platform, sys, sysconfig
import numpy
from vtkmodules.vtkCommonCore import vtkVersion
print({_MARKER!r} + json.dumps({{
    "python": list(sys.version_info[:2]), "platform": sysconfig.get_platform(), "libc": platform.libc_ver(),
    "numpy": numpy.__version__, "vtk": vtkVersion.GetVTKVersion(),
    "getargspec": hasattr(inspect, "getargspec")}}), flush=True)
"""
_SITECUSTOMIZE = '''"""Written by ``pverosion paraview setup``: ParaView <= 5.11 loads Python plugins on Python >= 3.11.

ParaView's plugin loader (paraview.detail.pythonalgorithm) imports inspect.getargspec, which Python 3.11
removed; it only reads ``.args``, which inspect.getfullargspec has too. The sitecustomize module this one
shadows (if any) runs afterwards.
"""
import importlib.util
import inspect
import os
import sys

if not hasattr(inspect, "getargspec"):
    inspect.getargspec = inspect.getfullargspec

_here = os.path.dirname(os.path.abspath(__file__))
for _entry in sys.path:
    _path = os.path.join(_entry or ".", "sitecustomize.py")
    if os.path.abspath(_entry or ".") != _here and os.path.isfile(_path):
        _spec = importlib.util.spec_from_file_location("_shadowed_sitecustomize", _path)
        _spec.loader.exec_module(importlib.util.module_from_spec(_spec))
        break
'''
"""``sitecustomize.py`` written into the target when ParaView's Python lacks ``inspect.getargspec``."""
_PYVISTA_FOR_VTK_BELOW_9_3_1 = "pyvista>=0.48,<0.49"
"""PyVista 0.49 needs VTK >= 9.3.1; 0.48 still runs on 9.2.2 and later (ParaView 5.11 bundles VTK 9.2)."""


def plugin_dir() -> Path:
    """Folder of the ParaView plugin file (``pverosion_filters.py``) and the colour-map preset."""
    return _PACKAGE / "paraview_plugin"


def probe(pvpython: str) -> dict:
    """Python version, platform, glibc, numpy and VTK versions of ParaView's Python.

    Raises
    ------
    RuntimeError
        If ``pvpython`` does not run the probe (its output is in the message).
    """
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as script:
        script.write(_PROBE)
    try:
        proc = subprocess.run([pvpython, script.name], capture_output=True, text=True, timeout=300,
                              env=_clean_env())
    finally:
        os.unlink(script.name)
    for line in proc.stdout.splitlines():
        if line.startswith(_MARKER):
            return json.loads(line[len(_MARKER):])
    raise RuntimeError(f"{pvpython} did not report its Python, numpy and VTK (exit code {proc.returncode}):\n"
                       f"{proc.stdout}{proc.stderr}")


def _clean_env() -> dict:
    """This environment without the Python variables that would give pvpython our packages (and our VTK)."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}


def _version(text: str) -> tuple[int, ...]:
    return tuple(int(x) for x in re.findall(r"\d+", text)[:3])


def _declared_requirements() -> list[str]:
    """pverosion's install requirements: from its metadata, or from pyproject.toml in a source checkout."""
    pyproject = _PACKAGE.parent / "pyproject.toml"
    if pyproject.is_file():
        import tomllib

        with open(pyproject, "rb") as f:
            return list(tomllib.load(f)["project"]["dependencies"])
    return [r for r in metadata.requires("pverosion") or [] if "extra ==" not in r]


def host_requirements(host: dict) -> list[str]:
    """pverosion's requirements for ParaView's Python ``host`` (a :func:`probe` result).

    ``vtk`` is dropped (ParaView's own is used), numpy is pinned to
    ParaView's, and PyVista is limited to versions that accept ParaView's VTK.
    """
    out = []
    for req in _declared_requirements():
        name = re.split(r"[\s<>=!~;\[]", req, maxsplit=1)[0].lower()
        if name == "vtk":
            continue
        if name == "numpy":
            req = f"numpy=={host['numpy']}"
        elif name == "pyvista" and _version(host["vtk"]) < (9, 3, 1):
            req = _PYVISTA_FOR_VTK_BELOW_9_3_1
        out.append(req)
    return out


def _target_options(host: dict) -> list[str]:
    """pip options selecting wheels for ParaView's Python (which need not be the Python running pip)."""
    major, minor = host["python"]
    options = ["--only-binary=:all:", "--python-version", f"{major}.{minor}", "--implementation", "cp",
               "--abi", f"cp{major}{minor}"]
    plat = host["platform"]
    if plat.startswith("linux-"):
        arch = plat.split("-", 1)[1]
        glibc = _version(host["libc"][1]) if host["libc"][0] == "glibc" else (2, 17)
        tags = [f"manylinux_2_{m}_{arch}" for m in range(glibc[1], 16, -1)] + [f"manylinux2014_{arch}"]
    else:  # macosx-11.0-arm64, win-amd64
        tags = [re.sub(r"[-.]", "_", plat)]
    for tag in tags:
        options += ["--platform", tag]
    return options


def _resolve(requirements: list[str], host: dict) -> list[str]:
    """Every distribution the requirements need for ``host``, as ``name==version``, without vtk and numpy."""
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "report.json"
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--dry-run", "--ignore-installed",
                        "--target", tmp, "--report", str(report), *_target_options(host), *requirements], check=True)
        items = json.loads(report.read_text())["install"]
    pins = [f"{i['metadata']['name']}=={i['metadata']['version']}" for i in items]
    return [p for p in pins if p.split("==")[0].lower() not in ("vtk", "numpy")]


def environment_lines(target: Path) -> list[str]:
    """The shell lines that give ParaView the packages in ``target`` and the plugin folder."""
    return [f'export PYTHONPATH="{target}${{PYTHONPATH:+:$PYTHONPATH}}"',
            f'export PV_PLUGIN_PATH="{target / "pverosion" / "paraview_plugin"}${{PV_PLUGIN_PATH:+:$PV_PLUGIN_PATH}}"']


def setup(pvpython: str, target: Path, *, warm: bool = True) -> list[str]:
    """Install pverosion for ParaView's Python into ``target``; return the environment lines.

    Parameters
    ----------
    pvpython : str
        ParaView's Python executable (``pvpython``).
    target : pathlib.Path
        Folder for pverosion and its dependencies; ``target/pverosion-paraview.sh``
        gets the environment lines.
    warm : bool
        Run every filter once in ``pvpython`` so numba's compiled kernels are
        cached (minutes, once).
    """
    host = probe(pvpython)
    print(f"ParaView's Python {'.'.join(map(str, host['python']))} on {host['platform']}: "
          f"numpy {host['numpy']}, VTK {host['vtk']}", flush=True)
    pins = _resolve(host_requirements(host), host)
    print("installing " + " ".join(pins), flush=True)
    target.mkdir(parents=True, exist_ok=True)
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--upgrade", "--target",
                    str(target), *_target_options(host), *pins], check=True)
    shutil.rmtree(target / "pverosion", ignore_errors=True)
    shutil.copytree(_PACKAGE, target / "pverosion", ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    if not host["getargspec"]:
        (target / "sitecustomize.py").write_text(_SITECUSTOMIZE)
    lines = environment_lines(target)
    (target / "pverosion-paraview.sh").write_text("\n".join(lines) + "\n")
    if warm:
        print("compiling pverosion's kernels in ParaView's Python (once, a few minutes)...", flush=True)
        env = _clean_env()
        env["PYTHONPATH"] = str(target)
        # from the target folder: ``-m`` puts the working directory first on sys.path
        subprocess.run([pvpython, "-m", "pverosion.paraview_warmup"], check=True, env=env, cwd=target)
    return lines


def add_parser(subparsers) -> None:
    """Register ``pverosion paraview {setup,plugin-path}``."""
    parser = subparsers.add_parser("paraview", help="use pverosion inside ParaView",
                                   description="Set pverosion up for ParaView's own Python, or print the plugin "
                                               "folder.")
    commands = parser.add_subparsers(dest="paraview_command", required=True)
    run = commands.add_parser("setup", help="install pverosion for a ParaView's Python (never a second VTK)")
    run.add_argument("--pvpython", required=True, help="ParaView's Python executable, e.g. /usr/bin/pvpython")
    run.add_argument("--target", type=Path, default=Path.home() / ".local" / "share" / "pverosion-paraview",
                     help="folder for pverosion and its dependencies (default: %(default)s)")
    run.add_argument("--no-warm", dest="warm", action="store_false",
                     help="skip compiling the kernels in ParaView's Python now (the first use does it)")
    run.set_defaults(func=_run_setup)
    path = commands.add_parser("plugin-path",
                               help="print the path of the ParaView plugin file (its folder goes on PV_PLUGIN_PATH)")
    path.set_defaults(func=_run_plugin_path)


def _run_setup(args: argparse.Namespace) -> int:
    target = args.target.expanduser().resolve()
    lines = setup(args.pvpython, target, warm=args.warm)
    print(f"\npverosion is installed for ParaView in {target}. Before starting paraview, pvpython or pvbatch:\n")
    print("\n".join(lines))
    print(f"\n(or: . {target / 'pverosion-paraview.sh'})")
    return 0


def _run_plugin_path(args: argparse.Namespace) -> int:
    print(plugin_dir() / PLUGIN_FILE)
    return 0
