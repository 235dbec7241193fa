"""Exactness of the robust orientation predicates, checked against rational arithmetic."""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest

from pverosion.kernels.exact.predicates import (
    _exact_orient2d,
    _exact_orient3d,
    orient2d,
    orient2d_batch,
    orient3d,
    orient3d_batch,
    sign_orient2d,
    sign_orient3d,
)

# ---------------------------------------------------------------------------
# Oracles and helpers
# ---------------------------------------------------------------------------


def _sign(x) -> int:
    return int(x > 0) - int(x < 0)


def exact_orient2d(a, b, c) -> Fraction:
    """det[[a - c], [b - c]] in rational arithmetic on the float coordinates."""
    ax, ay, bx, by, cx, cy = (Fraction(float(v)) for v in (*a, *b, *c))
    return (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)


def exact_orient3d(a, b, c, d) -> Fraction:
    """det[[a - d], [b - d], [c - d]] in rational arithmetic on the float coordinates."""
    ad = [Fraction(float(p)) - Fraction(float(q)) for p, q in zip(a, d)]
    bd = [Fraction(float(p)) - Fraction(float(q)) for p, q in zip(b, d)]
    cd = [Fraction(float(p)) - Fraction(float(q)) for p, q in zip(c, d)]
    return (
        ad[0] * (bd[1] * cd[2] - bd[2] * cd[1])
        - ad[1] * (bd[0] * cd[2] - bd[2] * cd[0])
        + ad[2] * (bd[0] * cd[1] - bd[1] * cd[0])
    )


def naive_orient2d(p: np.ndarray) -> np.ndarray:
    """The plain floating-point determinant of (N, 3, 2) triples (the predicate's own formula)."""
    a, b, c = p[:, 0], p[:, 1], p[:, 2]
    return (a[:, 0] - c[:, 0]) * (b[:, 1] - c[:, 1]) - (a[:, 1] - c[:, 1]) * (b[:, 0] - c[:, 0])


def naive_orient3d(p: np.ndarray) -> np.ndarray:
    """The plain floating-point determinant of (N, 4, 3) quadruples (the predicate's own formula)."""
    ad, bd, cd = p[:, 0] - p[:, 3], p[:, 1] - p[:, 3], p[:, 2] - p[:, 3]
    return (
        ad[:, 2] * (bd[:, 0] * cd[:, 1] - cd[:, 0] * bd[:, 1])
        + bd[:, 2] * (cd[:, 0] * ad[:, 1] - ad[:, 0] * cd[:, 1])
        + cd[:, 2] * (ad[:, 0] * bd[:, 1] - bd[:, 0] * ad[:, 1])
    )


def batch2(p: np.ndarray) -> np.ndarray:
    """orient2d_batch of (N, 3, 2) triples."""
    a, b, c = (np.ascontiguousarray(p[:, k]) for k in range(3))
    return orient2d_batch(a, b, c)


def batch3(p: np.ndarray) -> np.ndarray:
    """orient3d_batch of (N, 4, 3) quadruples."""
    a, b, c, d = (np.ascontiguousarray(p[:, k]) for k in range(4))
    return orient3d_batch(a, b, c, d)


def exact_signs2(p: np.ndarray) -> np.ndarray:
    return np.array([_sign(exact_orient2d(*q)) for q in p])


def exact_signs3(p: np.ndarray) -> np.ndarray:
    return np.array([_sign(exact_orient3d(*q)) for q in p])


def _is_float(v: int) -> bool:
    """Whether the integer ``v`` is exactly a float64."""
    return abs(v) < 2**1000 and float(v) == v


def _degenerate_configs(rng: np.random.Generator, n: int, n_points: int, dim: int, scale: int) -> np.ndarray:
    """(n, n_points, dim) exactly degenerate configurations: points o + sum_r s_kr u_r on a (dim-1)-flat.

    Built as integers in units of 2**-60: o is zero for every fourth
    configuration, else a 10-bit integer times 2**q; the dim - 1 directions
    u_r have up to 20 bits; each point's parameters s_kr are 10-bit integers
    times the point's own power of two in [2**-40, 2**20]. Configurations
    with a coordinate that is not exactly a float64 are redrawn, and each is
    scaled by a random power of two in [2**-scale, 2**scale]. Differences
    between points of unequal parameter scales need more than 53 bits and
    round, and so do the products, so plain floating point rarely gets 0.
    """
    out = np.empty((n, n_points, dim))
    filled = 0
    while filled < n:
        q = int(rng.integers(-20, 21))
        o = [int(m) << (q + 60) for m in rng.integers(-(2**10), 2**10, size=dim)] if filled % 4 else [0] * dim
        u = [[int(v) for v in rng.integers(-(2**20), 2**20, size=dim)] for _ in range(dim - 1)]
        f = rng.integers(-40, 21, size=n_points)
        s = [[int(m) << (int(f[k]) + 60) for m in rng.integers(-(2**10), 2**10, size=dim - 1)] for k in range(n_points)]
        pts = [[o[j] + sum(s[k][r] * u[r][j] for r in range(dim - 1)) for j in range(dim)] for k in range(n_points)]
        if all(_is_float(v) for row in pts for v in row):
            out[filled] = np.ldexp(np.array(pts, dtype=np.float64), -60)
            filled += 1
    e = rng.integers(-scale, scale + 1, size=(n, 1, 1))
    return np.ldexp(out, e)


