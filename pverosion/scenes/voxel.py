"""Procedural voxel scenes of Beneš et al. 2006: river meanders, low hill sediment wash, a natural spring."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyvista as pv

from pverosion.filters.voxel import voxel_grid

__all__ = ["Meander", "bank_erosion", "hill_wash_grid", "meander_grid", "spring_grid"]


@dataclass(frozen=True)
class Meander:
    """Shape of a sinuous channel cut into a block, all lengths in voxels.

    The centre line is ``y = y0 + amplitude e(x) sin(2 pi x / wavelength)``,
    where the envelope ``e`` rises smoothly (smoothstep) from 0 to 1 over the
    first ``run_in`` voxels, so the water enters along a straight reach.
    """

    y0: float
    amplitude: float
    wavelength: float
    half_width: float
    run_in: float = 0.0

    def _envelope(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """e(x) and its first two derivatives."""
        x = np.asarray(x, dtype=float)
        if self.run_in <= 0.0:
            return np.ones_like(x), np.zeros_like(x), np.zeros_like(x)
        t = np.clip(x / self.run_in, 0.0, 1.0)
        ramp = (x > 0.0) & (x < self.run_in)
        return (t * t * (3.0 - 2.0 * t), np.where(ramp, 6.0 * t * (1.0 - t) / self.run_in, 0.0),
                np.where(ramp, (6.0 - 12.0 * t) / self.run_in**2, 0.0))

    def centre(self, x: np.ndarray) -> np.ndarray:
        """Channel centre line y(x)."""
        return self.y0 + self.amplitude * self._envelope(x)[0] * np.sin(2 * np.pi * np.asarray(x) / self.wavelength)

    def bend(self, x: np.ndarray) -> np.ndarray:
        """y''(x): the centre of curvature lies on the side of its sign."""
        k = 2 * np.pi / self.wavelength
        e, de, dde = self._envelope(x)
        s, c = np.sin(k * np.asarray(x)), np.cos(k * np.asarray(x))
        return self.amplitude * (dde * s + 2.0 * de * k * c - e * k * k * s)


def meander_grid(shape=(128, 64, 64), *, spacing: float = 0.05, depth: int = 10, half_width: float = 4.0,
                 amplitude: float | None = None, wavelength: float | None = None,
                 water_depth: int | None = None) -> tuple[pv.ImageData, Meander]:
    """A block of material with a sinuous channel, water in it, an inflow at x = 0 and a drain at the far end.

    Parameters
    ----------
    shape : (3,) int, default: (128, 64, 64)
        Voxels along x, y, z; the block fills the lower 60 %.
    spacing : float, default: 0.05
        Voxel edge (m).
    depth : int, default: 10
        Channel depth (voxels).
    half_width : float, default: 4
        Channel half width (voxels).
    amplitude : float, optional
        Meander amplitude (voxels; default an eighth of the grid's width in y).
    wavelength : float, optional
        Meander wavelength (voxels; default two thirds of the grid's length).
        The first half wavelength is a straight run-in that turns smoothly
        into the meanders.
    water_depth : int, optional
        Initial water depth in the channel (default: depth - 2).

    Returns
    -------
    grid : pyvista.ImageData
        Voxel grid with ``material_amount``, ``water``, ``source``, ``drain``.
    meander : Meander
        The channel's shape, to tell outer from inner banks.
    """
    nx, ny, nz = shape
    top = int(0.6 * nz)
    wavelength = nx / 1.5 if wavelength is None else float(wavelength)
    meander = Meander(y0=ny / 2, amplitude=ny / 8 if amplitude is None else amplitude, wavelength=wavelength,
                      half_width=half_width, run_in=wavelength / 2)
    x = np.arange(nx)[:, None]
    y = np.arange(ny)[None, :]
    channel = np.abs(y - meander.centre(x)) < half_width
    amount = np.zeros(shape)
    amount[:, :, :top] = 1.0
    bed = top - depth
    for k in range(bed, top):
        amount[:, :, k][channel] = 0.0
    water_top = bed + (depth - 2 if water_depth is None else water_depth)
    water = np.zeros(shape)
    water[:, :, bed:water_top] = channel[:, :, None]
    source = np.zeros(shape, bool)
    source[1:3, :, bed:water_top] = channel[1:3, :, None]
    drain = np.zeros(shape, bool)
    drain[-3:-1, :, bed:water_top] = channel[-3:-1, :, None]
    return voxel_grid(amount, spacing=spacing, water=water, source=source, drain=drain), meander


def bank_erosion(before: np.ndarray, after: np.ndarray, meander: Meander, *, bend: float = 0.5) -> dict[str, float]:
    """Material removed from the outer and inner banks of a meander's bends (voxel volumes).

    Bank voxels are those outside the channel's original width (the bed is
    not counted). A voxel at (x, y) is on the outer bank when it lies on the
    side of the centre line away from the centre of curvature, and in a bend
    when ``|y''(x)|`` is at least ``bend`` times its largest value.

    Parameters
    ----------
    before, after : numpy.ndarray, shape (nx, ny, nz)
        Material amounts.
    meander : Meander

    Returns
    -------
    dict
        ``outer``, ``inner``: material lost on each side in the bends.
    """
    lost = np.clip(before - after, 0.0, None).sum(axis=2)
    x = np.arange(lost.shape[0])[:, None].astype(float)
    y = np.arange(lost.shape[1])[None, :].astype(float)
    curvature = meander.bend(x)
    in_bend = np.abs(curvature) >= bend * np.abs(curvature).max()
    offset = y - meander.centre(x)
    bank = in_bend & (np.abs(offset) >= meander.half_width)
    outer = float(lost[bank & (offset * curvature < 0)].sum())
    inner = float(lost[bank & (offset * curvature > 0)].sum())
    return {"outer": outer, "inner": inner}


def hill_wash_grid(shape=(64, 48, 40), *, spacing: float = 0.05, rain_rows: int = 2) -> pv.ImageData:
    """A low hill of material with water sources along its crest: water washes sediment down its flanks."""
    nx, ny, nz = shape
    x = np.arange(nx)[:, None] - nx / 2
    y = np.arange(ny)[None, :] - ny / 2
    height = 0.25 * nz + 0.35 * nz * np.exp(-(x**2 / (0.3 * nx) ** 2 + y**2 / (0.35 * ny) ** 2))
    z = np.arange(nz)[None, None, :]
    amount = np.clip(height[:, :, None] - z, 0.0, 1.0)
    crest = np.zeros(shape, bool)
    top = np.ceil(height).astype(int)
    ridge = np.abs(y) <= 1
    for k in range(rain_rows):
        crest[:, :, :][(np.arange(nz)[None, None, :] == (top + k)[:, :, None]) & ridge[:, :, None]] = True
    return voxel_grid(amount, spacing=spacing, source=crest & (amount == 0))


def spring_grid(shape=(64, 48, 40), *, spacing: float = 0.05) -> pv.ImageData:
    """A slope with a spring emerging from its face half way up: water seeps out and cuts a gully."""
    nx, ny, nz = shape
    x = np.arange(nx)[:, None]
    height = np.clip(0.8 * nz - 0.5 * x, 0.15 * nz, None) * np.ones((1, ny))
    z = np.arange(nz)[None, None, :]
    amount = np.clip(height[:, :, None] - z, 0.0, 1.0)
    source = np.zeros(shape, bool)
    i = nx // 3
    k = int(height[i, 0]) - 2
    source[i - 1:i + 1, ny // 2 - 2:ny // 2 + 2, k:k + 2] = True
    face = int(np.ceil((0.8 * nz - k) / 0.5)) + 1  # where the slope's face reaches the spring's level
    amount[i - 1:face, ny // 2 - 2:ny // 2 + 2, k:k + 2] = 0.0  # the outlet the water has found
    return voxel_grid(amount, spacing=spacing, source=source)
