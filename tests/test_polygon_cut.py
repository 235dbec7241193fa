"""Cutting a triangle along constraint segments: the output must be a valid constrained tiling."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pverosion.kernels.exact.polygon_cut import LOCATION_EDGE, LOCATION_INTERIOR, cut_triangle, cut_triangles
from pverosion.kernels.exact.predicates import orient2d_batch

# ---------------------------------------------------------------------------
# Building inputs
# ---------------------------------------------------------------------------


class Cut:
    """Incremental builder of the input of :func:`cut_triangle` for one triangle."""

    def __init__(self, corners):
        self.corners = np.asarray(corners, dtype=np.float64)
        self.xy = [p for p in self.corners]
        self.loc = [0, 1, 2]
        self.par = [0.0, 0.0, 0.0]
        self.seg = []

    def _add(self, p, loc, t):
        self.xy.append(np.asarray(p, dtype=np.float64))
        self.loc.append(loc)
        self.par.append(t)
        return len(self.xy) - 1

    def edge(self, k, t):
        """A point on edge k at parameter t from corner k."""
        p = (1.0 - t) * self.corners[k] + t * self.corners[(k + 1) % 3]
        return self._add(p, LOCATION_EDGE + k, t)

    def inner(self, p):
        return self._add(p, LOCATION_INTERIOR, 0.0)

    def bary(self, lam):
        return self.inner(np.asarray(lam) @ self.corners)

    def chain(self, idx, closed=False):
        idx = list(idx)
        pairs = list(itertools.pairwise(idx))
        if closed:
            pairs.append((idx[-1], idx[0]))
        self.seg.extend(pairs)
        return idx

    def loop(self, center, radius, count, aspect=1.0):
        th = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        pts = [self.inner(np.asarray(center) + radius * np.array([np.cos(a), aspect * np.sin(a)])) for a in th]
        return self.chain(pts, closed=True)

    def arrays(self):
        seg = np.array(self.seg, dtype=np.int64).reshape(-1, 2)
        return (
            np.array(self.xy, dtype=np.float64).reshape(-1, 2),
            np.array(self.loc, dtype=np.int64),
            np.array(self.par, dtype=np.float64),
            seg,
        )

    def run(self):
        return cut_triangle(*self.arrays())


# ---------------------------------------------------------------------------
# Checking outputs
# ---------------------------------------------------------------------------


def _mask(loc):
    if loc < 3:
        return (1 << loc) | (1 << ((loc + 2) % 3))
    if loc < LOCATION_INTERIOR:
        return 1 << (loc - LOCATION_EDGE)
    return 0


def _edge_chain(loc, par, k):
    """Corner k, the points of edge k in order, corner k + 1."""
    idx = np.flatnonzero(loc == LOCATION_EDGE + k)
    return [k, *idx[np.argsort(par[idx])].tolist(), (k + 1) % 3]


def _split_segment(xy, loc, par, a, b):
    """The points along segment a-b, in order (boundary points between its ends if it lies on an edge)."""
    common = _mask(loc[a]) & _mask(loc[b])
    if not common:  # any (isolated) point exactly on it splits it
        n = len(xy)
        on = orient2d_batch(np.tile(xy[a], (n, 1)), np.tile(xy[b], (n, 1)), xy) == 0.0
        lo, hi = np.minimum(xy[a], xy[b]), np.maximum(xy[a], xy[b])
        on &= np.all((xy >= lo) & (xy <= hi), axis=1)
        idx = np.flatnonzero(on)
        return idx[np.argsort(np.sum((xy[idx] - xy[a]) ** 2, axis=1))].tolist()
    k = int(common).bit_length() - 1
    chain = _edge_chain(loc, par, k)
    i, j = sorted((chain.index(a), chain.index(b)))
    return chain[i : j + 1]


def _area2(xy, tri):
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _polygon_area(xy, idx):
    p = xy[idx] - xy[idx[0]]
    q = np.roll(p, -1, axis=0)
    return 0.5 * np.sum(p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0])


def _segment_distance(p, a, b):
    """(N, E) distances of points p (N, 2) to segments a-b (E, 2 each)."""
    ab = b - a
    ap = p[:, None, :] - a[None, :, :]
    t = np.clip(np.sum(ap * ab[None], axis=2) / np.maximum(np.sum(ab * ab, axis=1), 1e-300)[None], 0.0, 1.0)
    d = ap - t[..., None] * ab[None]
    return np.sqrt(np.sum(d * d, axis=2))


def check_sampled_coverage(xy, tri, rng, n_samples=400, tol=None):
    """Random points of the triangle, away from every output edge, lie in exactly one output triangle."""
    c = xy[:3]
    diam = np.max(np.linalg.norm(c - np.roll(c, 1, axis=0), axis=1))
    tol = 1e-9 * diam if tol is None else tol
    r = rng.random((n_samples, 2))
    flip = r.sum(axis=1) > 1.0
    r[flip] = 1.0 - r[flip]
    p = c[0] + r[:, :1] * (c[1] - c[0]) + r[:, 1:] * (c[2] - c[0])
    edges = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1), axis=0)
    near = np.zeros(n_samples, dtype=bool)
    for s in range(0, len(edges), 2000):
        e = edges[s : s + 2000]
        near |= np.any(_segment_distance(p, xy[e[:, 0]], xy[e[:, 1]]) <= tol, axis=1)
    p = p[~near]
    nt = len(tri)
    inside = np.ones((len(p), nt), dtype=bool)
    pp = np.repeat(p, nt, axis=0)
    for j in range(3):
        a = np.tile(xy[tri[:, j]], (len(p), 1))
        b = np.tile(xy[tri[:, (j + 1) % 3]], (len(p), 1))
        inside &= (orient2d_batch(a, b, pp) > 0.0).reshape(len(p), nt)
    counts = inside.sum(axis=1)
    assert np.all(counts == 1), f"{np.sum(counts != 1)} of {len(p)} samples covered {set(counts.tolist())} times"
    return len(p)


def check_tiling(xy, loc, par, seg, tri, reg, rng=None, sample_tol=None, all_points_used=True):
    """Assert every property of a valid constrained tiling; return the area of each region."""
    n = len(xy)
    assert tri.ndim == 2 and tri.shape[1] == 3 and len(tri) > 0
    assert reg.shape == (len(tri),)
    assert tri.min() >= 0 and tri.max() < n
    # every output triangle is strictly counter-clockwise (exact)
    o = orient2d_batch(xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]])
    assert np.all(o > 0.0)
    # the areas add up to the triangle's
    total = 0.5 * _area2(xy, np.array([[0, 1, 2]]))[0]
    areas = 0.5 * _area2(xy, tri)
    assert abs(areas.sum() - total) <= 1e-12 * abs(total)
    # edge manifold: each directed edge once; boundary edges are exactly the split triangle boundary
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    dkeys = directed[:, 0] * n + directed[:, 1]
    assert len(np.unique(dkeys)) == len(dkeys), "a directed edge is used twice (overlap or fold)"
    dset = set(dkeys.tolist())
    boundary = {int(k) for k in dkeys if (k % n) * n + k // n not in dset}
    chain = []
    for k in range(3):
        chain.extend(_edge_chain(loc, par, k)[:-1])
    expected = {chain[i] * n + chain[(i + 1) % len(chain)] for i in range(len(chain))}
    assert boundary == expected
    # points are vertices
    used = set(tri.ravel().tolist())
    if all_points_used:
        assert used == set(range(n))
    # constraint segments, split at the points lying on them, are edges
    undirected = {(min(a, b), max(a, b)) for a, b in directed.tolist()}
    constrained = set()
    for a, b in seg.tolist():
        if a == b:
            continue
        pts = _split_segment(xy, loc, par, a, b)
        for u, v in itertools.pairwise(pts):
            e = (min(u, v), max(u, v))
            assert e in undirected, f"segment piece {e} missing"
            constrained.add(e)
    # regions: the triangles connected across unconstrained edges, one index each
    n_regions = reg.max() + 1
    assert set(reg.tolist()) == set(range(n_regions))
    parent = np.arange(len(tri))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner = {}
    for t, (a, b, c) in enumerate(tri.tolist()):
        for u, v in ((a, b), (b, c), (c, a)):
            owner[(u, v)] = t
    for (u, v), t in owner.items():
        s = owner.get((v, u))
        if s is not None and (min(u, v), max(u, v)) not in constrained:
            parent[find(t)] = find(s)
    roots = np.array([find(t) for t in range(len(tri))])
    for r in range(n_regions):
        assert len(set(roots[reg == r].tolist())) == 1, f"region {r} is not connected"
    assert len(set(roots.tolist())) == n_regions, "two regions are not separated by segments"
    if rng is not None:
        assert check_sampled_coverage(xy, tri, rng, tol=sample_tol) > 0
    return np.bincount(reg, weights=areas, minlength=n_regions)


def run_and_check(cut, rng=None, **kw):
    xy, loc, par, seg = cut.arrays()
    tri, reg = cut_triangle(xy, loc, par, seg)
    areas = check_tiling(xy, loc, par, seg, tri, reg, rng=rng, **kw)
    return tri, reg, areas


TRI = [(0.1, 0.2), (1.3, 0.1), (0.4, 1.1)]


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


# ---------------------------------------------------------------------------
# Simple configurations
# ---------------------------------------------------------------------------


def test_plain_triangle_with_edge_points(rng):
    cut = Cut(TRI)
    for k, t in [(0, 0.3), (0, 0.7), (1, 0.5), (2, 0.01), (2, 0.99), (2, 0.5)]:
        cut.edge(k, t)
    tri, _, areas = run_and_check(cut, rng)
    assert len(areas) == 1
    assert len(tri) == len(cut.xy) - 2  # a triangulated polygon without interior vertices


def test_single_chord_edge0_to_edge1(rng):
    cut = Cut(TRI)
    p = cut.edge(0, 0.4)
    q = cut.edge(1, 0.3)
    cut.seg.append((p, q))
    xy = cut.arrays()[0]
    _, _, areas = run_and_check(cut, rng)
    total = _polygon_area(xy, [0, 1, 2])
    corner = _polygon_area(xy, [p, 1, q])
    assert len(areas) == 2
    np.testing.assert_allclose(np.sort(areas), np.sort([corner, total - corner]), rtol=1e-12)


def test_square_loop_inside(rng):
    cut = Cut(TRI)
    sq = [cut.inner(p) for p in [(0.5, 0.4), (0.7, 0.4), (0.7, 0.6), (0.5, 0.6)]]
    cut.chain(sq, closed=True)
    xy = cut.arrays()[0]
    _, _, areas = run_and_check(cut, rng)
    total = _polygon_area(xy, [0, 1, 2])
    np.testing.assert_allclose(np.sort(areas), np.sort([0.04, total - 0.04]), rtol=1e-12)


def test_nested_loops(rng):
    cut = Cut(TRI)
    outer = cut.loop((0.6, 0.5), 0.2, 24)
    inner = cut.loop((0.62, 0.48), 0.08, 12)
    xy = cut.arrays()[0]
    _, _, areas = run_and_check(cut, rng)
    total = _polygon_area(xy, [0, 1, 2])
    a_out = _polygon_area(xy, outer)
    a_in = _polygon_area(xy, inner)
    assert len(areas) == 3
    np.testing.assert_allclose(np.sort(areas), np.sort([a_in, a_out - a_in, total - a_out]), rtol=1e-12)


def test_polyline_from_corner_to_opposite_edge(rng):
    cut = Cut(TRI)
    cut.edge(0, 0.5)  # an extra point on the side that is cut off
    q = cut.edge(1, 0.6)
    mid = [cut.bary(lam) for lam in [(0.8, 0.15, 0.05), (0.55, 0.3, 0.15), (0.4, 0.3, 0.3), (0.2, 0.45, 0.35)]]
    cut.chain([0, *mid, q])
    xy = cut.arrays()[0]
    _, _, areas = run_and_check(cut, rng)
    total = _polygon_area(xy, [0, 1, 2])
    side = _polygon_area(xy, [0, 3, 1, q, *mid[::-1]])  # corner 0, edge 0 point, corner 1, q, back along the path
    assert len(areas) == 2
    np.testing.assert_allclose(np.sort(areas), np.sort([side, total - side]), rtol=1e-12)


def test_segments_along_boundary(rng):
    cut = Cut(TRI)
    e0 = [cut.edge(0, t) for t in (0.2, 0.5, 0.8)]
    e1 = [cut.edge(1, t) for t in (0.25, 0.75)]
    cut.seg += [(0, e0[0]), (e0[0], e0[2]), (e0[2], 0), (1, 2), (2, 1), (2, 0), (e1[1], 1), (e0[1], e0[1])]
    _, _, areas = run_and_check(cut, rng)
    assert len(areas) == 1


def test_chord_plus_loop_on_one_side(rng):
    cut = Cut(TRI)
    p = cut.edge(0, 0.35)
    q = cut.edge(2, 0.6)  # edge 2 runs from corner 2 to corner 0: cuts off corner 0
    m = cut.bary((0.55, 0.3, 0.15))
    cut.chain([p, m, q])
    loop = cut.loop((0.7, 0.55), 0.12, 16)
    xy = cut.arrays()[0]
    _, _, areas = run_and_check(cut, rng)
    total = _polygon_area(xy, [0, 1, 2])
    corner = _polygon_area(xy, [0, p, m, q])
    a_loop = _polygon_area(xy, loop)
    assert len(areas) == 3
    np.testing.assert_allclose(np.sort(areas), np.sort([corner, a_loop, total - corner - a_loop]), rtol=1e-12)


def test_dangling_floating_and_isolated(rng):
    cut = Cut(TRI)
    # dangling chain from edge 1 into the interior
    cut.chain([cut.edge(1, 0.5), cut.bary((0.2, 0.4, 0.4)), cut.bary((0.3, 0.35, 0.35))])
    # U-shaped chain from edge 0 back to edge 0
    cut.chain([cut.edge(0, 0.3), cut.bary((0.6, 0.3, 0.1)), cut.bary((0.45, 0.45, 0.1)), cut.edge(0, 0.6)])
    # floating open polyline, floating loop with a tail, a single floating segment
    cut.chain([cut.bary(lam) for lam in [(0.5, 0.2, 0.3), (0.45, 0.2, 0.35), (0.5, 0.15, 0.35)]])
    loop = cut.loop(np.array([0.3, 0.2, 0.5]) @ cut.corners, 0.05, 8)
    cut.seg.append((loop[0], cut.bary((0.25, 0.25, 0.5))))
    cut.chain([cut.bary((0.6, 0.1, 0.3)), cut.bary((0.62, 0.1, 0.28))])
    # an isolated interior point and an edge point on no segment
    cut.bary((0.15, 0.3, 0.55))
    cut.edge(2, 0.4)
    _, _, areas = run_and_check(cut, rng)
    assert len(areas) == 3  # the triangle, the pocket of the U, the loop


def test_loops_touching_and_sharing_vertices(rng):
    cut = Cut(TRI)
    c = cut.bary((0.4, 0.3, 0.3))  # a figure-eight: two loops through one vertex
    a = [cut.bary(lam) for lam in [(0.5, 0.3, 0.2), (0.55, 0.25, 0.2)]]
    b = [cut.bary(lam) for lam in [(0.3, 0.4, 0.3), (0.3, 0.45, 0.25)]]
    cut.chain([c, *a], closed=True)
    cut.chain([c, *b], closed=True)
    # a loop touching edge 2 at one point
    t = cut.edge(2, 0.5)
    cut.chain([t, cut.bary((0.5, 0.05, 0.45)), cut.bary((0.4, 0.05, 0.55))], closed=True)
    _, _, areas = run_and_check(cut, rng)
    assert len(areas) == 4


# ---------------------------------------------------------------------------
# Random non-crossing chords with many points
# ---------------------------------------------------------------------------


def random_cut(rng):
    """Chords of one family of wavy non-crossing curves, some truncated, plus loops and loose points."""
    while True:
        corners = rng.random((3, 2))
        a2 = _area2(corners, np.array([[0, 1, 2]]))[0]
        if abs(a2) > 0.3:
            break
    if a2 < 0:
        corners = corners[[0, 2, 1]]
    cut = Cut(corners)
    k = int(rng.integers(3))
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    n_chords = int(rng.integers(3, 6))
    levels = np.sort(rng.uniform(0.1, 0.9, n_chords))
    while np.min(np.diff(levels)) < 0.08:
        levels = np.sort(rng.uniform(0.1, 0.9, n_chords))
    gaps = np.diff(np.concatenate([[0.0], levels, [1.0]]))
    amp = 0.3 * np.minimum(gaps[:-1], gaps[1:]) * rng.uniform(-1.0, 1.0, n_chords)
    full = 0

    def point(lk, u):
        lam = np.empty(3)
        lam[k], lam[k1], lam[k2] = lk, (1.0 - lk) * u, (1.0 - lk) * (1.0 - u)
        return lam

    for c, a in zip(levels, amp):
        m = int(rng.integers(20, 40))
        freq = int(rng.integers(1, 5))
        u = np.linspace(0.0, 1.0, m + 2)[1:-1]
        lk = c + a * np.sin(np.pi * u) * np.sin(freq * np.pi * u)
        path = [cut.edge(k2, c), *[cut.bary(point(x, y)) for x, y in zip(lk, u)], cut.edge(k, 1.0 - c)]
        if rng.random() < 0.25:  # dangling: stops inside
            path = path[: int(rng.integers(3, len(path) - 2))]
        else:
            full += 1
        if rng.random() < 0.5:
            path = path[::-1]
        cut.chain(path)
    # loops (possibly nested) and open polylines in the bands between the curves
    lo = np.concatenate([[0.0], levels + np.abs(amp)])
    hi = np.concatenate([levels - np.abs(amp), [1.0]])
    n_loops = 0
    for b in range(len(lo)):
        mid, half = 0.5 * (lo[b] + hi[b]), 0.5 * (hi[b] - lo[b])
        kind = rng.integers(4)
        th = np.linspace(0.0, 2.0 * np.pi, int(rng.integers(8, 20)), endpoint=False)
        if kind in (1, 2):
            for scale in (0.6, 0.3)[:kind]:
                pts = [cut.bary(point(mid + scale * half * np.cos(t), 0.5 + scale * 0.4 * np.sin(t))) for t in th]
                cut.chain(pts, closed=True)
                n_loops += 1
        elif kind == 3:
            cut.chain(
                [cut.bary(point(mid + 0.5 * half * np.cos(t), 0.3 + 0.2 * np.sin(t))) for t in th[: len(th) // 2]]
            )
        if rng.random() < 0.5:  # an isolated point
            cut.bary(point(mid + 0.9 * half * rng.uniform(-1, 1), rng.uniform(0.05, 0.95)))
    for _ in range(int(rng.integers(0, 6))):  # loose edge points
        cut.edge(int(rng.integers(3)), rng.uniform(0.01, 0.99))
    # duplicated and reversed segments
    extra = [cut.seg[i] for i in rng.integers(0, len(cut.seg), 5)]
    cut.seg += [(b, a) for a, b in extra]
    return cut, full + 1 + n_loops


@pytest.mark.parametrize("seed", range(8))
def test_random_non_crossing_chords(seed):
    rng = np.random.default_rng(seed)
    cut, expected_regions = random_cut(rng)
    assert len(cut.xy) >= 100
    _, _, areas = run_and_check(cut, rng)
    assert len(areas) == expected_regions
    assert np.all(areas > 0.0)


# ---------------------------------------------------------------------------
# Nearly degenerate inputs
# ---------------------------------------------------------------------------


def test_tiny_loop(rng):
    cut = Cut(TRI)
    s = 1e-9
    c = np.array([0.6, 0.5])
    sq = cut.chain([cut.inner(c + s * np.array(d)) for d in [(0, 0), (1, 0), (1, 1), (0, 1)]], closed=True)
    p = cut.edge(0, 0.5)
    cut.seg.append((p, cut.edge(1, 0.5)))
    xy = cut.arrays()[0]
    _, _, areas = run_and_check(cut, rng)
    assert len(areas) == 3
    np.testing.assert_allclose(np.min(areas), _polygon_area(xy, sq), rtol=1e-6)


def test_edge_points_next_to_corners(rng):
    cut = Cut(TRI)
    eps = 1e-12
    p = cut.edge(0, 1.0 - eps)
    q = cut.edge(1, eps)
    cut.seg.append((p, q))  # cuts off a tiny corner
    for k in range(3):
        cut.edge(k, eps if k != 1 else 2 * eps)
        cut.edge(k, 1.0 - 2 * eps)
    r = cut.edge(2, 0.5)
    cut.chain([r, cut.bary((1.0 - 1e-12, 5e-13, 5e-13)), cut.edge(0, 3 * eps)])  # a path hugging corner 0
    _, _, areas = run_and_check(cut, rng)
    assert len(areas) == 3


def test_thin_sliver(rng):
    h = 1e-10
    cut = Cut([(0.0, 0.0), (1.0, 0.0), (0.37, h)])
    for t in (0.1, 0.5, 0.9):
        cut.edge(0, t)
    p = cut.edge(1, 0.5)
    q = cut.edge(2, 0.3)
    cut.chain([p, cut.inner((0.5, 0.3 * h)), q])
    cut.seg.append((cut.edge(1, 0.1), cut.edge(0, 0.95)))  # cuts off corner 1
    _, _, areas = run_and_check(cut, rng, sample_tol=1e-4 * h)
    assert len(areas) == 3


def test_inconsistent_input_gives_empty():
    cut = Cut(TRI)
    a, b, c = cut.inner((0.5, 0.4)), cut.inner((0.6, 0.4)), cut.inner((0.7, 0.4))
    cut.seg += [(a, c), (a, b)]  # overlapping collinear segments
    assert cut.run()[0].shape == (0, 3)
    xy, loc, par, seg = Cut(TRI).arrays()
    assert cut_triangle(xy[[1, 0, 2]], loc, par, seg)[0].shape == (0, 3)  # clockwise corners
    bad = loc.copy()
    bad[1] = 4
    assert cut_triangle(xy, bad, par, seg)[0].shape == (0, 3)
    assert cut_triangle(xy, loc, par, np.array([[0, 7]]))[0].shape == (0, 3)


# ---------------------------------------------------------------------------
# Batch driver
# ---------------------------------------------------------------------------


def test_batch_matches_single_calls():
    rng = np.random.default_rng(7)
    cuts = [random_cut(rng)[0] for _ in range(3)]
    c = Cut(TRI)
    c.seg.append((c.edge(0, 0.4), c.edge(1, 0.3)))
    cuts.append(c)
    lone = Cut(TRI)  # a loop and an isolated interior point: cut by the full cut_triangle after the batch
    lone.loop(np.array([0.3, 0.3, 0.4]) @ lone.corners, 0.05, 6)
    isolated = lone.bary((0.6, 0.2, 0.2))
    cuts.append(lone)
    bad = Cut(TRI)
    bad.seg.append((0, 9))
    cuts.append(bad)
    arrays = [c.arrays() for c in cuts]
    point_start = np.cumsum([0] + [len(a[0]) for a in arrays])
    segment_start = np.cumsum([0] + [len(a[3]) for a in arrays])
    tri, reg, start = cut_triangles(
        np.concatenate([a[0] for a in arrays]),
        np.concatenate([a[1] for a in arrays]),
        np.concatenate([a[2] for a in arrays]),
        point_start,
        np.concatenate([a[3] for a in arrays]),
        segment_start,
    )
    assert start.shape == (len(cuts) + 1,)
    assert start[-1] == len(tri) == len(reg)
    for i, a in enumerate(arrays):
        t1, r1 = cut_triangle(*a)
        np.testing.assert_array_equal(tri[start[i] : start[i + 1]], t1)
        np.testing.assert_array_equal(reg[start[i] : start[i + 1]], r1)
    assert start[-1] == start[-2]  # the inconsistent one is empty
    assert np.any(tri[start[-3] : start[-2]] == isolated)  # the isolated point is a vertex
