"""Pressure projection on a MAC grid: multigrid-preconditioned conjugate gradients (MGPCG).

Cells are LIQUID (unknown pressure), AIR (free surface: pressure 0, a
Dirichlet condition) or SOLID (no flow through its faces, a Neumann
condition); the grid border counts as solid. With ``q = p dt / (rho h)`` the
discrete Poisson problem of a projection is::

    n_open(c) q_c - sum_{liquid nb} q_nb = -div(c)      for every liquid cell c

where ``div(c)`` is the sum of the outgoing face velocities of ``c`` and
``n_open`` counts its non-solid neighbours. The matrix is symmetric positive
(semi-)definite. It is solved by conjugate gradients preconditioned with one
geometric multigrid V-cycle (after McAdams, Sifakis and Teran 2010): damped
Jacobi smoothing, cell-type coarsening in which AIR dominates LIQUID
dominates SOLID, piecewise-constant prolongation and its transpose as
restriction (the Galerkin coarse operator of that pair is four times the
re-discretised one, which the restriction accounts for). The V-cycle is a
symmetric operator, so CG stays valid whatever the coarsening's quality.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import prange

from pverosion.kernels._jit import njit

__all__ = ["AIR", "LIQUID", "SOLID", "PoissonSolve", "divergence", "pressure_solve"]

AIR = np.int8(0)
LIQUID = np.int8(1)
SOLID = np.int8(2)

_JACOBI_WEIGHT = 2.0 / 3.0
_SMOOTHING = 2
_COARSEST = 6  # stop coarsening when a side reaches this many cells
_COARSE_SWEEPS = 40


@dataclass(frozen=True)
class PoissonSolve:
    """Outcome of :func:`pressure_solve`.

    Attributes
    ----------
    iterations : int
        CG iterations used.
    residual : float
        Largest remaining divergence of a liquid cell (sum of its outgoing face velocities).
    converged : bool
        Whether ``residual <= tolerance``.
    """

    iterations: int
    residual: float
    converged: bool


@njit(cache=True, parallel=True, error_model="numpy")
def divergence(u, v, w, types):
    """Sum of the outgoing face velocities of each LIQUID cell (0 elsewhere), shape (nx, ny, nz)."""
    nx, ny, nz = types.shape
    out = np.zeros((nx, ny, nz))
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if types[i, j, k] == LIQUID:
                    out[i, j, k] = u[i + 1, j, k] - u[i, j, k] + v[i, j + 1, k] - v[i, j, k] + w[i, j, k + 1] - w[i, j, k]
    return out


@njit(cache=True, inline="always")
def _kind(types, i, j, k):
    nx, ny, nz = types.shape
    if i < 0 or j < 0 or k < 0 or i >= nx or j >= ny or k >= nz:
        return SOLID
    return types[i, j, k]


@njit(cache=True, parallel=True, error_model="numpy")
def _diagonal(types):
    nx, ny, nz = types.shape
    diag = np.zeros((nx, ny, nz))
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if types[i, j, k] != LIQUID:
                    continue
                n = 0
                for di, dj, dk in ((-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)):
                    if _kind(types, i + di, j + dj, k + dk) != SOLID:
                        n += 1
                diag[i, j, k] = n
    return diag


@njit(cache=True, inline="always")
def _neighbour_sum(x, types, i, j, k):
    total = 0.0
    for di, dj, dk in ((-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)):
        if _kind(types, i + di, j + dj, k + dk) == LIQUID:
            total += x[i + di, j + dj, k + dk]
    return total


@njit(cache=True, parallel=True, error_model="numpy")
def _apply(x, types, diag, scale, out):
    """out = scale * A x on LIQUID cells (0 elsewhere)."""
    nx, ny, nz = types.shape
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if types[i, j, k] == LIQUID:
                    out[i, j, k] = scale * (diag[i, j, k] * x[i, j, k] - _neighbour_sum(x, types, i, j, k))
                else:
                    out[i, j, k] = 0.0


@njit(cache=True, parallel=True, error_model="numpy")
def _jacobi(x, b, types, diag, scale, sweeps):
    """Damped Jacobi sweeps on scale * A x = b (x updated in place)."""
    nx, ny, nz = types.shape
    tmp = np.empty_like(x)
    for _ in range(sweeps):
        for i in prange(nx):
            for j in range(ny):
                for k in range(nz):
                    if types[i, j, k] == LIQUID and diag[i, j, k] > 0.0:
                        ax = scale * (diag[i, j, k] * x[i, j, k] - _neighbour_sum(x, types, i, j, k))
                        tmp[i, j, k] = x[i, j, k] + _JACOBI_WEIGHT * (b[i, j, k] - ax) / (scale * diag[i, j, k])
                    else:
                        tmp[i, j, k] = 0.0
        x[:] = tmp


@njit(cache=True, parallel=True, error_model="numpy")
def _residual(x, b, types, diag, scale, out):
    nx, ny, nz = types.shape
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if types[i, j, k] == LIQUID:
                    out[i, j, k] = b[i, j, k] - scale * (diag[i, j, k] * x[i, j, k] - _neighbour_sum(x, types, i, j, k))
                else:
                    out[i, j, k] = 0.0


@njit(cache=True, parallel=True)
def _coarsen_types(types):
    nx, ny, nz = types.shape
    cx, cy, cz = (nx + 1) // 2, (ny + 1) // 2, (nz + 1) // 2
    out = np.empty((cx, cy, cz), np.int8)
    for I in prange(cx):
        for J in range(cy):
            for K in range(cz):
                air = False
                liquid = False
                for i in range(2 * I, min(2 * I + 2, nx)):
                    for j in range(2 * J, min(2 * J + 2, ny)):
                        for k in range(2 * K, min(2 * K + 2, nz)):
                            t = types[i, j, k]
                            air |= t == AIR
                            liquid |= t == LIQUID
                out[I, J, K] = AIR if air else (LIQUID if liquid else SOLID)
    return out


@njit(cache=True, parallel=True)
def _restrict(fine, fine_types, coarse, coarse_types):
    """Sum of the LIQUID children, divided by 4 (Galerkin scaling), on LIQUID coarse cells."""
    nx, ny, nz = fine.shape
    cx, cy, cz = coarse.shape
    for I in prange(cx):
        for J in range(cy):
            for K in range(cz):
                total = 0.0
                if coarse_types[I, J, K] == LIQUID:
                    for i in range(2 * I, min(2 * I + 2, nx)):
                        for j in range(2 * J, min(2 * J + 2, ny)):
                            for k in range(2 * K, min(2 * K + 2, nz)):
                                if fine_types[i, j, k] == LIQUID:
                                    total += fine[i, j, k]
                coarse[I, J, K] = 0.25 * total


@njit(cache=True, parallel=True)
def _prolong_add(coarse, fine, fine_types):
    nx, ny, nz = fine.shape
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if fine_types[i, j, k] == LIQUID:
                    fine[i, j, k] += coarse[i // 2, j // 2, k // 2]


class _Hierarchy:
    """Cell types and diagonals of every level."""

    def __init__(self, types: np.ndarray):
        self.types = [types]
        self.diag = [_diagonal(types)]
        while min(self.types[-1].shape) > _COARSEST:
            coarse = _coarsen_types(self.types[-1])
            self.types.append(coarse)
            self.diag.append(_diagonal(coarse))

    def vcycle(self, b: np.ndarray, level: int = 0) -> np.ndarray:
        types, diag = self.types[level], self.diag[level]
        x = np.zeros_like(b)
        if level == len(self.types) - 1:
            _jacobi(x, b, types, diag, 1.0, _COARSE_SWEEPS)
            return x
        _jacobi(x, b, types, diag, 1.0, _SMOOTHING)
        r = np.empty_like(b)
        _residual(x, b, types, diag, 1.0, r)
        coarse_b = np.empty(self.types[level + 1].shape)
        _restrict(r, types, coarse_b, self.types[level + 1])
        _prolong_add(self.vcycle(coarse_b, level + 1), x, types)
        _jacobi(x, b, types, diag, 1.0, _SMOOTHING)
        return x


@njit(cache=True, parallel=True)
def _dot_rows(a, b, partial):
    """partial[i] = sum(a[i] * b[i]): one slab per thread, each summed in the same order whatever the threads."""
    for i in prange(a.shape[0]):
        partial[i] = np.sum(a[i] * b[i])


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two (nx, ny, nz) arrays, bit-identical for any thread count.

    The slabs are summed in parallel, the slab sums sequentially: a parallel
    reduction (``partial.sum()`` inside a parallel kernel) would split the
    sum by thread and change its rounding with the thread count.
    """
    partial = np.empty(a.shape[0])
    _dot_rows(a, b, partial)
    return float(np.sum(partial))


