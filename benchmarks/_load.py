"""``--load N`` for every benchmark script: the same measurement quiet and with N busy processes.

A script adds the option to its parser with :func:`add_load_option` and ends with
``run(main, timings=(...))``. Without ``--load`` (or with ``--load 0``) ``run``
just calls ``main``. With ``--load N`` it runs the script twice in fresh
processes, first alone and then while N processes spin on the CPU, and prints
one JSON object::

    {"load": N, "busy_processes": N, "quiet": {...}, "loaded": {...},
     "loaded_vs_quiet": {"<timing>": ratio, ...}}

where ``quiet`` and ``loaded`` are the script's own JSON outputs and each
ratio divides a timing of the loaded run by the same timing of the quiet run
(``timings`` are dotted paths into the script's JSON, e.g. ``"median_ms.kernel"``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from collections.abc import Callable, Sequence
from contextlib import contextmanager

__all__ = ["add_load_option", "busy_processes", "run"]


def add_load_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--load N`` to a benchmark's parser (handled by :func:`run` before ``main`` sees it)."""
    parser.add_argument("--load", type=int, default=0, metavar="N",
                        help="also run with N busy processes and print the loaded/quiet ratios (default: 0)")


@contextmanager
def busy_processes(n: int):
    """Keep ``n`` processes spinning on the CPU for the duration of the block."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
        for proc in procs:
            proc.wait()


def _pop_load(argv: list[str]) -> tuple[int, list[str]]:
    parser = argparse.ArgumentParser(add_help=False)
    add_load_option(parser)
    known, rest = parser.parse_known_args(argv)
    if known.load < 0:
        raise SystemExit(f"--load must be >= 0; got {known.load}")
    return known.load, rest


def _figure(result, path: str) -> float | None:
    """The number at dotted ``path`` (list items by index, -1 the last); a list gives its median; None if absent."""
    value = result
    for key in path.split("."):
        if isinstance(value, list) and key.lstrip("-").isdigit() and -len(value) <= int(key) < len(value):
            value = value[int(key)]
        elif isinstance(value, dict) and key in value:
            value = value[key]
        else:
            return None
    if isinstance(value, list):
        value = statistics.median(value)
    return None if value is None else float(value)


def _ratios(quiet: dict, loaded: dict, timings: Sequence[str]) -> dict[str, float]:
    ratios = {}
    for path in timings:
        q, l = _figure(quiet, path), _figure(loaded, path)
        if q is not None and l is not None and q > 0:
            ratios[path] = round(l / q, 3)
    return ratios


def _measure(argv: list[str]) -> dict:
    """The script's JSON output, run in a fresh process with ``argv``."""
    done = subprocess.run([sys.executable, sys.argv[0], *argv], capture_output=True, text=True)
    if done.returncode != 0:
        sys.stderr.write(done.stderr)
        raise SystemExit(f"{sys.argv[0]} failed with status {done.returncode}")
    return json.loads(done.stdout[done.stdout.index("{"):])


def run(main: Callable[[], None], *, timings: Sequence[str]) -> None:
    """Entry point of a benchmark script: ``main()``, or the quiet/loaded pair with ``--load N``."""
    n, rest = _pop_load(sys.argv[1:])
    if n == 0:
        sys.argv[1:] = rest
        main()
        return
    quiet = _measure(rest)
    with busy_processes(n):
        loaded = _measure(rest)
    print(json.dumps({
        "load": n,
        "busy_processes": n,
        "quiet": quiet,
        "loaded": loaded,
        "loaded_vs_quiet": _ratios(quiet, loaded, timings),
    }, indent=2))
