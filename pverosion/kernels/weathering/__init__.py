"""Curvature-driven weathering (Skorkovská 2019 §3.2–3.3, §4.1).

:mod:`.model` holds the solver.  The package re-exports what
``pverosion.kernels.weathering`` held when it was one module.
"""

from pverosion._moved import reexport
from pverosion.kernels.weathering.model import *  # noqa: F401,F403

__all__, __getattr__ = reexport(__name__, "pverosion.kernels.weathering.model")
