"""Consistent, outward face orientation for closed meshes and open scans.

Faces are first made consistent inside each edge-connected component by
propagating across manifold edges (edges shared by exactly two faces). Each
component is then turned outward by the sign of its enclosed volume, where
the holes of open scans are virtually closed by a cone from every boundary
loop to that loop's centroid. A component that lies inside another one (the
wall of a cavity) is turned the other way, decided by the generalised
winding number, so that normals always point out of the solid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit, unsigned
from pverosion.kernels._scatter import CHUNKS, OwnedRows, chunk_range, outside_corners, owner_rows
from pverosion.kernels._threads import for_chunks, for_ranges, range_count
from pverosion.kernels.mesh.locality import locality_renumbering
from pverosion.kernels.mesh.topology import find_root, sorted_twins

__all__ = ["ORIENTATIONS", "Orientation", "SortedOrientation", "orient_faces", "orient_sorted", "winding_number"]

ORIENTATIONS = ("outward", "inward", "keep")
"""Accepted values of the ``orientation`` option."""

APPLY_FACES_PER_RANGE = 1 << 17
"""Smallest range of faces a thread reverses: a copy of fewer faces costs less than handing it to a thread."""

SPLIT_FACES = 1 << 16
"""Fewest faces whose propagation is split over the threads: on fewer, whose states stay in a core's caches,
one serial pass costs less than the parts and their union-find."""


@dataclass(frozen=True)
class Orientation:
    """Result of :func:`orient_faces`.

    Attributes
    ----------
    faces : numpy.ndarray, shape (F, 3), int64
        Faces in the chosen orientation.
    flipped : numpy.ndarray, shape (F,), bool
        Faces whose vertex order was reversed relative to the input.
    component : numpy.ndarray, shape (F,), int64, or None
        Edge-connected component of each face; None with ``mode="keep"``,
        which builds no topology.
    mode : str
        The orientation that was asked for.
    """

    faces: np.ndarray
    flipped: np.ndarray
    component: np.ndarray | None
    mode: str

    @property
    def n_flipped(self) -> int:
        """Number of faces whose order was reversed."""
        return int(np.count_nonzero(self.flipped))

    @property
    def n_components(self) -> int | None:
        """Number of edge-connected components (None with ``mode="keep"``)."""
        if self.component is None:
            return None
        return int(self.component.max()) + 1 if self.component.size else 0


@njit(cache=True, error_model="numpy")
def _propagate(faces, partner, flip, comp, stack):
    """Make the faces (F, 3) consistent across the manifold edges (twins ``partner`` (3F,)): the faces to reverse
    into ``flip`` (F,), False on entry, and the edge-connected component of each into ``comp`` (F,), -1 on entry;
    ``stack`` (F,) is scratch. Returns the number of components."""
    n_comp = 0
    for seed in range(faces.shape[0]):
        if comp[seed] >= 0:
            continue
        comp[seed] = n_comp
        top = 0
        stack[top] = seed
        top += 1
        while top > 0:
            top -= 1
            f = stack[top]
            for k in range(3):
                p = partner[3 * f + k]
                if p < 0:
                    continue
                g = p // 3
                if comp[g] >= 0:
                    continue
                same_direction = faces[f, k] == faces[g, p - 3 * g]
                comp[g] = n_comp
                flip[g] = flip[f] ^ same_direction
                stack[top] = g
                top += 1
        n_comp += 1
    return n_comp


_FLIP = np.uint8(8)
"""Bit of a face's state (:func:`_propagate_parts`) set when the face turns relative to its seed."""

_SEEN = np.uint8(16)
"""Bit of a face's state set once the propagation has reached the face."""


