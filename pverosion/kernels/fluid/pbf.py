"""The position-based fluid solver's kernels: density constraint, corrections, velocities, drains.

Part of :mod:`pverosion.kernels.fluid.particle_fluid` (its docstring describes the method).
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels.fluid.collision import _clamp, _plane_push
from pverosion.kernels.fluid.params import _PAIRS, PLANE_REACH

__all__: list[str] = []

# --- position-based fluid ----------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _solid(delta, r, h2, kw):
    """Density of the solid beyond a plane at distance ``delta`` and its derivative along the plane's normal."""
    rho = 0.0
    slope = 0.0
    z = max(delta, 0.0) + r
    for _ in range(2):
        q = h2 - z * z
        if q > 0.0:
            rho += kw * q**4
            slope -= 8.0 * kw * z * q**3
        z += 2.0 * r
    return rho, slope


@njit(cache=True)
def _boundary_density(p, i, r, h2, kw, planes, n_planes, walls, wlo, whi):
    """Density of the boundary planes and walls at particle ``i`` at ``p`` and its gradient with respect to ``p``."""
    rho = 0.0
    gx, gy, gz = 0.0, 0.0, 0.0
    for k in range(n_planes[i]):
        ux, uy, uz = planes[i, k, 0], planes[i, k, 1], planes[i, k, 2]
        w, slope = _solid(ux * p[0] + uy * p[1] + uz * p[2] - planes[i, k, 3], r, h2, kw)
        rho += w
        gx += slope * ux
        gy += slope * uy
        gz += slope * uz
    if walls:
        reach = PLANE_REACH * r
        for a in range(3):
            for side in range(2):
                delta = p[a] - wlo[a] if side == 0 else whi[a] - p[a]
                if delta < reach:
                    w, slope = _solid(delta, r, h2, kw)
                    rho += w
                    g = slope if side == 0 else -slope
                    if a == 0:
                        gx += g
                    elif a == 1:
                        gy += g
                    else:
                        gz += g
    return rho, (gx, gy, gz)


@njit(cache=True, parallel=True)
def _gather(pos, vel, order, x, v):
    """x = pos[order], v = vel[order]."""
    for s in prange(order.shape[0]):
        v3.store(x, s, v3.row(pos, order[s]))
        v3.store(v, s, v3.row(vel, order[s]))


@njit(cache=True, parallel=True, error_model="numpy")
def _predict(pos, vel, gravity, dt, out):
    """out = x + (v + g dt) dt."""
    for i in prange(pos.shape[0]):
        v3.store(out, i, v3.add(v3.row(pos, i), v3.scale(v3.add(v3.row(vel, i), v3.scale(gravity, dt)), dt)))


