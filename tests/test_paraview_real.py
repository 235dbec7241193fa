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

from pverosion.paraview_setup import plugin_dir

ROOT = Path(__file__).resolve().parents[1]
SUITE = ROOT / "tests" / "paraview" / "pvbatch_suite.py"
PVBATCH = shutil.which("pvbatch")
SITE = os.environ.get("PVEROSION_PARAVIEW_SITE")

pytestmark = [
    pytest.mark.skipif(PVBATCH is None, reason="ParaView's pvbatch is not on PATH (Debian/Ubuntu: apt-get install "
                                               "paraview python3-paraview xvfb)"),
    pytest.mark.skipif(not SITE, reason="PVEROSION_PARAVIEW_SITE is not set: run `pverosion paraview setup "
                                        "--pvpython pvpython --target DIR` and set it to DIR"),
]


def test_plugin_in_pvbatch(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["PYTHONPATH"] = f"{ROOT}{os.pathsep}{SITE}"
    env["PV_PLUGIN_PATH"] = str(plugin_dir())
    env["NUMBA_CACHE_DIR"] = str(Path(SITE) / "numba-cache")
    command = [PVBATCH, str(SUITE), str(tmp_path)]
    if shutil.which("xvfb-run") and not env.get("DISPLAY"):
        command = ["xvfb-run", "-a", *command]
    proc = subprocess.run(command, capture_output=True, text=True, env=env, cwd=tmp_path)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "PVEROSION-PARAVIEW-OK" in proc.stdout, output[-6000:]
    assert (tmp_path / "weathering.png").stat().st_size > 0
    assert not (tmp_path / "None").exists()
