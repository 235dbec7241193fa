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
from numba import njit, prange

from pverosion.kernels import _vec3 as v3
from pverosion.kernels.geometry import corner_areas, vertex_normals
from pverosion.kernels.topology import vertex_face_incidence
from pverosion.kernels.validation import as_triangle_mesh

__all__ = ["CurvatureResult", "principal_curvatures"]


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


@njit(cache=True, error_model="numpy", parallel=True)
def _face_tensors(points, faces, normals):
    """Least-squares second fundamental form of each face in its own frame."""
    n_faces = faces.shape[0]
    # per face: tangent t (0:3), bitangent b (3:6), normal n (6:9), tensor (9:12)
    data = np.zeros((n_faces, 12))
    for f in prange(n_faces):
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        p0, p1, p2 = v3.row(points, i0), v3.row(points, i1), v3.row(points, i2)
        # edge j is opposite corner j; the normal difference is taken along the same direction
        e0, e1, e2 = v3.sub(p2, p1), v3.sub(p0, p2), v3.sub(p1, p0)
        n0, n1, n2 = v3.row(normals, i0), v3.row(normals, i1), v3.row(normals, i2)
        dn0, dn1, dn2 = v3.sub(n2, n1), v3.sub(n0, n2), v3.sub(n1, n0)
        n = v3.cross(e0, e1)
        nn = v3.norm(n)
        if nn <= 1e-12 * (v3.dot(e0, e0) + v3.dot(e1, e1) + v3.dot(e2, e2)):
            continue  # degenerate face: contributes nothing
        t = v3.scale(e0, 1.0 / v3.norm(e0))
        n = v3.scale(n, 1.0 / nn)
        b = v3.cross(n, t)
        u0, u1, u2 = v3.dot(e0, t), v3.dot(e1, t), v3.dot(e2, t)
        w0, w1, w2 = v3.dot(e0, b), v3.dot(e1, b), v3.dot(e2, b)
        a0, a1, a2 = v3.dot(dn0, t), v3.dot(dn1, t), v3.dot(dn2, t)
        c0, c1, c2 = v3.dot(dn0, b), v3.dot(dn1, b), v3.dot(dn2, b)
        s_uu = u0 * u0 + u1 * u1 + u2 * u2
        s_uv = u0 * w0 + u1 * w1 + u2 * w2
        s_vv = w0 * w0 + w1 * w1 + w2 * w2
        m0 = a0 * u0 + a1 * u1 + a2 * u2
        m1 = a0 * w0 + a1 * w1 + a2 * w2 + c0 * u0 + c1 * u1 + c2 * u2
        m2 = c0 * w0 + c1 * w1 + c2 * w2
        s_mid = s_uu + s_vv
        # Cramer's rule on [[s_uu, s_uv, 0], [s_uv, s_mid, s_uv], [0, s_uv, s_vv]] x = m
        minor = s_mid * s_vv - s_uv * s_uv
        det = s_uu * minor - s_uv * s_uv * s_vv
        if det == 0.0:
            continue
        for d in range(3):
            data[f, d] = t[d]
            data[f, 3 + d] = b[d]
            data[f, 6 + d] = n[d]
        data[f, 9] = (m0 * minor - s_uv * (m1 * s_vv - s_uv * m2)) / det
        data[f, 10] = (s_uu * (m1 * s_vv - s_uv * m2) - m0 * s_uv * s_vv) / det
        data[f, 11] = (s_uu * (s_mid * m2 - s_uv * m1) - s_uv * s_uv * m2 + m0 * s_uv * s_uv) / det
    return data


@njit(cache=True, error_model="numpy")
def _tangent_frame(normal, hint):
    """Unit tangent vectors (u, v) with u x v = normal; u follows ``hint`` when possible."""
    u = v3.cross(hint, normal)
    lu = v3.norm(u)
    if lu < 1e-12 * max(v3.norm(hint), 1e-300):
        ax, ay, az = abs(normal[0]), abs(normal[1]), abs(normal[2])
        if ax <= ay and ax <= az:
            axis = (1.0, 0.0, 0.0)
        elif ay <= az:
            axis = (0.0, 1.0, 0.0)
        else:
            axis = (0.0, 0.0, 1.0)
        u = v3.cross(axis, normal)
        lu = v3.norm(u)
    u = v3.scale(u, 1.0 / lu)
    return u, v3.cross(normal, u)