@njit(cache=True, error_model="numpy", inline="always")
def _same_direction(state, h, q):
    """Whether half-edges ``h`` and ``q`` run the same way, from the face states' ascending bits."""
    return ((state[h // 3] >> (h % 3)) & 1) == ((state[q // 3] >> (q % 3)) & 1)


@njit(cache=True, error_model="numpy", nogil=True)
def _propagate_parts(faces, partner, bounds, state, seed_of, stack, seeds, n_seeds, cross, n_cross, conflict,
                     start, stop):
    """:func:`_propagate` inside each part ``start`` to ``stop`` of the faces (part ``p`` is ``bounds[p]`` to
    ``bounds[p + 1]``), across the edges whose two faces are in the part.

    Every face gets in ``state`` (F,) uint8 a bit per half-edge set when it runs from its smaller vertex,
    :data:`_FLIP` when it turns relative to the first face of its part's component, and :data:`_SEEN`; that
    first face (its seed) goes to ``seed_of`` (F,). Part ``p`` lists its seeds, ascending, from
    ``seeds[bounds[p]]`` (``n_seeds[p]`` of them) and the half-edges to other parts (each pair once, from its
    lower half-edge) from ``cross[3 bounds[p]]`` (``n_cross[p]``); ``conflict[p]`` is set when an edge inside
    the part joins two faces the other way than their flips (a non-orientable component). ``stack`` (F,) is
    scratch.
    """
    for p in range(start, stop):
        lo, hi = bounds[p], bounds[p + 1]
        for f in range(lo, hi):
            u = unsigned(f)
            a0, a1, a2 = faces[u, 0], faces[u, 1], faces[u, 2]
            state[u] = np.uint8((a0 < a1) | ((a1 < a2) << 1) | ((a2 < a0) << 2))
        n_seed = 0
        n_out = 0
        for seed in range(lo, hi):
            u = unsigned(seed)
            if state[u] & _SEEN:
                continue
            state[u] |= _SEEN
            seed_of[u] = seed
            seeds[unsigned(lo + n_seed)] = seed
            n_seed += 1
            stack[unsigned(lo)] = seed
            top = 1
            while top > 0:
                top -= 1
                f = stack[unsigned(lo + top)]
                here = state[unsigned(f)]
                for k in range(3):
                    h = 3 * f + k
                    q = partner[unsigned(h)]
                    if q < 0:
                        continue
                    g = q // 3
                    if g < lo or g >= hi:
                        if h < q:
                            cross[unsigned(3 * lo + n_out)] = h
                            n_out += 1
                        continue
                    there = state[unsigned(g)]
                    turn = (here & _FLIP) ^ (_FLIP if ((here >> k) ^ (there >> (q - 3 * g))) & 1 == 0 else 0)
                    if not there & _SEEN:
                        state[unsigned(g)] = there | _SEEN | turn
                        seed_of[unsigned(g)] = seed
                        stack[unsigned(lo + top)] = g
                        top += 1
                    elif h < q and (there & _FLIP) != turn:
                        conflict[p] = True
        n_seeds[p] = n_seed
        n_cross[p] = n_out


@njit(cache=True, error_model="numpy")
def _find_parity(parent, parity, x):
    """Root of ``x`` in the forest ``parent`` and the parity of ``x`` relative to it (``parity`` holds each
    node's parity relative to its parent), compressing the path."""
    root = x
    total = False
    while parent[root] != root:
        total ^= parity[root]
        root = parent[root]
    y = x
    here = total
    while parent[y] != y:
        up = parent[y]
        above = here ^ parity[y]
        parent[y] = root
        parity[y] = here
        y = up
        here = above
    return root, total


@njit(cache=True, error_model="numpy")
def _merge_parts(partner, bounds, state, seed_of, seeds, n_seeds, cross, n_cross, parent, parity,
                 root_comp, root_flip):
    """Join the part components of :func:`_propagate_parts` across the edges between parts.

    A union-find over the seeds (``parent`` (F,), ``parity`` (F,) scratch) keeps the lowest seed of every
    component as its root; each seed ``s`` gets its component, numbered in the order of the roots, in
    ``root_comp[s]`` and whether its faces flip relative to the root in ``root_flip[s]``. Returns the number of
    components, or -1 when an edge contradicts the flips (a non-orientable component).
    """
    n_parts = bounds.shape[0] - 1
    for p in range(n_parts):
        for i in range(bounds[p], bounds[p] + n_seeds[p]):
            parent[seeds[i]] = seeds[i]
            parity[seeds[i]] = False
    for p in range(n_parts):
        for i in range(3 * bounds[p], 3 * bounds[p] + n_cross[p]):
            h = cross[i]
            q = partner[h]
            f, g = h // 3, q // 3
            odd = (((state[f] ^ state[g]) & _FLIP) != 0) ^ _same_direction(state, h, q)
            ra, pa = _find_parity(parent, parity, seed_of[f])
            rb, pb = _find_parity(parent, parity, seed_of[g])
            if ra == rb:
                if (pa ^ pb) != odd:
                    return -1
            elif ra < rb:
                parent[rb] = ra
                parity[rb] = pa ^ pb ^ odd
            else:
                parent[ra] = rb
                parity[ra] = pa ^ pb ^ odd
    n_comp = 0
    for p in range(n_parts):
        for i in range(bounds[p], bounds[p] + n_seeds[p]):
            s = seeds[i]
            root, odd = _find_parity(parent, parity, s)
            if root == s:
                root_comp[s] = n_comp
                n_comp += 1
            root_comp[s] = root_comp[root]
            root_flip[s] = odd
    return n_comp


def _propagate_split(faces: np.ndarray, partner: np.ndarray) -> tuple[np.ndarray, ...]:
    """:func:`_propagate`, with the faces split into one part per thread from :data:`SPLIT_FACES` faces on.

    Returns ``state`` (F,) uint8, ``labels`` (F,), ``root_comp``, ``root_flip`` and the number of components:
    face ``f`` is in component ``root_comp[labels[f]]`` and flips when the :data:`_FLIP` bit of
    ``state[f]`` differs from ``root_flip[labels[f]]``. Every part propagates inside itself; a serial
    union-find joins the parts across the few edges between them (the faces come in an order of spatial
    locality), so the result is that of one serial pass whatever the number of threads. A non-orientable
    component, whose flips depend on the path of the propagation, is oriented by the serial pass.
    """
    n_faces = faces.shape[0]
    parts = range_count(n_faces)
    index = partner.dtype  # face and half-edge indices as compact as the twins
    labels, stack = np.empty(n_faces, index), np.empty(n_faces, index)
    if parts > 1 and n_faces >= SPLIT_FACES:
        bounds = np.array([p * n_faces // parts for p in range(parts + 1)], np.int64)
        state, seeds, cross = np.empty(n_faces, np.uint8), np.empty(n_faces, index), np.empty(3 * n_faces, index)
        n_seeds, n_cross = np.zeros(parts, np.int64), np.zeros(parts, np.int64)
        conflict = np.zeros(parts, np.bool_)
        for_ranges(_propagate_parts, parts, faces, partner, bounds, state, labels, stack, seeds, n_seeds, cross,
                   n_cross, conflict, min_items=1)
        if not conflict.any():
            root_comp, root_flip = np.empty(n_faces, np.int64), np.empty(n_faces, np.bool_)
            n_comp = _merge_parts(partner, bounds, state, labels, seeds, n_seeds, cross, n_cross, stack,
                                  np.empty(n_faces, np.bool_), root_comp, root_flip)
            if n_comp >= 0:
                return state, labels, root_comp, root_flip, n_comp
    flip = np.zeros(n_faces, np.bool_)
    labels[:] = -1
    n_comp = _propagate(faces, partner, flip, labels, stack)
    return flip.view(np.uint8) * _FLIP, labels, np.arange(n_comp), np.zeros(n_comp, np.bool_), n_comp


@njit(cache=True, error_model="numpy")
def _winding(point, points, faces):
    total = 0.0
    for f in range(faces.shape[0]):
        a = points[faces[f, 0]] - point
        b = points[faces[f, 1]] - point
        c = points[faces[f, 2]] - point
        la = np.sqrt(a @ a)
        lb = np.sqrt(b @ b)
        lc = np.sqrt(c @ c)
        det = a @ np.cross(b, c)
        den = la * lb * lc + (a @ b) * lc + (a @ c) * lb + (b @ c) * la
        total += 2.0 * np.arctan2(det, den)
    return total / (4.0 * np.pi)


def winding_number(point, points: np.ndarray, faces: np.ndarray) -> float:
    """Generalised winding number of a triangle mesh around a point.

    Parameters
    ----------
    point : array_like, shape (3,)
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)

    Returns
    -------
    float
        About 1 inside a closed outward-oriented mesh, 0 outside, fractional
        near the holes of an open one.
    """
    return float(_winding(np.asarray(point, dtype=np.float64), points, faces))


@njit(cache=True, error_model="numpy")
def _centre_extent(points):
    """Centroid ``(x, y, z)`` of the points (V, 3) and their largest extent along an axis."""
    sx = sy = sz = 0.0
    lx, ly, lz = points[0, 0], points[0, 1], points[0, 2]
    hx, hy, hz = lx, ly, lz
    for v in range(points.shape[0]):
        x, y, z = points[v, 0], points[v, 1], points[v, 2]
        sx += x
        sy += y
        sz += z
        lx, hx = (x if x < lx else lx), (x if x > hx else hx)
        ly, hy = (y if y < ly else ly), (y if y > hy else hy)
        lz, hz = (z if z < lz else lz), (z if z > hz else hz)
    n = points.shape[0]
    ex, ey, ez = hx - lx, hy - ly, hz - lz
    extent = ex if ex >= ey and ex >= ez else (ey if ey >= ez else ez)
    return sx / n, sy / n, sz / n, extent


@njit(cache=True, error_model="numpy", nogil=True)
def _settle_chunk(points, faces, root_comp, root_flip, state, labels, flip, component, others, origin, volume,
                  rims, owners, outside, c):
    """Resolve the faces of chunk ``c`` of :func:`_propagate_split` from their ``state`` and ``labels`` into
    ``flip`` and ``component``, then add six times their signed volume per component into
    ``volume[c]``, count their boundary half-edges into ``rims[c]`` and their corners outside the rows the
    chunk owns (``owners``, :class:`~pverosion.kernels._scatter.OwnedRows`) into ``outside[c]``."""
    start, stop = chunk_range(faces.shape[0], c)
    origin = (origin[0], origin[1], origin[2])  # in registers: the stores below could alias the array
    lo, hi = owners[c], owners[c + 1]
    n_outside = 0
    n_rim = 0
    here = -1  # the component whose volume ``total`` holds, added in face order as the array would be
    total = 0.0
    for f in range(start, stop):
        u = unsigned(f)
        label = unsigned(labels[u])
        comp = root_comp[label]
        component[u] = comp
        reverse = ((state[u] & _FLIP) != 0) ^ root_flip[label]
        flip[u] = reverse
        a = v3.sub(v3.row(points, unsigned(faces[u, 0])), origin)
        b = v3.sub(v3.row(points, unsigned(faces[u, 1])), origin)
        cc = v3.sub(v3.row(points, unsigned(faces[u, 2])), origin)
        det = v3.dot(a, v3.cross(b, cc))  # reversing the face negates it exactly
        if comp != here:
            if here >= 0:
                volume[c, here] = total
            here = comp
            total = volume[c, comp]
        total += -det if reverse else det
        h = 3 * f
        n_rim += (others[h] == 0) + (others[h + 1] == 0) + (others[h + 2] == 0)
        n_outside += outside_corners(faces, f, lo, hi)
    if here >= 0:
        volume[c, here] = total
    rims[c] += n_rim
    outside[c] = n_outside


@njit(cache=True, error_model="numpy")
def _hole_cones(points, faces, flip, component, others, origin, volume, rim, parent, centre, count):
    """Add to ``volume`` (six times) the cone from the centroid of every hole's rim over the rim's edges.

    Scratch: ``rim`` (R,) for the R boundary half-edges (``others`` zero), ``parent`` (V,) must be
    ``arange(V)``, ``centre`` (V, 3) and ``count`` (V,) zero.
    """
    n = 0
    for h in range(others.shape[0]):
        if others[h] == 0:
            rim[n] = h
            n += 1
    for h in rim:
        f, k = h // 3, h % 3
        ra = find_root(parent, faces[f, k])
        rb = find_root(parent, faces[f, (k + 1) % 3])
        parent[ra] = rb
    for h in rim:
        a = faces[h // 3, h % 3]
        r = find_root(parent, a)
        for d in range(3):
            centre[r, d] += points[a, d]
        count[r] += 1.0
    for h in rim:
        f = h // 3
        a = faces[f, h % 3]
        b = faces[f, (h % 3 + 1) % 3]
        if flip[f]:
            a, b = b, a
        r = find_root(parent, a)
        apex = v3.sub(v3.scale(v3.row(centre, r), 1.0 / count[r]), origin)
        pa = v3.sub(v3.row(points, a), origin)
        pb = v3.sub(v3.row(points, b), origin)
        volume[component[f]] += v3.dot(pb, v3.cross(pa, apex))


def _settled_volumes(points: np.ndarray, faces: np.ndarray, partner: np.ndarray,
                     others: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, np.ndarray, float, OwnedRows]:
    """The consistent faces of :func:`_propagate_split` and the signed volume of every component, each hole
    closed by a cone to its rim's centroid, from one more pass over the faces.

    Returns ``flip`` (F,), ``component`` (F,), the number of components, their volumes, the largest
    extent of the points along an axis and the :class:`~pverosion.kernels._scatter.OwnedRows` of the faces,
    counted in the same pass.
    """
    state, labels, root_comp, root_flip, n_comp = _propagate_split(faces, partner)
    flip, component = np.empty(faces.shape[0], np.bool_), np.empty(faces.shape[0], np.int64)
    *centre, extent = _centre_extent(points)
    origin = np.array(centre)
    chunks = np.zeros((CHUNKS, n_comp))
    rims = np.zeros(CHUNKS, np.int64)
    owners, outside = owner_rows(faces, points.shape[0]), np.zeros(CHUNKS, np.int64)
    for_chunks(_settle_chunk, faces.shape[0], points, faces, root_comp, root_flip, state, labels, flip, component,
               others, origin, chunks, rims, owners, outside)
    volume = chunks.sum(axis=0)
    n_rim = int(rims.sum())
    if n_rim:
        n_vertices = points.shape[0]
        _hole_cones(points, faces, flip, component, others, origin, volume, np.empty(n_rim, np.int64),
                    np.arange(n_vertices), np.zeros((n_vertices, 3)), np.zeros(n_vertices))
    return flip, component, n_comp, volume / 6.0, extent, OwnedRows.from_counts(owners, outside)


def orient_faces(
    points: np.ndarray,
    faces: np.ndarray,
    *,
    mode: str = "outward",
) -> Orientation:
    """Orient faces consistently, with normals pointing out of (or into) the solid.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray, shape (F, 3)
    mode : {"outward", "inward", "keep"}
        ``"outward"`` makes convex regions have positive mean curvature;
        ``"inward"`` is its mirror; ``"keep"`` returns the faces unchanged.

    Returns
    -------
    Orientation

    Notes
    -----
    A component whose closed volume is negligible (a flat or symmetric open
    sheet) keeps the orientation of its first face. Non-orientable
    components (a Möbius strip) keep whatever the propagation reached.
    Meshes whose face corners lie far apart in the vertex numbering are
    oriented in the numbering of
    :func:`~pverosion.kernels.mesh.locality.locality_renumbering`, as the
    curvature filter orients them (the result is the same for orientable
    components in any numbering); "first" then refers to the faces sorted
    in that numbering.
    """
    if mode not in ORIENTATIONS:
        raise ValueError(f"orientation must be one of {ORIENTATIONS}; got {mode!r}")
    if mode == "keep":
        return Orientation(faces, np.zeros(len(faces), bool), None, mode)
    renumbering = locality_renumbering(points, faces)
    if renumbering is None:
        local = orient_sorted(points, faces, mode=mode)
    else:
        local = orient_sorted(renumbering.to_local(points), renumbering.faces(faces), mode=mode)
    flipped = local.input_flip()
    out = _apply(faces, flipped) if local.n_flipped else faces.copy()
    return Orientation(out, flipped, _unsort(local.component, local.order), mode)


@dataclass(frozen=True)
class SortedOrientation:
    """Result of :func:`orient_sorted`, in the face order of :func:`~pverosion.kernels.mesh.topology.locality_order`.

    Attributes
    ----------
    order : numpy.ndarray, shape (F,), int64
        ``faces[order]`` is the sorted input.
    faces : numpy.ndarray, shape (F, 3), int64
        The sorted faces in the chosen orientation.
    flip : numpy.ndarray, shape (F,), bool
        Sorted faces whose vertex order was reversed.
    component : numpy.ndarray, shape (F,), int64
        Edge-connected component of each sorted face.
    n_flipped : int
        Number of reversed faces.
    n_nonmanifold : int
        Number of half-edges on edges with more than two faces (0 on a manifold mesh); the orientation does not
        propagate across them.
    owned : OwnedRows or None
        The :class:`~pverosion.kernels._scatter.OwnedRows` of ``faces``, for kernels that add from them into
        per-vertex sums (:meth:`~pverosion.kernels.curvature.operator.CurvatureOperator.from_sorted`).
    """

    order: np.ndarray
    faces: np.ndarray
    flip: np.ndarray
    component: np.ndarray
    n_flipped: int
    n_nonmanifold: int = 0
    owned: OwnedRows | None = None

    def input_flip(self) -> np.ndarray:
        """Mask (F,) of the reversed faces in the input order."""
        return _unsort(self.flip, self.order)

    def input_faces(self, faces: np.ndarray) -> np.ndarray:
        """The input ``faces`` (F, 3), in their order, in the chosen orientation."""
        return _apply(faces, self.input_flip())


def orient_sorted(points: np.ndarray, faces: np.ndarray, *, mode: str = "outward") -> SortedOrientation:
    """:func:`orient_faces` on the faces sorted by their smallest vertex, without mapping back.

    Kernels that sort faces the same way for memory locality (such as
    :class:`~pverosion.kernels.curvature.operator.CurvatureOperator`) take the result's
    faces as they are, which saves sorting, permuting and validating the faces
    again; :func:`orient_faces` maps the result back to the input order.

    Parameters
    ----------
    points : numpy.ndarray, shape (V, 3), float64
    faces : numpy.ndarray, shape (F, 3), int64
        Validated triangles.
    mode : {"outward", "inward"}

    Returns
    -------
    SortedOrientation
    """
    if mode not in ("outward", "inward"):
        raise ValueError(f"orientation must be 'outward' or 'inward'; got {mode!r}")
    order, local, partner, others = sorted_twins(faces, len(points))
    flip, component, n_comp, volume, extent, owned = _settled_volumes(points, local, partner, others)
    decided = np.abs(volume) > 1e-9 * extent**3
    turn = decided & (volume < 0)
    if n_comp > 1:
        turn ^= _cavity_walls(points, _apply(local, flip ^ turn[component]), component, n_comp, decided)
    if mode == "inward":
        turn ^= decided
    if turn.any():
        flip ^= turn[component]
    n_flipped = int(np.count_nonzero(flip))
    n_nonmanifold = int(np.count_nonzero(others >= 2)) if len(others) and others.max() >= 2 else 0
    return SortedOrientation(order, _apply(local, flip) if n_flipped else local, flip, component, n_flipped,
                             n_nonmanifold, owned)


def _unsort(values: np.ndarray, order: np.ndarray) -> np.ndarray:
    """The array ``out`` with ``out[order] = values`` (``order`` a permutation)."""
    out = np.empty_like(values)
    out[order] = values
    return out


@njit(cache=True, nogil=True)
def _apply_range(faces, flip, out, start, stop):
    for f in range(start, stop):
        out[f, 0] = faces[f, 0]
        if flip[f]:
            out[f, 1] = faces[f, 2]
            out[f, 2] = faces[f, 1]
        else:
            out[f, 1] = faces[f, 1]
            out[f, 2] = faces[f, 2]


def _apply(faces: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """``faces`` with the faces where ``flip`` is set reversed (their last two corners swapped)."""
    out = np.empty_like(faces)
    for_ranges(_apply_range, faces.shape[0], faces, flip, out, min_items=APPLY_FACES_PER_RANGE)
    return out


def _cavity_walls(points, outward, component, n_comp, decided):
    """Components nested inside an odd number of other solids (cavity walls)."""
    order = np.argsort(component, kind="stable")
    bounds = np.searchsorted(component[order], np.arange(n_comp + 1))
    comp_faces = [outward[order[bounds[c] : bounds[c + 1]]] for c in range(n_comp)]
    lo = np.array([points[f].reshape(-1, 3).min(axis=0) for f in comp_faces])
    hi = np.array([points[f].reshape(-1, 3).max(axis=0) for f in comp_faces])
    walls = np.zeros(n_comp, bool)
    for c in np.flatnonzero(decided):
        probe = points[comp_faces[c][0, 0]]
        depth = 0
        for d in np.flatnonzero(decided):
            if d != c and np.all(probe >= lo[d]) and np.all(probe <= hi[d]):
                depth += round(winding_number(probe, points, comp_faces[d]))
        walls[c] = depth % 2 == 1
    return walls
