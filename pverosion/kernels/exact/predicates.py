"""Robust geometric predicates: exact signs of the 2-D and 3-D orientation determinants.

The sign of an orientation determinant decides which side of a line or plane
a point lies on. Evaluated naively in floating point, it can come out with the
wrong sign (or zero) for nearly degenerate inputs, which breaks combinatorial
algorithms built on it. The predicates here return a value whose *sign* is the
sign of the determinant evaluated in exact arithmetic on the float64 inputs,
following Shewchuk (1997), "Adaptive precision floating-point arithmetic and
fast robust geometric predicates", Discrete Comput. Geom. 18:305-363.

Method
------
1. **Filter.** The determinant is evaluated in ordinary floating point
   together with a semi-static bound on its rounding error: the "permanent"
   (the same expression with every product replaced by its absolute value)
   times Shewchuk's constant ``ccwerrboundA = (3 + 16 eps) eps`` (2-D) or
   ``o3derrboundA = (7 + 56 eps) eps`` (3-D), with ``eps = 2**-53`` the unit
   round-off of float64. If the computed value is larger in magnitude than the
   bound, its sign is certain and it is returned. This path allocates nothing.
2. **Exact fallback.** Otherwise the determinant is evaluated exactly as a
   floating-point *expansion*: a sum of float64 components, ordered by
   increasing magnitude and nonoverlapping, whose exact sum is the determinant.
   The building blocks are error-free transformations: ``two_sum`` and
   ``two_diff`` (Knuth), ``two_product`` (Dekker, splitting each factor in two
   26-bit halves with the splitter ``2**27 + 1``), then sums of expansions
   (merge by magnitude followed by a chain of ``two_sum``) and products of an
   expansion by a float (``scale_expansion``), with zero components dropped.
   The coordinate differences are themselves two-component expansions, so no
   rounding happens anywhere. The sign of a nonoverlapping expansion is the
   sign of its largest (last) component. Shewchuk's intermediate adaptive
   stages B-D are not implemented: the fallback goes straight to the exact
   value. It is compiled once, as a C callback (a numba ``cfunc``) that the
   predicates call by its symbol name, so the kernels that use the predicates
   do not each compile a copy of it.

Range of exactness
------------------
The signs are exact when no intermediate result overflows or underflows, which
is guaranteed when every input is zero or has magnitude in
``[2**-300, 2**300]`` (about ``4.9e-91`` to ``2.0e90``): all inputs are then
integer multiples of ``2**-352``, so every intermediate value (up to products
of three coordinate differences) is a multiple of ``2**-1056``: either large
enough for the usual relative rounding-error model, or so small that it is
exactly representable (a multiple of the smallest subnormal ``2**-1074``).
No intermediate value exceeds about ``2**910``. Inputs a few decades outside
this range almost always still work, but are not guaranteed; for example
``orient2d(0, 5e-324, 2**-30, 0, 0, 0)`` is exactly ``-5e-324 * 2**-30``,
which underflows, and the predicate returns ``0.0``.
Results for infinite or NaN inputs are unspecified.

Rounding must be IEEE round-to-nearest-even without fused multiply-add
contraction, which is what numba produces unless ``fastmath`` is enabled;
these functions must not be compiled with ``fastmath``.
"""

from __future__ import annotations

import math

import llvmlite.binding as llvm
import numpy as np
from numba import cfunc, float64, int64, types

from pverosion.kernels._jit import njit

__all__ = [
    "CCW_ERRBOUND_A",
    "EPSILON",
    "O3D_ERRBOUND_A",
    "SPLITTER",
    "orient2d",
    "orient2d_batch",
    "orient3d",
    "orient3d_batch",
    "sign_orient2d",
    "sign_orient3d",
]

EPSILON = 2.0**-53
"""Unit round-off of float64: ``|fl(x op y) - (x op y)| <= EPSILON |x op y|`` without underflow."""

SPLITTER = 2.0**27 + 1.0
"""Dekker's splitter: ``SPLITTER * a`` cuts a float64 into two halves of at most 26 significant bits each."""