def collinear_triples(rng: np.random.Generator, n: int, scale: int = 200) -> np.ndarray:
    """(n, 3, 2) exactly collinear triples (see :func:`_degenerate_configs`)."""
    return _degenerate_configs(rng, n, 3, 2, scale)


def coplanar_quads(rng: np.random.Generator, n: int, scale: int = 200) -> np.ndarray:
    """(n, 4, 3) exactly coplanar quadruples (see :func:`_degenerate_configs`)."""
    return _degenerate_configs(rng, n, 4, 3, scale)


def perturb_one_ulp(rng: np.random.Generator, p: np.ndarray) -> np.ndarray:
    """Move one random nonzero coordinate of each configuration by one ulp up or down.

    Zeros are left alone: their neighbours are subnormal, outside the range
    where the predicates are guaranteed exact.
    """
    n, k, dim = p.shape
    flat = p.reshape(n, k * dim).copy()
    keys = np.where(flat != 0.0, rng.random(flat.shape), -1.0)
    pick = np.argmax(keys, axis=1)  # a random nonzero entry (every configuration has one)
    rows = np.arange(n)
    direction = np.where(rng.random(n) < 0.5, -np.inf, np.inf)
    flat[rows, pick] = np.nextafter(flat[rows, pick], direction)
    return flat.reshape(n, k, dim)


def random_points(rng: np.random.Generator, n: int, k: int, dim: int, spread: int) -> np.ndarray:
    """(n, k, dim) random points of magnitudes in [2**-spread, 2**spread), some mixed within a configuration."""
    mant = np.where(rng.random((n, k, dim)) < 0.5, -1.0, 1.0) * (1.0 + rng.random((n, k, dim)))
    per_config = rng.integers(-spread, spread, size=(n, 1, 1))
    per_coord = rng.integers(-spread, spread, size=(n, k, dim))
    mixed = rng.random((n, 1, 1)) < 0.3
    pts = np.ldexp(mant, np.where(mixed, per_coord, per_config))
    pts[rng.random((n, k, dim)) < 0.05] = 0.0
    return pts


