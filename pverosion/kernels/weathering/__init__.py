"""Curvature-driven weathering (Skorkovská 2019 §3.2–3.3, §4.1).

:mod:`.model` holds the solver, :mod:`.displacement` the kernel of its step.
The package re-exports what ``pverosion.kernels.weathering`` held when it was
one module, importing :mod:`.model` on first use: a process that compiles the
step kernel ahead of a stage (:mod:`pverosion._precompile`) imports
:mod:`.displacement` without the solver and its dependencies.
"""

from pverosion._moved import reexport

__all__, __getattr__ = reexport(__name__, "pverosion.kernels.weathering.model",
                                lazy_names=("DIRECTIONS", "STAT_NAMES", "WeatheringSolver"))


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
