"""Polygons of shard links and closed surfaces of shard unions (geometry output of the freeze–thaw model).

:func:`~pverosion.kernels.shards.graph.build_shards` keeps only the area, centroid
and normal of every link. This module rebuilds the link faces themselves as
triangles, cell by cell, from the same construction:

- an exterior link (a surface patch of a cell) is made of the pieces of its
  mesh triangles inside the cell: each triangle clipped to the cell's
  planes, a convex polygon, fanned;
- an interior link is the Voronoi face between two cells, or, when the mesh
  cuts it, the part of it inside the mesh: its boundary is the face's edges
  where they run inside the mesh and the sections of the mesh triangles
  with the face plane, the segments ``shards._cell`` integrates. They are
  chained into closed loops (end points that agree up to rounding are
  merged), the loops are sorted into outer boundaries and holes in the face
  plane, every hole is bridged to its outer boundary and the result is ear
  clipped. Each interior link is built once, by the lower-numbered cell.

Points that agree up to ``tolerance`` times the size of the bounding box are
then merged across all links, so the faces around any union of cells make a
watertight surface: :func:`cells_boundary` gives the eroded surface (the
boundary of the solid cells), :func:`cell_surfaces` the closed surface of each
shard.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from pverosion.kernels._jit import njit
from pverosion.kernels.mesh.topology import find_root, join_sets
from pverosion.kernels.shards.graph import (
    ShardGraph,
    _bounding_planes,
    _clip_polygon,
    _face_section,
    _may_meet,
    _plane,
)
from pverosion.kernels.shards.voronoi import cell_polygons, seed_grid
from pverosion.kernels.spatial.mesh_query import TriangleIndex, box_triangles, point_inside, segment_crossings

__all__ = ["LinkMesh", "cell_surfaces", "cells_boundary", "link_polygons"]

_BATCH = 256  # cells per kernel call; fixed, so the output does not depend on the thread count
_CAP_POINTS = 1024
_CAP_TRIANGLES = 2048
_MERGE_DIRECTION = np.array([0.4636, 0.5792, 0.6705]) / np.linalg.norm([0.4636, 0.5792, 0.6705])


@dataclass
class LinkMesh:
    """The faces of all links of a :class:`~pverosion.kernels.shards.graph.ShardGraph`, as one triangle soup.

    Attributes
    ----------
    points : (p, 3) float64
        Vertices; points of neighbouring link faces that coincide up to the
        merge tolerance are one point.
    triangles : (t, 3) int64
        Triangles, wound so that their normals agree with the ``link_normal``
        of their link; sorted by link.
    triangle_link : (t,) int64
        Link of every triangle.
    link_start : (n_links + 1,) int64
        Triangles of link ``k`` are ``triangles[link_start[k]:link_start[k + 1]]``.
    issues : int
        Faces whose boundary loops did not close, holes that no outer loop
        contains and ears cut without a clean candidate; 0 for regular input.
    """

    points: np.ndarray
    triangles: np.ndarray
    triangle_link: np.ndarray
    link_start: np.ndarray
    issues: int = 0

    @property
    def n_links(self) -> int:
        return len(self.link_start) - 1


# --- 2-D polygon helpers ----------------------------------------------------------------------------------


@njit(cache=True)
def _orient(X, Y, p, q, r):
    """Twice the signed area of triangle (p, q, r): positive when it turns left."""
    return (X[q] - X[p]) * (Y[r] - Y[p]) - (Y[q] - Y[p]) * (X[r] - X[p])


@njit(cache=True)
def _orient_xy(X, Y, p, q, rx, ry):
    return (X[q] - X[p]) * (ry - Y[p]) - (Y[q] - Y[p]) * (rx - X[p])


@njit(cache=True)
def _in_ring(ring, size, X, Y, px, py):
    """Crossing-number test of point (px, py) against the closed ring ``ring[:size]``."""
    inside = False
    for i in range(size):
        a = ring[i]
        b = ring[(i + 1) % size]
        if (Y[a] > py) != (Y[b] > py):
            x = X[a] + (py - Y[a]) * (X[b] - X[a]) / (Y[b] - Y[a])
            if px < x:
                inside = not inside
    return inside


@njit(cache=True)
def _locally_inside(ring, size, i, X, Y, tx, ty):
    """Does the direction from vertex ``ring[i]`` towards (tx, ty) start inside the region (on the ring's left)?"""
    a = ring[(i - 1) % size]
    v = ring[i]
    b = ring[(i + 1) % size]
    into_b = _orient_xy(X, Y, v, b, tx, ty)  # target left of v->b
    into_a = -_orient_xy(X, Y, v, a, tx, ty)  # target right of v->a
    if _orient(X, Y, a, v, b) >= 0.0:
        return into_b >= 0.0 and into_a >= 0.0
    return into_b > 0.0 or into_a > 0.0


@njit(cache=True)
def _crosses_ring(ring, size, X, Y, m, h):
    """Does segment m-h (vertex ids) properly cross an edge of the ring that touches neither end?"""
    for i in range(size):
        a = ring[i]
        b = ring[(i + 1) % size]
        if a == m or a == h or b == m or b == h:
            continue
        o1 = _orient(X, Y, m, h, a)
        o2 = _orient(X, Y, m, h, b)
        if (o1 > 0.0 and o2 > 0.0) or (o1 < 0.0 and o2 < 0.0) or (o1 == 0.0 and o2 == 0.0):
            continue
        o3 = _orient(X, Y, a, b, m)
        o4 = _orient(X, Y, a, b, h)
        if (o3 > 0.0 and o4 < 0.0) or (o3 < 0.0 and o4 > 0.0):
            return True
    return False


@njit(cache=True)
def _order(keys, n):
    """Indices that sort ``keys[:n]`` ascending (insertion sort: the arrays here are short)."""
    order = np.empty(n, np.int64)
    for i in range(n):
        k = i
        while k > 0 and keys[order[k - 1]] > keys[i]:
            order[k] = order[k - 1]
            k -= 1
        order[k] = i
    return order


@njit(cache=True)
def _bridge(poly, plen, hole, hlen, X, Y, loop_v, loop_off, others, nothers):
    """Positions (in ``poly``, in ``hole``) of a diagonal joining the hole to the polygon; (mi, hi, clean)."""
    hx = np.empty(hlen)
    for j in range(hlen):
        hx[j] = -X[hole[j]]
    horder = _order(hx, hlen)  # rightmost hole vertex first
    dist = np.empty(plen)
    for hh in horder:
        h = hole[hh]
        for i in range(plen):
            dist[i] = (X[poly[i]] - X[h]) ** 2 + (Y[poly[i]] - Y[h]) ** 2
        for mi in _order(dist, plen):
            m = poly[mi]
            if m == h:
                return mi, hh, True
            if not _locally_inside(poly, plen, mi, X, Y, X[h], Y[h]):
                continue
            if not _locally_inside(hole, hlen, hh, X, Y, X[m], Y[m]):
                continue
            if _crosses_ring(poly, plen, X, Y, m, h) or _crosses_ring(hole, hlen, X, Y, m, h):
                continue
            bad = False
            for q in range(nothers):
                o = others[q]
                if _crosses_ring(loop_v[loop_off[o]:loop_off[o + 1]], loop_off[o + 1] - loop_off[o], X, Y, m, h):
                    bad = True
                    break
            if not bad:
                return mi, hh, True
    hh = horder[0]
    h = hole[hh]
    mi = 0
    for i in range(plen):
        dist[i] = (X[poly[i]] - X[h]) ** 2 + (Y[poly[i]] - Y[h]) ** 2
        if dist[i] < dist[mi]:
            mi = i
    return mi, hh, False


@njit(cache=True)
def _is_ear(poly, prv, nxt, b, X, Y):
    a = prv[b]
    c = nxt[b]
    A, B, C = poly[a], poly[b], poly[c]
    if not _orient(X, Y, A, B, C) > 0.0:
        return False
    p = nxt[c]
    while p != a:
        P = poly[p]
        # only reflex vertices can lie in an ear of a (weakly) simple polygon
        if (P != A and P != B and P != C and _orient(X, Y, poly[prv[p]], P, poly[nxt[p]]) <= 0.0
                and _orient(X, Y, A, B, P) >= 0.0 and _orient(X, Y, B, C, P) >= 0.0
                and _orient(X, Y, C, A, P) >= 0.0):
            return False
        p = nxt[p]
    return True


@njit(cache=True)
def _ear_clip(poly, size, X, Y, tri, nt):
    """Ear clipping of the weakly simple counter-clockwise polygon ``poly[:size]``; (triangle count, issues)."""
    if size < 3:
        return nt, 0
    prv = np.empty(size, np.int64)
    nxt = np.empty(size, np.int64)
    for i in range(size):
        prv[i] = (i - 1) % size
        nxt[i] = (i + 1) % size
    issues = 0
    remaining = size
    cur = 0
    stall = 0
    while remaining > 3:
        if _is_ear(poly, prv, nxt, cur, X, Y):
            ear = cur
        else:
            cur = nxt[cur]
            stall += 1
            if stall <= remaining:
                continue
            # no clean ear left (rounding, touching loops): cut the most convex corner
            issues += 1
            ear = cur
            best = -np.inf
            p = cur
            for _ in range(remaining):
                w = _orient(X, Y, poly[prv[p]], poly[p], poly[nxt[p]])
                if w > best:
                    best = w
                    ear = p
                p = nxt[p]
        a, c = prv[ear], nxt[ear]
        tri[nt, 0], tri[nt, 1], tri[nt, 2] = poly[a], poly[ear], poly[c]
        nt += 1
        nxt[a] = c
        prv[c] = a
        remaining -= 1
        cur = c
        stall = 0
    tri[nt, 0], tri[nt, 1], tri[nt, 2] = poly[prv[cur]], poly[cur], poly[nxt[cur]]
    return nt + 1, issues


@njit(cache=True)
def _region_triangles(seg, nseg, n, tol):
    """Triangulate the planar region bounded by directed segments (inside on their left about normal ``n``).

    Parameters
    ----------
    seg : (>= nseg, 6) float64
        Segment start (columns 0-2) and end (3-5) points.
    nseg : int
    n : (3,) float64
        Unit normal of the plane.
    tol : float
        End points closer than this are one vertex.

    Returns
    -------
    vertices : (v, 3) float64
    triangles : (t, 3) int64
        Counter-clockwise about ``n``.
    issues : int
    """
    m = 2 * nseg
    rep = np.empty((max(m, 1), 3))
    vid = np.empty(max(m, 1), np.int64)
    nv = 0
    tol2 = tol * tol
    for p in range(m):
        k = p // 2
        base = 3 * (p % 2)
        x, y, z = seg[k, base], seg[k, base + 1], seg[k, base + 2]
        found = -1
        for v in range(nv):
            if (rep[v, 0] - x) ** 2 + (rep[v, 1] - y) ** 2 + (rep[v, 2] - z) ** 2 <= tol2:
                found = v
                break
        if found < 0:
            rep[nv, 0], rep[nv, 1], rep[nv, 2] = x, y, z
            found = nv
            nv += 1
        vid[p] = found
    # a basis of the plane with e1 x e2 = n
    ax = 0
    if abs(n[1]) < abs(n[ax]):
        ax = 1
    if abs(n[2]) < abs(n[ax]):
        ax = 2
    # e1 = n x (unit vector along ax), e2 = n x e1
    r0, r1, r2 = (1.0 if ax == 0 else 0.0), (1.0 if ax == 1 else 0.0), (1.0 if ax == 2 else 0.0)
    e1 = (n[1] * r2 - n[2] * r1, n[2] * r0 - n[0] * r2, n[0] * r1 - n[1] * r0)
    length = math.sqrt(e1[0] ** 2 + e1[1] ** 2 + e1[2] ** 2)
    e1 = (e1[0] / length, e1[1] / length, e1[2] / length)
    e2 = (n[1] * e1[2] - n[2] * e1[1], n[2] * e1[0] - n[0] * e1[2], n[0] * e1[1] - n[1] * e1[0])
    X = np.empty(nv)
    Y = np.empty(nv)
    for v in range(nv):
        dx, dy, dz = rep[v, 0] - rep[0, 0], rep[v, 1] - rep[0, 1], rep[v, 2] - rep[0, 2]
        X[v] = dx * e1[0] + dy * e1[1] + dz * e1[2]
        Y[v] = dx * e2[0] + dy * e2[1] + dz * e2[2]
    # directed edges between vertices, grouped by start vertex
    src = np.empty(nseg, np.int64)
    dst = np.empty(nseg, np.int64)
    ne = 0
    for k in range(nseg):
        if vid[2 * k] != vid[2 * k + 1]:
            src[ne] = vid[2 * k]
            dst[ne] = vid[2 * k + 1]
            ne += 1
    ostart = np.zeros(nv + 1, np.int64)
    for e in range(ne):
        ostart[src[e] + 1] += 1
    for v in range(nv):
        ostart[v + 1] += ostart[v]
    fill = np.empty(nv, np.int64)
    for v in range(nv):
        fill[v] = ostart[v]
    oedge = np.empty(ne, np.int64)
    for e in range(ne):
        oedge[fill[src[e]]] = e
        fill[src[e]] += 1
    # closed loops; at a vertex with several ways on, take the first clockwise from the way back
    used = np.zeros(ne, np.bool_)
    loop_v = np.empty(ne, np.int64)
    loop_off = np.zeros(ne + 1, np.int64)
    nloops = 0
    nl = 0
    issues = 0
    for e0 in range(ne):
        if used[e0]:
            continue
        start = src[e0]
        e = e0
        while True:
            used[e] = True
            loop_v[nl] = src[e]
            nl += 1
            v = dst[e]
            if v == start:
                break
            rx, ry = X[src[e]] - X[v], Y[src[e]] - Y[v]
            best = -1
            best_angle = np.inf
            for q in range(ostart[v], ostart[v + 1]):
                g = oedge[q]
                if used[g]:
                    continue
                dx, dy = X[dst[g]] - X[v], Y[dst[g]] - Y[v]
                angle = math.atan2(dx * ry - dy * rx, dx * rx + dy * ry)
                if angle < 0.0:
                    angle += 2.0 * math.pi
                if angle < best_angle:
                    best_angle = angle
                    best = g
            if best < 0:
                issues += 1
                break
            e = best
        nloops += 1
        loop_off[nloops] = nl
    area = np.zeros(nloops)
    for q in range(nloops):
        a0, a1 = loop_off[q], loop_off[q + 1]
        for i in range(a0, a1):
            p, r = loop_v[i], loop_v[a0 + (i + 1 - a0) % (a1 - a0)]
            area[q] += X[p] * Y[r] - X[r] * Y[p]
        if a1 - a0 < 3:
            area[q] = 0.0
    # every hole belongs to the smallest outer loop around it
    owner = np.full(nloops, -1, np.int64)
    for h in range(nloops):
        if not area[h] < 0.0:
            continue
        a0 = loop_off[h]
        px = 0.5 * (X[loop_v[a0]] + X[loop_v[a0 + 1]])
        py = 0.5 * (Y[loop_v[a0]] + Y[loop_v[a0 + 1]])
        best_area = np.inf
        for o in range(nloops):
            if (area[o] > 0.0 and area[o] < best_area
                    and _in_ring(loop_v[loop_off[o]:loop_off[o + 1]], loop_off[o + 1] - loop_off[o], X, Y, px, py)):
                owner[h] = o
                best_area = area[o]
        if owner[h] < 0:
            issues += 1
    tri = np.empty((ne + 2 * nloops, 3), np.int64)
    nt = 0
    poly = np.empty(ne + 2 * nloops, np.int64)
    work = np.empty(ne + 2 * nloops, np.int64)
    others = np.empty(nloops, np.int64)
    for o in range(nloops):
        if not area[o] > 0.0:
            continue
        plen = loop_off[o + 1] - loop_off[o]
        for i in range(plen):
            poly[i] = loop_v[loop_off[o] + i]
        nothers = 0
        for h in range(nloops):
            if owner[h] == o:
                others[nothers] = h
                nothers += 1
        # holes with the rightmost vertex first
        key = np.empty(nothers)
        for q in range(nothers):
            h = others[q]
            key[q] = np.inf
            for i in range(loop_off[h], loop_off[h + 1]):
                key[q] = min(key[q], -X[loop_v[i]])
        sorted_holes = _order(key, nothers)
        for q in range(nothers):
            key[q] = others[sorted_holes[q]]
        for q in range(nothers):
            others[q] = int(key[q])
        for q in range(nothers):
            h = others[q]
            hole = loop_v[loop_off[h]:loop_off[h + 1]]
            hlen = hole.size
            mi, hi, clean = _bridge(poly, plen, hole, hlen, X, Y, loop_v, loop_off, others[q + 1:], nothers - q - 1)
            if not clean:
                issues += 1
            # poly[:mi+1], hole[hi:], hole[:hi+1], poly[mi:]  (one copy of the ends when they are one vertex)
            k = 0
            for i in range(mi + 1):
                work[k] = poly[i]
                k += 1
            same = poly[mi] == hole[hi]
            for j in range(hlen + (0 if same else 1)):
                work[k] = hole[(hi + j + (1 if same else 0)) % hlen]
                k += 1
            for i in range(mi, plen):
                work[k] = poly[i]
                k += 1
            for i in range(k):
                poly[i] = work[i]
            plen = k
        nt, iss = _ear_clip(poly, plen, X, Y, tri, nt)
        issues += iss
    return rep[:nv], tri[:nt], issues


# --- per cell ---------------------------------------------------------------------------------------------


@njit(cache=True)
def _push(seg, nseg, a, b):
    """Append segment a->b (3-tuples) to ``seg``, growing it when full; returns the array."""
    if nseg >= seg.shape[0]:
        bigger = np.empty((2 * seg.shape[0], 6))
        for k in range(nseg):
            for j in range(6):
                bigger[k, j] = seg[k, j]
        seg = bigger
    for k in range(3):
        seg[nseg, k] = a[k]
        seg[nseg, 3 + k] = b[k]
    return seg


@njit(cache=True)
def _meeting(tris, verts, count, nf, planes, offsets, points, faces, normals, margin):
    """The triangles of ``tris`` that may meet the convex cell.

    Left out: triangles with all vertices outside one cell plane, and those with all cell vertices on one side of
    their plane (both by more than ``margin``; :func:`~pverosion.kernels.shards.graph._may_meet`).
    """
    kept = 0
    out = np.empty(tris.size, np.int64)
    everywhere_lo = np.full(3, -np.inf)
    everywhere_hi = np.full(3, np.inf)
    for q in range(tris.size):
        t = tris[q]
        meets = _may_meet(t, verts, count, nf, planes, offsets, everywhere_lo, everywhere_hi, points, faces, normals,
                          margin)
        if meets:
            out[kept] = t
            kept += 1
    return out[:kept]


@njit(cache=True)
def _cell_links(seed, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tlo,
                tsize, tdims, tstart, titems, tstart2, titems2, w0, w1, want_label, want_link, want_flip, tol,
                margin, out_pts, out_tri, out_link):
    """Triangles of the links ``want_*[w0:w1]`` of the cell of seed ``seed``.

    ``want_label`` is the neighbouring seed of an interior link and ``-1 - t``
    for the piece of mesh triangle ``t``. Returns (points, triangles, issues,
    status): status 0 ok, 1 cell polygon capacity exceeded, 2 output capacity
    (the lengths of ``out_*``) exceeded.
    """
    cap_p = out_pts.shape[0]
    cap_t = out_tri.shape[0]
    verts, _, count, label, nf = cell_polygons(seed, seeds, start, order, dims, size, lo, hi, bound_n, bound_d)
    if nf <= 0:
        return 0, 0, 0, 1
    planes = np.empty((nf, 3))
    offsets = np.empty(nf)
    bmin = np.full(3, np.inf)
    bmax = np.full(3, -np.inf)
    for f in range(nf):
        nrm, d = _plane(seed, label[f], seeds, lo, hi, bound_n, bound_d)
        for a in range(3):
            planes[f, a] = nrm[a]
        offsets[f] = d
        for m in range(count[f]):
            for a in range(3):
                bmin[a] = min(bmin[a], verts[f, m, a])
                bmax[a] = max(bmax[a], verts[f, m, a])
    tris = box_triangles(bmin, bmax, points, faces, tlo, tsize, tdims, tstart, titems)
    tris = _meeting(tris, verts, count, nf, planes, offsets, points, faces, normals, margin)
    cross = np.empty(max(tris.size, 1))
    buf = (np.empty((nf + 3, 3)), np.empty((nf + 3, 3)))
    seg = np.empty((64, 6))
    tri = np.empty((3, 3))
    npts = 0
    ntri = 0
    issues = 0
    for w in range(w0, w1):
        lab = want_label[w]
        link = want_link[w]
        flip = want_flip[w]
        if lab < 0:  # the piece of a mesh triangle: convex, fanned
            t = -1 - lab
            for m in range(3):
                for a in range(3):
                    tri[m, a] = points[faces[t, m], a]
            poly, k = _clip_polygon(tri, planes, offsets, nf, buf)
            if k < 3:
                continue
            if npts + k > cap_p or ntri + k - 2 > cap_t:
                return npts, ntri, issues, 2
            for m in range(k):
                for a in range(3):
                    out_pts[npts + m, a] = poly[m, a]
            for m in range(1, k - 1):
                out_tri[ntri, 0] = npts
                out_tri[ntri, 1] = npts + (m + 1 if flip else m)
                out_tri[ntri, 2] = npts + (m if flip else m + 1)
                out_link[ntri] = link
                ntri += 1
            npts += k
            continue
        f = -1
        for g in range(nf):
            if label[g] == lab:
                f = g
                break
        if f < 0:
            continue
        n = planes[f]
        cnt = count[f]
        whole = True
        nseg = 0
        if tris.size > 0:
            # the face's edges where they run inside the mesh, as in shards._cell
            state = point_inside(verts[f, 0], points, faces, tlo, tsize, tdims, tstart2, titems2)
            ncross_all = 0
            for m in range(cnt):
                u = (verts[f, m, 0], verts[f, m, 1], verts[f, m, 2])
                q1 = (m + 1) % cnt
                wv = (verts[f, q1, 0], verts[f, q1, 1], verts[f, q1, 2])
                ncross = segment_crossings(u, wv, tris, points, faces, normals, cross)
                ncross_all += ncross
                t0 = 0.0
                for q in range(ncross + 1):
                    t1 = cross[q] if q < ncross else 1.0
                    if state and t1 > t0:
                        a = (u[0] + (wv[0] - u[0]) * t0, u[1] + (wv[1] - u[1]) * t0, u[2] + (wv[2] - u[2]) * t0)
                        if t1 == 1.0:
                            b = wv
                        else:
                            b = (u[0] + (wv[0] - u[0]) * t1, u[1] + (wv[1] - u[1]) * t1,
                                 u[2] + (wv[2] - u[2]) * t1)
                        seg = _push(seg, nseg, a, b)
                        nseg += 1
                    if q < ncross:
                        state = not state
                    t0 = t1
            nedge = nseg
            # the sections of the mesh triangles, inside on the left, clipped to the face
            for q in range(tris.size):
                t = tris[q]
                ok, a, b = _face_section(t, f, planes, offsets, nf, points, faces, normals)
                if not ok:
                    continue
                seg = _push(seg, nseg, a, b)
                nseg += 1
            if nseg == 0:
                continue
            whole = ncross_all == 0 and nseg == nedge and nedge == cnt
        if whole:  # the convex Voronoi face
            if npts + cnt > cap_p or ntri + cnt - 2 > cap_t:
                return npts, ntri, issues, 2
            for m in range(cnt):
                for a in range(3):
                    out_pts[npts + m, a] = verts[f, m, a]
            for m in range(1, cnt - 1):
                out_tri[ntri, 0] = npts
                out_tri[ntri, 1] = npts + (m + 1 if flip else m)
                out_tri[ntri, 2] = npts + (m if flip else m + 1)
                out_link[ntri] = link
                ntri += 1
            npts += cnt
            continue
        vx, tr, iss = _region_triangles(seg, nseg, n, tol)
        issues += iss
        if npts + vx.shape[0] > cap_p or ntri + tr.shape[0] > cap_t:
            return npts, ntri, issues, 2
        for m in range(vx.shape[0]):
            for a in range(3):
                out_pts[npts + m, a] = vx[m, a]
        for m in range(tr.shape[0]):
            out_tri[ntri, 0] = npts + tr[m, 0]
            out_tri[ntri, 1] = npts + (tr[m, 2] if flip else tr[m, 1])
            out_tri[ntri, 2] = npts + (tr[m, 1] if flip else tr[m, 2])
            out_link[ntri] = link
            ntri += 1
        npts += vx.shape[0]
    return npts, ntri, issues, 0


@njit(cache=True, nogil=True)
def _links_batch(todo, cell_seed, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals,
                 tlo, tsize, tdims, tstart, titems, tstart2, titems2, want_start, want_label, want_link, want_flip,
                 tol, margin, cap_p, cap_t):
    """Link triangles of the cells ``todo``, in fixed slots of ``cap_p`` points and ``cap_t`` triangles each."""
    nb = todo.size
    pts = np.empty((nb, cap_p, 3))
    tri = np.empty((nb, cap_t, 3), np.int64)
    link = np.empty((nb, cap_t), np.int64)
    npts = np.zeros(nb, np.int64)
    ntri = np.zeros(nb, np.int64)
    issues = np.zeros(nb, np.int64)
    status = np.zeros(nb, np.int64)
    for q in range(nb):
        c = todo[q]
        npts[q], ntri[q], issues[q], status[q] = _cell_links(
            cell_seed[c], seeds, start, order, dims, size, lo, hi, bound_n, bound_d, points, faces, normals, tlo,
            tsize, tdims, tstart, titems, tstart2, titems2, want_start[c], want_start[c + 1], want_label, want_link,
            want_flip, tol, margin, pts[q], tri[q], link[q])
    return pts, tri, link, npts, ntri, issues, status


@njit(cache=True, nogil=True)
def _gather(pts, tri, link, npts, ntri, ok):
    """Concatenate the filled slots of the cells where ``ok``; triangle indices become global."""
    tp = 0
    tt = 0
    for q in range(npts.size):
        if ok[q]:
            tp += npts[q]
            tt += ntri[q]
    out_p = np.empty((tp, 3))
    out_t = np.empty((tt, 3), np.int64)
    out_l = np.empty(tt, np.int64)
    kp = 0
    kt = 0
    for q in range(npts.size):
        if not ok[q]:
            continue
        for m in range(npts[q]):
            for a in range(3):
                out_p[kp + m, a] = pts[q, m, a]
        for m in range(ntri[q]):
            out_t[kt, 0] = tri[q, m, 0] + kp
            out_t[kt, 1] = tri[q, m, 1] + kp
            out_t[kt, 2] = tri[q, m, 2] + kp
            out_l[kt] = link[q, m]
            kt += 1
        kp += npts[q]
    return out_p, out_t, out_l


@njit(cache=True)
def _merge_points(pts, proj, order, tol):
    """Merge points closer than ``tol`` (transitively); returns (new index of every point, merged points).

    Points are swept in ``order`` of their projections ``proj`` on a direction; merged points keep the
    coordinates of the lowest-numbered point of their group.
    """
    n = pts.shape[0]
    parent = np.arange(n)
    tol2 = tol * tol
    for i in range(n):
        p = order[i]
        for j in range(i + 1, n):
            q = order[j]
            if proj[q] - proj[p] > tol:
                break
            if (pts[p, 0] - pts[q, 0]) ** 2 + (pts[p, 1] - pts[q, 1]) ** 2 + (pts[p, 2] - pts[q, 2]) ** 2 <= tol2:
                join_sets(parent, p, q)
    new = np.full(n, -1, np.int64)
    out = np.empty((n, 3))
    k = 0
    for p in range(n):
        r = find_root(parent, p)
        if new[r] < 0:
            new[r] = k
            for a in range(3):
                out[k, a] = pts[r, a]
            k += 1
        new[p] = new[r]
    return new, out[:k]


# --- public API -------------------------------------------------------------------------------------------


def _wants(n_cells: int, cell: np.ndarray, label: np.ndarray, link: np.ndarray, flip: np.ndarray):
    """CSR (by cell) of the links a pass has to build."""
    order = np.argsort(cell, kind="stable")
    start = np.searchsorted(cell[order], np.arange(n_cells + 1)).astype(np.int64)
    return (start, np.ascontiguousarray(label[order], dtype=np.int64),
            np.ascontiguousarray(link[order], dtype=np.int64), np.ascontiguousarray(flip[order], dtype=np.bool_))


def link_polygons(graph: ShardGraph, *, tolerance: float = 1e-9) -> LinkMesh:
    """Triangulate the face of every link of ``graph``.

    Parameters
    ----------
    graph : ShardGraph
        From :func:`~pverosion.kernels.shards.graph.build_shards`.
    tolerance : float, default 1e-9
        Points closer than ``tolerance`` times the largest extent of the
        Voronoi box, or than 256 units in the last place of its largest
        coordinate, are one point (boundary loops are chained and the faces
        of neighbouring links joined with it).

    Returns
    -------
    LinkMesh
        Triangles of all links, sorted by link and wound along ``link_normal``.
        The triangulated area and centroid of every link are its
        ``link_area`` and ``link_centroid`` up to rounding.

    Raises
    ------
    ValueError
        ``tolerance`` not positive, or a graph without its mesh.
    RuntimeError
        A cell cannot be rebuilt (a graph whose seeds, box or mesh were changed).

    Notes
    -----
    Cells are rebuilt with :func:`~pverosion.kernels.shards.voronoi.cell_polygons` and the
    mesh queries ``build_shards`` uses, in batches on
    ``numba.get_num_threads()`` threads; the result does not depend on the
    thread count. Faces whose loops could not be closed or bridged cleanly
    (degenerate input, e.g. seeds placed symmetrically to mesh edges) are
    still triangulated and counted in :attr:`LinkMesh.issues`.
    """
    if not (tolerance > 0.0 and np.isfinite(tolerance)):
        raise ValueError(f"tolerance must be a positive number; got {tolerance!r}")
    if len(graph.mesh_faces) == 0:
        raise ValueError("the graph carries no mesh (mesh_points/mesh_faces are empty); build it with build_shards")
    n_cells, n_links = graph.n_cells, graph.n_links
    lo, hi = (np.asarray(b, dtype=np.float64) for b in graph.box)
    extent = float((hi - lo).max())
    # far from the origin the points computed from planes carry the rounding of their coordinates: never merge
    # more finely than that (256 units in the last place of the largest coordinate)
    tol = max(tolerance * extent, 256.0 * np.finfo(np.float64).eps * float(np.abs(np.concatenate([lo, hi])).max()))
    seeds = np.ascontiguousarray(graph.input_seeds, dtype=np.float64)
    start, order, dims, size = seed_grid(seeds, lo, hi)
    index = TriangleIndex.build(graph.mesh_points, graph.mesh_faces)
    bound_n, bound_d = _bounding_planes(index.points, margin=1e-7 * extent)
    cell_seed = np.ascontiguousarray(graph.cell_seed, dtype=np.int64)
    args = (cell_seed, seeds, start, order, dims, size, lo, hi, bound_n, bound_d, index.points, index.faces,
            index.normals, index.lo, index.size, index.dims, index.start, index.items, index.start2, index.items2)
    first, second = graph.link_cells[:, 0], graph.link_cells[:, 1]
    exterior = second < 0
    links = np.arange(n_links, dtype=np.int64)
    # pass 1: every link from its first (lower-numbered) cell; an exterior link is its pieces of mesh triangles
    inner = np.flatnonzero(~exterior)
    per_link = np.diff(graph.surface_start)
    outer = np.repeat(links, per_link)
    cell = np.concatenate([first[inner], first[outer]])
    label = np.concatenate([cell_seed[second[inner]], -1 - graph.surface_triangle])
    wants = _wants(n_cells, cell, label, np.concatenate([inner, outer]), np.zeros(len(cell), bool))
    parts = []
    issues = 0
    threads = numba.get_num_threads()

    def batch(todo: np.ndarray, wants, cap: int):
        """One batch, in a worker thread (the kernels release the GIL)."""
        pts, tri, lnk, npts, ntri, iss, status = _links_batch(todo, *args, *wants, tol, 1e-7 * extent,
                                                              cap * _CAP_POINTS, cap * _CAP_TRIANGLES)
        ok = status == 0
        return _gather(pts, tri, lnk, npts, ntri, ok), int(iss[ok].sum()), todo[status == 2], bool((status == 1).any())

    def run(todo: np.ndarray, wants) -> None:
        nonlocal issues
        chunks = [todo[b:b + _BATCH] for b in range(0, len(todo), _BATCH)]
        if threads > 1 and len(chunks) > 1:
            with ThreadPoolExecutor(max_workers=threads) as pool:
                results = list(pool.map(lambda chunk: batch(chunk, wants, 1), chunks))
        else:
            results = [batch(chunk, wants, 1) for chunk in chunks]
        for part, iss, overflow, failed in results:
            if failed:
                raise RuntimeError("a Voronoi cell could not be rebuilt; was the graph built from these seeds?")
            parts.append(part)
            issues += iss
            for c in overflow:  # too many pieces for a slot: alone, with more room
                cap = 4
                while True:
                    part, iss, again, _ = batch(np.array([c], np.int64), wants, cap)
                    if not len(again):
                        break
                    cap *= 4
                parts.append(part)
                issues += iss

    run(np.arange(n_cells, dtype=np.int64), wants)
    # pass 2: interior links the first cell found empty (rounding) come from the second, reversed
    count = np.bincount(np.concatenate([p[2] for p in parts]), minlength=n_links) if parts else np.zeros(n_links)
    missing = np.flatnonzero((count == 0) & ~exterior)
    if len(missing):
        wants = _wants(n_cells, second[missing], cell_seed[first[missing]], missing, np.ones(len(missing), bool))
        run(np.unique(second[missing]).astype(np.int64), wants)
    if parts:
        offsets = np.cumsum([0] + [len(p[0]) for p in parts])
        points = np.concatenate([p[0] for p in parts])
        triangles = np.concatenate([p[1] + o for p, o in zip(parts, offsets)])
        triangle_link = np.concatenate([p[2] for p in parts])
    else:
        points, triangles, triangle_link = np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int64)
    proj = points @ _MERGE_DIRECTION
    new, points = _merge_points(points, proj, np.argsort(proj, kind="stable"), tol)
    triangles = new[triangles]
    keep = ((triangles[:, 0] != triangles[:, 1]) & (triangles[:, 1] != triangles[:, 2])
            & (triangles[:, 2] != triangles[:, 0]))
    triangles, triangle_link = triangles[keep], triangle_link[keep]
    order_t = np.argsort(triangle_link, kind="stable")
    triangles, triangle_link = triangles[order_t], triangle_link[order_t]
    link_start = np.searchsorted(triangle_link, np.arange(n_links + 1)).astype(np.int64)
    return LinkMesh(points=points, triangles=np.ascontiguousarray(triangles), triangle_link=triangle_link,
                    link_start=link_start, issues=issues)


