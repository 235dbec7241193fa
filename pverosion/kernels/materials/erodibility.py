"""Erodibility of mesh vertices: per-vertex values, a function of position, or a material field.

Shared by every stage that erodes a mesh (weathering, hydraulic erosion).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pverosion.kernels.materials.field import MaterialField

__all__ = ["Erodibility", "check_erodibility", "erodibility_now", "renumbered_erodibility"]

Erodibility = np.ndarray | Callable[[np.ndarray], np.ndarray] | MaterialField | None
"""What the stages accept as erodibility: an array (V,), a callable of points (N, 3) -> (N,), a
:class:`~pverosion.kernels.materials.field.MaterialField`, or None (uniform)."""


def check_erodibility(erodibility: Erodibility, n_vertices: int):
    """Validated erodibility: None, a callable, a MaterialField, or a copy of an array (V,) of values >= 0."""
    if erodibility is None or callable(erodibility) or isinstance(erodibility, MaterialField):
        return erodibility
    values = np.asarray(erodibility, dtype=np.float64)
    if values.shape != (n_vertices,):
        raise ValueError(f"erodibility must have shape ({n_vertices},) (one value per vertex); got {values.shape}")
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError("erodibility must be finite and non-negative")
    return values.copy()


class _Renumbered(MaterialField):
    """A material field read in another vertex numbering: local vertex ``i`` is the field's vertex ``order[i]``."""

    def __init__(self, field: MaterialField, order: np.ndarray) -> None:
        self.field = field
        self.order = order

    def sample(self, points, *, ids=None):
        return self.field.sample(points, ids=self.order if ids is None else self.order[np.asarray(ids, np.int64)])


def renumbered_erodibility(erodibility: Erodibility, order: np.ndarray) -> Erodibility:
    """``erodibility`` of the caller's vertices, for a solver whose vertex ``i`` is the caller's ``order[i]``.

    Parameters
    ----------
    erodibility : Erodibility
        Validated (:func:`check_erodibility`) for the caller's vertices.
    order : numpy.ndarray, shape (V,), int64

    Returns
    -------
    Erodibility
        An array in the solver's order, a field that reads the caller's
        per-vertex materials, or ``erodibility`` itself when it depends on
        the points only (a callable) or is None.
    """
    if isinstance(erodibility, MaterialField):
        return _Renumbered(erodibility, order)
    if erodibility is None or callable(erodibility):
        return erodibility
    return np.asarray(erodibility)[order]


def erodibility_now(erodibility: Erodibility, points: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Erodibility (V',) of the current vertices ``points`` (V', 3) with input indices ``ids`` (V',)."""
    if isinstance(erodibility, MaterialField):
        return erodibility.erodibility(points, ids=ids)
    if callable(erodibility):
        values = np.asarray(erodibility(points.copy()), dtype=np.float64)
        if values.shape != (len(points),):
            raise ValueError(f"erodibility callable must return shape ({len(points)},); got {values.shape}")
        if not np.all(np.isfinite(values)) or np.any(values < 0):
            raise ValueError("erodibility callable returned negative or non-finite values")
        return values
    return erodibility[ids]
