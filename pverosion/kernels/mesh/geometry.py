"""Per-face and per-vertex geometric quantities of triangle meshes.

Inputs are validated arrays: ``points`` (V, 3) float64 and ``faces`` (F, 3)
int64 (see :func:`pverosion.kernels.validation.as_triangle_mesh`).
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels._scatter import CHUNKS, chunk_range, chunk_total
from pverosion.kernels._threads import for_chunks, for_ranges
from pverosion.kernels.mesh.topology import edge_topology

__all__ = [
    "average_edge_length",
    "corner_areas",
    "face_normals",
    "meyer_corner_areas",
    "mixed_corner_areas",
    "point_areas",
    "signed_volume",
    "vertex_normals",
]

_NORMAL_WEIGHTINGS = ("area", "max")


def face_normals(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (right-hand rule on the vertex order) and face areas.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)

    Returns
    -------
    normals : numpy.ndarray, shape (F, 3)
        Unit normals; zero for degenerate faces.
    areas : numpy.ndarray, shape (F,)
    """
    p0, p1, p2 = (points[faces[:, k]] for k in range(3))
    cross = np.cross(p1 - p0, p2 - p0)
    double_area = np.linalg.norm(cross, axis=1)
    normals = np.zeros_like(cross)
    ok = double_area > 0
    normals[ok] = cross[ok] / double_area[ok, None]
    return normals, 0.5 * double_area


@njit(cache=True, error_model="numpy", inline="always")
def normal_terms(p0, p1, p2, max_weights):
    """Contribution of the triangle ``p0, p1, p2`` to the normals of its corners: (n, w0, w1, w2).

    ``n`` is the unnormalised face normal (twice the area); each corner adds
    ``w_k n``, with weights 1 (area weighting) or Max's ``1 / (|e_a|^2 |e_b|^2)``
    of the corner's two edges, all zero where an edge has zero length. Without
    branches (each case computed, then selected), so that loops over batches
    of faces become vector instructions; called from kernels with
    ``error_model="numpy"``.
    """
    a, b, e = v3.sub(p1, p0), v3.sub(p2, p1), v3.sub(p0, p2)
    n = v3.cross(a, b)
    la, lb, le = v3.dot(a, a), v3.dot(b, b), v3.dot(e, e)
    skip = la * lb * le == 0.0
    m0, m1, m2 = 1.0 / (la * le), 1.0 / (la * lb), 1.0 / (lb * le)
    m0, m1, m2 = (0.0 if skip else m0), (0.0 if skip else m1), (0.0 if skip else m2)
    return n, (m0 if max_weights else 1.0), (m1 if max_weights else 1.0), (m2 if max_weights else 1.0)


@njit(cache=True, error_model="numpy", inline="always")
def face_normal_terms(points, faces, f, max_weights):
    """:func:`normal_terms` of face ``f``: (n, w0, w1, w2)."""
    return normal_terms(v3.row(points, faces[f, 0]), v3.row(points, faces[f, 1]), v3.row(points, faces[f, 2]),
                        max_weights)


@njit(cache=True, error_model="numpy", nogil=True)
def add_normal_chunk(points, faces, max_weights, acc, c):
    """Zero ``acc[c]`` and add the weighted normals of chunk ``c`` of the faces to their corners in
    ``acc[c, :, :3]`` (``acc`` is (C, V, 3) or wider).

    Called with a Python bool from :func:`vertex_normals`.
    """
    acc[c] = 0.0
    start, stop = chunk_range(faces.shape[0], c)
    for f in range(start, stop):
        n, w0, w1, w2 = face_normal_terms(points, faces, f, max_weights)
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        for d in range(3):
            acc[c, i0, d] += w0 * n[d]
            acc[c, i1, d] += w1 * n[d]
            acc[c, i2, d] += w2 * n[d]