def rotated_plane_quads(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 4, 3) quadruples from two exactly planar point sets rotated by 1 degree about x (then rounded)."""
    i, j = np.meshgrid(np.arange(-40, 41), np.arange(-40, 41), indexing="ij")
    x = np.ldexp(i.ravel().astype(np.float64), -2)
    y = np.ldexp(j.ravel().astype(np.float64), -2)
    flat = np.stack([x, y, np.zeros_like(x)], axis=1)  # z = 0
    tilted = np.stack([x, y, (x + 2.0 * y) / 4.0], axis=1)  # exact: z = x/4 + y/2
    cos, sin = math.cos(math.radians(1.0)), math.sin(math.radians(1.0))
    out = []
    for plane in (flat, tilted):
        r = plane.copy()
        r[:, 1] = cos * plane[:, 1] - sin * plane[:, 2]
        r[:, 2] = sin * plane[:, 1] + cos * plane[:, 2]
        idx = rng.integers(0, len(r), size=(n // 2, 4))
        out.append(r[idx])
    return np.concatenate(out)


# ---------------------------------------------------------------------------
# Conventions and API
# ---------------------------------------------------------------------------


def test_sign_conventions():
    # a, b, c counter-clockwise in the plane -> positive
    assert orient2d(0.0, 0.0, 1.0, 0.0, 0.0, 1.0) > 0
    assert orient2d(0.0, 0.0, 0.0, 1.0, 1.0, 0.0) < 0
    assert orient2d(0.0, 0.0, 1.0, 1.0, 3.0, 3.0) == 0.0
    assert orient2d(0, 0, 1, 0, 0, 1) == 1.0  # integer arguments are converted to float64
    # huge integers round to float64 (2**62 + 1 -> 2**62) instead of overflowing int64 products
    assert orient2d(2**62 + 1, 0, 0, 2**62 + 1, 0, 0) == 2.0**124
    # a, b, c counter-clockwise seen from +z; d below the plane -> positive
    assert orient3d(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0) > 0
    assert orient3d(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0) < 0
    assert orient3d(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 5.0, 7.0, 0.0) == 0.0
    # outside a closed mesh with outward (right-handed) normals -> negative: unit tetrahedron
    verts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]  # outward
    outside = [np.array([0.2, 0.2, -1.0]), np.array([0.2, -1.0, 0.2]), np.array([-1.0, 0.2, 0.2]), np.ones(3)]
    inside = np.array([0.1, 0.1, 0.1])
    for (i, j, k), out in zip(faces, outside):
        assert sign_orient3d(*verts[i], *verts[j], *verts[k], *out) == -1
        assert sign_orient3d(*verts[i], *verts[j], *verts[k], *inside) == 1


def test_values_are_determinants_on_small_integers():
    """Small integers: every step is exact, so the value is the determinant (orient3d = -6 x signed volume)."""
    rng = np.random.default_rng(0)
    p3 = rng.integers(-1000, 1000, size=(300, 4, 3)).astype(np.float64)
    for a, b, c, d in p3:
        volume6 = np.dot(b - a, np.cross(c - a, d - a))
        assert orient3d(*a, *b, *c, *d) == -volume6
        assert orient3d(*a, *b, *c, *d) == exact_orient3d(a, b, c, d)
    p2 = rng.integers(-(2**20), 2**20, size=(300, 3, 2)).astype(np.float64)
    for a, b, c in p2:
        cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        assert orient2d(*a, *b, *c) == cross == exact_orient2d(a, b, c)


def test_sign_functions_and_batches_match_scalars():
    rng = np.random.default_rng(1)
    p2 = np.concatenate([random_points(rng, 100, 3, 2, 30), collinear_triples(rng, 100)])
    p3 = np.concatenate([random_points(rng, 100, 4, 3, 30), coplanar_quads(rng, 100)])
    b2, b3 = batch2(p2), batch3(p3)
    for q, v in zip(p2, b2):
        s = sign_orient2d(*q.ravel())
        assert isinstance(s, int) and s in (-1, 0, 1)
        assert s == _sign(orient2d(*q.ravel())) == _sign(v)
    for q, v in zip(p3, b3):
        s = sign_orient3d(*q.ravel())
        assert isinstance(s, int) and s in (-1, 0, 1)
        assert s == _sign(orient3d(*q.ravel())) == _sign(v)


# ---------------------------------------------------------------------------
# Agreement with rational arithmetic
# ---------------------------------------------------------------------------


def test_random_points_agree_with_fractions():
    rng = np.random.default_rng(2)
    p2 = random_points(rng, 3000, 3, 2, 280)
    p3 = random_points(rng, 3000, 4, 3, 280)
    np.testing.assert_array_equal(np.sign(batch2(p2)), exact_signs2(p2))
    np.testing.assert_array_equal(np.sign(batch3(p3)), exact_signs3(p3))


def test_exact_fallback_alone_agrees_with_fractions():
    """The expansion arithmetic on its own, on inputs spanning the whole documented range [2**-300, 2**300]."""
    rng = np.random.default_rng(3)
    cases2 = np.concatenate(
        [
            random_points(rng, 700, 3, 2, 300),
            collinear_triples(rng, 150),
            perturb_one_ulp(rng, collinear_triples(rng, 150)),
        ]
    )
    cases3 = np.concatenate(
        [random_points(rng, 700, 4, 3, 300), coplanar_quads(rng, 150), perturb_one_ulp(rng, coplanar_quads(rng, 150))]
    )
    # the extremes of the documented range, mixed in one configuration
    edge = np.array([2.0**-300, -(2.0**-300), 2.0**300, -(2.0**300), 0.0, 1.5 * 2.0**-300, (1 + 2**-52) * 2.0**300])
    cases2 = np.concatenate([cases2, rng.choice(edge, size=(200, 3, 2))])
    cases3 = np.concatenate([cases3, rng.choice(edge, size=(200, 4, 3))])
    for q in cases2:
        exact = exact_orient2d(*q)
        value = _exact_orient2d(*q.ravel())
        assert _sign(value) == _sign(exact)
        if exact != 0:  # the returned magnitude is the exact value, rounded
            assert abs(Fraction(value) / exact - 1) < Fraction(1, 10**14)
    for q in cases3:
        exact = exact_orient3d(*q)
        value = _exact_orient3d(*q.ravel())
        assert _sign(value) == _sign(exact)
        if exact != 0:
            assert abs(Fraction(value) / exact - 1) < Fraction(1, 10**14)


def test_exactly_collinear_points_give_zero():
    rng = np.random.default_rng(4)
    p = collinear_triples(rng, 1500)
    assert all(exact_orient2d(*q) == 0 for q in p[:200])  # the construction is exact
    np.testing.assert_array_equal(batch2(p), 0.0)
    assert np.count_nonzero(naive_orient2d(p)) > 100  # plain floating point does not see it


def test_exactly_coplanar_points_give_zero():
    rng = np.random.default_rng(5)
    p = coplanar_quads(rng, 1500)
    assert all(exact_orient3d(*q) == 0 for q in p[:200])
    np.testing.assert_array_equal(batch3(p), 0.0)
    assert np.count_nonzero(naive_orient3d(p)) > 100
    # coplanar in a coordinate plane: every product is zero (the shortcut before the exact path)
    flat = p.copy()
    flat[:, :, 2] = flat[:, :1, 2]
    np.testing.assert_array_equal(batch3(flat), 0.0)


def test_one_ulp_off_a_line():
    rng = np.random.default_rng(6)
    p = perturb_one_ulp(rng, collinear_triples(rng, 2000))
    exact = exact_signs2(p)
    assert np.count_nonzero(exact) > 1500
    np.testing.assert_array_equal(np.sign(batch2(p)), exact)
    assert np.count_nonzero(np.sign(naive_orient2d(p)) != exact) > 100


def test_one_ulp_off_a_plane():
    rng = np.random.default_rng(7)
    p = perturb_one_ulp(rng, coplanar_quads(rng, 2000))
    exact = exact_signs3(p)
    assert np.count_nonzero(exact) > 1500
    np.testing.assert_array_equal(np.sign(batch3(p)), exact)
    assert np.count_nonzero(np.sign(naive_orient3d(p)) != exact) > 50


def test_ulp_grid_near_a_line_where_naive_flips_sign():
    """Kettner et al.'s classroom example: c on a 64 x 64 ulp grid at (0.5, 0.5), a = (12, 12), b = (24, 24)."""
    steps = [0.5]
    for _ in range(63):
        steps.append(float(np.nextafter(steps[-1], 1.0)))
    cx, cy = np.meshgrid(steps, steps, indexing="ij")
    p = np.zeros((cx.size, 3, 2))
    p[:, 0] = 12.0
    p[:, 1] = 24.0
    p[:, 2, 0], p[:, 2, 1] = cx.ravel(), cy.ravel()
    exact = exact_signs2(p)
    np.testing.assert_array_equal(np.sign(batch2(p)), exact)
    naive = np.sign(naive_orient2d(p))
    assert np.count_nonzero((naive == -exact) & (exact != 0)) > 50  # outright wrong signs

    # one such point spelled out: left of the line y = x, yet the naive determinant says right
    c = (float.fromhex("0x1.0000000000029p-1"), float.fromhex("0x1.0000000000030p-1"))
    assert c[1] > c[0]
    assert exact_orient2d((12.0, 12.0), (24.0, 24.0), c) > 0
    assert (12.0 - c[0]) * (24.0 - c[1]) - (12.0 - c[1]) * (24.0 - c[0]) < 0
    assert orient2d(12.0, 12.0, 24.0, 24.0, *c) > 0
    assert sign_orient2d(12.0, 12.0, 24.0, 24.0, *c) == 1


