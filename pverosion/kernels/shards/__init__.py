"""Freeze–thaw weathering on Voronoi shards (Mateos et al.).

:mod:`.voronoi` (cells), :mod:`.seed_patterns` (seeds), :mod:`.graph` (shards and links),
:mod:`.geometry` (link polygons, shard surfaces), :mod:`.freeze_thaw` (the weathering).  The
package re-exports what ``pverosion.kernels.shards`` held when it was one module.
"""

from pverosion._moved import reexport
from pverosion.kernels.shards.graph import *  # noqa: F401,F403

__all__, __getattr__ = reexport(__name__, "pverosion.kernels.shards.graph")
