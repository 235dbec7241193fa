"""Reproductions of the papers' scenes, shared by ``pipelines/`` and ``pverosion demo``.

One module per stage: :mod:`.weathering`, :mod:`.hydraulic`, :mod:`.intersection`,
:mod:`.shards`, :mod:`.voxel`.  The package re-exports what ``pverosion.scenes`` held when
it was one module (the weathering scenes).
"""

from pverosion._moved import reexport
from pverosion.scenes.weathering import *  # noqa: F401,F403

__all__, __getattr__ = reexport(__name__, "pverosion.scenes.weathering")
