"""Principal curvatures of triangle meshes after Rusinkiewicz (2004).

For every face the second fundamental form is fitted, by least squares, to
the differences of the vertex normals along its three edges. Each face tensor
is then rotated into the tangent frame of its three vertices and averaged
there with mixed Voronoi corner-area weights; diagonalising the averaged
tensor gives the principal curvatures and directions. With outward normals,
convex regions have positive mean curvature (H = 1/r on a sphere of radius r).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import prange

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit, unsigned
from pverosion.kernels._scatter import OwnedRows, add_outside, chunk_range, owned_add, owned_rows, owned_start
from pverosion.kernels._threads import for_chunks, for_ranges
from pverosion.kernels.mesh.geometry import face_normal_terms, mixed_corner_areas, normal_terms
from pverosion.kernels.mesh.locality import Renumbering, morton_renumbering, poor_locality
from pverosion.kernels.mesh.topology import locality_sorted, vertex_face_incidence
from pverosion.kernels.validation import InvalidMeshError, as_faces, as_points

__all__ = ["CurvatureOperator", "CurvatureResult", "CurvatureTracker", "MeanCurvatureOperator", "MeanCurvatureResult",
           "principal_curvatures"]


@dataclass(frozen=True)
class CurvatureResult:
    """Per-vertex curvature of a triangle mesh.

    Attributes
    ----------
    k1, k2 : numpy.ndarray, shape (V,)
        Principal curvatures, ``k1 >= k2``.
    direction1, direction2 : numpy.ndarray, shape (V, 3)
        Unit principal directions of ``k1`` and ``k2``, tangent to the surface.
    normals : numpy.ndarray, shape (V, 3)
        Unit vertex normals used by the estimate.
    point_areas : numpy.ndarray, shape (V,)
        Mixed Voronoi area of each vertex.
    """

    k1: np.ndarray
    k2: np.ndarray
    direction1: np.ndarray
    direction2: np.ndarray
    normals: np.ndarray
    point_areas: np.ndarray

    @property
    def mean(self) -> np.ndarray:
        """Mean curvature H = (k1 + k2) / 2, shape (V,)."""
        return 0.5 * (self.k1 + self.k2)

    @property
    def gaussian(self) -> np.ndarray:
        """Gaussian curvature K = k1 k2, shape (V,)."""
        return self.k1 * self.k2


@njit(cache=True, error_model="numpy")
def _normal_frame(normal):
    """Unit tangents (u, v) with u x v = normal, a fixed function of the normal alone."""
    ax, ay, az = abs(normal[0]), abs(normal[1]), abs(normal[2])
    if ax <= ay and ax <= az:
        u = (0.0, -normal[2], normal[1])  # (1, 0, 0) x n
    elif ay <= az:
        u = (normal[2], 0.0, -normal[0])  # (0, 1, 0) x n
    else:
        u = (-normal[1], normal[0], 0.0)  # (0, 0, 1) x n
    u = v3.scale(u, 1.0 / v3.norm(u))
    return u, v3.cross(normal, u)


@njit(cache=True, error_model="numpy", nogil=True)
def _tangent_range(normals, tangents, start, stop):
    """First tangent of the :func:`_normal_frame` of vertices ``start`` to ``stop``; zero where the normal is."""
    for i in range(start, stop):
        nrm = v3.row(normals, i)
        v3.store(tangents, i, _normal_frame(nrm)[0] if v3.dot(nrm, nrm) != 0.0 else (0.0, 0.0, 0.0))


@njit(cache=True, error_model="numpy", inline="always")
def _unit_sum(acc, i):
    """The unit vector of ``acc[i, :3]``, or zero where that is zero."""
    total = (acc[i, 0], acc[i, 1], acc[i, 2])
    length = v3.norm(total)
    return v3.scale(total, 1.0 / length) if length > 0.0 else (0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy", nogil=True)
def _unit_range(acc, normals, start, stop):
    """Unit normals (the sums ``acc[:, :3]``) of vertices ``start`` to ``stop``; zero where the sum is."""
    for i in range(start, stop):
        v3.store(normals, i, _unit_sum(acc, i))


@njit(cache=True, error_model="numpy", nogil=True)
def _frame_range(acc, normals, tangents, start, stop):
    """:func:`_unit_range` and the first frame tangents of vertices ``start`` to ``stop``; zero where the normal
    is."""
    for i in range(start, stop):
        u = unsigned(i)
        nrm = _unit_sum(acc, u)
        v3.store(normals, u, nrm)
        v3.store(tangents, u, _normal_frame(nrm)[0] if v3.dot(nrm, nrm) != 0.0 else (0.0, 0.0, 0.0))


BATCH = 32
"""Faces per batch of the curvature passes. A batch's corners are gathered into small arrays
(:func:`_gather`) and its faces fitted in loops without branches, which the compiler turns into vector
instructions: about twice as fast as one face at a time (the tensor pass on 1.6M faces, one thread: 52-55 ms
against 120 ms), with the same results bit for bit (each lane does the same operations in the same order)."""


@njit(cache=True, error_model="numpy", inline="always")
def _batch_buffers():
    """Scratch of one batch: the corners' vertices (3, BATCH), what is gathered at them (27, BATCH), the face
    fits (19, BATCH) and the corner results (12, BATCH)."""
    return np.empty((3, BATCH), np.int64), np.empty((27, BATCH)), np.empty((19, BATCH)), np.empty((12, BATCH))


@njit(cache=True, error_model="numpy", inline="always")
def _corner_ids(faces, ids, first, n, corners):
    """The vertices of the ``n`` faces from ``first`` on (faces ``ids[first + k]`` when ``ids`` is not empty)
    into ``corners`` (3, BATCH): corner ``j`` of face ``k`` at ``[j, k]``."""
    for k in range(n):
        f = unsigned(ids[first + k] if ids.shape[0] else first + k)
        for j in range(3):
            corners[j, k] = faces[f, j]


@njit(cache=True, error_model="numpy", inline="always")
def _gather(values, corners, n, g, row):
    """Gather ``values`` (V, 3) at the ``corners`` (3, BATCH) of ``n`` faces into ``g`` (27, BATCH): corner ``j``
    in rows ``row + 3 j`` to ``row + 3 j + 2``. The batches take the points in rows 0 to 8, the vertex normals
    in rows 9 to 17 and the frame tangents in rows 18 to 26."""
    for k in range(n):
        for j in range(3):
            i = unsigned(corners[j, k])
            for d in range(3):
                g[row + 3 * j + d, k] = values[i, d]


@njit(cache=True, error_model="numpy", inline="always")
def _gather_fit(points, normals, corners, n, g):
    """:func:`_gather` of the points and the vertex normals, in one pass."""
    for k in range(n):
        for j in range(3):
            i = unsigned(corners[j, k])
            for d in range(3):
                g[3 * j + d, k] = points[i, d]
                g[9 + 3 * j + d, k] = normals[i, d]


@njit(cache=True, error_model="numpy", inline="always")
def _gathered(g, row, k):
    return g[row, k], g[row + 1, k], g[row + 2, k]


@njit(cache=True, error_model="numpy", inline="always")
def _fit_batch(g, n, ft):
    """Corner areas and least-squares second fundamental form of the ``n`` gathered faces of ``g``.

    For every face, the normal differences along its three edges are fitted
    in its own frame (tangent ``t`` along the edge opposite corner 0,
    bitangent ``b``, unit normal ``nf``) by the 3 x 3 normal equations,
    solved by Cramer's rule. ``ft`` (19, BATCH) gets per face: the mixed
    Voronoi corner areas (rows 0 to 2), 1.0 where the fit holds or 0.0 for a
    degenerate face or a singular system (row 3), ``t``, ``b`` and ``nf``
    (rows 4 to 12), the tensor ``[[ta, tb], [tb, tc]]`` (rows 13 to 15) and,
    for corner ``j``, ``1 / (1 + n_j . nf)`` in row ``16 + j`` where the
    tensor counts there (the fit holds, the vertex has a normal and the face
    is not folded fully against it; the value is then at least 0.5), else 0.
    (Each value is computed, then selected: a branch around a computation,
    or a helper returning a flag, keeps the loop from becoming vector
    instructions.)
    """
    for k in range(n):
        p0, p1, p2 = _gathered(g, 0, k), _gathered(g, 3, k), _gathered(g, 6, k)
        # edge j is opposite corner j; the normal difference is taken along the same direction
        e0, e1, e2 = v3.sub(p2, p1), v3.sub(p0, p2), v3.sub(p1, p0)
        l0, l1, l2 = v3.dot(e0, e0), v3.dot(e1, e1), v3.dot(e2, e2)
        normal = v3.cross(e0, e1)
        nn = v3.norm(normal)
        w0, w1, w2 = mixed_corner_areas(0.5 * nn, l0, l1, l2, e0, e1, e2)
        n0, n1, n2 = _gathered(g, 9, k), _gathered(g, 12, k), _gathered(g, 15, k)
        dn0, dn1, dn2 = v3.sub(n2, n1), v3.sub(n0, n2), v3.sub(n1, n0)
        t = v3.scale(e0, 1.0 / np.sqrt(l0))
        nf = v3.scale(normal, 1.0 / nn)
        b = v3.cross(nf, t)
        u0, u1, u2 = v3.dot(e0, t), v3.dot(e1, t), v3.dot(e2, t)
        v0, v1, v2 = v3.dot(e0, b), v3.dot(e1, b), v3.dot(e2, b)
        a0, a1, a2 = v3.dot(dn0, t), v3.dot(dn1, t), v3.dot(dn2, t)
        c0, c1, c2 = v3.dot(dn0, b), v3.dot(dn1, b), v3.dot(dn2, b)
        s_uu = u0 * u0 + u1 * u1 + u2 * u2
        s_uv = u0 * v0 + u1 * v1 + u2 * v2
        s_vv = v0 * v0 + v1 * v1 + v2 * v2
        m0 = a0 * u0 + a1 * u1 + a2 * u2
        m1 = a0 * v0 + a1 * v1 + a2 * v2 + c0 * u0 + c1 * u1 + c2 * u2
        m2 = c0 * v0 + c1 * v1 + c2 * v2
        s_mid = s_uu + s_vv
        # Cramer's rule on [[s_uu, s_uv, 0], [s_uv, s_mid, s_uv], [0, s_uv, s_vv]] x = m
        minor = s_mid * s_vv - s_uv * s_uv
        det = s_uu * minor - s_uv * s_uv * s_vv
        ok = (nn > 1e-12 * (l0 + l1 + l2)) & (det != 0.0)
        inv = 1.0 / (det if ok else 1.0)
        mid = m1 * s_vv - s_uv * m2
        ft[0, k], ft[1, k], ft[2, k] = w0, w1, w2
        ft[3, k] = 1.0 if ok else 0.0
        ft[4, k], ft[5, k], ft[6, k] = t
        ft[7, k], ft[8, k], ft[9, k] = b
        ft[10, k], ft[11, k], ft[12, k] = nf
        ta = (m0 * minor - s_uv * mid) * inv
        tb = (s_uu * mid - m0 * s_uv * s_vv) * inv
        tc = (s_uu * (s_mid * m2 - s_uv * m1) - s_uv * s_uv * m2 + m0 * s_uv * s_uv) * inv
        ft[13, k] = ta if ok else 0.0
        ft[14, k] = tb if ok else 0.0
        ft[15, k] = tc if ok else 0.0
        for j, nrm in enumerate((n0, n1, n2)):
            align = 1.0 + v3.dot(nrm, nf)
            seen = ok & (align > 1e-12) & (v3.dot(nrm, nrm) != 0.0)
            inv = 1.0 / (align if seen else 1.0)
            ft[16 + j, k] = inv if seen else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _tensor_batch(g, ft, n, out):
    """The face tensors of a fitted batch in the frames of its corners, weighted by the corner areas.

    The frame (u, nrm x u, nrm) of corner ``j`` (:func:`_normal_frame`) is
    rotated rigidly into the face plane and expressed in the face frame.
    ``out`` (12, BATCH) gets ``(w ku, w kuv, w kv, w)`` of corner ``j`` in
    rows ``4 j`` to ``4 j + 3``; a corner where the tensor does not count
    (row ``16 + j`` of ``ft`` is 0) keeps its area ``w`` with a zero tensor.
    """
    for j in range(3):
        for k in range(n):
            nrm, u = _gathered(g, 9 + 3 * j, k), _gathered(g, 18 + 3 * j, k)
            t, b, nf = _gathered(ft, 4, k), _gathered(ft, 7, k), _gathered(ft, 10, k)
            inv = ft[16 + j, k]
            seen = inv != 0.0
            v = v3.cross(nrm, u)
            dt = v3.dot(nrm, t) * inv
            db = v3.dot(nrm, b) * inv
            # perp . u = nf . u because nrm is normal to u
            pu = v3.dot(nf, u)
            pv = v3.dot(nf, v)
            u1 = v3.dot(u, t) - dt * pu
            v1 = v3.dot(u, b) - db * pu
            u2 = v3.dot(v, t) - dt * pv
            v2 = v3.dot(v, b) - db * pv
            ta, tb, tc = ft[13, k], ft[14, k], ft[15, k]
            w = ft[j, k]
            ku = w * (ta * u1 * u1 + 2.0 * tb * u1 * v1 + tc * v1 * v1)
            kuv = w * (ta * u1 * u2 + tb * (u1 * v2 + u2 * v1) + tc * v1 * v2)
            kv = w * (ta * u2 * u2 + 2.0 * tb * u2 * v2 + tc * v2 * v2)
            # selected, not multiplied by 0 (the lanes of a degenerate face may hold NaN); each select is of two
            # values already computed, so that the compiler keeps the loop free of branches
            out[4 * j, k] = ku if seen else 0.0
            out[4 * j + 1, k] = kuv if seen else 0.0
            out[4 * j + 2, k] = kv if seen else 0.0
            out[4 * j + 3, k] = w


@njit(cache=True, error_model="numpy", inline="always")
def _trace_batch(g, ft, n, out):
    """The traces of the face tensors of a fitted batch, weighted by the corner areas, as seen at each corner: a
    rotation keeps the trace, so it is the face's, or zero where :func:`_tensor_batch` gives a zero tensor.
    ``out`` (12, BATCH) gets ``(w trace, w, 0, 0)`` of corner ``j`` in rows ``4 j`` to ``4 j + 3``."""
    for j in range(3):
        for k in range(n):
            seen = ft[16 + j, k] != 0.0
            w = ft[j, k]
            trace = w * (ft[13, k] + ft[15, k])
            out[4 * j, k] = trace if seen else 0.0
            out[4 * j + 1, k] = w
            out[4 * j + 2, k] = 0.0
            out[4 * j + 3, k] = 0.0


@njit(cache=True, error_model="numpy", nogil=True)
def _mean_range(normals, acc, order, mean, area, normals_out, start, stop):
    """Mean curvature (half the averaged trace) and area of vertices ``start`` to ``stop``, stored with their
    normals in the caller's rows ``order[i]``; zero without area or normal, as :func:`_diagonalise` gives."""
    for i in range(start, stop):
        total = acc[i, 1]
        row = order[i]
        area[row] = total
        nrm = v3.row(normals, i)
        mean[row] = 0.0 if total <= 0.0 or v3.dot(nrm, nrm) == 0.0 else 0.5 * (acc[i, 0] / total)
        v3.store(normals_out, row, nrm)