@njit(cache=True, error_model="numpy", nogil=True)
def normalise_range(acc, out, start, stop):
    """Unit sums over the chunks of ``acc[:, :, :3]`` for vertices ``start`` to ``stop`` (zero where the sum is
    zero)."""
    for i in range(start, stop):
        total = (chunk_total(acc, i, 0), chunk_total(acc, i, 1), chunk_total(acc, i, 2))
        length = v3.norm(total)
        v3.store(out, i, v3.scale(total, 1.0 / length) if length > 0.0 else (0.0, 0.0, 0.0))


def _scatter_normals(points: np.ndarray, faces: np.ndarray, max_weights: bool) -> np.ndarray:
    n_vertices = points.shape[0]
    acc = np.empty((CHUNKS, n_vertices, 3))
    for_chunks(add_normal_chunk, faces.shape[0], points, faces, max_weights, acc)
    out = np.empty((n_vertices, 3))
    for_ranges(normalise_range, n_vertices, acc, out)
    return out


def vertex_normals(
    points: np.ndarray,
    faces: np.ndarray,
    *,
    weighting: str = "area",
) -> np.ndarray:
    """Unit vertex normals from the incident faces.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
    weighting : {"area", "max"}
        ``"area"`` weights each face normal by the face area; ``"max"`` uses
        Max's (1999) weights ``1 / (|e_a|^2 |e_b|^2)`` of the two edges at the
        corner, which are exact for vertices lying on a sphere and are what the
        curvature estimator uses.

    Returns
    -------
    numpy.ndarray, shape (V, 3)
        Unit normals; zero for vertices without a non-degenerate face.
    """
    if weighting not in _NORMAL_WEIGHTINGS:
        raise ValueError(f"weighting must be one of {_NORMAL_WEIGHTINGS}; got {weighting!r}")
    return _scatter_normals(points, faces, weighting == "max")


@njit(cache=True, error_model="numpy", inline="always")
def meyer_corner_areas(e0, e1, e2):
    """Mixed Voronoi areas of the corners of one triangle (Meyer et al. 2003).

    ``e0, e1, e2`` are the edge vectors opposite corners 0, 1, 2, running
    around the triangle (``e0 = p2 - p1``, ``e1 = p0 - p2``, ``e2 = p1 - p0``).
    Returns the three corner areas (zero for a degenerate triangle).
    """
    area = 0.5 * v3.norm(v3.cross(e0, e1))
    return mixed_corner_areas(area, v3.dot(e0, e0), v3.dot(e1, e1), v3.dot(e2, e2), e0, e1, e2)


@njit(cache=True, error_model="numpy", inline="always")
def mixed_corner_areas(area, l0, l1, l2, e0, e1, e2):
    """:func:`meyer_corner_areas` from the triangle's area and squared edge lengths ``l0, l1, l2``.

    Without branches, so that loops over batches of faces become vector
    instructions: every case is computed and the right one selected, with
    each value's operations in the same order as a branch would take them.
    Kernels that call it use ``error_model="numpy"`` (the cases not taken may
    divide by zero).
    """
    w0 = l0 * (l1 + l2 - l0)
    w1 = l1 * (l2 + l0 - l1)
    w2 = l2 * (l0 + l1 - l2)
    d01, d02, d12 = v3.dot(e0, e1), v3.dot(e0, e2), v3.dot(e1, e2)
    # an obtuse corner j takes the area left by its two neighbours, which get -area |e|^2 / (4 e . e')
    obtuse0 = w0 <= 0.0
    obtuse1 = (w1 <= 0.0) & (w0 > 0.0)
    obtuse2 = (w2 <= 0.0) & (w0 > 0.0) & (w1 > 0.0)
    first = -0.25 * (l2 if obtuse0 else (l0 if obtuse1 else l1)) * area / (
        d02 if obtuse0 else (d01 if obtuse1 else d12))
    second = -0.25 * (l1 if obtuse0 else (l2 if obtuse1 else l0)) * area / (
        d01 if obtuse0 else (d12 if obtuse1 else d02))
    rest = area - first - second
    k = 0.5 * area / (w0 + w1 + w2)
    c0 = rest if obtuse0 else (second if obtuse1 else (first if obtuse2 else k * (w1 + w2)))
    c1 = first if obtuse0 else (rest if obtuse1 else (second if obtuse2 else k * (w2 + w0)))
    c2 = second if obtuse0 else (first if obtuse1 else (rest if obtuse2 else k * (w0 + w1)))
    if area == 0.0:
        return 0.0, 0.0, 0.0
    return c0, c1, c2


