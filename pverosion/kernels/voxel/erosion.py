"""Erosion and deposition at the water/material interface of a voxel grid (Beneš et al. 2006).

Voxel classes follow the slides: MAT cells hold material ``m`` in (0, 1]
(``amount``), FULL cells hold water (liquid cells of
:class:`~pverosion.kernels.voxel.fluid.VoxelFluid`) and dissolved material
``C``, EMPTY cells hold air. Every step exchanges material between each wet
cell (water fraction at least ``WET_FRACTION``, so thin films running down a
slope count) and its face-adjacent MAT cells:

- **cohesive** (Langendoen): ``E = e (tau / tau_ce - 1)`` when
  ``tau > tau_ce``, ``D = omega d (1 - tau / tau_cd)`` when ``tau < tau_cd``,
  with the bed shear stress ``tau = f rho U^2 / 2`` from the speed ``U`` at
  the liquid cell; ``dC/dt = E - D`` by explicit Euler.
- **cohesionless**: ``E - D = (C_hat - C) / T`` with the equilibrium load
  ``C_hat = min(k |u|, c_max)``.

Erosion takes material from the adjacent MAT cells in proportion to their
erodibility (from the material field); deposition puts it on adjacent MAT
cells with room, four times preferring the one below (material settles).
A MAT cell whose material reaches 0 becomes an open (FULL/EMPTY) cell; a
liquid cell whose dissolved load exceeds ``c_max`` becomes a MAT cell
holding ``c_max``, its excess spread over the adjacent open cells and its
water moved up. Every transfer is done by gathering per cell (no races, the
same result for any thread count), and the material is conserved to
round-off: solid + dissolved stays constant apart from what drains remove.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import prange

from pverosion.kernels._jit import njit
from pverosion.kernels.solver.protocol import SolverLoop
from pverosion.kernels.voxel.fluid import VoxelFluid, cell_velocity

__all__ = ["MODELS", "WET_FRACTION", "ErosionParameters", "VoxelErosionSolver", "erosion_step"]

MODELS = ("cohesive", "cohesionless")

WET_FRACTION = 0.1
"""Cells holding at least this fraction of water exchange material (films on slopes included)."""
_NEIGHBOURS = ((-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1))
_BELOW_WEIGHT = 4.0  # deposition onto the MAT cell below counts this many side cells


@dataclass(frozen=True)
class ErosionParameters:
    """Constants of the erosion–deposition models (defaults from the slides where they give them).

    Attributes
    ----------
    model : {"cohesive", "cohesionless"}
    erosion_rate : float, default: 0.01
        e, cohesive erosion-rate constant (material per second).
    deposition_rate : float, default: 0.01
        d, cohesive deposition-rate constant.
    fall_velocity : float, default: 0.2
        omega, fall velocity of particles within the water.
    tau_erosion, tau_deposition : float, default: 10.0
        tau_ce (shear strength of the material) and tau_cd (below it particles deposit), Pa.
    friction : float, default: 0.05
        f in tau = f rho U^2 / 2 (the slides leave it open).
    density : float, default: 1000.0
        Water density rho (kg/m³).
    capacity : float, default: 0.7
        k in ``C_hat = min(k |u|, c_max)`` (cohesionless), per m/s.
    saturation : float, default: 0.5
        c_max, the most dissolved material a water cell holds; above it the cell becomes material.
    time_scale : float, default: 1.0
        T, adjustment time of the cohesionless load (s).
    """

    model: str = "cohesive"
    erosion_rate: float = 0.01
    deposition_rate: float = 0.01
    fall_velocity: float = 0.2
    tau_erosion: float = 10.0
    tau_deposition: float = 10.0
    friction: float = 0.05
    density: float = 1000.0
    capacity: float = 0.7
    saturation: float = 0.5
    time_scale: float = 1.0

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}; got {self.model!r}")
        for name in ("erosion_rate", "deposition_rate", "fall_velocity", "friction", "density", "capacity"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0; got {getattr(self, name)!r}")
        for name in ("tau_erosion", "tau_deposition", "time_scale"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0; got {getattr(self, name)!r}")
        if not 0.0 < self.saturation <= 1.0:
            raise ValueError(f"saturation must be in (0, 1]; got {self.saturation!r}")


@njit(cache=True, inline="always")
def _inside(shape, i, j, k):
    return 0 <= i < shape[0] and 0 <= j < shape[1] and 0 <= k < shape[2]


@njit(cache=True, parallel=True, error_model="numpy")
def _rates(liquid, amount, water, load, speed, cohesive, e, d, omega, tau_ce, tau_cd, friction, rho, k_cap, c_max,
           t_scale):
    """Erosion and deposition rates (material per second) of each liquid cell touching material."""
    nx, ny, nz = liquid.shape
    ero = np.zeros((nx, ny, nz))
    dep = np.zeros((nx, ny, nz))
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if not liquid[i, j, k]:
                    continue
                touches = False
                for di, dj, dk in _NEIGHBOURS:
                    p, q, r = i + di, j + dj, k + dk
                    if _inside(liquid.shape, p, q, r) and amount[p, q, r] > 0.0:
                        touches = True
                if not touches:
                    continue
                u = speed[i, j, k]
                if cohesive:
                    tau = 0.5 * friction * rho * u * u
                    if tau > tau_ce:
                        ero[i, j, k] = e * (tau / tau_ce - 1.0)
                    if tau < tau_cd:
                        dep[i, j, k] = omega * d * (1.0 - tau / tau_cd)
                else:
                    conc = load[i, j, k] / water[i, j, k] if water[i, j, k] > 0.0 else 0.0
                    rate = (min(k_cap * u, c_max) - conc) / t_scale
                    if rate > 0.0:
                        ero[i, j, k] = rate
                    else:
                        dep[i, j, k] = -rate
    return ero, dep


@njit(cache=True, parallel=True, error_model="numpy")
def _erode(liquid, amount, erodibility, load, ero, dt):
    """Move eroded material from MAT cells into the adjacent liquid cells; return what each cell gained (nx, ny, nz)."""
    nx, ny, nz = liquid.shape
    ratio = np.zeros((nx, ny, nz))
    taken = np.zeros((nx, ny, nz))
    for i in prange(nx):  # each MAT cell: what its liquid neighbours ask, limited by what it holds
        for j in range(ny):
            for k in range(nz):
                if amount[i, j, k] <= 0.0 or erodibility[i, j, k] <= 0.0:
                    continue
                demand = 0.0
                for di, dj, dk in _NEIGHBOURS:
                    p, q, r = i + di, j + dj, k + dk
                    if _inside(liquid.shape, p, q, r) and liquid[p, q, r]:
                        demand += ero[p, q, r] * dt * erodibility[i, j, k]
                if demand > 0.0:
                    ratio[i, j, k] = min(1.0, amount[i, j, k] / demand)
                    taken[i, j, k] = demand * ratio[i, j, k]
    gained = np.zeros((nx, ny, nz))
    for i in prange(nx):  # each liquid cell: what it received
        for j in range(ny):
            for k in range(nz):
                if not liquid[i, j, k] or ero[i, j, k] <= 0.0:
                    continue
                total = 0.0
                for di, dj, dk in _NEIGHBOURS:
                    p, q, r = i + di, j + dj, k + dk
                    if _inside(liquid.shape, p, q, r) and ratio[p, q, r] > 0.0:
                        total += ero[i, j, k] * dt * erodibility[p, q, r] * ratio[p, q, r]
                gained[i, j, k] = total
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                load[i, j, k] += gained[i, j, k]
                amount[i, j, k] = max(amount[i, j, k] - taken[i, j, k], 0.0)
    return gained


@njit(cache=True, inline="always")
def _weight(amount, shape, p, q, r, dk):
    """Deposition weight of the neighbour (p, q, r) at vertical offset dk: room in a MAT cell, below preferred."""
    if not _inside(shape, p, q, r) or amount[p, q, r] <= 0.0 or amount[p, q, r] >= 1.0 or dk > 0:
        return 0.0
    return _BELOW_WEIGHT if dk < 0 else 1.0


@njit(cache=True, parallel=True, error_model="numpy")
def _deposit(liquid, amount, load, dep, dt):
    """Settle dissolved material onto adjacent MAT cells with room; return what each cell received (nx, ny, nz)."""
    nx, ny, nz = liquid.shape
    shape = liquid.shape
    wanted = np.zeros((nx, ny, nz))  # per liquid cell, what it sends (before the acceptors' limits)
    weight_sum = np.zeros((nx, ny, nz))
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if not liquid[i, j, k] or dep[i, j, k] <= 0.0 or load[i, j, k] <= 0.0:
                    continue
                total = 0.0
                for di, dj, dk in _NEIGHBOURS:
                    total += _weight(amount, shape, i + di, j + dj, k + dk, dk)
                if total > 0.0:
                    wanted[i, j, k] = min(dep[i, j, k] * dt, load[i, j, k])
                    weight_sum[i, j, k] = total
    accept = np.zeros((nx, ny, nz))
    received = np.zeros((nx, ny, nz))
    for i in prange(nx):  # each MAT cell: accepted fraction of what comes in
        for j in range(ny):
            for k in range(nz):
                if amount[i, j, k] <= 0.0 or amount[i, j, k] >= 1.0:
                    continue
                incoming = 0.0
                for di, dj, dk in _NEIGHBOURS:
                    p, q, r = i + di, j + dj, k + dk
                    if _inside(shape, p, q, r) and wanted[p, q, r] > 0.0:
                        incoming += wanted[p, q, r] * _weight(amount, shape, i, j, k, -dk) / weight_sum[p, q, r]
                if incoming > 0.0:
                    accept[i, j, k] = min(1.0, (1.0 - amount[i, j, k]) / incoming)
                    received[i, j, k] = incoming * accept[i, j, k]
    sent = np.zeros((nx, ny, nz))
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if wanted[i, j, k] <= 0.0:
                    continue
                total = 0.0
                for di, dj, dk in _NEIGHBOURS:
                    p, q, r = i + di, j + dj, k + dk
                    w = _weight(amount, shape, p, q, r, dk)
                    if w > 0.0:
                        total += wanted[i, j, k] * w / weight_sum[i, j, k] * accept[p, q, r]
                sent[i, j, k] = total
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                load[i, j, k] = max(load[i, j, k] - sent[i, j, k], 0.0)
                amount[i, j, k] = min(amount[i, j, k] + received[i, j, k], 1.0)
    return received


@njit(cache=True, error_model="numpy")
def _saturate(liquid, amount, water, load, c_max):
    """Liquid cells loaded beyond c_max become MAT (holding c_max); excess and water go to open neighbours.

    Serial and in index order, so the result does not depend on threads.
    Returns the number of cells converted.
    """
    nx, ny, nz = amount.shape
    converted = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if not liquid[i, j, k] or load[i, j, k] <= c_max:
                    continue
                open_count = 0
                for di, dj, dk in _NEIGHBOURS:
                    p, q, r = i + di, j + dj, k + dk
                    if _inside(amount.shape, p, q, r) and amount[p, q, r] <= 0.0:
                        open_count += 1
                if open_count == 0:
                    continue
                excess = load[i, j, k] - c_max
                for di, dj, dk in _NEIGHBOURS:
                    p, q, r = i + di, j + dj, k + dk
                    if _inside(amount.shape, p, q, r) and amount[p, q, r] <= 0.0:
                        load[p, q, r] += excess / open_count
                # the water leaves upwards if it can, else to the first open neighbour
                target = (-1, -1, -1)
                if k + 1 < nz and amount[i, j, k + 1] <= 0.0:
                    target = (i, j, k + 1)
                else:
                    for di, dj, dk in _NEIGHBOURS:
                        p, q, r = i + di, j + dj, k + dk
                        if _inside(amount.shape, p, q, r) and amount[p, q, r] <= 0.0:
                            target = (p, q, r)
                            break
                water[target[0], target[1], target[2]] += water[i, j, k]
                water[i, j, k] = 0.0
                load[i, j, k] = 0.0
                amount[i, j, k] = c_max
                converted += 1
    return converted


def erosion_step(
    params: ErosionParameters,
    *,
    liquid: np.ndarray,
    amount: np.ndarray,
    erodibility: np.ndarray,
    water: np.ndarray,
    load: np.ndarray,
    speed: np.ndarray,
    dt: float,
) -> dict[str, float]:
    """One erosion–deposition step, in place on ``amount``, ``water`` and ``load``.

    Parameters
    ----------
    params : ErosionParameters
    liquid : numpy.ndarray of bool, shape (nx, ny, nz)
        FULL cells (taking part in the exchange).
    amount : numpy.ndarray, shape (nx, ny, nz)
        Material per cell (MAT where > 0), updated.
    erodibility : numpy.ndarray, shape (nx, ny, nz)
        Scale of the erosion of each MAT cell (1 / hardness).
    water, load : numpy.ndarray, shape (nx, ny, nz)
        Water fraction and dissolved material per cell, updated.
    speed : numpy.ndarray, shape (nx, ny, nz)
        Water speed at the cell centres (m/s).
    dt : float
        Time step (s).

    Returns
    -------
    dict
        ``eroded``, ``deposited`` (material moved this step), ``saturated`` (cells turned into material).
    """
    cohesive = params.model == "cohesive"
    ero, dep = _rates(liquid, amount, water, load, speed, cohesive, params.erosion_rate, params.deposition_rate,
                      params.fall_velocity, params.tau_erosion, params.tau_deposition, params.friction,
                      params.density, params.capacity, params.saturation, params.time_scale)
    # summed here, not in the parallel kernels, whose reductions would depend on the thread count
    eroded = float(np.sum(_erode(liquid, amount, erodibility, load, ero, dt)))
    deposited = float(np.sum(_deposit(liquid, amount, load, dep, dt)))
    saturated = _saturate(liquid, amount, water, load, params.saturation)
    return {"eroded": float(eroded), "deposited": float(deposited), "saturated": int(saturated)}


class VoxelErosionSolver(SolverLoop):
    """Water flow (:class:`~pverosion.kernels.voxel.fluid.VoxelFluid`) eroding and depositing material.

    Parameters
    ----------
    amount : numpy.ndarray, shape (nx, ny, nz)
        Material per cell in [0, 1]; MAT cells are those with ``amount > 0``.
    water : numpy.ndarray, shape (nx, ny, nz)
        Initial water fraction per cell (ignored in MAT cells).
    spacing : float
        Cell edge (m).
    erodibility : numpy.ndarray, optional
        Per-cell erosion scale (1 / hardness); 1 everywhere by default.
    params : ErosionParameters, optional
        Erosion–deposition model and constants.
    time_step : float, default: 0.01
        Time per step (s) when :meth:`step` is given none.
    **fluid_options
        Passed to :class:`~pverosion.kernels.voxel.fluid.VoxelFluid` (``source``,
        ``source_velocity``, ``drain``, ``viscosity``, ``tolerance``, ``cfl``, ...).

    Attributes
    ----------
    fluid : VoxelFluid
    amount : numpy.ndarray
        Current material per cell.
    drained_material : float
        Dissolved material removed by drains so far.
    initial_material : float
        Solid + dissolved material at the start.
    """

    STAT_NAMES = ("solid", "dissolved", "drained", "eroded", "deposited", "water", "substeps", "iterations",
                  "divergence")
    """Per-step statistics (:attr:`statistics`): material and water totals, and the step's figures."""

    def __init__(self, amount, water, *, spacing: float, erodibility=None, params: ErosionParameters | None = None,
                 time_step: float = 0.01, **fluid_options):
        amount = np.asarray(amount, dtype=np.float64)
        if amount.ndim != 3:
            raise ValueError(f"amount must be a 3-D array (nx, ny, nz); got shape {amount.shape}")
        if not np.all(np.isfinite(amount)) or amount.min(initial=0.0) < 0.0 or amount.max(initial=0.0) > 1.0:
            raise ValueError("material amounts must be finite and in [0, 1]")
        if erodibility is None:
            erodibility = np.ones(amount.shape)
        erodibility = np.asarray(erodibility, dtype=np.float64)
        if erodibility.shape != amount.shape:
            raise ValueError(f"erodibility has shape {erodibility.shape} but amount has shape {amount.shape}")
        if not np.all(np.isfinite(erodibility)) or erodibility.min(initial=0.0) < 0.0:
            raise ValueError("erodibility must be finite and >= 0")
        self.params = params or ErosionParameters()
        self.amount = amount.copy()
        self.erodibility = erodibility.copy()
        self.fluid = VoxelFluid(self.amount > 0.0, water, spacing=spacing, **fluid_options)
        self.drained_material = 0.0
        self.initial_material = self.material_total()
        self.time_step = float(time_step)
        self.step_count = 0
        self._stats: list[tuple] = []
        self._record_totals({})

    def _record_totals(self, figures: dict) -> None:
        self._record({**figures, "solid": float(self.amount.sum()), "dissolved": float(self.fluid.material.sum()),
                      "drained": self.drained_material, "water": float(self.fluid.water.sum())})

    @property
    def state(self) -> dict[str, np.ndarray]:
        """Material ``amount``, ``water`` and ``dissolved`` material per cell, each (nx, ny, nz)."""
        return {"amount": self.amount, "water": self.fluid.water, "dissolved": self.fluid.material}

    def material_total(self) -> float:
        """Solid + dissolved material now (cell volumes)."""
        return float(self.amount.sum() + self.fluid.material.sum())

    def mass_error(self) -> float:
        """Relative change of solid + dissolved + drained material since the start."""
        total = self.material_total() + self.drained_material
        return abs(total - self.initial_material) / max(self.initial_material, 1e-300)

    def step(self, dt: float | None = None) -> dict[str, float]:
        """Advance the water by ``dt`` (:attr:`time_step` when None) then exchange material; return the step's figures."""
        dt = self.time_step if dt is None else dt
        fluid = self.fluid
        info = fluid.step(dt)
        self.drained_material += info.drained_material
        start = time.perf_counter()
        speed = np.linalg.norm(cell_velocity(fluid.u, fluid.v, fluid.w), axis=-1)
        wet = (fluid.water >= WET_FRACTION) & ~fluid.solid
        figures = erosion_step(self.params, liquid=wet, amount=self.amount, erodibility=self.erodibility,
                               water=fluid.water, load=fluid.material, speed=speed, dt=dt)
        solid = self.amount > 0.0
        opened = fluid.solid & ~solid
        fluid.water[opened] = 0.0  # eroded away: an empty cell the water flows into
        fluid.solid = solid
        fluid.profile["erosion"] = fluid.profile.get("erosion", 0.0) + time.perf_counter() - start
        self.step_count += 1
        figures.update(substeps=info.substeps, iterations=info.iterations, divergence=info.divergence,
                       max_speed=info.max_speed, inflow=info.inflow, outflow=info.outflow,
                       drained_material=info.drained_material)
        self._record_totals(figures)
        return figures
