"""The displacement of one weathering step (Skorkovská 2019, eqs. 3-5), in a module of its own.

The step kernel lives apart from :mod:`~pverosion.kernels.weathering.model`
so that a process compiling it ahead of the stage
(:mod:`pverosion._precompile`) imports it without the solver and its
dependencies.
"""

from __future__ import annotations

import numpy as np

from pverosion.kernels import _vec3 as v3
from pverosion.kernels._jit import njit
from pverosion.kernels._threads import for_ranges
from pverosion.kernels.tolerances import FLAT_CURVATURE, ZERO_DIRECTION

__all__ = ["displace"]


@njit(cache=True, error_model="numpy")
def _ring_offset(points, ring_ptr, ring_idx, i):
    """Uniform Laplacian of vertex ``i``: the mean of its one-ring minus the vertex, summed neighbour by neighbour
    as :func:`~pverosion.kernels.mesh.laplacian.laplacian_vectors` sums it (zero without neighbours)."""
    first, last = ring_ptr[i], ring_ptr[i + 1]
    if last == first:
        return (0.0, 0.0, 0.0)
    x = y = z = 0.0
    for s in range(first, last):
        j = ring_idx[s]
        x += points[j, 0]
        y += points[j, 1]
        z += points[j, 2]
    n = last - first
    return (x / n - points[i, 0], y / n - points[i, 1], z / n - points[i, 2])


@njit(cache=True, error_model="numpy", nogil=True)
def _displace_range(points, direction, ring_ptr, ring_idx, unit, h_norm, h_raw, e_avg, power, length, factor,
                    erodibility, fixed, displacement, out, start, stop):
    """Steps of vertices ``start`` to ``stop`` (see :func:`displace`), written to ``out`` and added to
    ``displacement``; the direction is a row of ``direction`` or, when ``ring_ptr`` has entries, the uniform
    Laplacian from the one-ring CSR."""
    along_ring = ring_ptr.shape[0] > 0
    uniform = erodibility.shape[0] == 0
    for i in range(start, stop):
        if (fixed[i] or h_norm[i] <= 0.0 or h_raw[i] * e_avg <= FLAT_CURVATURE or factor[i] == 0.0
                or (not uniform and erodibility[i] == 0.0)):
            continue
        vec = _ring_offset(points, ring_ptr, ring_idx, i) if along_ring else v3.row(direction, i)
        if unit:
            size = v3.norm(vec)
            # no direction: flatter than FLAT_CURVATURE, or within the rounding of the vertex's coordinates
            reach = FLAT_CURVATURE * e_avg
            for d in range(3):
                noise = ZERO_DIRECTION * abs(points[i, d])
                reach = noise if noise > reach else reach
            if size <= reach:
                continue
            vec = v3.scale(vec, 1.0 / size)
        # x ** 1.0 is x exactly: the default power skips the call of pow, the slowest part of the loop
        weight = h_norm[i] if power == 1.0 else h_norm[i] ** power
        rate = weight if uniform else weight * erodibility[i]
        step = v3.scale(vec, min(rate, 1.0) * length * factor[i])  # at most ``length`` times the factor
        v3.store(out, i, v3.add(v3.row(points, i), step))
        for d in range(3):
            displacement[i, d] += step[d]


def displace(points, direction, unit, h_norm, h_raw, e_avg, power, length, factor, fixed, displacement, *,
             ring=None, erodibility=None):
    """Points after one step along ``direction`` (made unit length when ``unit``).

    A moving vertex ``i`` steps ``min(h_norm[i] ** power * erodibility[i], 1) * length * factor[i]``: never
    more than ``length`` times its ``factor`` (the guard's slowing down), however large its erodibility
    (a soft material, or a :class:`~pverosion.kernels.materials.field.Gradual` falloff, gives values above
    1); ``erodibility`` None is 1 everywhere.
    Adds each vertex's step to ``displacement`` in place. With ``ring``, the
    one-ring CSR ``(ring_ptr, ring_idx)`` of
    :func:`~pverosion.kernels.mesh.topology.one_ring`, ``direction`` is None
    and each moving vertex steps along its uniform Laplacian, bit for bit
    :func:`~pverosion.kernels.mesh.laplacian.laplacian_vectors`, computed
    for the moving vertices only.
    """
    if ring is None:
        ring_ptr = ring_idx = np.zeros(0, np.int64)
    else:
        ring_ptr, ring_idx = ring
        direction = np.zeros((0, 3))
    rate = np.zeros(0) if erodibility is None else np.ascontiguousarray(erodibility, dtype=np.float64)
    out = points.copy()
    for_ranges(_displace_range, points.shape[0], points, direction, ring_ptr, ring_idx, unit, h_norm, h_raw, e_avg,
               power, length, factor, rate, fixed, displacement, out)
    return out
