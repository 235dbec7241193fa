"""Material fields (thesis ch. 11): implicit splitting surfaces, BSP trees, the fields built on them.

:mod:`.surfaces` (implicit surfaces), :mod:`.bsp` (trees), :mod:`.field` (fields).  The package
re-exports what ``pverosion.kernels.materials`` held when it was one module.
"""

from pverosion._moved import reexport
from pverosion.kernels.materials.field import *  # noqa: F401,F403

__all__, __getattr__ = reexport(__name__, "pverosion.kernels.materials.field")
