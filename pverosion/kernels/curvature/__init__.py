"""Principal curvatures after Rusinkiewicz (2004) and their normalisations (Skorkovská 2019 §3.1, §3.4).

:mod:`.operator` holds the estimator, :mod:`.normalize` the normalisations.  The package
re-exports what ``pverosion.kernels.curvature`` held when it was one module.
"""

from pverosion._moved import reexport
from pverosion.kernels.curvature.operator import *  # noqa: F401,F403

__all__, __getattr__ = reexport(__name__, "pverosion.kernels.curvature.operator")