@njit(cache=True, error_model="numpy", inline="always")
def _normal_batch(g, n, out):
    """The Max-weighted normal of each of the ``n`` gathered faces (:func:`normal_terms`) as its corners add it:
    ``(w n, 0)`` of corner ``j`` in rows ``4 j`` to ``4 j + 3`` of ``out`` (12, BATCH)."""
    for k in range(n):
        normal, w0, w1, w2 = normal_terms(_gathered(g, 0, k), _gathered(g, 3, k), _gathered(g, 6, k), True)
        out[0, k], out[1, k], out[2, k] = v3.scale(normal, w0)
        out[4, k], out[5, k], out[6, k] = v3.scale(normal, w1)
        out[8, k], out[9, k], out[10, k] = v3.scale(normal, w2)
        out[3, k] = out[7, k] = out[11, k] = 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _add_batch(acc, spill, spill_rows, slot, lo, hi, faces, first, n, out):
    """Add the corner results ``out`` (12, BATCH) of the ``n`` faces from ``first`` on to their vertices'
    rows of ``acc`` (V, 4) (:func:`~pverosion.kernels._scatter.owned_add`); returns the next slot."""
    for k in range(n):
        for j in range(3):
            slot = owned_add(acc, spill, spill_rows, slot, lo, hi, faces[unsigned(first + k), j], out[4 * j, k],
                             out[4 * j + 1, k], out[4 * j + 2, k], out[4 * j + 3, k])
    return slot


