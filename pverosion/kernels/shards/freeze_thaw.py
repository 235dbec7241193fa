"""Freeze–thaw weathering on a shard graph (Mateos et al. §5): water paths, link damage, detachment.

Every path infiltrates one exterior link (chosen with probability
``a * max(-n . d, 0)`` for a water direction ``d`` drawn from a cone around
the mean direction), then walks the links graph G_L one neighbour at a time
with probability ``f_g * (1 - f_r)``: ``f_g`` the alignment of the step
between link centroids with gravity, ``f_r = life * rho`` the resistance of
the next link. Each link absorbs ``a k_solid + f_r k_res`` of the water
(``a k_air`` once broken), or, at random with probability
``1 - w / w_in``, all that is left; absorbed water damages a link by
``k_dmg w_abs / a``. A link breaks at zero life, or earlier at random below
``k_break``. Broken links stay in G_L as open cracks.

Detachment is incremental. Breaking the link between solid cells ``a`` and
``b`` starts two breadth-first searches over unbroken links, one from each
cell, advanced one cell at a time in turn. If they meet, nothing happened.
If one runs out first, its cells are a whole component, the smaller one (on
a tie, the component of the link's first cell); components carry a label
and a count of core cells, so the other side's core count is known without
visiting it. The side without core cells goes to air (the smaller one when
neither has any); when both hold core cells both stay. After cells go to
air, exterior links are updated by a search restricted to solid–air links
that are not yet exterior: a group reaching an exterior link becomes
exterior, one that does not is an enclosed air pocket and stays interior
(§5.3, Figure 12).

Infiltration samples an exterior link by area with a Fenwick tree and
accepts it with probability ``max(-n . d, 0)``, so a path costs the same
for a thousand cells or a million. Random numbers come from SplitMix64
started from the seed's hash (:func:`~pverosion.kernels.random_streams.stream_state`),
so the same seed gives the same run bit for bit on any machine and different
seeds give independent runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pverosion.kernels._jit import njit
from pverosion.kernels.random_streams import stream_state
from pverosion.kernels.shards.graph import ShardGraph
from pverosion.kernels.solver.protocol import SolverLoop

__all__ = ["AIR", "CORE", "SOLID", "FreezeThawParameters", "FreezeThawSimulation", "FreezeThawSolver", "PathRecord"]

SOLID, AIR, CORE = 0, 1, 2
"""Cell states."""

_TRIES = 64
"""Rejection-sampling attempts for the infiltration link before an exact scan."""


@dataclass(frozen=True)
class FreezeThawParameters:
    """Parameters of the water paths (Mateos et al. §5.1–5.2; the paper's values are the defaults).

    Attributes
    ----------
    water_direction : (3,) float
        Mean direction the water travels in (rain falls along -z). Faces
        facing against it take the water.
    spread : float
        Half-angle in degrees of the cone the direction of each path is drawn
        from, uniformly on the sphere cap.
    gravity : (3,) float
        Direction water flows in between links (only the direction is used).
    water : float
        Water per path, ``w_in``.
    k_solid, k_air : float
        Absorption per unit area on unbroken and broken links, in units of
        ``1 / a_mean`` (paper: 0.1 and 0.05).
    k_res : float
        Absorption per unit of flow resistance (paper: 0.25).
    k_dmg : float
        Damage per unit of absorbed water per area, in units of ``a_mean``
        (paper: 0.5).
    k_break : float
        Life below which a traversed link may break at random (paper: 0.4).
    break_probability : float
        Probability of that forced break as the life reaches zero; it falls
        linearly to 0 at ``k_break`` (paper: 0.9).
    complete_absorption : float
        Scale of the probability ``1 - w / w_in`` that a link absorbs all the
        water left (1 as in the paper, 0 switches it off).
    """

    water_direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    spread: float = 0.0
    gravity: tuple[float, float, float] = (0.0, 0.0, -1.0)
    water: float = 1.0
    k_solid: float = 0.1
    k_air: float = 0.05
    k_res: float = 0.25
    k_dmg: float = 0.5
    k_break: float = 0.4
    break_probability: float = 0.9
    complete_absorption: float = 1.0

    def __post_init__(self):
        for name in ("water_direction", "gravity"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.isfinite(v).all() or not np.linalg.norm(v) > 0.0:
                raise ValueError(f"{name} must be a finite non-zero 3-vector; got {getattr(self, name)!r}")
        if not 0.0 <= self.spread <= 180.0:
            raise ValueError(f"spread must be an angle in [0, 180] degrees; got {self.spread}")
        if not self.water > 0.0:
            raise ValueError(f"water must be positive; got {self.water}")
        for name in ("k_solid", "k_air", "k_res", "k_dmg", "k_break"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0; got {value}")
        for name in ("break_probability", "complete_absorption"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1]; got {value}")


@dataclass
class PathRecord:
    """Water paths of one :meth:`FreezeThawSimulation.run` call.

    Attributes
    ----------
    start : (n_paths + 1,) int64
        Path ``p`` visited ``link[start[p]:start[p+1]]``.
    link : (n_visits,) int64
    water : (n_visits,) float64
        Water arriving at each visited link.
    """

    start: np.ndarray
    link: np.ndarray
    water: np.ndarray

    @property
    def n_paths(self) -> int:
        return len(self.start) - 1


@dataclass
class _Log:
    """Breaks of links between solid cells: link, path and the end of the cells each sent to air."""

    link: np.ndarray
    path: np.ndarray
    removed_end: np.ndarray
    removed: np.ndarray
    counts: np.ndarray = field(default_factory=lambda: np.zeros(2, np.int64))  # events, removed cells


class FreezeThawSimulation:
    """State of a freeze–thaw run on a :class:`~pverosion.kernels.shards.graph.ShardGraph`.

    Parameters
    ----------
    graph : ShardGraph
    parameters : FreezeThawParameters, optional
    core : (n_cells,) bool or sequence of int, optional
        Cells that are never removed.
    air : (n_cells,) bool or sequence of int, optional
        Cells that start removed (e.g. cells outside a terrain, §6.2).
    resistance : float, (n_links,) array or callable, optional
        The resistance field rho at the link centroids, or a function of
        points (n, 3) -> (n,); values are clipped to [0, 1]. Default 0.
    seed : int
        Seed (>= 0) of the water paths; hashed, so different seeds give
        independent runs.

    Attributes
    ----------
    life : (n_links,) float64
    state : (n_cells,) int8
        SOLID, AIR or CORE.
    exterior : (n_links,) bool
        Links water can infiltrate: between a solid cell and the outside, or
        an air cell connected to the outside (not an enclosed pocket).
    paths : int
        Paths run so far.
    """

    def __init__(self, graph: ShardGraph, parameters: FreezeThawParameters | None = None, *, core=None, air=None,
                 resistance=None, seed: int = 0) -> None:
        p = parameters if parameters is not None else FreezeThawParameters()
        if not isinstance(p, FreezeThawParameters):
            raise TypeError(f"parameters must be FreezeThawParameters; got {type(p).__name__}")
        if graph.n_cells == 0 or graph.n_links == 0:
            raise ValueError("the shard graph is empty: no cell lies inside the mesh")
        self.graph = graph
        self.parameters = p
        n, m = graph.n_cells, graph.n_links
        self.state = np.full(n, SOLID, np.int8)
        core_mask = _cell_mask(core, n, "core")
        air_mask = _cell_mask(air, n, "air")
        if (core_mask & air_mask).any():
            raise ValueError("a cell cannot be both core and air")
        self.state[core_mask] = CORE
        self.state[air_mask] = AIR
        self.life = np.ones(m)
        self.rho = _resistance(resistance, graph.link_centroid)
        a_mean = graph.mean_area
        self._coef = np.array([p.water, p.k_solid / a_mean, p.k_air / a_mean, p.k_res, p.k_dmg * a_mean, p.k_break,
                               p.break_probability, p.complete_absorption, math.cos(math.radians(p.spread))])
        self._direction = np.asarray(p.water_direction, float) / np.linalg.norm(p.water_direction)
        self._gravity = np.asarray(p.gravity, float) / np.linalg.norm(p.gravity)
        self._rng = np.array([stream_state(seed, "freeze_thaw")], np.uint64)
        # every link of every cell, exterior ones included
        cells = graph.link_cells
        inner = cells[:, 1] >= 0
        rows = np.concatenate([cells[:, 0], cells[inner, 1]])
        cols = np.concatenate([np.arange(m), np.flatnonzero(inner)])
        order = np.lexsort((cols, rows))
        self._all_start = np.searchsorted(rows[order], np.arange(n + 1)).astype(np.int64)
        self._all_links = cols[order].astype(np.int64)
        # components of the solid cells and their core counts
        solid = self.state != AIR
        both = inner & solid[cells[:, 0]] & solid[np.maximum(cells[:, 1], 0)]
        adjacency = coo_matrix((np.ones(int(both.sum())), (cells[both, 0], cells[both, 1])), shape=(n, n))
        _, labels = connected_components(adjacency, directed=False)
        self.component = labels.astype(np.int64)
        self.core_count = np.zeros(n + int(inner.sum()) + 1, np.int64)  # one new label per split at most
        np.add.at(self.core_count, self.component[self.state == CORE], 1)
        self._next_label = np.array([labels.max() + 1], np.int64)
        # exterior links: surface links of solid cells, then the restricted search from the initial air cells
        self.exterior = (cells[:, 1] < 0) & solid[cells[:, 0]]
        self._tree = np.zeros(m + 1)
        _fenwick_build(self._tree, np.where(self.exterior, graph.link_area, 0.0))
        self._cell_mark = np.zeros(n, np.int64)
        self._link_mark = np.zeros(m, np.int64)
        self._stamp = np.zeros(1, np.int64)
        self._queue = np.empty(n, np.int64)
        self._queue2 = np.empty(n, np.int64)
        self._lqueue = np.empty(m, np.int64)
        self._log = _Log(np.empty(m, np.int64), np.empty(m, np.int64), np.empty(m, np.int64), np.empty(n, np.int64))
        initial_air = np.flatnonzero(air_mask).astype(np.int64)
        g = self.graph
        _update_exterior(initial_air, g.link_cells, g.link_area, self._all_start, self._all_links, g.link_start,
                         g.link_neighbours, self.state, self.exterior, self._tree, self._link_mark, self._stamp,
                         self._lqueue)
        self.paths = 0

    # --- public -----------------------------------------------------------------------------------------

    @property
    def solid(self) -> np.ndarray:
        """(n_cells,) bool: cells still part of the model (solid or core)."""
        return self.state != AIR

    @property
    def n_breaks(self) -> int:
        """Breaks of links between solid cells so far."""
        return int(self._log.counts[0])

    @property
    def breaks(self) -> list[tuple[int, int, np.ndarray]]:
        """Every break of a link between two solid cells, in order: (link, path index, cells sent to air)."""
        log = self._log
        k = int(log.counts[0])
        ends = log.removed_end[:k]
        starts = np.concatenate([[0], ends[:-1]]) if k else ends
        return [(int(log.link[q]), int(log.path[q]), log.removed[starts[q]:ends[q]].copy()) for q in range(k)]

    def run(self, paths: int, *, record: bool = False, progress=None, chunk: int = 1000) -> PathRecord | None:
        """Run ``paths`` water paths.

        Parameters
        ----------
        paths : int
            Number of paths (>= 0).
        record : bool
            Return the visited links and water of every path.
        progress : callable, optional
            Called with the number of paths done after every chunk.
        chunk : int
            Paths per compiled call between progress reports.

        Returns
        -------
        PathRecord or None
        """
        if int(paths) != paths or paths < 0:
            raise ValueError(f"paths must be a non-negative integer; got {paths!r}")
        starts, links, water = [np.zeros(1, np.int64)], [], []
        done = 0
        scratch_link = np.empty(self.graph.n_links, np.int64)
        scratch_water = np.empty(self.graph.n_links)
        while done < paths:
            k = min(chunk, paths - done)
            cap = 64 * k if record else 0
            out_start = np.zeros(k + 1, np.int64)
            out_link = np.empty(cap, np.int64)
            out_water = np.empty(cap)
            n_done, n_visits, pending = _run_paths(
                k, self.paths, record, out_start, out_link, out_water, scratch_link, scratch_water, self._coef,
                self._direction, self._gravity, self._rng, *self._arrays())
            if record:
                links.append(out_link[:n_visits])
                water.append(out_water[:n_visits])
                if pending >= 0:  # the last path did not fit: it is still in the scratch arrays
                    links.append(scratch_link[:pending].copy())
                    water.append(scratch_water[:pending].copy())
                    lengths = np.append(np.diff(out_start[:n_done]), pending)
                else:
                    lengths = np.diff(out_start[:n_done + 1])
                starts.append(starts[-1][-1] + np.cumsum(lengths))
            self.paths += n_done
            done += n_done
            if progress is not None:
                progress(n_done)
        if not record:
            return None
        return PathRecord(np.concatenate(starts), np.concatenate(links) if links else np.zeros(0, np.int64),
                          np.concatenate(water) if water else np.zeros(0))

    # --- internals ---------------------------------------------------------------------------------------

    def _arrays(self) -> tuple:
        """The state arrays the compiled kernels work on, in their argument order."""
        g, log = self.graph, self._log
        return (g.link_cells, g.link_area, g.link_normal, g.link_centroid, self.rho, self.life, self.state,
                self.exterior, self._tree, g.cell_start, g.cell_links, self._all_start, self._all_links, g.link_start,
                g.link_neighbours, self.component, self.core_count, self._next_label, self._cell_mark,
                self._link_mark, self._stamp, self._queue, self._queue2, self._lqueue, log.link, log.path,
                log.removed_end, log.removed, log.counts)


def _cell_mask(cells, n: int, name: str) -> np.ndarray:
    if cells is None:
        return np.zeros(n, bool)
    arr = np.asarray(cells)
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise ValueError(f"{name} mask must have shape ({n},); got {arr.shape}")
        return arr.copy()
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name} must be a boolean mask or cell indices; got dtype {arr.dtype}")
    arr = arr.astype(np.int64).ravel()
    if arr.size and (arr.min() < 0 or arr.max() >= n):
        raise ValueError(f"{name} cell indices must lie in [0, {n}); got {arr.min()}..{arr.max()}")
    mask = np.zeros(n, bool)
    mask[arr] = True
    return mask


def _resistance(resistance, centroids: np.ndarray) -> np.ndarray:
    m = len(centroids)
    if resistance is None:
        values = np.zeros(m)
    elif callable(resistance):
        values = np.asarray(resistance(centroids.copy()), dtype=float)
        if values.shape != (m,):
            raise ValueError(f"the resistance function must return shape ({m},) for {m} link centroids; "
                             f"got {values.shape}")
    else:
        values = np.broadcast_to(np.asarray(resistance, dtype=float), (m,)) if np.ndim(resistance) == 0 else \
            np.asarray(resistance, dtype=float)
        if values.shape != (m,):
            raise ValueError(f"resistance must be a number, a function or an array of shape ({m},); "
                             f"got shape {values.shape}")
    if not np.isfinite(values).all():
        raise ValueError("the resistance field has NaN or infinite values at some link centroids")
    return np.clip(values, 0.0, 1.0).astype(np.float64)


# --- random numbers ----------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _uniform(rng):
    """SplitMix64 step: a double in [0, 1)."""
    z = rng[0] + np.uint64(0x9E3779B97F4A7C15)
    rng[0] = z
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return np.float64(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _cone_direction(rng, axis, cos_spread):
    """A direction uniform on the sphere cap of half-angle acos(cos_spread) around the unit ``axis``."""
    c = 1.0 - _uniform(rng) * (1.0 - cos_spread)
    phi = 2.0 * math.pi * _uniform(rng)
    s = math.sqrt(max(0.0, 1.0 - c * c))
    # an orthonormal basis around the axis
    ax, ay, az = axis[0], axis[1], axis[2]
    if abs(ax) < 0.9:
        ux, uy, uz = 0.0, -az, ay
    else:
        ux, uy, uz = az, 0.0, -ax
    norm = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / norm, uy / norm, uz / norm
    vx, vy, vz = ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux
    cp, sp = math.cos(phi), math.sin(phi)
    return (c * ax + s * (cp * ux + sp * vx), c * ay + s * (cp * uy + sp * vy), c * az + s * (cp * uz + sp * vz))


# --- Fenwick tree of exterior link areas --------------------------------------------------------------------


@njit(cache=True)
def _fenwick_build(tree, values):
    for i in range(values.size):
        tree[i + 1] += values[i]
        j = i + 1 + ((i + 1) & -(i + 1))
        if j < tree.size:
            tree[j] += tree[i + 1]


@njit(cache=True, inline="always")
def _fenwick_add(tree, i, delta):
    j = i + 1
    while j < tree.size:
        tree[j] += delta
        j += j & -j


@njit(cache=True)
def _fenwick_find(tree, target):
    """Smallest index whose prefix sum exceeds ``target`` (clamped to the last index)."""
    pos = 0
    step = 1
    while step * 2 < tree.size:
        step *= 2
    while step > 0:
        nxt = pos + step
        if nxt < tree.size and tree[nxt] <= target:
            pos = nxt
            target -= tree[nxt]
        step //= 2
    return min(pos, tree.size - 2)


@njit(cache=True, inline="always")
def _set_exterior(link, value, exterior, tree, area):
    if exterior[link] != value:
        exterior[link] = value
        _fenwick_add(tree, link, area[link] if value else -area[link])


# --- cells and links ---------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _solid(cell, state):
    return cell >= 0 and state[cell] != 1


@njit(cache=True, inline="always")
def _outward(link, link_cells, state):
    """+1 if the link's normal points away from its solid side, else -1."""
    return 1.0 if _solid(link_cells[link, 0], state) else -1.0


@njit(cache=True)
def _update_exterior(new_air, link_cells, area, all_start, all_links, link_start, link_neighbours, state, exterior,
                     tree, link_mark, stamp, lqueue):
    """Exterior links after the cells ``new_air`` went to air (restricted search, §5.3)."""
    # links with no solid side left are gone
    for q in range(new_air.size):
        c = new_air[q]
        for k in range(all_start[c], all_start[c + 1]):
            m = all_links[k]
            if not (_solid(link_cells[m, 0], state) or _solid(link_cells[m, 1], state)):
                _set_exterior(m, False, exterior, tree, area)
    # solid–air links that are not exterior yet: exterior if their group reaches an exterior link
    base = stamp[0]
    for q in range(new_air.size):
        c = new_air[q]
        for k in range(all_start[c], all_start[c + 1]):
            m = all_links[k]
            if exterior[m] or link_mark[m] > base or not (_solid(link_cells[m, 0], state)
                                                          or _solid(link_cells[m, 1], state)):
                continue
            stamp[0] += 1  # one stamp per group; groups searched in this update have stamps above base
            s = stamp[0]
            link_mark[m] = s
            lqueue[0] = m
            head, tail = 0, 1
            reached = False
            while head < tail:
                x = lqueue[head]
                head += 1
                for r in range(link_start[x], link_start[x + 1]):
                    y = link_neighbours[r]
                    if exterior[y]:
                        reached = True
                    elif link_mark[y] <= base and _solid(link_cells[y, 0], state) != _solid(link_cells[y, 1], state):
                        link_mark[y] = s
                        lqueue[tail] = y
                        tail += 1
            if reached:
                for r in range(tail):
                    _set_exterior(lqueue[r], True, exterior, tree, area)


# --- detachment ---------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _expand(x, own, other, queue, tail, link_cells, cell_start, cell_links, life, state, cell_mark):
    """Queue the unvisited solid neighbours of cell ``x`` across unbroken links, marked ``own``.

    Returns the new queue length and whether a cell marked ``other`` (the other search) was reached.
    """
    for k in range(cell_start[x], cell_start[x + 1]):
        m = cell_links[k]
        if life[m] <= 0.0:
            continue
        y = link_cells[m, 1] if link_cells[m, 0] == x else link_cells[m, 0]
        if state[y] == 1:
            continue
        if cell_mark[y] == other:
            return tail, True
        if cell_mark[y] != own:
            cell_mark[y] = own
            queue[tail] = y
            tail += 1
    return tail, False


@njit(cache=True)
def _detach(link, link_cells, cell_start, cell_links, life, state, component, core_count, next_label, cell_mark,
            queue_a, queue_b, stamp):
    """Handle the break of interior ``link`` between two solid cells; returns the number of cells to air.

    The cells sent to air are left in ``queue_a[:n]``.
    """
    a, b = link_cells[link, 0], link_cells[link, 1]
    stamp[0] += 2
    sa, sb = stamp[0] - 1, stamp[0]  # stamps are never reused: a later search takes stamp[0] + 1
    cell_mark[a] = sa
    cell_mark[b] = sb
    queue_a[0] = a
    queue_b[0] = b
    ha, ta, hb, tb = 0, 1, 0, 1
    side = -1  # the side that ran out: 0 = a, 1 = b
    while True:
        if ha == ta:
            side = 0
            break
        ta, met = _expand(queue_a[ha], sa, sb, queue_a, ta, link_cells, cell_start, cell_links, life, state, cell_mark)
        ha += 1
        if met:
            return 0
        if hb == tb:
            side = 1
            break
        tb, met = _expand(queue_b[hb], sb, sa, queue_b, tb, link_cells, cell_start, cell_links, life, state, cell_mark)
        hb += 1
        if met:
            return 0
    small = queue_a if side == 0 else queue_b
    n_small = ta if side == 0 else tb
    other = b if side == 0 else a
    label = component[a]
    cores = 0
    for q in range(n_small):
        if state[small[q]] == 2:
            cores += 1
    if cores == 0:  # the smaller part goes (with or without core cells on the other side)
        if side == 1:
            for q in range(n_small):
                queue_a[q] = queue_b[q]
        return n_small
    if core_count[label] - cores == 0:  # only the smaller part holds core cells: the other side goes
        stamp[0] += 1
        s = stamp[0]
        cell_mark[other] = s
        queue_a[0] = other
        head, tail = 0, 1
        while head < tail:
            tail, _ = _expand(queue_a[head], s, -1, queue_a, tail, link_cells, cell_start, cell_links, life, state,
                              cell_mark)
            head += 1
        return tail
    # both parts hold core cells: both stay, the smaller one gets a new label
    new = next_label[0]
    next_label[0] += 1
    for q in range(n_small):
        component[small[q]] = new
    core_count[new] = cores
    core_count[label] -= cores
    return 0


# --- paths --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _infiltration_link(rng, direction, cos_spread, link_cells, area, normal, state, exterior, tree):
    """Draw the direction of this path and the exterior link it enters; -1 if no exterior link faces it."""
    total = 0.0
    j = tree.size - 1
    while j > 0:  # prefix sum of everything
        total += tree[j]
        j -= j & -j
    if not total > 0.0:
        return -1
    d = _cone_direction(rng, direction, cos_spread)
    for _ in range(_TRIES):
        m = _fenwick_find(tree, _uniform(rng) * total)
        if not exterior[m]:
            continue
        s = _outward(m, link_cells, state)
        cosine = -s * (normal[m, 0] * d[0] + normal[m, 1] * d[1] + normal[m, 2] * d[2])
        if _uniform(rng) < cosine:
            return m
    # few faces face the water: exact draw over all exterior links
    acc = 0.0
    for m in range(exterior.size):
        if exterior[m]:
            s = _outward(m, link_cells, state)
            acc += area[m] * max(0.0, -s * (normal[m, 0] * d[0] + normal[m, 1] * d[1] + normal[m, 2] * d[2]))
    if not acc > 0.0:
        return -1
    target = _uniform(rng) * acc
    last = -1
    for m in range(exterior.size):
        if exterior[m]:
            s = _outward(m, link_cells, state)
            w = area[m] * max(0.0, -s * (normal[m, 0] * d[0] + normal[m, 1] * d[1] + normal[m, 2] * d[2]))
            if w > 0.0:
                last = m
                target -= w
                if target < 0.0:
                    return m
    return last


@njit(cache=True)
def _run_paths(n_paths, path_offset, record, out_start, out_link, out_water, scratch_link, scratch_water, coef,
               direction, gravity, rng, link_cells, area, normal, centroid, rho, life, state, exterior, tree, cell_start,
               cell_links, all_start, all_links, link_start, link_neighbours, component, core_count, next_label,
               cell_mark, link_mark, stamp, queue_a, queue_b, lqueue, log_link, log_path, log_end, log_removed,
               log_counts):
    """Run up to ``n_paths`` paths; returns (paths done, visits recorded, length of an unrecorded last path or -1)."""
    w_in, k_solid, k_air, k_res, k_dmg, k_break, p_break, p_full, cos_spread = (
        coef[0], coef[1], coef[2], coef[3], coef[4], coef[5], coef[6], coef[7], coef[8])
    n_visits = 0
    for p in range(n_paths):
        length = 0
        cur = _infiltration_link(rng, direction, cos_spread, link_cells, area, normal, state, exterior, tree)
        w = w_in
        while cur >= 0:
            scratch_link[length] = cur
            scratch_water[length] = w
            length += 1
            lam = life[cur]
            f_r = lam * rho[cur]
            if p_full > 0.0 and _uniform(rng) < p_full * (1.0 - w / w_in):
                absorbed = w
            elif lam > 0.0:
                absorbed = min(w, area[cur] * k_solid + f_r * k_res)
            else:
                absorbed = min(w, area[cur] * k_air)
            if lam > 0.0:
                lam -= k_dmg * absorbed / area[cur]
                broken = lam <= 0.0
                if not broken and lam < k_break and _uniform(rng) < p_break * (1.0 - lam / k_break):
                    broken = True
                life[cur] = 0.0 if broken else lam
                c0, c1 = link_cells[cur, 0], link_cells[cur, 1]
                if broken and c1 >= 0 and state[c0] != 1 and state[c1] != 1:
                    n_air = _detach(cur, link_cells, cell_start, cell_links, life, state, component, core_count,
                                    next_label, cell_mark, queue_a, queue_b, stamp)
                    e = log_counts[0]
                    r0 = log_counts[1]
                    for q in range(n_air):
                        state[queue_a[q]] = 1
                        log_removed[r0 + q] = queue_a[q]
                    log_link[e] = cur
                    log_path[e] = path_offset + p
                    log_end[e] = r0 + n_air
                    log_counts[0] = e + 1
                    log_counts[1] = r0 + n_air
                    if n_air > 0:
                        _update_exterior(queue_a[:n_air], link_cells, area, all_start, all_links, link_start,
                                         link_neighbours, state, exterior, tree, link_mark, stamp, lqueue)
            w -= absorbed
            if not w > 0.0:
                break
            if not (_solid(link_cells[cur, 0], state) or _solid(link_cells[cur, 1], state)):
                break  # the water went with the detached shards
            # next link: p ~ f_g (1 - f_r) over the living neighbours
            total = 0.0
            for r in range(link_start[cur], link_start[cur + 1]):
                total += _flow_weight(cur, link_neighbours[r], link_cells, state, centroid, gravity, life, rho)
            if not total > 0.0:
                break
            target = _uniform(rng) * total
            nxt = -1
            for r in range(link_start[cur], link_start[cur + 1]):
                y = link_neighbours[r]
                f = _flow_weight(cur, y, link_cells, state, centroid, gravity, life, rho)
                if f > 0.0:
                    nxt = y
                    target -= f
                    if target < 0.0:
                        break
            cur = nxt
        if record:
            if n_visits + length > out_link.size:
                return p + 1, n_visits, length
            for q in range(length):
                out_link[n_visits + q] = scratch_link[q]
                out_water[n_visits + q] = scratch_water[q]
            n_visits += length
            out_start[p + 1] = n_visits
    return n_paths, n_visits, -1


@njit(cache=True, inline="always")
def _flow_weight(i, j, link_cells, state, centroid, gravity, life, rho):
    if not (_solid(link_cells[j, 0], state) or _solid(link_cells[j, 1], state)):
        return 0.0
    dx = centroid[j, 0] - centroid[i, 0]
    dy = centroid[j, 1] - centroid[i, 1]
    dz = centroid[j, 2] - centroid[i, 2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not length > 0.0:
        return 0.0
    f_g = (gravity[0] * dx + gravity[1] * dy + gravity[2] * dz) / length
    if not f_g > 0.0:
        return 0.0
    return f_g * (1.0 - life[j] * rho[j])


class FreezeThawSolver(SolverLoop):
    """Freeze–thaw weathering as a time-stepped solver: every step runs ``paths_per_step`` water paths.

    Parameters
    ----------
    simulation : FreezeThawSimulation
        The run it advances (kept as :attr:`simulation`).
    paths_per_step : int, default: 100
        Water paths per step (>= 1).
    record_paths : bool, default: False
        Keep the paths of the last step run up to a checkpoint of :meth:`run` (``outputs`` and its last
        step) as :attr:`record`.

    Attributes
    ----------
    record : PathRecord or None
        Paths of the last checkpoint step (None before one, or without ``record_paths``).
    """

    STAT_NAMES = ("paths", "breaks", "solid_cells")
    """Per-step statistics: paths run, breaks of solid links and solid cells, all so far."""

    def __init__(self, simulation: FreezeThawSimulation, *, paths_per_step: int = 100,
                 record_paths: bool = False) -> None:
        if int(paths_per_step) != paths_per_step or paths_per_step < 1:
            raise ValueError(f"paths_per_step must be an integer >= 1; got {paths_per_step!r}")
        self.simulation = simulation
        self.paths_per_step = int(paths_per_step)
        self.record_paths = bool(record_paths)
        self.record: PathRecord | None = None
        self.step_count = 0
        self._stats: list[tuple] = []
        self._record_totals()

    def _record_totals(self) -> None:
        sim = self.simulation
        self._record({"paths": sim.paths, "breaks": sim.n_breaks, "solid_cells": int(sim.solid.sum())})

    def step(self) -> None:
        """Run one step's water paths."""
        self._advance(False)

    def _advance(self, checkpoint: bool) -> bool:
        record = self.simulation.run(self.paths_per_step, record=self.record_paths and checkpoint)
        if record is not None:
            self.record = record
        self.step_count += 1
        self._record_totals()
        return True

    @property
    def state(self) -> dict[str, np.ndarray]:
        """Cell ``state`` (n_cells,) int8 (SOLID, AIR, CORE), link ``life`` (n_links,) and ``exterior`` (n_links,) bool."""
        sim = self.simulation
        return {"state": sim.state, "life": sim.life, "exterior": sim.exterior}

