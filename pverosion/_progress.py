"""Progress bars of the front ends, drawn from the step callbacks of the kernels' solvers."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any


@contextmanager
def step_bar(total: int, *, label: str, enabled: bool = True) -> Iterator[Callable[[Any], None] | None]:
    """A tqdm bar over ``total`` solver steps; yields the ``on_step(solver)`` callback that advances it.

    The callback reads ``solver.step_count`` (steps done so far, absolute) and, when the solver has
    it, ``solver.progress_postfix()`` (figures shown after the bar).  Yields ``None`` when
    ``enabled`` is false, so callers pass it on unchanged.
    """
    if not enabled:
        yield None
        return
    from tqdm.auto import tqdm

    with tqdm(total=int(total), desc=label, unit="step") as bar:
        start: list[int] = []

        def on_step(solver: Any) -> None:
            if not start:
                start.append(solver.step_count - 1)
            done = solver.step_count - start[0] - bar.n  # negative after a guard rollback: wait
            if done > 0:
                bar.update(done)
            postfix = getattr(solver, "progress_postfix", None)
            if postfix is not None:
                bar.set_postfix(**postfix())

        yield on_step