CCW_ERRBOUND_A = (3.0 + 16.0 * EPSILON) * EPSILON
"""Relative error bound of the floating-point 2-D orientation determinant (Shewchuk's ``ccwerrboundA``)."""

O3D_ERRBOUND_A = (7.0 + 56.0 * EPSILON) * EPSILON
"""Relative error bound of the floating-point 3-D orientation determinant (Shewchuk's ``o3derrboundA``)."""

# Explicit signatures: every argument is converted to float64 (so integer
# arguments never select integer arithmetic) and one compiled version serves all.
_ORIENT2D_SIG = float64(*(6 * (float64,)))
_ORIENT3D_SIG = float64(*(12 * (float64,)))
_SIGN2D_SIG = int64(*(6 * (float64,)))
_SIGN3D_SIG = int64(*(12 * (float64,)))


# ---------------------------------------------------------------------------
# Error-free transformations of two floats
# ---------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _two_sum(a: float, b: float) -> tuple[float, float]:
    """``(s, e)`` with ``s = fl(a + b)`` and ``s + e == a + b`` exactly (Knuth; any magnitudes)."""
    s = a + b
    b_virtual = s - a
    a_virtual = s - b_virtual
    return s, (a - a_virtual) + (b - b_virtual)


@njit(cache=True, inline="always")
def _two_diff(a: float, b: float) -> tuple[float, float]:
    """``(d, e)`` with ``d = fl(a - b)`` and ``d + e == a - b`` exactly."""
    d = a - b
    b_virtual = a - d
    a_virtual = d + b_virtual
    return d, (a - a_virtual) + (b_virtual - b)


@njit(cache=True, inline="always")
def _split(a: float) -> tuple[float, float]:
    """``(hi, lo)`` with ``hi + lo == a``, each of at most 26 significant bits (Dekker)."""
    c = SPLITTER * a
    big = c - a
    hi = c - big
    return hi, a - hi


@njit(cache=True, inline="always")
def _two_product_presplit(a: float, b: float, b_hi: float, b_lo: float) -> tuple[float, float]:
    """``(p, e)`` with ``p = fl(a * b)`` and ``p + e == a * b`` exactly; ``b_hi, b_lo = _split(b)``."""
    p = a * b
    a_hi, a_lo = _split(a)
    err = p - a_hi * b_hi
    err = err - a_lo * b_hi
    err = err - a_hi * b_lo
    return p, a_lo * b_lo - err


@njit(cache=True, inline="always")
def _two_product(a: float, b: float) -> tuple[float, float]:
    """``(p, e)`` with ``p = fl(a * b)`` and ``p + e == a * b`` exactly (Dekker)."""
    b_hi, b_lo = _split(b)
    return _two_product_presplit(a, b, b_hi, b_lo)


# ---------------------------------------------------------------------------
# Expansion arithmetic. All expansions of one evaluation live in a single
# float64 work array ``w``; an expansion is ``w[e : e + n]`` (an offset and a
# length): nonzero components sorted by increasing magnitude and
# nonoverlapping (a single 0.0 stands for zero). Every routine returns the
# length of its output; outputs never overlap inputs. Offsets into one array,
# rather than array views, keep the slow path free of reference counting.
# ---------------------------------------------------------------------------


@njit(cache=True)
def _diff_expansion(a: float, b: float, w: np.ndarray, h: int) -> int:
    """Write ``a - b`` as an expansion of length 1 or 2 at ``w[h]``."""
    d, err = _two_diff(a, b)
    if err == 0.0:
        w[h] = d
        return 1
    w[h] = err
    w[h + 1] = d
    return 2


