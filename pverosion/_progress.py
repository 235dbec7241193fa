"""Progress bars of the Python front ends, all tqdm: one over a filter's progress events, one over a solver's steps."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
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


def filter_bar(alg: Any, *, enabled: bool = True):
    """Context manager: the progress events of VTK algorithm ``alg`` in a tqdm bar (0–100 %) when ``enabled``."""
    return _filter_bar(alg) if enabled else nullcontext()


@contextmanager
def _filter_bar(alg: Any) -> Iterator[None]:
    from tqdm.auto import tqdm

    with tqdm(total=100, desc=alg.command_name(), unit="%") as shown:
        def update(caller, _event) -> None:
            shown.update(max(round(100 * caller.GetProgress()) - shown.n, 0))

        tag = alg.AddObserver("ProgressEvent", update)
        try:
            yield
        finally:
            alg.RemoveObserver(tag)
