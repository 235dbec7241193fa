"""Isosurfaces of sampled volumes by scikit-image's marching cubes, without ties at the level.

scikit-image's marching cubes (Lewiner et al.) is topologically consistent
only when nothing ties with the level. A sample at the level puts the
vertices of all its edges on the sample, and the cubes around it then emit
repeated triangles, triangles coinciding with opposite orientations and
edges used by one or by three or more triangles; a face whose bilinear
saddle is at the level (two diagonal samples above, two below, symmetric
about it: every such face of a 0/1 grid at 0.5) is resolved one way by one
of its cubes and the other way by the other, which leaves cracks and
repeated triangles. :func:`marching_cubes` runs it on :func:`untied_field`,
where nothing is at the level.
"""

from __future__ import annotations

import numpy as np

__all__ = ["AT_LEVEL", "UNTIED_LEVEL", "marching_cubes", "untied_field"]

AT_LEVEL = ("above", "below")
"""Sides of the level a sample equal to it can be taken on."""

UNTIED_LEVEL = 2.0**-40
"""Level of :func:`untied_field`, a fraction of the largest distance of a sample from the level: the vertices it
moves stay within float32 rounding of the samples, and the saddles it moves stay far above the 2.2e-16 below which
scikit-image's face test takes a saddle for a tie."""


def untied_field(values: np.ndarray, level: float, *, at_level: str) -> tuple[np.ndarray, float]:
    """The float32 volume and the level that scikit-image's marching cubes is run on, without ties.

    The field is the samples' distance above ``level`` divided by the
    largest distance of a sample from it, in float32 (more digits near the
    level than the samples themselves in float32); its level is
    :data:`UNTIED_LEVEL`. A sample above ``level`` (greater, or equal with
    ``at_level="above"``) that is not above the new level is raised to twice
    it. No sample is then at the level, the vertices on the edges of a
    sample equal to ``level`` stay within float32 rounding of it, and a face
    whose saddle was at ``level`` is resolved as by a level slightly above
    it: its two samples above the level are separated.

    Parameters
    ----------
    values : array_like, shape (nx, ny, nz)
        Volume samples; not modified.
    level : float
        Iso level.
    at_level : {"above", "below"}
        Side of the level of the samples equal to it.

    Returns
    -------
    field : numpy.ndarray, shape (nx, ny, nz), float32
        A new C-contiguous array.
    level : float
        :data:`UNTIED_LEVEL`.
    """
    if at_level not in AT_LEVEL:
        raise ValueError(f"at_level must be one of {AT_LEVEL}; got {at_level!r}")
    values = np.asarray(values)
    level = float(level)
    scale = max(float(values.max()) - level, level - float(values.min()))
    if not 0.0 < scale < np.inf:  # no sample off the level, or NaN or infinite samples
        scale = 1.0
    field = np.empty(values.shape, dtype=np.float32)
    np.subtract(values, level, out=field, dtype=np.float64, casting="same_kind")  # rounded once, from float64
    field *= np.float32(1.0 / scale)
    near = (field >= 0.0) & (field <= UNTIED_LEVEL)  # with -0.0, which a sample just below the level can give
    above = values[near] >= level if at_level == "above" else values[near] > level
    field[near] = np.where(above, 2.0 * UNTIED_LEVEL, 0.0)
    return field, UNTIED_LEVEL


def marching_cubes(values: np.ndarray, level: float, *, at_level: str,
                   spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Isosurface of a volume at ``level`` by scikit-image's marching cubes (Lewiner et al.) on :func:`untied_field`.

    The surface is manifold, closed where the samples above the level do not
    reach the volume's border, with no repeated triangle and no triangle
    repeating a vertex. The samples equal to ``level`` lie on the surface
    within float32 rounding: the triangles between the vertices around one
    may have zero area, as with VTK's flying edges.

    Parameters
    ----------
    values : array_like, shape (nx, ny, nz)
        Volume samples, at least 2 per axis; not modified.
    level : float
        Iso level.
    at_level : {"above", "below"}
        Side of the level of the samples equal to it (above: the surface encloses them).
    spacing : (3,) float, default: (1, 1, 1)
        Sample spacing along each axis.

    Returns
    -------
    verts : numpy.ndarray, shape (V, 3)
        Vertex positions: index coordinates times ``spacing``, axes in the order of ``values``.
    faces : numpy.ndarray, shape (F, 3), int32
        Vertex ids of each triangle, wound with the right-hand normal towards the samples above
        the level. Both arrays are empty when every sample is on one side of the level.
    """
    from skimage.measure import marching_cubes as lewiner

    field, untied = untied_field(values, level, at_level=at_level)
    if not field.min() < untied < field.max():
        return np.empty((0, 3)), np.empty((0, 3), np.int32)
    verts, faces, _, _ = lewiner(field, level=untied, spacing=tuple(float(s) for s in spacing))
    return verts, faces