@njit(cache=True)
def _expansion_sum(w: np.ndarray, e: int, elen: int, f: int, flen: int, h: int) -> int:
    """Write the expansion ``e + f`` at ``w[h]`` (room for ``elen + flen`` components).

    The components of both inputs are merged by increasing magnitude and
    accumulated with a chain of ``two_sum``; every rounding error that is not
    zero becomes an output component, and the final running sum the largest
    one (Shewchuk's FAST-EXPANSION-SUM with zero elimination; it keeps the
    output nonoverlapping under round-to-nearest-even).
    """
    i = e
    i_end = e + elen
    j = f
    j_end = f + flen
    if abs(w[i]) <= abs(w[j]):
        q = w[i]
        i += 1
    else:
        q = w[j]
        j += 1
    n = np.int64(0)
    while i < i_end or j < j_end:
        if j >= j_end or (i < i_end and abs(w[i]) <= abs(w[j])):
            g = w[i]
            i += 1
        else:
            g = w[j]
            j += 1
        q, err = _two_sum(q, g)
        if err != 0.0:
            w[h + n] = err
            n += 1
    if q != 0.0 or n == 0:
        w[h + n] = q
        n += 1
    return n


@njit(cache=True)
def _scale_expansion(w: np.ndarray, e: int, elen: int, b: float, h: int) -> int:
    """Write the expansion ``b * e`` at ``w[h]`` (room for ``2 * elen`` components)."""
    b_hi, b_lo = _split(b)
    q, err = _two_product_presplit(w[e], b, b_hi, b_lo)
    n = 0
    if err != 0.0:
        w[h] = err
        n = 1
    for i in range(e + 1, e + elen):
        p, p_err = _two_product_presplit(w[i], b, b_hi, b_lo)
        s, err = _two_sum(q, p_err)
        if err != 0.0:
            w[h + n] = err
            n += 1
        q, err = _two_sum(p, s)
        if err != 0.0:
            w[h + n] = err
            n += 1
    if q != 0.0 or n == 0:
        w[h + n] = q
        n += 1
    return n


@njit(cache=True)
def _product_expansion(w: np.ndarray, e: int, elen: int, f: int, flen: int, h: int, t: int) -> int:
    """Write the expansion ``e * f`` at ``w[h]`` for an ``f`` of length 1 or 2.

    Needs room for ``2 * elen * flen`` components at ``h`` and ``4 * elen``
    of scratch at ``t``.
    """
    if flen == 1:
        return _scale_expansion(w, e, elen, w[f], h)
    t1 = t + 2 * elen
    n0 = _scale_expansion(w, e, elen, w[f], t)
    n1 = _scale_expansion(w, e, elen, w[f + 1], t1)
    return _expansion_sum(w, t, n0, t1, n1, h)


@njit(cache=True)
def _minor2(
    w: np.ndarray, a: int, alen: int, b: int, blen: int, c: int, clen: int, d: int, dlen: int, h: int, t: int
) -> int:
    """Write ``a * b - c * d`` for expansions of length <= 2 at ``w[h]`` (room for 16); 24 of scratch at ``t``."""
    p = t
    r = t + 8
    n_p = _product_expansion(w, a, alen, b, blen, p, t + 16)
    n_r = _product_expansion(w, c, clen, d, dlen, r, t + 16)
    for i in range(r, r + n_r):
        w[i] = -w[i]
    return _expansion_sum(w, p, n_p, r, n_r, h)


@njit(cache=True)
def _estimate(w: np.ndarray, e: int, n: int) -> float:
    """An approximation of the value of the expansion ``w[e : e + n]`` that has its exact sign.

    The sign of a nonoverlapping expansion is the sign of its largest
    component; the rounded sum of the components is returned when it has
    that sign (it always should), the largest component otherwise.
    """
    top = w[e + n - 1]
    total = 0.0
    for i in range(e, e + n):
        total += w[i]
    if (total > 0.0 and top > 0.0) or (total < 0.0 and top < 0.0):
        return total
    return top


# ---------------------------------------------------------------------------
# Exact evaluations (slow path)
# ---------------------------------------------------------------------------


@njit(cache=True)
def _opaque_zero(x: float) -> int:
    """0, or 1 if ``x`` is NaN: a base offset for the work arrays that LLVM cannot constant-fold.

    With literal offsets LLVM specialises the inlined expansion loops so
    aggressively that compiling ``_exact_orient3d`` takes ~10 s instead of
    ~0.5 s, for no gain at run time. The work arrays have one spare slot.
    """
    return 1 if math.isnan(x) else 0


