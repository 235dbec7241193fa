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
import numpy.typing as npt

__all__ = ["AT_LEVEL", "LARGEST_RATIO", "UNTIED_LEVEL", "marching_cubes", "untied_field"]

AT_LEVEL = ("above", "below")
"""Sides of the level a sample equal to it can be taken on."""

UNTIED_LEVEL = 2.0**-40
"""Level of :func:`untied_field`, whose samples off the level are at least 1 from it: the vertices next to a sample
moved to either side of this level stay within float32 rounding of the sample, and scikit-image's face test, which
takes a saddle within 2.2e-16 of the level for a tie, sees products of samples at least 1 away."""

_FLOAT32_MAX = float(np.finfo(np.float32).max)

LARGEST_RATIO = 2.0**100
"""Largest distance from the level of a sample of :func:`untied_field` (in units of the nearest one), so that the
field stays within the float32 range; samples nearer than ``2**-100`` of the farthest one count as its nearest."""


def untied_field(values: npt.ArrayLike, level: float, *, at_level: str) -> tuple[np.ndarray, float]:
    """The float32 volume and the level that scikit-image's marching cubes is run on, without ties.

    The field is the samples' distance above ``level`` in units of the
    nearest distance of a sample off the level (at least :data:`LARGEST_RATIO`
    ``**-1`` of the farthest), in float32: every sample off the level is 1 or
    more away from it, however far others lie, so that no face saddle ties
    with the level in scikit-image's absolute test. Its level is
    :data:`UNTIED_LEVEL`. A sample equal to ``level`` goes to the side
    ``at_level`` names: twice the new level above it, 0 below. The vertices
    on the edges of such a sample stay within float32 rounding of it, and a
    face whose saddle was at ``level`` is resolved as by a level slightly
    above it: its two samples above the level are separated.

    Parameters
    ----------
    values : array_like, shape (nx, ny, nz)
        Finite volume samples; not modified.
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

    Raises
    ------
    ValueError
        If ``at_level`` is unknown, a sample is NaN or infinite, or farther from the level than the float32
        range.
    """
    if at_level not in AT_LEVEL:
        raise ValueError(f"at_level must be one of {AT_LEVEL}; got {at_level!r}")
    values = np.asarray(values)
    level = float(level)
    lowest, highest = (float(values.min()), float(values.max())) if values.size else (level, level)
    if not (np.isfinite(lowest) and np.isfinite(highest)):
        bad = values.size - int(np.count_nonzero(np.isfinite(values)))
        raise ValueError(f"the volume has {bad} NaN or infinite samples; the surface through them is undefined")
    farthest = max(highest - level, level - lowest)
    if farthest > _FLOAT32_MAX:
        raise ValueError(f"the volume has samples more than {_FLOAT32_MAX:.3g} from the level {level:g}, beyond the "
                         "float32 range of the marching cubes: rescale the volume first")
    field = np.empty(values.shape, dtype=np.float32)
    np.subtract(values, level, out=field, dtype=np.float64, casting="same_kind")  # rounded once, from float64
    distance = np.abs(field)
    nearest = float(np.min(distance, where=distance > 0.0, initial=np.inf))
    del distance
    if nearest < np.inf:  # some sample is off the level
        field *= np.float32(1.0 / max(nearest, farthest / LARGEST_RATIO))
    near = (field >= 0.0) & (field <= UNTIED_LEVEL)  # with -0.0, which a sample just below the level can give
    above = values[near] >= level if at_level == "above" else values[near] > level
    field[near] = np.where(above, 2.0 * UNTIED_LEVEL, 0.0)
    return field, UNTIED_LEVEL


def marching_cubes(values: npt.ArrayLike, level: float, *, at_level: str,
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
        Finite volume samples, at least 2 per axis; not modified.
    level : float
        Iso level.
    at_level : {"above", "below"}
        Side of the level of the samples equal to it (above: the surface encloses them).
    spacing : (3,) float, default: (1, 1, 1)
        Sample spacing along each axis.

    Returns
    -------
    verts : numpy.ndarray, shape (V, 3), float32
        Vertex positions: index coordinates times ``spacing``, axes in the order of ``values``.
    faces : numpy.ndarray, shape (F, 3), int32
        Vertex ids of each triangle, wound with the right-hand normal towards the samples above
        the level. Both arrays are empty when every sample is on one side of the level.

    Raises
    ------
    ValueError
        As :func:`untied_field`: a NaN or infinite sample, or one beyond the float32 range from the level.
    """
    from skimage.measure import marching_cubes as lewiner

    field, untied = untied_field(values, level, at_level=at_level)
    if not field.min() < untied < field.max():
        return np.empty((0, 3), np.float32), np.empty((0, 3), np.int32)
    verts, faces, _, _ = lewiner(field, level=untied, spacing=tuple(float(s) for s in spacing))
    return verts, faces