@njit(cache=True, error_model="numpy", nogil=True)
def _corner_area_range(points, faces, out, start, stop):
    for f in range(start, stop):
        p0, p1, p2 = v3.row(points, faces[f, 0]), v3.row(points, faces[f, 1]), v3.row(points, faces[f, 2])
        c0, c1, c2 = meyer_corner_areas(v3.sub(p2, p1), v3.sub(p0, p2), v3.sub(p1, p0))
        out[f, 0] = c0
        out[f, 1] = c1
        out[f, 2] = c2


def _corner_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    out = np.zeros((faces.shape[0], 3))
    for_ranges(_corner_area_range, faces.shape[0], points, faces, out)
    return out


def corner_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Mixed Voronoi areas of each triangle corner (Meyer et al. 2003).

    Non-obtuse triangles are split at their circumcentre; obtuse ones give the
    obtuse corner half the area and the others a quarter each. The three
    corner areas of a face sum to its area.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)

    Returns
    -------
    numpy.ndarray, shape (F, 3)
    """
    return _corner_areas(points, faces)


def point_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Mixed Voronoi area around each vertex; they sum to the surface area.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)

    Returns
    -------
    numpy.ndarray, shape (V,)
    """
    return np.bincount(faces.ravel(), weights=corner_areas(points, faces).ravel(), minlength=len(points))


@njit(cache=True, error_model="numpy", nogil=True)
def _edge_length_chunk(points, edges, partial, c):
    lo, hi = chunk_range(edges.shape[0], c)
    for e in range(lo, hi):
        partial[c] += v3.norm(v3.sub(v3.row(points, edges[e, 0]), v3.row(points, edges[e, 1])))


def _mean_edge_length(points: np.ndarray, edges: np.ndarray) -> float:
    """Summed in fixed edge chunks, so bit-identical for any thread count."""
    partial = np.zeros(CHUNKS)
    for_chunks(_edge_length_chunk, edges.shape[0], points, edges, partial)
    total = 0.0
    for c in range(CHUNKS):
        total += float(partial[c])
    return total / max(edges.shape[0], 1)


def average_edge_length(points: np.ndarray, faces: np.ndarray, *, edges: np.ndarray | None = None) -> float:
    """Mean length of the mesh's unique undirected edges.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
    edges : numpy.ndarray, shape (E, 2), optional
        Reuse the edges of :func:`~pverosion.kernels.mesh.topology.edge_topology`.

    Returns
    -------
    float
    """
    if edges is None:
        edges = edge_topology(faces, len(points)).edges
    return float(_mean_edge_length(points, edges))


def signed_volume(points: np.ndarray, faces: np.ndarray, *, origin=None) -> float:
    """Signed volume enclosed by the faces, as seen from ``origin``.

    Positive for a closed mesh whose faces wind counter-clockwise seen from
    outside (normals pointing out). For an open mesh the value is the volume
    of the mesh closed by a cone to ``origin``.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
    origin : array_like, shape (3,), optional
        Apex of the closing cone; defaults to the centroid of the points.

    Returns
    -------
    float
    """
    o = points.mean(axis=0) if origin is None else np.asarray(origin, dtype=float)
    p0, p1, p2 = (points[faces[:, k]] - o for k in range(3))
    return float(np.einsum("ij,ij->", p0, np.cross(p1, p2)) / 6.0)