@cfunc(_ORIENT2D_SIG, cache=True)
def _exact_orient2d(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    """Exact ``det[[ax-cx, ay-cy], [bx-cx, by-cy]]``, returned as a float with the exact sign."""
    o = _opaque_zero(ax)
    # layout: differences at o, o + 2, o + 4, o + 6; result (16) at o + 8; scratch (24) at o + 24
    w = np.empty(49)
    n_acx = _diff_expansion(ax, cx, w, o)
    n_acy = _diff_expansion(ay, cy, w, o + 2)
    n_bcx = _diff_expansion(bx, cx, w, o + 4)
    n_bcy = _diff_expansion(by, cy, w, o + 6)
    n = _minor2(w, o, n_acx, o + 6, n_bcy, o + 2, n_acy, o + 4, n_bcx, o + 8, o + 24)
    return _estimate(w, o + 8, n)


@cfunc(_ORIENT3D_SIG, cache=True)
def _exact_orient3d(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    cx: float,
    cy: float,
    cz: float,
    dx: float,
    dy: float,
    dz: float,
) -> float:
    """Exact ``det[[a-d], [b-d], [c-d]]``, returned as a float with the exact sign.

    Expanded along the z column: ``adz * m_bc + bdz * m_ca + cdz * m_ab`` with
    the 2x2 minors ``m_bc = bdx*cdy - cdx*bdy``, ``m_ca = cdx*ady - adx*cdy``,
    ``m_ab = adx*bdy - bdx*ady``. Lengths: differences <= 2, minors <= 16,
    terms <= 64, total <= 192 components.
    """
    # layout of the work array (sizes in the comments)
    o = _opaque_zero(ax)
    adx, ady, adz = o, o + 2, o + 4  # 2 each
    bdx, bdy, bdz = o + 6, o + 8, o + 10
    cdx, cdy, cdz = o + 12, o + 14, o + 16
    m_bc, m_ca, m_ab = o + 18, o + 34, o + 50  # 16 each
    scratch = o + 66  # 64
    u = o + 130  # 64
    v = o + 194  # 64
    uv = o + 258  # 128
    total = o + 386  # 192
    w = np.empty(579)

    n_adx = _diff_expansion(ax, dx, w, adx)
    n_ady = _diff_expansion(ay, dy, w, ady)
    n_adz = _diff_expansion(az, dz, w, adz)
    n_bdx = _diff_expansion(bx, dx, w, bdx)
    n_bdy = _diff_expansion(by, dy, w, bdy)
    n_bdz = _diff_expansion(bz, dz, w, bdz)
    n_cdx = _diff_expansion(cx, dx, w, cdx)
    n_cdy = _diff_expansion(cy, dy, w, cdy)
    n_cdz = _diff_expansion(cz, dz, w, cdz)

    n_bc = _minor2(w, bdx, n_bdx, cdy, n_cdy, cdx, n_cdx, bdy, n_bdy, m_bc, scratch)
    n_ca = _minor2(w, cdx, n_cdx, ady, n_ady, adx, n_adx, cdy, n_cdy, m_ca, scratch)
    n_ab = _minor2(w, adx, n_adx, bdy, n_bdy, bdx, n_bdx, ady, n_ady, m_ab, scratch)

    n_u = _product_expansion(w, m_bc, n_bc, adz, n_adz, u, scratch)
    n_v = _product_expansion(w, m_ca, n_ca, bdz, n_bdz, v, scratch)
    n_uv = _expansion_sum(w, u, n_u, v, n_v, uv)
    n_u = _product_expansion(w, m_ab, n_ab, cdz, n_cdz, u, scratch)
    n = _expansion_sum(w, uv, n_uv, u, n_u, total)
    return _estimate(w, total, n)


# The kernels call the exact evaluations through these symbols: a call to a
# numba function would link and optimise a copy of the expansion arithmetic
# into every kernel that uses a predicate (0.1 to 0.15 CPU s each on a cold
# cache); a symbol is resolved once, like a C library function.
llvm.add_symbol("pverosion_orient2d_exact", _exact_orient2d.address)
llvm.add_symbol("pverosion_orient3d_exact", _exact_orient3d.address)
_exact_orient2d_by_name = types.ExternalFunction("pverosion_orient2d_exact", _ORIENT2D_SIG)
_exact_orient3d_by_name = types.ExternalFunction("pverosion_orient3d_exact", _ORIENT3D_SIG)


# ---------------------------------------------------------------------------
# Public predicates
# ---------------------------------------------------------------------------


@njit(_ORIENT2D_SIG, cache=True)
def orient2d(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    """Orientation of three points in the plane, with an exact sign.

    Parameters
    ----------
    ax, ay, bx, by, cx, cy : float
        Coordinates of the points ``a``, ``b`` and ``c``.

    Returns
    -------
    float
        A value whose sign is exactly the sign of
        ``det[[ax - cx, ay - cy], [bx - cx, by - cy]]``, i.e. of the z component
        of ``(b - a) x (c - a)``, evaluated in exact arithmetic: positive when
        ``a, b, c`` turn counter-clockwise (x to the right, y up), negative
        when clockwise, exactly zero when collinear. The magnitude is an
        approximation of the determinant (twice the signed triangle area).

    Notes
    -----
    Compiled for float64 arguments only; others (e.g. Python ints) are
    converted. Exact for inputs that are zero or of magnitude in
    ``[2**-300, 2**300]`` (see the module docstring). Allocation-free unless
    the floating-point filter fails, i.e. for nearly or exactly collinear
    points.
    """
    detleft = (ax - cx) * (by - cy)
    detright = (ay - cy) * (bx - cx)
    det = detleft - detright
    # The computed products have the signs of the exact ones (no underflow in
    # the guaranteed range): when they differ, or detleft is zero, the sign of
    # det is already exact.
    if detleft > 0.0:
        if detright <= 0.0:
            return det
        detsum = detleft + detright
    elif detleft < 0.0:
        if detright >= 0.0:
            return det
        detsum = -detleft - detright
    else:
        return det
    errbound = CCW_ERRBOUND_A * detsum
    if det >= errbound or -det >= errbound:
        return det
    return _exact_orient2d_by_name(ax, ay, bx, by, cx, cy)


@njit(_ORIENT3D_SIG, cache=True)
def orient3d(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    cx: float,
    cy: float,
    cz: float,
    dx: float,
    dy: float,
    dz: float,
) -> float:
    """Orientation of four points in space, with an exact sign (Shewchuk's convention).

    Parameters
    ----------
    ax, ay, az, bx, by, bz, cx, cy, cz : float
        Coordinates of the points ``a``, ``b``, ``c`` spanning the plane.
    dx, dy, dz : float
        Coordinates of the query point ``d``.

    Returns
    -------
    float
        A value whose sign is exactly the sign of ``det[[a - d], [b - d], [c - d]]``
        (rows are the 3-vectors ``a - d`` etc.) evaluated in exact arithmetic.
        This determinant equals ``-n . (d - a)`` with ``n = (b - a) x (c - a)``,
        the right-handed normal of the triangle ``a, b, c``: the result is

        - **positive** when ``d`` lies on the side opposite to ``n``, i.e.
          below the plane when ``a, b, c`` appear counter-clockwise seen
          from above (``orient3d(0,0,0, 1,0,0, 0,1,0, 0,0,-1) > 0``);
        - **negative** when ``d`` lies on the side ``n`` points to (in front
          of a face whose vertices are ordered counter-clockwise as seen by
          the viewer, e.g. outside a closed mesh with outward normals);
        - **exactly zero** when the four points are coplanar.

        It is ``-6`` times the signed volume of the tetrahedron ``a, b, c, d``
        (``(b - a) . ((c - a) x (d - a)) / 6``). The magnitude is an
        approximation of the determinant.

    Notes
    -----
    Compiled for float64 arguments only; others (e.g. Python ints) are
    converted. Exact for inputs that are zero or of magnitude in
    ``[2**-300, 2**300]`` (see the module docstring). Allocation-free unless
    the floating-point filter fails, i.e. for nearly or exactly coplanar
    points. Coplanar points that make every product in the floating-point
    evaluation zero (for example all four at the same z, or the same x) are
    answered without the exact evaluation.
    """
    adx = ax - dx
    bdx = bx - dx
    cdx = cx - dx
    ady = ay - dy
    bdy = by - dy
    cdy = cy - dy
    adz = az - dz
    bdz = bz - dz
    cdz = cz - dz

    bdxcdy = bdx * cdy
    cdxbdy = cdx * bdy
    cdxady = cdx * ady
    adxcdy = adx * cdy
    adxbdy = adx * bdy
    bdxady = bdx * ady

    det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady)
    permanent = (
        (abs(bdxcdy) + abs(cdxbdy)) * abs(adz)
        + (abs(cdxady) + abs(adxcdy)) * abs(bdz)
        + (abs(adxbdy) + abs(bdxady)) * abs(cdz)
    )
    errbound = O3D_ERRBOUND_A * permanent
    if det > errbound or -det > errbound:
        return det
    if permanent == 0.0:
        # Every computed product is zero, so (without underflow) every exact
        # product is zero too and the determinant is exactly zero.
        return 0.0
    return _exact_orient3d_by_name(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz)


@njit(_SIGN2D_SIG, cache=True)
def sign_orient2d(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> int:
    """Exact sign of :func:`orient2d`: 1 (counter-clockwise), -1 (clockwise) or 0 (collinear).

    Parameters
    ----------
    ax, ay, bx, by, cx, cy : float
        Coordinates of the points ``a``, ``b`` and ``c``.

    Returns
    -------
    int
        ``sign(det[[ax - cx, ay - cy], [bx - cx, by - cy]])`` in exact arithmetic.
    """
    d = orient2d(ax, ay, bx, by, cx, cy)
    if d > 0.0:
        return 1
    if d < 0.0:
        return -1
    return 0


@njit(_SIGN3D_SIG, cache=True)
def sign_orient3d(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    cx: float,
    cy: float,
    cz: float,
    dx: float,
    dy: float,
    dz: float,
) -> int:
    """Exact sign of :func:`orient3d`: 1, -1 or 0 (coplanar).

    Parameters
    ----------
    ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz : float
        Coordinates of the points ``a``, ``b``, ``c`` and ``d``.

    Returns
    -------
    int
        ``sign(det[[a - d], [b - d], [c - d]])`` in exact arithmetic: 1 when
        ``d`` is on the side opposite to the normal ``(b - a) x (c - a)``,
        -1 on the side of the normal, 0 when the points are coplanar.
    """
    d = orient3d(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz)
    if d > 0.0:
        return 1
    if d < 0.0:
        return -1
    return 0


@njit(cache=True)
def orient2d_batch(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """:func:`orient2d` of corresponding rows of three (N, 2) float64 arrays.

    Parameters
    ----------
    a, b, c : numpy.ndarray
        (N, 2) float64 point arrays.

    Returns
    -------
    numpy.ndarray
        (N,) float64, each with the exact sign of its orientation determinant.
    """
    n = a.shape[0]
    out = np.empty(n)
    for i in range(n):
        out[i] = orient2d(a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1])
    return out


@njit(cache=True)
def orient3d_batch(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """:func:`orient3d` of corresponding rows of four (N, 3) float64 arrays.

    Parameters
    ----------
    a, b, c, d : numpy.ndarray
        (N, 3) float64 point arrays.

    Returns
    -------
    numpy.ndarray
        (N,) float64, each with the exact sign of its orientation determinant.
    """
    n = a.shape[0]
    out = np.empty(n)
    for i in range(n):
        out[i] = orient3d(
            a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2], c[i, 0], c[i, 1], c[i, 2], d[i, 0], d[i, 1], d[i, 2]
        )
    return out