@njit(cache=True, parallel=True)
def _axpy(alpha, x, y):
    """y += alpha * x."""
    for i in prange(x.shape[0]):
        y[i] += alpha * x[i]


@njit(cache=True, parallel=True)
def _xpby(x, beta, y):
    """y = x + beta * y."""
    for i in prange(x.shape[0]):
        y[i] = x[i] + beta * y[i]


def pressure_solve(
    rhs: np.ndarray, types: np.ndarray, *, guess: np.ndarray | None = None, tolerance: float = 1e-8,
    max_iterations: int = 200,
) -> tuple[np.ndarray, PoissonSolve]:
    """Solve ``A q = rhs`` on the LIQUID cells by MGPCG.

    Parameters
    ----------
    rhs : numpy.ndarray, shape (nx, ny, nz)
        Right-hand side (``-divergence``); ignored outside LIQUID cells.
    types : numpy.ndarray of int8, shape (nx, ny, nz)
        AIR, LIQUID or SOLID per cell.
    guess : numpy.ndarray, optional
        Starting value (e.g. the previous step's pressure); zeros by default.
    tolerance : float, default: 1e-8
        Stop when the largest residual of a liquid cell is at most this.
    max_iterations : int, default: 200

    Returns
    -------
    q : numpy.ndarray, shape (nx, ny, nz)
        The solution (0 outside LIQUID cells).
    info : PoissonSolve
    """
    types = np.ascontiguousarray(types, dtype=np.int8)
    if rhs.shape != types.shape:
        raise ValueError(f"rhs has shape {rhs.shape} but types has shape {types.shape}")
    liquid = types == LIQUID
    if not liquid.any():
        return np.zeros(types.shape), PoissonSolve(0, 0.0, True)
    # solve on the liquid's bounding box grown by one cell: it holds every neighbour of a liquid cell
    box = tuple(slice(max(int(idx.min()) - 1, 0), int(idx.max()) + 2) for idx in np.nonzero(liquid))
    if any(b.stop - b.start < n for b, n in zip(box, types.shape)):
        q = np.zeros(types.shape)
        q[box], info = pressure_solve(np.ascontiguousarray(rhs[box]), types[box],
                                      guess=None if guess is None else np.ascontiguousarray(guess[box]),
                                      tolerance=tolerance, max_iterations=max_iterations)
        return q, info
    x = np.zeros(types.shape) if guess is None else np.where(liquid, guess, 0.0)
    b = np.where(liquid, rhs, 0.0)
    hierarchy = _Hierarchy(types)
    diag = hierarchy.diag[0]
    r = np.empty_like(b)
    _residual(x, b, types, diag, 1.0, r)
    residual = float(np.abs(r).max()) if r.size else 0.0
    if residual <= tolerance:
        return x, PoissonSolve(0, residual, True)
    z = hierarchy.vcycle(r)
    p = z.copy()
    rz = _dot(r, z)
    ap = np.empty_like(b)
    for iteration in range(1, max_iterations + 1):
        _apply(p, types, diag, 1.0, ap)
        pap = _dot(p, ap)
        if pap <= 0.0:
            break
        alpha = rz / pap
        _axpy(alpha, p, x)
        _axpy(-alpha, ap, r)
        residual = float(np.abs(r).max())
        if residual <= tolerance:
            return x, PoissonSolve(iteration, residual, True)
        z = hierarchy.vcycle(r)
        rz_new = _dot(r, z)
        _xpby(z, rz_new / rz, p)
        rz = rz_new
    return x, PoissonSolve(iteration, residual, residual <= tolerance)