@njit(cache=True, error_model="numpy", nogil=True)
def _normal_chunk(points, faces, acc, owners, outside, spill, spill_rows, c):
    """Zero the rows chunk ``c`` of the faces owns in ``acc`` (V, 4) and add the Max-weighted normals of its
    faces to their corners in ``acc[:, :3]`` (:class:`~pverosion.kernels._scatter.OwnedRows`)."""
    lo, hi, slot = owned_start(acc, owners, outside, c)
    start, stop = chunk_range(faces.shape[0], c)
    corners, g, _, out = _batch_buffers()
    every = np.empty(0, np.int64)
    for first in range(start, stop, BATCH):
        n = min(BATCH, stop - first)
        _corner_ids(faces, every, first, n, corners)
        _gather(points, corners, n, g, 0)
        _normal_batch(g, n, out)
        slot = _add_batch(acc, spill, spill_rows, slot, lo, hi, faces, first, n, out)


@njit(cache=True, error_model="numpy", nogil=True)
def _trace_chunk(points, faces, normals, acc, owners, outside, spill, spill_rows, c):
    """Zero the rows chunk ``c`` of the faces owns in ``acc`` (V, 4) and add the corner-area-weighted traces of
    its face tensors and the weights into ``acc[:, :2]``."""
    lo, hi, slot = owned_start(acc, owners, outside, c)
    start, stop = chunk_range(faces.shape[0], c)
    corners, g, ft, out = _batch_buffers()
    every = np.empty(0, np.int64)
    for first in range(start, stop, BATCH):
        n = min(BATCH, stop - first)
        _corner_ids(faces, every, first, n, corners)
        _gather_fit(points, normals, corners, n, g)
        _fit_batch(g, n, ft)
        _trace_batch(g, ft, n, out)
        slot = _add_batch(acc, spill, spill_rows, slot, lo, hi, faces, first, n, out)


