"""Collision of the fluid's particles with the mesh: boundary planes, crossings, push-out.

Part of :mod:`pverosion.kernels.fluid.particle_fluid` (its docstring describes the method).
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels.fluid.grids import _cell_box, _corner, _first_visit, _row
from pverosion.kernels.fluid.params import (
    _GAP_ROUNDING,
    _LIMIT,
    _PLANE_COS,
    _REUSE,
    _STOP,
    _SWEEP_ROUNDS,
    MAX_PLANES,
    PLANE_REACH,
)
from pverosion.kernels.tolerances import CROSSING_GROWTH

__all__: list[str] = []

# --- mesh collision --------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _over(p, a, b, c, n):
    """Whether the projection of ``p`` on the plane of triangle (a, b, c) with unit normal ``n`` falls inside it."""
    return (v3.dot(v3.cross(v3.sub(b, a), v3.sub(p, a)), n) >= 0.0
            and v3.dot(v3.cross(v3.sub(c, b), v3.sub(p, b)), n) >= 0.0
            and v3.dot(v3.cross(v3.sub(a, c), v3.sub(p, c)), n) >= 0.0)


@njit(cache=True)
def _closest_on_boundary(p, a, b, c):
    """Closest point to ``p`` on the three edges of triangle (a, b, c)."""
    best = a
    best2 = np.inf
    for m in range(3):
        u, w = (a, b) if m == 0 else ((b, c) if m == 1 else (c, a))
        e = v3.sub(w, u)
        ee = v3.dot(e, e)
        t = 0.0 if ee == 0.0 else min(max(v3.dot(v3.sub(p, u), e) / ee, 0.0), 1.0)
        q = v3.add(u, v3.scale(e, t))
        d = v3.sub(p, q)
        if v3.dot(d, d) < best2:
            best2 = v3.dot(d, d)
            best = q
    return best


@njit(cache=True, inline="always")
def _nearer(dist, f, other_dist, other_face):
    """Whether (dist, f) comes before (other_dist, other_face): nearer, or as near with a lower face index."""
    return dist < other_dist or (dist == other_dist and f < other_face)


@njit(cache=True)
def _keep_plane(planes, plane_face, i, taken, data, f, u, offset, dist, edge):
    """Offer face ``f`` (plane ``u . x = offset`` at ``dist``; ``edge``: of an edge or corner) as a boundary plane
    of particle ``i``.

    A face turned less than 30 degrees from a plane already kept replaces it
    when nearer; otherwise it takes a free slot, or the farthest one's when
    nearer (ties go to the lower face index; the visiting order is fixed by
    the grid, and :func:`_sort_planes` orders the result). Returns the
    number of planes kept.
    """
    n = _corner(data, f, 3)
    slot = -1
    for k in range(taken):
        if v3.dot(n, _corner(data, plane_face[i, k], 3)) > _PLANE_COS:
            if not _nearer(dist, f, planes[i, k, 4], plane_face[i, k]):
                return taken
            slot = k
            break
    if slot < 0:
        if taken < MAX_PLANES:
            slot = taken
            taken += 1
        else:
            slot = 0
            for k in range(1, MAX_PLANES):
                if _nearer(planes[i, slot, 4], plane_face[i, slot], planes[i, k, 4], plane_face[i, k]):
                    slot = k
            if not _nearer(dist, f, planes[i, slot, 4], plane_face[i, slot]):
                return taken
    planes[i, slot, 0], planes[i, slot, 1], planes[i, slot, 2] = u
    planes[i, slot, 3] = offset
    planes[i, slot, 4] = dist
    planes[i, slot, 5] = 1.0 if edge else 0.0
    plane_face[i, slot] = f
    return taken


@njit(cache=True)
def _sort_planes(planes, plane_face, i, taken):
    """Order the first ``taken`` boundary planes of particle ``i`` by face (the order the faces were met in
    depends on the search box; the push-out and the solid's density sum the planes in order)."""
    for k in range(1, taken):
        m = k
        while m > 0 and plane_face[i, m - 1] > plane_face[i, m]:
            plane_face[i, m - 1], plane_face[i, m] = plane_face[i, m], plane_face[i, m - 1]
            for c in range(planes.shape[2]):
                planes[i, m - 1, c], planes[i, m, c] = planes[i, m, c], planes[i, m - 1, c]
            m -= 1


@njit(cache=True, inline="always")
def _covered(planes, plane_face, i, taken, data, f, n, s):
    """Whether a plane kept for particle ``i`` on the same wall as face ``f`` (normal ``n``) beats distance ``s``.

    ``s``, the distance to a face's plane, bounds the distance to the face
    from below, so such a face cannot replace the kept plane.
    """
    for k in range(taken):
        if ((planes[i, k, 4] < s or (planes[i, k, 4] == s and plane_face[i, k] < f))
                and v3.dot(n, _corner(data, plane_face[i, k], 3)) > _PLANE_COS):
            return True
    return False


@njit(cache=True)
def _listed(lo_box, hi_box, grid):
    """Whether any face is listed in the mesh-grid cells of the box [lo_box, hi_box]."""
    lo, size, dims, start, keys = grid[1], grid[2], grid[3], grid[4], grid[5]
    i0, j0, k0, i1, j1, k1 = _cell_box(lo_box, hi_box, lo, size, dims)
    mask = start.shape[0] - 2
    for k in range(k0, k1 + 1 if i0 <= i1 else k0):
        for j in range(j0, j1 + 1):
            key0, key1, a0, a1, w0, w1 = _row(i0, i1, dims[0] * (j + dims[1] * k), mask, start)
            for part in range(2):
                lo_q, hi_q = (a0, a1) if part == 0 else (w0, w1)
                for q in range(lo_q, hi_q):
                    if key0 <= keys[q] <= key1:
                        return True
    return False


@njit(cache=True)
def _search(p, r, slack, grid, planes, plane_face, i):
    """Boundary planes of particle ``i`` at ``p``: faces it is over within PLANE_REACH r, edges and corners
    within r, and the face it is less than r behind (when no face it is over is nearer).

    Returns the number of planes kept and the gap: a lower bound of the
    distance from ``p`` to every face listed within PLANE_REACH r + ``slack``
    of ``p`` along any axis (inf when there is none; faces farther along an
    axis are not listed). A motion that stays within ``slack`` along every
    axis and nearer than the gap to ``p`` cannot meet a face.
    """
    data, lo, size, dims, start, keys, items, firsts, spheres = grid
    reach = PLANE_REACH * r
    # only faces in the cells within reach can give planes or bound the gap below reach; the rest of the box
    # within reach + slack matters only when those cells are empty (gap reach, or inf when it is empty too)
    i0, j0, k0, i1, j1, k1 = _cell_box(v3.sub(p, (reach, reach, reach)), v3.add(p, (reach, reach, reach)), lo, size,
                                       dims)
    mask = start.shape[0] - 2
    gap = np.inf
    taken = 0
    nearest = r  # the face it is over with the smallest |distance| below r, for the behind rule
    over_face = -1
    over_s = 0.0
    for k in range(k0, k1 + 1 if i0 <= i1 else k0):
        for j in range(j0, j1 + 1):
            base = dims[0] * (j + dims[1] * k)
            key0, key1, a0, a1, w0, w1 = _row(i0, i1, base, mask, start)
            for part in range(2):
                lo_q, hi_q = (a0, a1) if part == 0 else (w0, w1)
                for q in range(lo_q, hi_q):
                    if keys[q] < key0 or keys[q] > key1:
                        continue
                    # a face it is over within reach, or an edge within r, lies within reach of p
                    dx, dy, dz = p[0] - spheres[q, 0], p[1] - spheres[q, 1], p[2] - spheres[q, 2]
                    if dx * dx + dy * dy + dz * dz > (reach + spheres[q, 3]) ** 2:
                        gap = min(gap, reach)  # outside the sphere grown by reach
                        continue
                    if not _first_visit(firsts[q], keys[q], base, i0, j, k, j0, k0):
                        continue
                    f = items[q]
                    n = _corner(data, f, 3)
                    a = _corner(data, f, 0)
                    s = v3.dot(n, v3.sub(p, a))
                    gap = min(gap, abs(s))  # the distance to a face's plane bounds the distance to the face
                    if (s <= -r or s >= reach or (n[0] == 0.0 and n[1] == 0.0 and n[2] == 0.0)
                            or (s >= 0.0 and _covered(planes, plane_face, i, taken, data, f, n, s))):
                        continue
                    b, c = _corner(data, f, 1), _corner(data, f, 2)
                    if _over(p, a, b, c, n):
                        if _nearer(abs(s), f, nearest, over_face if over_face >= 0 else data.shape[0]):
                            nearest = abs(s)
                            over_face = f
                            over_s = s
                        if s >= 0.0:
                            taken = _keep_plane(planes, plane_face, i, taken, data, f, n, v3.dot(n, a), s, False)
                    elif 0.0 <= s < r:
                        e = _closest_on_boundary(p, a, b, c)
                        d = v3.sub(p, e)
                        dist = v3.norm(d)
                        if 0.0 < dist < r:
                            u = v3.scale(d, 1.0 / dist)
                            taken = _keep_plane(planes, plane_face, i, taken, data, f, u, v3.dot(u, e), dist, True)
    box = reach + slack
    if gap == np.inf and _listed(v3.sub(p, (box, box, box)), v3.add(p, (box, box, box)), grid):
        gap = reach
    if over_face >= 0 and over_s < 0.0:  # behind the nearest face it is over: to its front
        n = _corner(data, over_face, 3)
        taken = _keep_plane(planes, plane_face, i, taken, data, over_face, n, v3.dot(n, _corner(data, over_face, 0)),
                            0.0, False)
    _sort_planes(planes, plane_face, i, taken)
    return taken, gap * (1.0 - _GAP_ROUNDING) - _GAP_ROUNDING * r


@njit(cache=True)
def _plane_push(p, r, planes, taken, plane_face, i):
    """Move ``p`` to ``r`` in front of the first ``taken`` boundary planes of particle ``i``.

    Returns the new position, the face of the last plane that moved it (-1: none) and that plane's direction.
    """
    contact = -1
    push = (0.0, 0.0, 0.0)
    for k in range(taken):
        u = (planes[i, k, 0], planes[i, k, 1], planes[i, k, 2])
        delta = v3.dot(u, p) - planes[i, k, 3]
        if delta < r:
            p = v3.add(p, v3.scale(u, r - delta))
            contact = plane_face[i, k]
            push = u
    return p, contact, push


@njit(cache=True)
def _drift_buckets(grid, face_move, box):
    """Largest move of a face within ``box`` (along every axis) of the cells of each bucket of the mesh grid: (T,).

    A point's bucket holds at least the largest move of any face that is now
    within ``box`` of it (more, where cells share a bucket). Whichever costs
    less: every moved face writes its move into the cells its bounding box
    grown by ``box`` meets, or it writes into the cells of its own box in a
    dense grid, which is then dilated by ``box`` rounded up to whole cells.
    """
    data, lo, size, dims, start = grid[0], grid[1], grid[2], grid[3], grid[4]
    mask = start.shape[0] - 2
    out = np.zeros(mask + 1)
    reach = math.ceil(box / size)
    moved = 0
    for f in range(data.shape[0]):
        moved += face_move[f] > 0.0
    n_cells = dims[0] * dims[1] * dims[2]
    dense = n_cells * (6 * reach + 4) < moved * (2 * reach + 2) ** 3
    cells = np.zeros((dims[2], dims[1], dims[0]) if dense else (0, 0, 0))
    grow = 0.0 if dense else box
    for f in range(data.shape[0]):
        move = face_move[f]
        if move <= 0.0:
            continue
        a, b, c = _corner(data, f, 0), _corner(data, f, 1), _corner(data, f, 2)
        low = (min(a[0], b[0], c[0]) - grow, min(a[1], b[1], c[1]) - grow, min(a[2], b[2], c[2]) - grow)
        high = (max(a[0], b[0], c[0]) + grow, max(a[1], b[1], c[1]) + grow, max(a[2], b[2], c[2]) + grow)
        i0, j0, k0, i1, j1, k1 = _cell_box(low, high, lo, size, dims)
        for k in range(k0, k1 + 1 if i0 <= i1 else k0):
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    if dense:
                        cells[k, j, i] = max(cells[k, j, i], move)
                    else:
                        q = (i + dims[0] * (j + dims[1] * k)) & mask
                        out[q] = max(out[q], move)
    if dense:
        for axis in range(3):  # running maximum over 2 reach + 1 cells, one axis after the other
            source = cells.copy()
            for k in range(dims[2]):
                for j in range(dims[1]):
                    for i in range(dims[0]):
                        at = (k, j, i)[2 - axis]
                        top = dims[axis] - 1
                        best = 0.0
                        for m in range(max(at - reach, 0), min(at + reach, top) + 1):
                            best = max(best, source[(m if axis == 2 else k), (m if axis == 1 else j),
                                                    (m if axis == 0 else i)])
                        cells[k, j, i] = best
        for k in range(dims[2]):
            for j in range(dims[1]):
                for i in range(dims[0]):
                    q = (i + dims[0] * (j + dims[1] * k)) & mask
                    out[q] = max(out[q], cells[k, j, i])
    return out


@njit(cache=True, parallel=True)
def _refresh(grid, drift, most_slack, anchor, slack, gap, planes, n_planes, plane_face):
    """Carry the searches over a mesh move, in place; ``drift`` is :func:`_drift_buckets` for a box of
    PLANE_REACH r + ``most_slack``.

    Around a search point whose bucket holds a move ``d`` > 0, the slack
    shrinks by ``d`` (the faces may have come that much nearer; a negative
    slack forces a new search), the gap by sqrt(3) ``d`` (the same, as a
    distance), and every boundary plane is recomputed from its face's new
    position: the face's plane, or for an edge or corner the direction from
    its closest point to the anchor. A search with more slack than
    ``most_slack`` is dropped (the drift does not cover it).
    """
    data, lo, size, dims, start = grid[0], grid[1], grid[2], grid[3], grid[4]
    mask = start.shape[0] - 2
    for i in prange(anchor.shape[0]):
        if slack[i] > most_slack:
            slack[i] = -1.0
        if slack[i] < 0.0:
            continue
        key = 0
        for m in range(2, -1, -1):  # the anchor's cell, clamped into the grid like the faces' cell ranges
            c = min(max(int(np.floor(min(max((anchor[i, m] - lo[m]) / size, -_LIMIT), _LIMIT))), 0), dims[m] - 1)
            key = key * dims[m] + c
        d = drift[key & mask]
        if d <= 0.0:
            continue  # no face within box moved, nor any of its planes' faces
        slack[i] -= d
        gap[i] -= math.sqrt(3.0) * d
        for k in range(n_planes[i]):
            f = plane_face[i, k]
            a = _corner(data, f, 0)
            u = _corner(data, f, 3)
            offset = v3.dot(u, a)
            if planes[i, k, 5] > 0.0:
                e = _closest_on_boundary(v3.row(anchor, i), a, _corner(data, f, 1), _corner(data, f, 2))
                dv = v3.sub(v3.row(anchor, i), e)
                dist = v3.norm(dv)
                if dist > 0.0:
                    u = v3.scale(dv, 1.0 / dist)
                    offset = v3.dot(u, e)
            planes[i, k, 0], planes[i, k, 1], planes[i, k, 2] = u
            planes[i, k, 3] = offset


@njit(cache=True, parallel=True)
def _carry(rows, anchor, slack, gap, planes, n_planes, plane_face, to_anchor, to_slack, to_gap, to_planes,
           to_n_planes, to_plane_face):
    """Row ``s`` of the ``to_`` arrays = row ``rows[s]`` of the others (-1: never searched)."""
    for s in prange(rows.shape[0]):
        q = rows[s]
        if q < 0:
            to_anchor[s, 0] = np.nan
            to_n_planes[s] = 0
            continue
        for a in range(3):
            to_anchor[s, a] = anchor[q, a]
        to_slack[s] = slack[q]
        to_gap[s] = gap[q]
        to_n_planes[s] = n_planes[q]
        for k in range(n_planes[q]):
            to_plane_face[s, k] = plane_face[q, k]
            for c in range(planes.shape[2]):
                to_planes[s, k, c] = planes[q, k, c]


@njit(cache=True)
def _first_crossing(x0, x1, grid):
    """Earliest front-to-back crossing of the segment x0 -> x1 with a face: (parameter t, face or -1)."""
    data, lo, size, dims, start, keys, items, firsts, spheres = grid
    mask = start.shape[0] - 2
    seg = v3.sub(x1, x0)
    seg2 = v3.dot(seg, seg)
    pieces = max(1, int(np.ceil(v3.norm(seg) / size)))
    margin = 1e-9 * size
    best_t = 2.0
    best_f = -1
    for piece in range(pieces):
        u = v3.add(x0, v3.scale(seg, piece / pieces))
        w = v3.add(x0, v3.scale(seg, (piece + 1) / pieces))
        i0, j0, k0, i1, j1, k1 = _cell_box(
            (min(u[0], w[0]) - margin, min(u[1], w[1]) - margin, min(u[2], w[2]) - margin),
            (max(u[0], w[0]) + margin, max(u[1], w[1]) + margin, max(u[2], w[2]) + margin), lo, size, dims)
        for k in range(k0, k1 + 1 if i0 <= i1 else k0):
            for j in range(j0, j1 + 1):
                base = dims[0] * (j + dims[1] * k)
                key0, key1, a0, a1, b0, b1 = _row(i0, i1, base, mask, start)
                for part in range(2):
                    lo_q, hi_q = (a0, a1) if part == 0 else (b0, b1)
                    for q in range(lo_q, hi_q):
                        if keys[q] < key0 or keys[q] > key1:
                            continue
                        centre = (spheres[q, 0], spheres[q, 1], spheres[q, 2])
                        e = v3.sub(centre, x0)
                        t = min(max(v3.dot(e, seg) / seg2, 0.0), 1.0) if seg2 > 0.0 else 0.0
                        e = v3.sub(e, v3.scale(seg, t))  # from the segment's closest point to the centre
                        if (v3.dot(e, e) > spheres[q, 3] ** 2
                                or not _first_visit(firsts[q], keys[q], base, i0, j, k, j0, k0)):
                            continue
                        f = items[q]
                        n = _corner(data, f, 3)
                        a = _corner(data, f, 0)
                        s0 = v3.dot(n, v3.sub(x0, a))
                        s1 = v3.dot(n, v3.sub(x1, a))
                        if not (s0 >= 0.0 and s1 < 0.0):
                            continue
                        t = s0 / (s0 - s1)
                        if not _nearer(t, f, best_t, best_f if best_f >= 0 else data.shape[0]):
                            continue
                        b, c = _corner(data, f, 1), _corner(data, f, 2)
                        y = v3.add(x0, v3.scale(seg, t))
                        tol = -CROSSING_GROWTH * v3.norm(v3.cross(v3.sub(b, a), v3.sub(c, a)))
                        if (v3.dot(v3.cross(v3.sub(b, a), v3.sub(y, a)), n) >= tol
                                and v3.dot(v3.cross(v3.sub(c, b), v3.sub(y, b)), n) >= tol
                                and v3.dot(v3.cross(v3.sub(a, c), v3.sub(y, c)), n) >= tol):
                            best_t = t
                            best_f = f
        if best_t <= (piece + 1) / pieces:
            break
    return best_t, best_f


@njit(cache=True)
def _sweep(x0, p, r, grid):
    """Keep the motion x0 -> p on the front side of every face it would cross.

    Returns the new end point, the face it hit (-1: none) and that face's normal.
    """
    data = grid[0]
    contact = -1
    push = (0.0, 0.0, 0.0)
    for _ in range(_SWEEP_ROUNDS):
        t, f = _first_crossing(x0, p, grid)
        if f < 0:
            return p, contact, push
        n = _corner(data, f, 3)
        p = v3.add(p, v3.scale(n, r - v3.dot(n, v3.sub(p, _corner(data, f, 0)))))
        contact = f
        push = n
    t, f = _first_crossing(x0, p, grid)
    if f >= 0:  # still crossing: stop just before the first crossing
        p = v3.add(x0, v3.scale(v3.sub(p, x0), t * (1.0 - _STOP)))
        contact = f
        push = _corner(data, f, 3)
    return p, contact, push


@njit(cache=True, inline="always")
def _clamp(p, r, wlo, whi):
    """``p`` clamped into the box [wlo + r, whi - r]."""
    return (min(max(p[0], wlo[0] + r), whi[0] - r), min(max(p[1], wlo[1] + r), whi[1] - r),
            min(max(p[2], wlo[2] + r), whi[2] - r))


@njit(cache=True, inline="always")
def _near(p, anchor, slack):
    """Whether ``p`` is within ``slack`` of ``anchor`` along every axis (False for a NaN anchor)."""
    return abs(p[0] - anchor[0]) <= slack and abs(p[1] - anchor[1]) <= slack and abs(p[2] - anchor[2]) <= slack


@njit(cache=True, parallel=True)
def _collide(pos, start, r, grid, friction, boundary, walls, wlo, whi, contact, normal, anchor, slack, gap,
             planes, n_planes, plane_face, spread):
    """Mesh collision and walls for every particle, in place.

    In order: ``friction`` (at the particles that touched the mesh this
    substep); when ``boundary``, the boundary planes (searched afresh at
    ``pos`` by :func:`_search` unless ``start`` and ``pos`` lie within
    ``slack`` of the last search's ``anchor``; then ``slack`` becomes
    ``max(_REUSE r, 1.5 |pos - start|)``, enough for the next substep too)
    and the push-out of ``start`` itself, moving ``pos`` along (a mesh that
    moved over a particle gives it no velocity); the swept test from
    ``start`` (skipped when both ends lie within the slack of the last
    search and nearer to its anchor than its ``gap``); when ``boundary``, the push-out of ``pos``; the clamp
    into the walls. ``contact`` and ``normal`` receive the face and
    direction of the latest contact. Particles are visited in the order
    ``spread`` (:func:`_spread`), so the threads share the particles near
    the mesh.
    """
    has_mesh = grid[0].shape[0] > 0
    for t in prange(pos.shape[0]):
        i = spread[t]
        p = v3.row(pos, i)
        x0 = v3.row(start, i)
        a = v3.row(anchor, i)
        if friction > 0.0 and contact[i] >= 0:
            n = v3.row(normal, i)
            move = v3.sub(p, x0)
            p = v3.sub(p, v3.scale(v3.sub(move, v3.scale(n, v3.dot(n, move))), friction))
        if has_mesh and boundary:
            if not (_near(x0, a, slack[i]) and _near(p, a, slack[i])):
                move = v3.sub(p, x0)
                slack[i] = max(_REUSE * r, 1.5 * max(abs(move[0]), abs(move[1]), abs(move[2])))
                a = p
                v3.store(anchor, i, a)
                n_planes[i], gap[i] = _search(p, r, slack[i], grid, planes, plane_face, i)
            y, f, n = _plane_push(x0, r, planes, n_planes[i], plane_face, i)
            if f >= 0:
                p = v3.add(p, v3.sub(y, x0))
                x0 = y
                v3.store(start, i, y)
                contact[i] = f
                v3.store(normal, i, n)
        if has_mesh and not (_near(x0, a, slack[i]) and _near(p, a, slack[i]) and v3.norm(v3.sub(x0, a)) < gap[i]
                             and v3.norm(v3.sub(p, a)) < gap[i]):
            p, f, n = _sweep(x0, p, r, grid)
            if f >= 0:
                contact[i] = f
                v3.store(normal, i, n)
        if has_mesh and boundary:
            p, f, n = _plane_push(p, r, planes, n_planes[i], plane_face, i)
            if f >= 0:
                contact[i] = f
                v3.store(normal, i, n)
        if walls:
            p = _clamp(p, r, wlo, whi)
        v3.store(pos, i, p)


@njit(cache=True, parallel=True)
def _plane_distances(pos, contact, data, out):
    """Signed distance of every particle to the plane of its contact face (inf without one)."""
    for i in prange(pos.shape[0]):
        f = contact[i]
        out[i] = np.inf if f < 0 else v3.dot(_corner(data, f, 3), v3.sub(v3.row(pos, i), _corner(data, f, 0)))