def test_ulp_grid_near_a_plane_where_naive_flips_sign():
    """d on a 48 x 48 ulp grid at (0.5, 0.5, 0.5), near the plane x = y through a, b, c."""
    steps = [0.5]
    for _ in range(47):
        steps.append(float(np.nextafter(steps[-1], 1.0)))
    dx, dy = np.meshgrid(steps, steps, indexing="ij")
    p = np.zeros((dx.size, 4, 3))
    p[:, 0] = (12.0, 12.0, 0.0)
    p[:, 1] = (24.0, 24.0, 0.0)
    p[:, 2] = (7.0, 7.0, 5.0)
    p[:, 3, 0], p[:, 3, 1], p[:, 3, 2] = dx.ravel(), dy.ravel(), 0.5
    exact = exact_signs3(p)
    np.testing.assert_array_equal(np.sign(batch3(p)), exact)
    naive = np.sign(naive_orient3d(p))
    assert np.count_nonzero((naive == -exact) & (exact != 0)) > 50
    assert np.count_nonzero((naive == 0) & (exact != 0)) > 50

    # two such points spelled out, both on the side y > x, which is opposite to the normal (60, -60, 0)
    a, b, c = (12.0, 12.0, 0.0), (24.0, 24.0, 0.0), (7.0, 7.0, 5.0)
    wrong = (float.fromhex("0x1.0000000000005p-1"), float.fromhex("0x1.0000000000011p-1"), 0.5)
    lost = (0.5, float(np.nextafter(0.5, 1.0)), 0.5)  # one ulp off the plane
    for d, naive_sign in ((wrong, -1), (lost, 0)):
        assert exact_orient3d(a, b, c, d) > 0
        assert _sign(naive_orient3d(np.array([[a, b, c, d]]))[0]) == naive_sign
        assert orient3d(*a, *b, *c, *d) > 0
        assert sign_orient3d(*a, *b, *c, *d) == 1


