"""numba's on-disk cache, made to follow every kernel source file instead of one.

numba keeps a compiled kernel with a stamp of the kernel's own source file,
and reuses it as long as that file is unchanged. But the compiled code also
holds the kernels it calls, inlined or linked in, and the module constants it
reads (:data:`~pverosion.kernels._scatter.CHUNKS`, say), as they were when it
was compiled. After an upgrade or a ``git pull`` that changes only a callee or a
constant, numba would load old code for the unchanged callers: wrong results,
or out-of-bounds memory when an array size changed.

:func:`install` puts :class:`KernelTreeLocator` first among numba's cache
locators. For the functions of ``pverosion/kernels`` it finds the same cache
folder as numba's own locators, and stamps the cache with the file's own stamp
and the digest of every kernel source file (:func:`sources_digest`). Any change
to a kernel source then recompiles every kernel once. Other functions are left
to numba's locators. ``NUMBA_CACHE_LOCATOR_CLASSES``, when set, takes precedence.
"""

from __future__ import annotations

import hashlib
import os
from functools import cache
from pathlib import Path

__all__ = ["KERNELS", "KernelTreeLocator", "install", "sources_digest"]

KERNELS = Path(__file__).resolve().parent
"""The folder of the kernel sources the stamp covers."""


def sources_digest(folder: Path = KERNELS) -> bytes:
    """SHA-256 over the relative path and content of every ``.py`` file under ``folder``, in path order.

    Parameters
    ----------
    folder : pathlib.Path, default: the kernels folder

    Returns
    -------
    bytes
        32 bytes; the same for the same sources wherever they are.
    """
    digest = hashlib.sha256()
    for path in sorted(folder.rglob("*.py")):
        digest.update(path.relative_to(folder).as_posix().encode())
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.digest()


@cache
def _kernels_digest() -> bytes:
    return sources_digest(KERNELS)


def _is_kernel_source(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(KERNELS)
    except OSError:
        return False


def _locator_base():
    from numba.core import caching

    return caching._CacheLocator


class KernelTreeLocator(_locator_base()):
    """The locator numba's own locators give for a kernel, with a stamp that covers every kernel source file."""

    def __init__(self, inner) -> None:
        self._inner = inner
        self._py_file = getattr(inner, "_py_file", None)  # numba names the file in its warnings

    def ensure_cache_path(self) -> None:
        self._inner.ensure_cache_path()

    def get_cache_path(self) -> str:
        return self._inner.get_cache_path()

    def get_source_stamp(self) -> tuple:
        return self._inner.get_source_stamp(), _kernels_digest()

    def get_disambiguator(self) -> str:
        return self._inner.get_disambiguator()

    @classmethod
    def from_function(cls, py_func, py_file):
        """The wrapped locator of the first of numba's locators that takes ``py_func``; None outside the kernels."""
        if not _is_kernel_source(py_file):
            return None
        for other in _numba_locators():
            if other is not cls:
                inner = other.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
        return None


def _numba_locators() -> list:
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    return impl._locator_classes


def install() -> None:
    """Put :class:`KernelTreeLocator` first among numba's cache locators (once; before any kernel is defined)."""
    if os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES"):
        return
    locators = _numba_locators()
    if KernelTreeLocator not in locators:
        locators.insert(0, KernelTreeLocator)
