"""Curvature-driven weathering (Skorkovská 2019 §3.2–3.3, §4.1).

:mod:`.model` holds the solver, :mod:`.displacement` the kernel of its step.
The package re-exports what ``pverosion.kernels.weathering`` held when it was
one module, importing :mod:`.model` on first use: a process that compiles the
step kernel ahead of a stage (:mod:`pverosion._precompile`) imports
:mod:`.displacement` without the solver and its dependencies.
"""

import importlib
import warnings

__all__ = ["DIRECTIONS", "STAT_NAMES", "WeatheringSolver"]
"""The public names of :mod:`.model`."""


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    model = importlib.import_module(f"{__name__}.model")
    try:
        value = getattr(model, name)
    except AttributeError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    if name not in __all__:
        warnings.warn(f"{__name__}.{name} is now {model.__name__}.{name}", DeprecationWarning, stacklevel=2)
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