def _check_links(graph: ShardGraph, links: LinkMesh | None) -> LinkMesh:
    if links is None:
        return link_polygons(graph)
    if not isinstance(links, LinkMesh) or links.n_links != graph.n_links:
        raise ValueError("links must be the LinkMesh of this graph (from link_polygons(graph))")
    return links


def _compact(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep only the points the triangles use."""
    used, inverse = np.unique(triangles, return_inverse=True)
    return points[used], inverse.reshape(-1, 3).astype(np.int64)


def _link_triangles(links: LinkMesh, chosen: np.ndarray) -> np.ndarray:
    """Indices of the triangles of the links ``chosen``, link by link."""
    counts = links.link_start[chosen + 1] - links.link_start[chosen]
    first = np.repeat(links.link_start[chosen] - np.cumsum(counts) + counts, counts)
    return first + np.arange(counts.sum())


def cells_boundary(graph: ShardGraph, mask: np.ndarray, *,
                   links: LinkMesh | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The closed surface around the union of the cells where ``mask`` is True.

    It is made of the link faces with the union on exactly one side (the
    outside of the mesh counts as not in the union), wound outward.

    Parameters
    ----------
    graph : ShardGraph
    mask : numpy.ndarray of bool, shape (n_cells,)
        The cells of the union (for example the solid ones).
    links : LinkMesh, optional
        ``link_polygons(graph)``, when already computed.

    Returns
    -------
    points : numpy.ndarray, shape (p, 3), float64
        Only the points the triangles use.
    triangles : numpy.ndarray, shape (t, 3), int64
        Every edge is shared by an even number of triangles, as often in one
        direction as in the other.
    triangle_link : numpy.ndarray, shape (t,), int64
    flipped : numpy.ndarray, shape (t,), bool
        True where the triangle is wound against ``link_normal`` (the union
        is on the link's second side).

    Raises
    ------
    ValueError
        ``mask`` not a boolean array of shape (n_cells,), or ``links`` not
        from this graph.
    """
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != (graph.n_cells,):
        raise ValueError(f"mask must be a bool array of shape ({graph.n_cells},); got {mask.dtype} {mask.shape}")
    links = _check_links(graph, links)
    first, second = graph.link_cells[:, 0], graph.link_cells[:, 1]
    in_first = mask[first]
    in_second = np.where(second >= 0, mask[np.maximum(second, 0)], False)
    chosen = np.flatnonzero(in_first != in_second)
    tri_ids = _link_triangles(links, chosen)
    triangles = links.triangles[tri_ids]
    triangle_link = links.triangle_link[tri_ids]
    flipped = in_second[triangle_link]
    triangles[flipped] = triangles[flipped][:, ::-1]
    points, triangles = _compact(links.points, triangles)
    return points, triangles, triangle_link, flipped


def cell_surfaces(graph: ShardGraph, cells: np.ndarray, *,
                  links: LinkMesh | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed surface of every listed cell, each with points of its own.

    Parameters
    ----------
    graph : ShardGraph
    cells : numpy.ndarray of int, shape (k,)
        Distinct cell indices in ``[0, n_cells)``.
    links : LinkMesh, optional
        ``link_polygons(graph)``, when already computed.

    Returns
    -------
    points : numpy.ndarray, shape (p, 3), float64
    triangles : numpy.ndarray, shape (t, 3), int64
        All links of each cell, wound outward from that cell; an interior link
        between two listed cells appears once for each. Grouped by cell, in
        the order of ``cells``.
    triangle_cell : numpy.ndarray, shape (t,), int64
        The cell of every triangle.

    Raises
    ------
    ValueError
        ``cells`` not integers, out of range or repeated, or ``links`` not
        from this graph.
    """
    cells = np.asarray(cells)
    if cells.ndim != 1 or (cells.size and not np.issubdtype(cells.dtype, np.integer)):
        raise ValueError(f"cells must be a 1-D array of cell indices; got dtype {cells.dtype}, shape {cells.shape}")
    cells = cells.astype(np.int64)
    if cells.size and (cells.min() < 0 or cells.max() >= graph.n_cells):
        raise ValueError(f"cell indices must be in [0, {graph.n_cells}); got {cells.min()}..{cells.max()}")
    if len(np.unique(cells)) != len(cells):
        raise ValueError("cells must be distinct; some are repeated")
    links = _check_links(graph, links)
    slot = np.full(graph.n_cells, -1, np.int64)
    slot[cells] = np.arange(len(cells))
    first, second = graph.link_cells[:, 0], graph.link_cells[:, 1]
    ids = np.arange(graph.n_links)
    inner = second >= 0
    # (slot of the cell, link, link runs away from the cell?)
    rows = np.concatenate([slot[first], np.where(inner, slot[np.maximum(second, 0)], -1)])
    link_of = np.concatenate([ids, ids])
    reverse = np.concatenate([np.zeros(len(ids), bool), np.ones(len(ids), bool)])
    keep = rows >= 0
    rows, link_of, reverse = rows[keep], link_of[keep], reverse[keep]
    order = np.lexsort((link_of, rows))
    rows, link_of, reverse = rows[order], link_of[order], reverse[order]
    counts = links.link_start[link_of + 1] - links.link_start[link_of]
    tri_ids = _link_triangles(links, link_of)
    triangles = links.triangles[tri_ids]
    flip = np.repeat(reverse, counts)
    triangles[flip] = triangles[flip][:, ::-1]
    tri_slot = np.repeat(rows, counts)
    # own points per cell: key (slot, point)
    key = tri_slot[:, None] * len(links.points) + triangles
    used, inverse = np.unique(key, return_inverse=True)
    points = links.points[used % max(len(links.points), 1)]
    return points, inverse.reshape(-1, 3).astype(np.int64), cells[tri_slot]