@njit(cache=True, error_model="numpy", parallel=True)
def _vertex_curvatures(points, faces, normals, data, corner, indptr, face_ids, corner_ids):
    n_vertices = points.shape[0]
    k1 = np.zeros(n_vertices)
    k2 = np.zeros(n_vertices)
    d1 = np.zeros((n_vertices, 3))
    d2 = np.zeros((n_vertices, 3))
    area = np.zeros(n_vertices)
    for i in prange(n_vertices):
        start = indptr[i]
        stop = indptr[i + 1]
        nrm = v3.row(normals, i)
        total = 0.0
        for s in range(start, stop):
            total += corner[face_ids[s], corner_ids[s]]
        area[i] = total
        if total <= 0.0 or v3.dot(nrm, nrm) == 0.0:
            continue
        f0 = face_ids[start]
        hint = v3.sub(v3.row(points, faces[f0, (corner_ids[start] + 1) % 3]), v3.row(points, i))
        u, v = _tangent_frame(nrm, hint)
        ku = 0.0
        kuv = 0.0
        kv = 0.0
        for s in range(start, stop):
            f = face_ids[s]
            wt = corner[f, corner_ids[s]] / total
            if wt == 0.0:
                continue
            # rotate the vertex frame (u, v, nrm) rigidly into the face plane (normal nf) and
            # express it in the face frame (t, b); perp . u = nf . u because nrm is normal to u
            t = (data[f, 0], data[f, 1], data[f, 2])
            b = (data[f, 3], data[f, 4], data[f, 5])
            nf = (data[f, 6], data[f, 7], data[f, 8])
            align = 1.0 + v3.dot(nrm, nf)
            if align <= 1e-12:
                continue  # face folded fully against the vertex normal: no rotation defined
            inv = 1.0 / align
            dt = v3.dot(nrm, t) * inv
            db = v3.dot(nrm, b) * inv
            pu = v3.dot(nf, u)
            pv = v3.dot(nf, v)
            u1 = v3.dot(u, t) - dt * pu
            v1 = v3.dot(u, b) - db * pu
            u2 = v3.dot(v, t) - dt * pv
            v2 = v3.dot(v, b) - db * pv
            a = data[f, 9]
            b = data[f, 10]
            c = data[f, 11]
            ku += wt * (a * u1 * u1 + 2.0 * b * u1 * v1 + c * v1 * v1)
            kuv += wt * (a * u1 * u2 + b * (u1 * v2 + u2 * v1) + c * v1 * v2)
            kv += wt * (a * u2 * u2 + 2.0 * b * u2 * v2 + c * v2 * v2)
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
        p1 = v3.sub(v3.scale(u, cs), v3.scale(v, sn))
        if a1 < a2:
            a1, a2 = a2, a1
            p1 = v3.cross(nrm, p1)
        k1[i] = a1
        k2[i] = a2
        v3.store(d1, i, p1)
        v3.store(d2, i, v3.cross(nrm, p1))
    return k1, k2, d1, d2, area


def principal_curvatures(points, faces, *, normals=None) -> CurvatureResult:
    """Estimate principal curvatures and directions at every vertex.

    Parameters
    ----------
    points : array_like, shape (V, 3)
        Vertex coordinates.
    faces : array_like, shape (F, 3)
        Triangles, oriented consistently; the curvature sign follows the
        normals they imply (see :func:`pverosion.kernels.orientation.orient_faces`).
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

    Examples
    --------
    >>> import numpy as np, pyvista as pv
    >>> from pverosion.kernels.curvature import principal_curvatures
    >>> sphere = pv.Icosphere(radius=2.0, nsub=4)
    >>> faces = sphere.regular_faces
    >>> H = principal_curvatures(sphere.points, faces).mean
    >>> bool(np.allclose(H, 0.5, rtol=1e-6))
    True
    """
    pts, fcs = as_triangle_mesh(points, faces)
    if normals is None:
        nrm = vertex_normals(pts, fcs, weighting="max")
    else:
        nrm = np.ascontiguousarray(normals, dtype=np.float64)
        if nrm.shape != pts.shape:
            raise ValueError(f"normals must have shape {pts.shape}; got {nrm.shape}")
    corner = corner_areas(pts, fcs)
    face_data = _face_tensors(pts, fcs, nrm)
    indptr, face_ids, corner_ids = vertex_face_incidence(fcs, len(pts))
    k1, k2, d1, d2, area = _vertex_curvatures(
        pts, fcs, nrm, face_data, corner, indptr, face_ids, corner_ids
    )
    return CurvatureResult(k1=k1, k2=k2, direction1=d1, direction2=d2, normals=nrm, point_areas=area)