@njit(cache=True, parallel=True)
def _scatter(order, x, v, touched, pos, vel, contact_face):
    """pos[order] = x, vel[order] = v, contact_face[order] = touched."""
    for s in prange(order.shape[0]):
        i = order[s]
        v3.store(pos, i, v3.row(x, s))
        v3.store(vel, i, v3.row(v, s))
        contact_face[i] = touched[s]


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _lambdas(pos, nbr, count, kern, planes, n_planes, walls, wlo, whi, lam):
    """lambda_i = -w C_i / (sum_k |grad_k C_i|² + eps) of the unilateral density constraint.

    ``kern`` is (r, h, k6, ks, 1 / rho0, eps, kw, 1 / W(dq), tensile k / S, w).
    """
    r, h, k6, ks, inv_rho0, eps, kw, weight = kern[0], kern[1], kern[2], kern[3], kern[4], kern[5], kern[6], kern[9]
    h2 = h * h
    floor = 1e-24 * h2  # coincident particles: zero offset times a finite factor
    for i in prange(pos.shape[0]):
        p = v3.row(pos, i)
        rho, grad = _boundary_density(p, i, r, h2, kw, planes, n_planes, walls, wlo, whi)
        rho += k6 * h2 * h2 * h2
        gx, gy, gz = grad[0] * inv_rho0, grad[1] * inv_rho0, grad[2] * inv_rho0
        sum2 = 0.0
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = p[0] - pos[j, 0], p[1] - pos[j, 1], p[2] - pos[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            q = max(h2 - r2, 0.0)
            rho += k6 * q * q * q
            dist = math.sqrt(max(r2, floor))
            t = max(h - dist, 0.0)
            s = -ks * t * t / dist * inv_rho0  # grad_i W_ij / rho0 = s * d
            gx += s * dx
            gy += s * dy
            gz += s * dz
            sum2 += s * s * r2
        c = rho * inv_rho0 - 1.0
        lam[i] = -weight * c / (sum2 + gx * gx + gy * gy + gz * gz + eps) if c > 0.0 else 0.0


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _corrections(pos, nbr, count, lam, kern, fraction, planes, n_planes, plane_face, walls, wlo, whi, contact,
                 normal, out):
    """out = pos + fraction * (sum_j (lambda_i + lambda_j + s_corr) grad W_ij + lambda_i grad rho_solid) / rho0,
    then pushed to ``r`` in front of the particle's boundary planes and clamped into the walls."""
    r, h, k6, ks, inv_rho0, kw, inv_wdq, tensile = kern[0], kern[1], kern[2], kern[3], kern[4], kern[6], kern[7], kern[8]
    h2 = h * h
    floor = 1e-24 * h2
    for i in prange(pos.shape[0]):
        p = v3.row(pos, i)
        _, grad = _boundary_density(p, i, r, h2, kw, planes, n_planes, walls, wlo, whi)
        li = lam[i]
        dx_sum, dy_sum, dz_sum = grad[0] * li, grad[1] * li, grad[2] * li
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = p[0] - pos[j, 0], p[1] - pos[j, 1], p[2] - pos[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            dist = math.sqrt(max(r2, floor))
            t = max(h - dist, 0.0)
            both = li + lam[j]
            if tensile > 0.0:  # loop-invariant: the loop is compiled both ways
                q = max(h2 - r2, 0.0)
                w = k6 * q * q * q * inv_wdq
                w2 = w * w
                both -= tensile * w2 * w2
            s = -both * ks * t * t / dist
            dx_sum += s * dx
            dy_sum += s * dy
            dz_sum += s * dz
        scale = fraction * inv_rho0
        p, f, u = _plane_push((p[0] + dx_sum * scale, p[1] + dy_sum * scale, p[2] + dz_sum * scale), r, planes,
                              n_planes[i], plane_face, i)
        if f >= 0:
            contact[i] = f
            v3.store(normal, i, u)
        if walls:
            p = _clamp(p, r, wlo, whi)
        v3.store(out, i, p)


@njit(cache=True, parallel=True, fastmath=_PAIRS, error_model="numpy")
def _velocities(pos, start, nbr, count, dt, h, k6, xsph, contact, normal, vel, out):
    """v = (pos - start) / dt (into ``vel``), then XSPH and no into-surface velocity at contacts (into ``out``)."""
    inv_dt = 1.0 / dt
    for i in prange(pos.shape[0]):
        v3.store(vel, i, v3.scale(v3.sub(v3.row(pos, i), v3.row(start, i)), inv_dt))
    h2 = h * h
    for i in prange(pos.shape[0]):
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
        ax, ay, az = 0.0, 0.0, 0.0
        for m in range(count[i]):
            j = nbr[i, m]
            dx, dy, dz = px - pos[j, 0], py - pos[j, 1], pz - pos[j, 2]
            q = max(h2 - dx * dx - dy * dy - dz * dz, 0.0)
            w = k6 * q * q * q
            ax += (vel[j, 0] - vx) * w
            ay += (vel[j, 1] - vy) * w
            az += (vel[j, 2] - vz) * w
        v = (vx + ax * xsph, vy + ay * xsph, vz + az * xsph)
        if contact[i] >= 0:
            n = v3.row(normal, i)
            vn = v3.dot(v, n)
            if vn < 0.0:
                v = v3.sub(v, v3.scale(n, vn))
        v3.store(out, i, v)


@njit(cache=True, parallel=True)
def _drained(pos, lo, hi, outside, planes, boxes, out):
    """Which particles leave: outside [lo, hi] (when ``outside``), past a plane, inside a box, or not finite."""
    for i in prange(pos.shape[0]):
        x, y, z = pos[i, 0], pos[i, 1], pos[i, 2]
        gone = not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z))
        if outside and not (lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]):
            gone = True
        for k in range(planes.shape[0]):
            if planes[k, 0] * x + planes[k, 1] * y + planes[k, 2] * z > planes[k, 3]:
                gone = True
        for k in range(boxes.shape[0]):
            if boxes[k, 0] <= x <= boxes[k, 3] and boxes[k, 1] <= y <= boxes[k, 4] and boxes[k, 2] <= z <= boxes[k, 5]:
                gone = True
        out[i] = gone


@njit(cache=True)
def _uniforms(rng, n):
    """``n`` doubles in [0, 1) from the SplitMix64 state ``rng[0]`` (advanced in place)."""
    out = np.empty(n)
    for k in range(n):
        z = rng[0] + np.uint64(0x9E3779B97F4A7C15)
        rng[0] = z
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
        out[k] = np.float64(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return out
