"""What every time-stepped kernel offers, and the one loop that advances them.

Weathering and hydraulic erosion of meshes, voxel erosion and freeze–thaw
weathering are all solvers: set up once, then advanced step by step.  They
share one protocol, :class:`Solver`, so that one filter execution
(:class:`pverosion.filters.base.TimeSteppedFilter`) caches, continues and
reruns any of them, reports progress and stops on Ctrl-C between steps.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

__all__ = ["Solver", "SolverLoop", "check_steps"]


@runtime_checkable
class Solver(Protocol):
    """A time-stepped kernel.

    Attributes
    ----------
    step_count : int
        Steps done so far (absolute time: step ``n`` is time ``n``).
    """

    step_count: int

    def step(self) -> Any:
        """Advance one step."""

    def run(self, steps: int, *, outputs: Iterable[int] = (), callback: Callable[[Any], None] | None = None,
            on_step: Callable[[Any], None] | None = None) -> None:
        """Advance ``steps`` steps, calling ``callback`` at the absolute steps ``outputs`` and ``on_step`` after each."""

    @property
    def state(self) -> dict[str, np.ndarray]:
        """The arrays that make the current state, by name (views, not copies)."""

    @property
    def statistics(self) -> dict[str, np.ndarray]:
        """Per-step figures, one array per name, one row per step (step 0 first)."""


def check_steps(steps) -> int:
    """``steps`` as an int, or ValueError when it is not a whole number >= 0."""
    if int(steps) != steps or steps < 0:
        raise ValueError(f"iterations must be an integer >= 0; got {steps!r}")
    return int(steps)


class SolverLoop:
    """The loop of every solver: :meth:`run` advances :meth:`step` by step.

    A solver whose steps can be undone (the self-intersection guard of the mesh
    solvers) overrides :meth:`_advance`; the loop then repeats until the step
    count reaches its target.  Per-step figures are kept as rows of
    :attr:`STAT_NAMES` through :meth:`_record`.
    """

    STAT_NAMES: ClassVar[tuple[str, ...]] = ()
    step_count: int
    _stats: list

    def _advance(self, checkpoint: bool) -> bool:
        """One step; ``checkpoint`` asks for a state safe to hand out.  False when the step was undone."""
        self.step()
        return True

    def run(self, steps: int, *, outputs: Iterable[int] = (), callback: Callable[[Any], None] | None = None,
            on_step: Callable[[Any], None] | None = None) -> None:
        """Advance ``steps`` steps.

        Parameters
        ----------
        steps : int
            Number of steps to add (>= 0).
        outputs : iterable of int
            Step numbers (absolute times) at which ``callback`` is called; each is a checkpoint.
        callback : callable, optional
            ``callback(solver)`` at every output step.
        on_step : callable, optional
            ``on_step(solver)`` after every step that counts (progress reports, interruption).
        """
        target = self.step_count + check_steps(steps)
        wanted = {int(s) for s in outputs}
        while self.step_count < target:
            upcoming = self.step_count + 1
            if not self._advance(upcoming in wanted or upcoming == target):
                continue
            if on_step is not None:
                on_step(self)
            if callback is not None and self.step_count in wanted:
                callback(self)

    def _record(self, row: dict[str, float]) -> None:
        """Append one row of the per-step statistics (missing names count 0)."""
        self._stats.append(tuple(float(row.get(name, 0.0)) for name in self.STAT_NAMES))

    @property
    def statistics(self) -> dict[str, np.ndarray]:
        """Per-step figures, one array per name of :attr:`STAT_NAMES` (step 0 first)."""
        table = np.asarray(self._stats, dtype=np.float64).reshape(-1, len(self.STAT_NAMES))
        return {name: table[:, k] for k, name in enumerate(self.STAT_NAMES)}
