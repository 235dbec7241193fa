"""Compile the stages' numba kernels ahead of use: ``pverosion warmup`` and :func:`warm_up`.

numba compiles a kernel the first time it is called and keeps the machine code
in its on-disk cache; every later process loads it from there. The first run
of a stage after installing (or upgrading numba) therefore pays the
compilation. :func:`warm_up` runs each chosen stage once on a tiny procedural
input, in parallel processes when there are several stages, so the cache is
filled before real work starts: ``pverosion demo`` and batch runs call it.
The inputs go through the same filters and validation as real data, so the
kernels are compiled for the same argument types a real run uses.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

from pverosion._runtime import stage_run
from pverosion._stages import STAGE_INDEX, resolve_command

__all__ = ["WARMUPS", "warm_up"]


def _rock():
    from pverosion.examples import load_rock

    return load_rock(subdivisions=2)


def _ball(n: int = 12):
    import numpy as np
    import pyvista as pv

    axis = np.linspace(-1.0, 1.0, n)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    image = pv.ImageData(dimensions=(n, n, n), origin=(-1.0, -1.0, -1.0), spacing=(2 / (n - 1),) * 3)
    image["density"] = (1.0 - np.sqrt(x**2 + y**2 + z**2)).transpose(2, 1, 0).ravel()  # x fastest
    return image


def _curvature() -> None:
    from pverosion.api import curvature

    curvature(_rock(), normalization="symmetric")


def _weather() -> None:
    from pverosion.api import weather

    weather(_rock(), iterations=2, check_every=1)


def _hydraulic() -> None:
    import pyvista as pv

    from pverosion.api import hydraulic_erosion

    slab = pv.Box(bounds=(-2, 2, -2, 2, -0.5, 0.5), level=4, quads=False).clean()
    hydraulic_erosion(slab, emitter=["0,0,1.2,0.3,0,-1,0.3,500"], drain=["plane:0,0,-1,0.2"], radius=0.1,
                      iterations=2)


def _materials() -> None:
    from pverosion.api import materials_from_volume

    materials_from_volume(_ball(), [0.2, 0.6])


def _sample_materials() -> None:
    from pverosion.api import materials_from_volume, sample_materials

    field = materials_from_volume(_ball(), [0.2, 0.6])
    sample_materials(field, dimensions=(6, 6, 6), bounds=(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0))


def _voxel() -> None:
    from pverosion.api import voxel_erosion
    from pverosion.scenes.voxel import meander_grid

    grid, _ = meander_grid((16, 8, 8), spacing=0.05, depth=2, half_width=2.0, amplitude=1.0)
    voxel_erosion(grid, iterations=2, source_velocity=(1.5, 0.0, 0.0))


def _shard_graph() -> None:
    from pverosion.api import shard_graph
    from pverosion.scenes.shards import hill_cone

    shard_graph(hill_cone(resolution=16), cells=20)


def _shards() -> None:
    from pverosion.api import freeze_thaw
    from pverosion.scenes.shards import hill_cone

    freeze_thaw(hill_cone(resolution=16), iterations=1, paths_per_step=50, cells=20)


def _repair() -> None:
    from pverosion.api import repair
    from pverosion.scenes.intersection import two_spheres

    a, b = two_spheres()
    repair(a + b)


def _boolean() -> None:
    from pverosion.api import boolean
    from pverosion.scenes.intersection import two_spheres

    boolean(*two_spheres(), "union")


WARMUPS: dict[str, Callable[[], None]] = {
    "curvature": _curvature,
    "weather": _weather,
    "hydraulic": _hydraulic,
    "materials": _materials,
    "sample-materials": _sample_materials,
    "voxel": _voxel,
    "shard-graph": _shard_graph,
    "freeze-thaw": _shards,
    "repair": _repair,
    "boolean": _boolean,
}
"""The tiny run of each stage, by command name."""


def _warm_one(stage: str) -> float:
    """Run the tiny ``stage``; returns its wall time in seconds."""
    start = time.perf_counter()
    with stage_run(stage):
        WARMUPS[stage]()
    return time.perf_counter() - start


def _without_helper() -> None:
    os.environ["PVEROSION_PRECOMPILE"] = "0"  # in a pool worker


def warm_up(stages: Sequence[str] | None = None, *, processes: int | None = None) -> dict[str, float]:
    """Compile (or load from numba's cache) the kernels of ``stages``.

    Parameters
    ----------
    stages : sequence of str, optional
        Command names of the stages (default: all, see :data:`WARMUPS`).
    processes : int, optional
        Worker processes when there are several stages (default: one per core,
        at most one per stage). One stage, or ``processes=1``, runs in this
        process, which then has the kernels loaded too.

    Returns
    -------
    dict
        Wall seconds of each stage's tiny run (compilation included), by stage.

    Raises
    ------
    ValueError
        If a stage is unknown or ``processes`` is below 1.
    """
    stages = list(WARMUPS) if stages is None else list(dict.fromkeys(resolve_command(s, stacklevel=2) for s in stages))
    unknown = [s for s in stages if s not in WARMUPS]
    if unknown:
        raise ValueError(f"unknown stage(s) {', '.join(map(repr, unknown))}; "
                         f"stages: {', '.join(s.command for s in STAGE_INDEX)}")
    if processes is not None and processes < 1:
        raise ValueError(f"processes must be >= 1; got {processes}")
    n = min(processes or os.cpu_count() or 1, len(stages))
    if n <= 1:
        return {stage: _warm_one(stage) for stage in stages}
    # spawn: a forked child would inherit numba's thread pool state from this process
    # each worker compiles its own stage: no compile helper processes (pverosion._precompile) on top
    with ProcessPoolExecutor(max_workers=n, mp_context=get_context("spawn"), initializer=_without_helper) as pool:
        return dict(zip(stages, pool.map(_warm_one, stages)))