def test_rotated_plane_agrees_with_fractions():
    """Planar grids rotated by 1 degree about x: coplanarity is lost to rounding, the exact sign must follow."""
    rng = np.random.default_rng(8)
    p = rotated_plane_quads(rng, 2000)
    exact = exact_signs3(p)
    np.testing.assert_array_equal(np.sign(batch3(p)), exact)
    assert np.count_nonzero(exact) > 1000  # mostly no longer coplanar
    assert np.count_nonzero(np.sign(naive_orient3d(p)) != exact) > 20


# ---------------------------------------------------------------------------
# Symmetries
# ---------------------------------------------------------------------------


def _hard_cases2(rng: np.random.Generator) -> np.ndarray:
    return np.concatenate(
        [
            random_points(rng, 300, 3, 2, 100),
            collinear_triples(rng, 300),
            perturb_one_ulp(rng, collinear_triples(rng, 600)),
        ]
    )


def _hard_cases3(rng: np.random.Generator) -> np.ndarray:
    return np.concatenate(
        [
            random_points(rng, 300, 4, 3, 100),
            coplanar_quads(rng, 300),
            perturb_one_ulp(rng, coplanar_quads(rng, 600)),
            rotated_plane_quads(rng, 400),
        ]
    )


def test_orient2d_swaps_flip_and_cyclic_shifts_keep_the_sign():
    rng = np.random.default_rng(9)
    p = _hard_cases2(rng)
    base = np.sign(batch2(p))
    assert np.count_nonzero(base) > 0 and np.count_nonzero(base == 0) > 0
    for perm in itertools.permutations(range(3)):
        parity = 1 if perm in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1
        np.testing.assert_array_equal(np.sign(batch2(p[:, perm])), parity * base)


def test_orient3d_swaps_flip_the_sign():
    rng = np.random.default_rng(10)
    p = _hard_cases3(rng)
    base = np.sign(batch3(p))
    assert np.count_nonzero(base) > 0 and np.count_nonzero(base == 0) > 0
    for perm in itertools.permutations(range(4)):
        inversions = sum(perm[i] > perm[j] for i in range(4) for j in range(i + 1, 4))
        parity = -1 if inversions % 2 else 1
        np.testing.assert_array_equal(np.sign(batch3(p[:, perm])), parity * base)


# ---------------------------------------------------------------------------
# Translation
# ---------------------------------------------------------------------------


def _exactly_translated(p: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """``p + t`` and a mask of the configurations where every translated coordinate is exact."""
    q = p + t
    ft = Fraction(t)
    ok = np.array(
        [all(Fraction(float(y)) == Fraction(float(x)) + ft for x, y in zip(a.ravel(), b.ravel())) for a, b in zip(p, q)]
    )
    return q, ok


@pytest.mark.parametrize("dim", [2, 3])
def test_translation_by_powers_of_two_keeps_the_sign(dim):
    rng = np.random.default_rng(11 + dim)
    if dim == 2:
        p = perturb_one_ulp(rng, collinear_triples(rng, 600, scale=8))
        signs = batch2
    else:
        p = perturb_one_ulp(rng, coplanar_quads(rng, 600, scale=8))
        signs = batch3
    base = np.sign(signs(p))
    assert np.count_nonzero(base) > len(p) // 2
    kept = 0
    for k in (-40, 0, 10, 30):
        for t in (2.0**k, -(2.0**k)):
            # translate only configurations on a grid fine enough for the result to stay exact
            q, ok = _exactly_translated(p, t)
            kept += np.count_nonzero(ok)
            np.testing.assert_array_equal(np.sign(signs(q))[ok], base[ok])
    assert kept > len(p)
