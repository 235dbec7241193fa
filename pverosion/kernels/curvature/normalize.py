"""Curvature normalisations of Skorkovská et al. (2019), §3.1 and §3.4."""

from __future__ import annotations

import numpy as np

__all__ = ["NORMALIZATIONS", "SOLVER_NORMALIZATIONS", "normalize_curvature", "normalize_shifted", "normalize_symmetric"]

NORMALIZATIONS = ("none", "symmetric", "shifted")
"""Accepted values of the ``normalization`` option of the curvature stage."""

SOLVER_NORMALIZATIONS = ("scale_free", "paper")
"""Accepted values of the ``normalization`` option of weathering and curvature-driven hydraulic erosion.

``"scale_free"``: the curvature is divided by its extremes over the interior
vertices (neither fixed boundary vertices nor their one-ring), always, so a
model in any units and an open scan erode as the closed model does.
``"paper"``: Skorkovská et al. (2019) exactly: the extremes over all
vertices, and the symmetric rule leaves curvatures within ``<-1, 1>`` alone.
"""


def _bounds_over(h: np.ndarray, where) -> np.ndarray:
    """The values of ``h`` the statistics are taken over: ``h[where]``, or all of ``h`` when ``where`` is
    None or selects nothing."""
    if where is None:
        return h
    mask = np.asarray(where, dtype=bool)
    if mask.shape != h.shape:
        raise ValueError(f"where must have the shape of the values {h.shape}; got {mask.shape}")
    return h[mask] if mask.any() else h


def normalize_symmetric(values, *, where=None, always: bool = False) -> np.ndarray:
    """Scale ``<-H, H>`` to ``<-1, 1>`` with ``H = max(|min|, |max|)``, keeping zero at zero.

    Used by weathering. By default (``always=False``) values that already lie
    in ``<-1, 1>`` are returned unchanged, as in the paper (rescaling a nearly
    flat scene would blow up noise); as ``|H|`` scales with 1 / length, that rule
    depends on the model's units. ``always=True`` divides by H whatever its
    size, which makes the result independent of the units.

    Parameters
    ----------
    values : array_like, shape (V,)
    where : array_like of bool, shape (V,), optional
        Values H is taken over (default: all; a mask selecting none counts
        as all). Values outside it may exceed H; with ``always=True`` the
        result is clipped to ``<-1, 1>``.
    always : bool, default: False
        Divide by H even when it is <= 1.

    Returns
    -------
    numpy.ndarray, shape (V,)
    """
    h = np.asarray(values, dtype=np.float64)
    if h.size == 0:
        return h.copy()
    bound = float(np.max(np.abs(_bounds_over(h, where))))
    if always:
        return np.clip(h / bound, -1.0, 1.0) if bound > 0.0 else h.copy()
    return h.copy() if bound <= 1.0 else h / bound


def normalize_shifted(values, *, where=None) -> np.ndarray:
    """Map ``<H_min, H_max>`` linearly onto ``<0, 1>``.

    Used by hydraulic erosion, where gaps erode slowest and protrusions
    fastest. A constant input (no curvature range) maps to 0.5 everywhere.

    Parameters
    ----------
    values : array_like, shape (V,)
    where : array_like of bool, shape (V,), optional
        Values H_min and H_max are taken over (default: all; a mask
        selecting none counts as all); the others are clipped to ``<0, 1>``.

    Returns
    -------
    numpy.ndarray, shape (V,)
    """
    h = np.asarray(values, dtype=np.float64)
    if h.size == 0:
        return h.copy()
    over = _bounds_over(h, where)
    lo, hi = float(over.min()), float(over.max())
    if hi <= lo:
        return np.full_like(h, 0.5)
    return np.clip((h - lo) / (hi - lo), 0.0, 1.0)


def normalize_curvature(values, method: str) -> np.ndarray:
    """Apply the normalisation named ``method``: the ``mean_curvature_normalized`` array of the curvature stage.

    ``"symmetric"`` divides by ``max |H|`` always (:func:`normalize_symmetric` with ``always=True``) and
    ``"shifted"`` maps the range onto ``<0, 1>``, so both are the same in any units.

    Parameters
    ----------
    values : array_like, shape (V,)
    method : {"none", "symmetric", "shifted"}

    Returns
    -------
    numpy.ndarray, shape (V,)
    """
    if method == "symmetric":
        return normalize_symmetric(values, always=True)
    if method == "shifted":
        return normalize_shifted(values)
    if method == "none":
        return np.asarray(values, dtype=np.float64).copy()
    raise ValueError(f"normalization must be one of {NORMALIZATIONS}; got {method!r}")