@njit(cache=True, error_model="numpy", nogil=True)
def _tensor_chunk(points, faces, normals, tangents, acc, owners, outside, spill, spill_rows, c):
    """Zero the rows chunk ``c`` of the faces owns in ``acc`` (V, 4) and add the corner-area-weighted tensors of
    its faces, in the vertex frames, and the weights: (ku, kuv, kv, w) per vertex."""
    lo, hi, slot = owned_start(acc, owners, outside, c)
    start, stop = chunk_range(faces.shape[0], c)
    corners, g, ft, out = _batch_buffers()
    every = np.empty(0, np.int64)
    for first in range(start, stop, BATCH):
        n = min(BATCH, stop - first)
        _corner_ids(faces, every, first, n, corners)
        _gather_fit(points, normals, corners, n, g)
        _gather(tangents, corners, n, g, 18)
        _fit_batch(g, n, ft)
        _tensor_batch(g, ft, n, out)
        slot = _add_batch(acc, spill, spill_rows, slot, lo, hi, faces, first, n, out)


@njit(cache=True, error_model="numpy", inline="always")
def _diagonalise(nrm, u, ku, kuv, kv, total):
    """Principal curvatures and directions (k1, k2, d1, d2) of the summed tensor of a vertex.

    ``nrm`` is the vertex normal and ``u`` the first tangent of its frame;
    ``ku, kuv, kv`` are sums weighted by the corner areas, ``total`` their sum;
    a vertex without area or normal gets zeros.
    """
    zero = (0.0, 0.0, 0.0)
    if total <= 0.0 or v3.dot(nrm, nrm) == 0.0:
        return 0.0, 0.0, zero, zero
    inv = 1.0 / total
    ku *= inv
    kuv *= inv
    kv *= inv
    # Jacobi rotation diagonalising [[ku, kuv], [kuv, kv]]
    cs = 1.0
    sn = 0.0
    tt = 0.0
    if kuv != 0.0:
        h = 0.5 * (kv - ku) / kuv
        if h < 0.0:
            tt = 1.0 / (h - np.sqrt(1.0 + h * h))
        else:
            tt = 1.0 / (h + np.sqrt(1.0 + h * h))
        cs = 1.0 / np.sqrt(1.0 + tt * tt)
        sn = tt * cs
    a1 = ku - tt * kuv
    a2 = kv + tt * kuv
    v = v3.cross(nrm, u)
    p1 = v3.sub(v3.scale(u, cs), v3.scale(v, sn))
    if a1 < a2:
        a1, a2 = a2, a1
        p1 = v3.cross(nrm, p1)
    return a1, a2, p1, v3.cross(nrm, p1)


