"""Curvature normalisations of Skorkovská et al. (2019), §3.1 and §3.4."""

from __future__ import annotations

import numpy as np

__all__ = ["NORMALIZATIONS", "normalize_curvature", "normalize_shifted", "normalize_symmetric"]

NORMALIZATIONS = ("none", "symmetric", "shifted")
"""Accepted values of the ``normalization`` option."""


def normalize_symmetric(values) -> np.ndarray:
    """Scale ``<-H, H>`` to ``<-1, 1>`` with ``H = max(|min|, |max|)``, keeping zero at zero.

    Used by weathering. Values that already lie in ``<-1, 1>`` are returned
    unchanged, as in the paper (rescaling a nearly flat scene would blow up noise).

    Parameters
    ----------
    values : array_like, shape (V,)

    Returns
    -------
    numpy.ndarray, shape (V,)
    """
    h = np.asarray(values, dtype=np.float64)
    bound = float(np.max(np.abs(h))) if h.size else 0.0
    return h.copy() if bound <= 1.0 else h / bound


def normalize_shifted(values) -> np.ndarray:
    """Map ``<H_min, H_max>`` linearly onto ``<0, 1>``.

    Used by hydraulic erosion, where gaps erode slowest and protrusions
    fastest. A constant input (no curvature range) maps to 0.5 everywhere.

    Parameters
    ----------
    values : array_like, shape (V,)

    Returns
    -------
    numpy.ndarray, shape (V,)
    """
    h = np.asarray(values, dtype=np.float64)
    if h.size == 0:
        return h.copy()
    lo, hi = float(h.min()), float(h.max())
    if hi <= lo:
        return np.full_like(h, 0.5)
    return (h - lo) / (hi - lo)


def normalize_curvature(values, method: str) -> np.ndarray:
    """Apply the normalisation named ``method``.

    Parameters
    ----------
    values : array_like, shape (V,)
    method : {"none", "symmetric", "shifted"}

    Returns
    -------
    numpy.ndarray, shape (V,)
    """
    if method == "symmetric":
        return normalize_symmetric(values)
    if method == "shifted":
        return normalize_shifted(values)
    if method == "none":
        return np.asarray(values, dtype=np.float64).copy()
    raise ValueError(f"normalization must be one of {NORMALIZATIONS}; got {method!r}")
