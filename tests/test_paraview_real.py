"""The plugin in a real ParaView: runs tests/paraview/pvbatch_suite.py under ``xvfb-run pvbatch``.

Needs ParaView's ``pvbatch`` and a folder set up with ``pverosion paraview
setup --pvpython PVPYTHON --target DIR``, named by ``PVEROSION_PARAVIEW_SITE``
(.ci/run does both). The suite runs this checkout's pverosion (placed before
DIR on ParaView's ``PYTHONPATH``) with DIR's dependencies, and caches numba's
kernels in DIR, apart from this interpreter's.
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from conftest import run_pvbatch

from pverosion.paraview_setup import host_requirements, plugin_dir, probe

ROOT = Path(__file__).resolve().parents[1]
SUITE = ROOT / "tests" / "paraview" / "pvbatch_suite.py"
TRACE = ROOT / "examples" / "paraview" / "weathering_scene.py"
PVBATCH, PVPYTHON = shutil.which("pvbatch"), shutil.which("pvpython")
SITE = os.environ.get("PVEROSION_PARAVIEW_SITE")

needs_paraview = pytest.mark.skipif(PVBATCH is None or PVPYTHON is None,
                                    reason="ParaView's pvbatch/pvpython are not on PATH (Debian/Ubuntu: apt-get "
                                           "install paraview python3-paraview xvfb)")
needs_site = pytest.mark.skipif(not SITE, reason="PVEROSION_PARAVIEW_SITE is not set: run `pverosion paraview "
                                                 "setup --pvpython pvpython --target DIR` and set it to DIR")


def _environment() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{SITE}"
    env["PV_PLUGIN_PATH"] = str(plugin_dir())
    env["NUMBA_CACHE_DIR"] = str(Path(SITE) / "numba-cache")
    return env


def _pvbatch(script: Path, out: Path) -> subprocess.CompletedProcess:
    return run_pvbatch([PVBATCH, str(script), str(out)], env=_environment(), cwd=out)


@needs_paraview
def test_probe_reads_paraviews_own_python_and_vtk():
    host = probe(PVPYTHON)
    script = "import numpy, vtkmodules.vtkCommonCore as c; print(numpy.__version__, c.vtkVersion.GetVTKVersion())"
    numpy_version, vtk_version = subprocess.run([PVPYTHON, "-c", script], capture_output=True, text=True,
                                                check=True).stdout.split()[-2:]
    assert (host["numpy"], host["vtk"]) == (numpy_version, vtk_version)
    assert f"numpy=={numpy_version}" in host_requirements(host)


@needs_paraview
@needs_site
def test_importing_pverosion_keeps_pvpython_audible():
    # pvpython prints Python's output and tracebacks through VTK's output window, which PyVista's import replaces
    script = "import pverosion; print('still visible'); raise ValueError('boom')"
    proc = subprocess.run([PVPYTHON, "-c", script], capture_output=True, text=True, env=_environment())
    assert "still visible" in proc.stdout
    assert "ValueError: boom" in proc.stderr and proc.returncode != 0


@needs_paraview
@needs_site
def test_plugin_in_pvbatch(tmp_path):
    proc = _pvbatch(SUITE, tmp_path)
    assert proc.returncode == 0 and "PVEROSION-PARAVIEW-OK" in proc.stdout, (proc.stdout + proc.stderr)[-6000:]
    assert (tmp_path / "weathering.png").stat().st_size > 0
    assert not (tmp_path / "None").exists()


@needs_paraview
@needs_site
def test_sample_trace_runs(tmp_path):
    proc = _pvbatch(TRACE, tmp_path)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-6000:]
    written = sorted(p.name for p in tmp_path.glob("weathering_*.png"))
    assert written == ["weathering_curvature.png"] + [f"weathering_step_{n}.png" for n in (0, 100, 25, 50)]