@njit(cache=True, error_model="numpy", inline="always")
def _vertex_curvature(normals, tangents, acc, i, row, k1, k2, d1, d2, area):
    """Average the corner tensors of vertex ``i``, diagonalise them and store the results in ``row``."""
    total = acc[i, 3]
    area[row] = total
    k1[row], k2[row], p1, p2 = _diagonalise(v3.row(normals, i), v3.row(tangents, i), acc[i, 0], acc[i, 1],
                                            acc[i, 2], total)
    v3.store(d1, row, p1)
    v3.store(d2, row, p2)


@njit(cache=True, error_model="numpy", nogil=True)
def _curvature_range(normals, tangents, acc, k1, k2, d1, d2, area, start, stop):
    """Average the corner tensors of vertices ``start`` to ``stop`` and diagonalise them."""
    for i in range(start, stop):
        _vertex_curvature(normals, tangents, acc, i, i, k1, k2, d1, d2, area)


@njit(cache=True, error_model="numpy", nogil=True)
def _restored_curvature_range(normals, tangents, acc, order, k1, k2, d1, d2, area, normals_out, start, stop):
    """:func:`_curvature_range` of local vertices ``start`` to ``stop``, stored with their normals in the
    caller's rows ``order[i]``."""
    for i in range(start, stop):
        u, row = unsigned(i), unsigned(order[i])
        _vertex_curvature(normals, tangents, acc, u, row, k1, k2, d1, d2, area)
        v3.store(normals_out, row, v3.row(normals, u))


def _vertex_curvatures(normals: np.ndarray, tangents: np.ndarray, acc: np.ndarray,
                       order: np.ndarray | None) -> CurvatureResult:
    """Average the corner tensors of every vertex and diagonalise them.

    ``order`` (V,) maps the local vertex numbering to the caller's, in which
    the result is returned; None keeps the numbering.
    """
    n_vertices = normals.shape[0]
    k1, k2, area = np.empty(n_vertices), np.empty(n_vertices), np.empty(n_vertices)
    d1, d2 = np.empty((n_vertices, 3)), np.empty((n_vertices, 3))
    if order is None:
        normals_out = normals
        for_ranges(_curvature_range, n_vertices, normals, tangents, acc, k1, k2, d1, d2, area)
    else:
        normals_out = np.empty_like(normals)
        for_ranges(_restored_curvature_range, n_vertices, normals, tangents, acc, order, k1, k2, d1, d2, area,
                   normals_out)
    return CurvatureResult(k1=k1, k2=k2, direction1=d1, direction2=d2, normals=normals_out, point_areas=area)


# --- tracking: recompute around the points that moved ----------------------------------------------------------


@njit(cache=True)
def _dirty(changed, faces, indptr, face_ids):
    """What a move of the ``changed`` vertices touches.

    Returns the vertices whose normals change (those of the faces around a
    changed vertex), the faces whose tensors change (those around such a
    vertex) and the vertices whose curvatures change (those of such faces).
    """
    n_vertices = indptr.shape[0] - 1
    normal = np.zeros(n_vertices, np.bool_)
    for v in changed:
        for q in range(indptr[v], indptr[v + 1]):
            for k in range(3):
                normal[faces[face_ids[q], k]] = True
    face = np.zeros(faces.shape[0], np.bool_)
    vertex = np.zeros(n_vertices, np.bool_)
    for v in np.flatnonzero(normal):
        for q in range(indptr[v], indptr[v + 1]):
            f = face_ids[q]
            face[f] = True
            for k in range(3):
                vertex[faces[f, k]] = True
    return np.flatnonzero(normal), np.flatnonzero(face), np.flatnonzero(vertex)


@njit(cache=True, parallel=True)
def _changed(points, before):
    """Indices of the points (V, 3) that differ from ``before`` in any coordinate."""
    moved = np.zeros(points.shape[0], np.bool_)
    for i in prange(points.shape[0]):
        moved[i] = points[i, 0] != before[i, 0] or points[i, 1] != before[i, 1] or points[i, 2] != before[i, 2]
    return np.flatnonzero(moved)


