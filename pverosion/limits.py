"""Resource limits: requests are estimated and refused *before* anything is allocated.

A run whose estimated memory exceeds :func:`memory_limit`, or whose work per
step exceeds :func:`work_limit`, stops at once with a :class:`ResourceLimitError`
naming the option responsible and the estimate, instead of ending in a
``MemoryError``, a C++ ``std::bad_alloc`` or a run that never finishes.

The limits are read from the environment on every check:

``PVEROSION_MEMORY_LIMIT``
    Bytes a single request may allocate, with an optional ``K``/``M``/``G``/``T``
    suffix (binary units), e.g. ``16G``; ``0`` disables the check. Default: half
    of the memory available when the check runs (``MemAvailable`` on Linux).
``PVEROSION_WORK_LIMIT``
    The most elementary operations (cell or particle updates) one time step may
    take, e.g. ``1e12``; ``0`` disables the check. Default ``1e11``, about an
    hour of one step on one core.
"""

from __future__ import annotations

import math
import os

__all__ = ["ResourceLimitError", "check_memory", "check_work", "format_bytes", "memory_limit", "work_limit"]

_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
_DEFAULT_WORK = 1e11


class ResourceLimitError(ValueError):
    """A request that would need more memory or time than the configured limit."""


def _available_memory() -> float:
    """Bytes of memory available to a new allocation (MemAvailable on Linux; physical memory elsewhere)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as info:
            for line in info:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return float(8 << 30)


def _parse_size(text: str, name: str) -> float:
    text = text.strip().upper().removesuffix("B").removesuffix("I")
    unit = text[-1:] if text[-1:] in _UNITS and text[-1:] else ""
    try:
        value = float(text[: len(text) - len(unit)]) * _UNITS[unit]
    except ValueError:
        raise ValueError(f"{name} must be a number of bytes such as 8G or 512M; got {text!r}") from None
    if not value >= 0 or value == float("inf"):
        raise ValueError(f"{name} must be a finite number >= 0; got {text!r}")
    return value


def memory_limit() -> float:
    """Bytes one request may allocate (``inf`` when the check is disabled).

    ``PVEROSION_MEMORY_LIMIT`` if set, else half of the available memory.
    """
    text = os.environ.get("PVEROSION_MEMORY_LIMIT", "").strip()
    if text:
        value = _parse_size(text, "PVEROSION_MEMORY_LIMIT")
        return float("inf") if value == 0 else value
    return 0.5 * _available_memory()


def work_limit() -> float:
    """Elementary operations one step may take (``inf`` when disabled): ``PVEROSION_WORK_LIMIT`` or 1e11."""
    text = os.environ.get("PVEROSION_WORK_LIMIT", "").strip()
    if not text:
        return _DEFAULT_WORK
    value = _parse_size(text, "PVEROSION_WORK_LIMIT")
    return float("inf") if value == 0 else value


def format_bytes(nbytes: float) -> str:
    """``nbytes`` in binary units, e.g. ``"7.5 GiB"``."""
    value = float(nbytes)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(value) < 1024 or unit == "PiB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1024
    return f"{value:.1f} PiB"  # pragma: no cover - the loop always returns


def _as_float(value: float) -> float:
    """``float(value)``, ``inf`` for an integer too large for a float (an estimate from a huge count)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def check_memory(nbytes: float, *, option: str, what: str, remedy: str | None = None) -> None:
    """Refuse a request estimated to need ``nbytes`` bytes when that exceeds :func:`memory_limit`.

    Parameters
    ----------
    nbytes : float
        Estimated bytes.
    option : str
        The option (or options) that set the size, named in the message.
    what : str
        What would be allocated, e.g. ``"the list of 1000000001 time steps"``.
    remedy : str, optional
        What the user can do instead (default: ``"lower <option>"``).

    Raises
    ------
    ResourceLimitError
        If the estimate exceeds the limit.
    """
    limit = memory_limit()
    nbytes = _as_float(nbytes)
    if not nbytes <= limit:
        source = ("PVEROSION_MEMORY_LIMIT" if os.environ.get("PVEROSION_MEMORY_LIMIT", "").strip()
                  else "half the available memory, as PVEROSION_MEMORY_LIMIT is not set")
        raise ResourceLimitError(
            f"{option}: {what} would need about {format_bytes(nbytes)}, more than the memory limit of "
            f"{format_bytes(limit)} ({source}); {remedy or f'lower {option}'}, or raise PVEROSION_MEMORY_LIMIT")


def check_work(operations: float, *, option: str, what: str) -> None:
    """Refuse a step estimated to take ``operations`` elementary operations above :func:`work_limit`.

    Raises
    ------
    ResourceLimitError
        If the estimate exceeds the limit.
    """
    limit = work_limit()
    operations = _as_float(operations)
    if not operations <= limit:
        raise ResourceLimitError(
            f"{option}: {what} would take about {float(operations):.3g} operations per step, more than the limit of "
            f"{limit:.3g} (PVEROSION_WORK_LIMIT); lower {option}, or raise PVEROSION_WORK_LIMIT")
