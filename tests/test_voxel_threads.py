"""Voxel erosion gives bit-identical output for any thread count, like every other stage."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# a meander wide enough in x that two threads split every x-parallel loop and reduction
SCRIPT = """
import hashlib
import numpy as np
from pverosion.api import voxel_erosion
from pverosion.scenes.voxel import meander_grid

grid = meander_grid(shape=(64, 32, 16), depth=4, half_width=3.0)[0]
state = voxel_erosion(grid, iterations=3, time_step=0.02)["state"]
digest = hashlib.sha256()
for data in (state.point_data, state.field_data):
    for name in sorted(data.keys()):
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(data[name]).tobytes())
print(digest.hexdigest(), float(np.abs(state["pressure"]).max()))
"""


def _run(threads: int) -> str:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_NUM_THREADS": str(threads)}
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True)
    return done.stdout.split()


def test_voxel_erosion_is_bit_identical_with_one_and_two_threads():
    one, two = _run(1), _run(2)
    assert float(one[1]) > 0.0  # the water moved: the pressure solve ran
    assert one[0] == two[0]