@njit(cache=True, error_model="numpy", parallel=True)
def _track(points, faces, indptr, face_ids, corners, vertices, face_list, curved, terms, normals, tangents, contrib,
           k1, k2, d1, d2, area):
    """Recompute the normal terms and tensors of ``face_list``, the normals of ``vertices`` and the curvatures of
    ``curved``; every vertex sums its faces in incidence order."""
    for q in prange(face_list.shape[0]):
        f = face_list[q]
        n, w0, w1, w2 = face_normal_terms(points, faces, f, True)
        for k, w in enumerate((w0, w1, w2)):
            for d in range(3):
                terms[f, k, d] = w * n[d]
    for q in prange(vertices.shape[0]):
        v = vertices[q]
        total = (0.0, 0.0, 0.0)
        for m in range(indptr[v], indptr[v + 1]):
            f, k = face_ids[m], corners[m]
            total = v3.add(total, (terms[f, k, 0], terms[f, k, 1], terms[f, k, 2]))
        length = v3.norm(total)
        nrm = v3.scale(total, 1.0 / length) if length > 0.0 else (0.0, 0.0, 0.0)
        v3.store(normals, v, nrm)
        v3.store(tangents, v, _normal_frame(nrm)[0] if length > 0.0 else (0.0, 0.0, 0.0))
    for q in prange((face_list.shape[0] + BATCH - 1) // BATCH):
        ids, g, ft, out = _batch_buffers()
        first = q * BATCH
        n = min(BATCH, face_list.shape[0] - first)
        _corner_ids(faces, face_list, first, n, ids)
        _gather_fit(points, normals, ids, n, g)
        _gather(tangents, ids, n, g, 18)
        _fit_batch(g, n, ft)
        _tensor_batch(g, ft, n, out)
        for k in range(n):
            for j in range(3):
                for d in range(4):
                    contrib[face_list[first + k], j, d] = out[4 * j + d, k]
    for q in prange(curved.shape[0]):
        v = curved[q]
        ku = kuv = kv = total = 0.0
        for m in range(indptr[v], indptr[v + 1]):
            f, k = face_ids[m], corners[m]
            ku += contrib[f, k, 0]
            kuv += contrib[f, k, 1]
            kv += contrib[f, k, 2]
            total += contrib[f, k, 3]
        area[v] = total
        k1[v], k2[v], p1, p2 = _diagonalise(v3.row(normals, v), v3.row(tangents, v), ku, kuv, kv, total)
        v3.store(d1, v, p1)
        v3.store(d2, v, p2)


class CurvatureTracker:
    """Curvature of a mesh whose points move a few at a time, recomputed only around the moved points.

    The estimate is :class:`CurvatureOperator`'s with Max-weighted normals.
    Each call compares the points with those of the previous call and
    recomputes the normals of the moved points' one-ring, the tensors of the
    faces around those, and the curvatures of those faces' vertices. Every
    vertex sums its faces in a fixed order, so an update equals a fresh
    evaluation bit for bit (and agrees with :class:`CurvatureOperator` to
    rounding). Use it for erosion that moves a small part of a large mesh
    per step (hydraulic erosion); build a new one when the faces change.

    Parameters
    ----------
    faces : array_like, shape (F, 3)
        Triangles, oriented consistently.
    n_vertices : int
        Number of mesh vertices V.

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> sphere = pv.Icosphere(radius=2.0, nsub=4)
    >>> tracker = CurvatureTracker(sphere.regular_faces, sphere.n_points)
    >>> bool(np.allclose(tracker(sphere.points).mean, 0.5, rtol=1e-4))  # float32 points
    True
    >>> bumped = np.array(sphere.points, dtype=float)
    >>> bumped[0] *= 1.1
    >>> fresh = CurvatureTracker(sphere.regular_faces, sphere.n_points)(bumped)
    >>> bool(np.array_equal(tracker(bumped).mean, fresh.mean))
    True
    """

    def __init__(self, faces, n_vertices: int) -> None:
        n_vertices = int(n_vertices)
        if n_vertices <= 0:
            raise InvalidMeshError("mesh is empty: it has no points")
        self.faces = as_faces(faces, n_vertices)
        self.n_vertices = n_vertices
        self._incidence = vertex_face_incidence(self.faces, n_vertices)
        n_faces = len(self.faces)
        self._terms = np.zeros((n_faces, 3, 3))
        self._contrib = np.zeros((n_faces, 3, 4))
        self._normals = np.zeros((n_vertices, 3))
        self._tangents = np.zeros((n_vertices, 3))
        self._k = (np.zeros(n_vertices), np.zeros(n_vertices), np.zeros((n_vertices, 3)), np.zeros((n_vertices, 3)),
                   np.zeros(n_vertices))
        self._points: np.ndarray | None = None

    def __call__(self, points) -> CurvatureResult:
        """Principal curvatures at ``points`` (V, 3); the arrays are read-only views, valid until the next call."""
        pts = as_points(points)
        if pts.shape[0] != self.n_vertices:
            raise InvalidMeshError(f"points must have shape ({self.n_vertices}, 3); got {pts.shape}")
        indptr, face_ids, corners = self._incidence
        if self._points is None:
            everything = np.arange(self.n_vertices)
            vertices, face_list, curved = everything, np.arange(len(self.faces)), everything
        else:
            vertices, face_list, curved = _dirty(_changed(pts, self._points), self.faces, indptr, face_ids)
        _track(pts, self.faces, indptr, face_ids, corners, vertices, face_list, curved, self._terms, self._normals,
               self._tangents, self._contrib, *self._k)
        self._points = pts.copy()
        k1, k2, d1, d2, area = (_read_only(a) for a in self._k)
        return CurvatureResult(k1=k1, k2=k2, direction1=d1, direction2=d2, normals=_read_only(self._normals),
                               point_areas=area)


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


class CurvatureOperator:
    """Curvature estimator bound to one mesh connectivity.

    Building it validates the faces and sorts them for memory locality once;
    calling it with new point coordinates costs only the per-step passes.
    When the corners of the faces lie far apart in the vertex numbering
    (:func:`~pverosion.kernels.mesh.locality.poor_locality`, as after Loop
    subdivision), the first call also numbers the vertices along the Morton
    curve of its points (:func:`~pverosion.kernels.mesh.locality.morton_renumbering`);
    every call then evaluates in that numbering and returns the results in
    the caller's vertex order. Results are bit-identical whatever the number
    of threads. The scratch arrays of a call (about 110 bytes per vertex)
    are kept for the next one, so one operator serves one thread at a time; the
    returned arrays are always fresh. Use it when the points move but the
    faces stay (iterative erosion), or call :func:`principal_curvatures` for
    one shot.

    Parameters
    ----------
    faces : array_like, shape (F, 3)
        Triangles, oriented consistently; the curvature sign follows the
        normals they imply (see :func:`pverosion.kernels.mesh.orientation.orient_faces`).
    n_vertices : int
        Number of mesh vertices V.

    Attributes
    ----------
    faces : numpy.ndarray, shape (F, 3), int64, or None
        The faces sorted by their smallest vertex, in the local numbering;
        None before the first call of an operator that renumbers.
    renumbering : Renumbering or None
        The local vertex numbering, None while it is the caller's.

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> sphere = pv.Icosphere(radius=2.0, nsub=4)
    >>> op = CurvatureOperator(sphere.regular_faces, sphere.n_points)
    >>> bool(np.allclose(op(sphere.points).mean, 0.5, rtol=1e-4))  # float32 points
    True
    >>> bool(np.allclose(op(3.0 * sphere.points).mean, 1 / 6, rtol=1e-4))
    True
    """

    def __init__(self, faces, n_vertices: int) -> None:
        n_vertices = int(n_vertices)
        if n_vertices <= 0:
            raise InvalidMeshError("mesh is empty: it has no points")
        fcs = as_faces(faces, n_vertices)
        self.n_vertices = n_vertices
        self.renumbering: Renumbering | None = None
        self._scattered = fcs if poor_locality(fcs, n_vertices) else None
        self.faces = None if self._scattered is not None else locality_sorted(fcs, n_vertices)[1]
        self._scratch: tuple | None = None
        self._owned: tuple[OwnedRows, np.ndarray, np.ndarray] | None = None
        self._owned_rows: OwnedRows | None = None

    @classmethod
    def from_sorted(cls, faces: np.ndarray, n_vertices: int, *, renumbering: Renumbering | None = None,
                    owned: OwnedRows | None = None) -> CurvatureOperator:
        """An operator on faces already validated and sorted by their smallest vertex (stable).

        The faces of :func:`~pverosion.kernels.mesh.orientation.orient_sorted` are;
        the result equals the one built from the same faces in any order.

        Parameters
        ----------
        faces : numpy.ndarray, shape (F, 3), int64
            In the local numbering of ``renumbering`` when it is given.
        n_vertices : int
        renumbering : Renumbering, optional
            The numbering of ``faces``; the operator takes and returns per-vertex
            arrays in the caller's order, as one that renumbered itself.
        owned : OwnedRows, optional
            :func:`~pverosion.kernels._scatter.owned_rows` of ``faces`` when the
            caller has it (:func:`~pverosion.kernels.mesh.orientation.orient_sorted`
            counts it); else the first call counts it.
        """
        operator = cls.__new__(cls)
        operator.n_vertices = int(n_vertices)
        operator.renumbering = renumbering
        operator._scattered = None
        operator.faces = faces
        operator._scratch = None
        operator._owned = None
        operator._owned_rows = owned
        return operator

    def __call__(self, points, *, normals=None) -> CurvatureResult:
        """Principal curvatures at ``points`` (V, 3); ``normals`` (V, 3) optional, else Max-weighted."""
        pts = as_points(points)
        if pts.shape[0] != self.n_vertices:
            raise InvalidMeshError(f"points must have shape ({self.n_vertices}, 3); got {pts.shape}")
        return self._evaluate(pts, normals)

    def at_local_points(self, points: np.ndarray) -> CurvatureResult:
        """:meth:`__call__` on points already in the operator's numbering, with Max-weighted normals.

        A caller that has numbered the points as ``renumbering`` does, for another kernel on the same mesh
        (the orientation of :func:`~pverosion.kernels.mesh.orientation.orient_sorted`, say), saves a pass.

        Parameters
        ----------
        points : numpy.ndarray, shape (V, 3), float64, C-contiguous
            ``renumbering.to_local`` of the caller's finite points (the points themselves without a
            renumbering); read, not kept.

        Returns
        -------
        CurvatureResult
            In the caller's numbering.
        """
        if self._scattered is not None:
            raise RuntimeError("this operator numbers its points at its first call; call it with the caller's")
        if points.shape != (self.n_vertices, 3):
            raise InvalidMeshError(f"points must have shape ({self.n_vertices}, 3); got {points.shape}")
        return self._evaluate(points, None, local=True)

    def _evaluate(self, pts: np.ndarray, normals, *, local: bool = False) -> CurvatureResult:
        """The estimate on already validated points (V, 3) float64, in their order (or the local one)."""
        pts, nrm, tangents, acc = self._normals(pts, normals, local=local)
        self._scatter(_tensor_chunk, acc, pts, self.faces, nrm, tangents)
        return _vertex_curvatures(nrm, tangents, acc, None if self.renumbering is None else self.renumbering.order)

    def _normals(self, pts: np.ndarray, normals, *, tangents: bool = True,
                 local: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The points, vertex normals and frame tangents (V, 3) in the local numbering, and the per-vertex sums
        (V, 4) to fill; the normals are ``normals`` when given, else Max-weighted. Without ``tangents`` the
        tangents are not computed (the array is returned unfilled); with ``local`` the points are in the local
        numbering already."""
        nrm = None
        if normals is not None:
            nrm = np.ascontiguousarray(normals, dtype=np.float64)
            if nrm.shape != pts.shape:
                raise ValueError(f"normals must have shape {pts.shape}; got {nrm.shape}")
        if self._scattered is not None:
            self.renumbering = morton_renumbering(pts)
            self.faces = self.renumbering.sorted_faces(self._scattered)
            self._scattered = None
        ren = self.renumbering
        local_points, local_normals, frame, acc = self._buffers()
        if ren is not None and not local:
            pts = ren.to_local(pts, out=local_points)
            nrm = None if nrm is None else ren.to_local(nrm, out=local_normals)
        if nrm is None:
            nrm = local_normals if ren is not None else np.empty((self.n_vertices, 3))
            self._scatter(_normal_chunk, acc, pts, self.faces)  # Max-weighted, as vertex_normals computes them
            if tangents:
                for_ranges(_frame_range, self.n_vertices, acc, nrm, frame)
            else:
                for_ranges(_unit_range, self.n_vertices, acc, nrm)
        elif tangents:
            for_ranges(_tangent_range, self.n_vertices, nrm, frame)
        return pts, nrm, frame, acc

    def _buffers(self) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray, np.ndarray]:
        """The scratch arrays of a call, made by the first and reused by the next ones: the points and
        normals in the local numbering (None without a renumbering), the frame tangents (V, 3) and the
        per-vertex sums (V, 4); also the face chunks' :class:`~pverosion.kernels._scatter.OwnedRows` and their
        slots for the corners outside them, (S, 4) and (S,)."""
        if self._scratch is None:
            n = self.n_vertices
            local = self.renumbering is not None
            rows = (np.empty((n, 3)), np.empty((n, 3))) if local else (None, None)
            owned = self._owned_rows if self._owned_rows is not None else owned_rows(self.faces, n)
            self._owned = (owned, np.empty((owned.n_outside, 4)), np.empty(owned.n_outside, np.int64))
            self._scratch = (*rows, np.empty((n, 3)), np.empty((n, 4)))
        return self._scratch

    def _scatter(self, kernel, acc: np.ndarray, *args) -> None:
        """Run the face chunks of ``kernel(*args, acc, owners, outside, spill, spill_rows, c)``, which zero their
        rows of ``acc`` (V, 4) and add into them, then add their corners outside their rows."""
        owned, spill, spill_rows = self._owned
        for_chunks(kernel, self.faces.shape[0], *args, acc, owned.owners, owned.outside, spill, spill_rows)
        add_outside(acc, spill, spill_rows)


@dataclass(frozen=True)
class MeanCurvatureResult:
    """Per-vertex mean curvature of a triangle mesh.

    Attributes
    ----------
    mean : numpy.ndarray, shape (V,)
        Mean curvature H = (k1 + k2) / 2.
    normals : numpy.ndarray, shape (V, 3)
        Unit vertex normals used by the estimate.
    point_areas : numpy.ndarray, shape (V,)
        Mixed Voronoi area of each vertex.
    """

    mean: np.ndarray
    normals: np.ndarray
    point_areas: np.ndarray


class MeanCurvatureOperator(CurvatureOperator):
    """The mean curvature of :class:`CurvatureOperator`, without the principal curvatures and directions.

    Rotating a face tensor into a vertex frame keeps its trace, so the
    averaged tensor's trace, twice the mean curvature, is the corner-area
    weighted average of the face tensors' traces: no vertex frames, no
    diagonalisation, and half the per-vertex sums. ``mean`` equals
    :class:`CurvatureOperator`'s to rounding (the sums are taken in another
    order); ``normals`` and ``point_areas`` are equal bit for bit. Same
    parameters, renumbering and reuse as :class:`CurvatureOperator`.

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> sphere = pv.Icosphere(radius=2.0, nsub=4)
    >>> op = MeanCurvatureOperator(sphere.regular_faces, sphere.n_points)
    >>> bool(np.allclose(op(sphere.points).mean, 0.5, rtol=1e-4))  # float32 points
    True
    """

    def _evaluate(self, pts: np.ndarray, normals) -> MeanCurvatureResult:
        pts, nrm, _, acc = self._normals(pts, normals, tangents=False)
        self._scatter(_trace_chunk, acc, pts, self.faces, nrm)
        n = self.n_vertices
        ren = self.renumbering
        mean, area = np.empty(n), np.empty(n)
        normals_out = nrm if ren is None else np.empty((n, 3))
        order = np.arange(n) if ren is None else ren.order
        for_ranges(_mean_range, n, nrm, acc, order, mean, area, normals_out)
        return MeanCurvatureResult(mean=mean, normals=normals_out, point_areas=area)


def principal_curvatures(points, faces, *, normals=None) -> CurvatureResult:
    """Estimate principal curvatures and directions at every vertex.

    Parameters
    ----------
    points : array_like, shape (V, 3)
        Vertex coordinates.
    faces : array_like, shape (F, 3)
        Triangles, oriented consistently; the curvature sign follows the
        normals they imply (see :func:`pverosion.kernels.mesh.orientation.orient_faces`).
    normals : array_like, shape (V, 3), optional
        Unit vertex normals to use; by default Max-weighted vertex normals.

    Returns
    -------
    CurvatureResult

    Notes
    -----
    Works on open meshes, meshes with holes and non-manifold spots: degenerate
    faces are skipped, and vertices without any non-degenerate face (or
    unreferenced vertices) get zero curvature, so every value is finite.
    For repeated calls on one connectivity, build a :class:`CurvatureOperator`.

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> from pverosion.kernels.curvature.operator import principal_curvatures
    >>> sphere = pv.Icosphere(radius=2.0, nsub=4)
    >>> faces = sphere.regular_faces
    >>> H = principal_curvatures(sphere.points, faces).mean
    >>> bool(np.allclose(H, 0.5, rtol=1e-4))  # pyvista stores float32 points
    True
    """
    pts = as_points(points)
    return CurvatureOperator(faces, len(pts))._evaluate(pts, normals)
