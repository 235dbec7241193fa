"""Uniform discretisation of the Laplace-Beltrami operator (Skorkovská 2019, eq. 2)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels._threads import for_ranges
from pverosion.kernels.mesh.topology import one_ring

if TYPE_CHECKING:
    import scipy.sparse as sp

__all__ = ["laplacian_vectors", "uniform_laplacian"]


@njit(cache=True, error_model="numpy")
def _with_diagonal(indptr, indices):
    """CSR rows ``1/deg`` at the (sorted) neighbours and ``-1`` on the diagonal."""
    n = indptr.shape[0] - 1
    out_ptr = np.zeros(n + 1, np.int64)
    for i in range(n):
        deg = indptr[i + 1] - indptr[i]
        out_ptr[i + 1] = out_ptr[i] + (deg + 1 if deg > 0 else 0)
    out_idx = np.empty(out_ptr[n], np.int64)
    data = np.empty(out_ptr[n])
    for i in range(n):
        deg = indptr[i + 1] - indptr[i]
        if deg == 0:
            continue
        k = out_ptr[i]
        placed = False
        for s in range(indptr[i], indptr[i + 1]):
            j = indices[s]
            if not placed and j > i:
                out_idx[k] = i
                data[k] = -1.0
                k += 1
                placed = True
            out_idx[k] = j
            data[k] = 1.0 / deg
            k += 1
        if not placed:
            out_idx[k] = i
            data[k] = -1.0
    return out_ptr, out_idx, data


def uniform_laplacian(faces: np.ndarray, n_vertices: int, *, edges: np.ndarray | None = None) -> sp.csr_matrix:
    """Sparse uniform Laplacian ``L`` with ``(L @ P)[i] = mean_{j in N(i)} P[j] - P[i]``.

    Build it once per connectivity; apply it to changing point arrays.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int
    edges : numpy.ndarray, shape (E, 2), optional
        Reuse the unique edges of :func:`~pverosion.kernels.mesh.topology.edge_topology`.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (V, V)
        Rows of isolated vertices are zero.
    """
    import scipy.sparse as sp  # SciPy only where a matrix is built, not for the kernels of this module

    indptr, indices = one_ring(faces, n_vertices, edges=edges)
    out_ptr, out_idx, data = _with_diagonal(indptr, indices)
    return sp.csr_matrix((data, out_idx, out_ptr), shape=(n_vertices, n_vertices))


@njit(cache=True, error_model="numpy", nogil=True)
def _ring_offset_range(points, ring_ptr, ring_idx, out, first, last):
    for i in range(first, last):
        start, stop = ring_ptr[i], ring_ptr[i + 1]
        if stop == start:
            continue
        for d in range(3):
            total = 0.0
            for s in range(start, stop):
                total += points[ring_idx[s], d]
            out[i, d] = total / (stop - start) - points[i, d]


def _ring_mean_offsets(points: np.ndarray, ring_ptr: np.ndarray, ring_idx: np.ndarray) -> np.ndarray:
    out = np.zeros_like(points)
    for_ranges(_ring_offset_range, points.shape[0], points, ring_ptr, ring_idx, out)
    return out


def laplacian_vectors(
    points: np.ndarray, faces: np.ndarray, *, ring: tuple[np.ndarray, np.ndarray] | None = None
) -> np.ndarray:
    """Uniform Laplacian vectors L_i of every vertex (seed eq. 2).

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
    ring : tuple, optional
        Reuse the one-ring CSR of :func:`~pverosion.kernels.mesh.topology.one_ring`
        (build it once per connectivity; this is the fast path of iterative
        stages).

    Returns
    -------
    numpy.ndarray, shape (V, 3)
        ``L_i = (1/|N(i)|) sum_{j in N(i)} (v_j - v_i)``; zero for isolated vertices.
    """
    ring_ptr, ring_idx = ring if ring is not None else one_ring(faces, len(points))
    return _ring_mean_offsets(np.ascontiguousarray(points, dtype=np.float64), ring_ptr, ring_idx)
