"""Uniform discretisation of the Laplace-Beltrami operator (Skorkovská 2019, eq. 2)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from pverosion.kernels.topology import one_ring

__all__ = ["laplacian_vectors", "uniform_laplacian"]


def uniform_laplacian(faces: np.ndarray, n_vertices: int) -> sp.csr_matrix:
    """Sparse uniform Laplacian ``L`` with ``(L @ P)[i] = mean_{j in N(i)} P[j] - P[i]``.

    Build it once per connectivity; apply it to changing point arrays.

    Parameters
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
    n_vertices : int

    Returns
    -------
    scipy.sparse.csr_matrix, shape (V, V)
        Rows of isolated vertices are zero.
    """
    indptr, indices = one_ring(faces, n_vertices)
    degree = np.diff(indptr)
    inv = np.zeros(n_vertices)
    np.divide(1.0, degree, out=inv, where=degree > 0)
    average = sp.csr_matrix((np.repeat(inv, degree), indices, indptr), shape=(n_vertices, n_vertices))
    identity = sp.diags((degree > 0).astype(float), format="csr")
    return (average - identity).tocsr()


def laplacian_vectors(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Uniform Laplacian vectors L_i of every vertex.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)

    Returns
    -------
    numpy.ndarray, shape (V, 3)
        ``L_i = (1/|N(i)|) sum_{j in N(i)} (v_j - v_i)``.
    """
    return uniform_laplacian(faces, len(points)) @ points
