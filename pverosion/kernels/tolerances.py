"""Numerical tolerances shared by the kernels, in one place.

Lengths are relative to a mesh's size (its bounding-box diagonal or mean edge length, as each
name says), so results do not depend on the model's units.
"""

from __future__ import annotations

__all__ = ['COPLANAR', 'CROSSING_GROWTH', 'FLAT_CURVATURE', 'RAY_SHADOW', 'RAY_SHIFT', 'RAY_START', 'REPAIR_TOLERANCE',
           'ZERO_DIRECTION']

COPLANAR = 1e-12
"""Relative plane distance below which a vertex counts as lying in the other triangle's plane."""

REPAIR_TOLERANCE = 1e-9
"""Default ``tolerance`` of the repair pre-pass: faces with an edge shorter than this, or a corner this close to the
opposite edge, relative to the input's bounding-box diagonal, are nearly degenerate."""

FLAT_CURVATURE = 1e-9
"""Vertices with ``H * e_avg <= FLAT_CURVATURE`` count as flat (a radius above 10⁹ edge lengths)."""

ZERO_DIRECTION = 64 * 2.0**-52
"""A weathering step's direction (an unnormalised uniform Laplacian) no longer than this times the vertex's largest
coordinate, or than ``FLAT_CURVATURE`` times the mean edge length, is no direction: the vertex does not move. (A
vertex at the centroid of its ring, as hole filling places them, would otherwise step along rounding noise, which
depends on where the model sits.)"""

CROSSING_GROWTH = 1e-7
"""Triangles are grown by this fraction of their size in the particles' crossing test, so no segment slips between two."""

RAY_START = 1e-9
"""Start of an upward ray above its vertex, relative to the bounding-box diagonal."""

RAY_SHIFT = 1e-8
"""Horizontal nudge of the rays of a vertex with a tilted normal, relative to the bounding-box diagonal."""

RAY_SHADOW = 1e-12
"""How far (relative to the diagonal) outside a face's (x, y) shadow a vertical ray still meets the face."""
