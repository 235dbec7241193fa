"""``--load N`` of the benchmark scripts: every script takes it, and its quiet/loaded ratios are right."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
SCRIPTS = sorted(BENCHMARKS.glob("bench_*.py"))


def _called_names(tree: ast.AST) -> set[str]:
    return {node.func.id for node in ast.walk(tree)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)}


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.stem for s in SCRIPTS])
def test_every_benchmark_takes_load(script):
    """Each script adds ``--load`` to its parser and runs its main through the quiet/loaded runner, from ``__main__``."""
    tree = ast.parse(script.read_text())
    assert "add_load_option" in _called_names(tree), f"{script.name} does not add --load to its parser"
    main_blocks = [node for node in tree.body if isinstance(node, ast.If) and "__main__" in ast.unparse(node.test)]
    assert main_blocks, f"{script.name} has no __main__ block"
    assert "run" in _called_names(main_blocks[0]), f"{script.name} does not start through _load.run"


def _toy_script(tmp_path: Path) -> Path:
    """A benchmark that prints a spin loop's wall time: slower while other processes spin on every core."""
    script = tmp_path / "bench_toy.py"
    script.write_text(textwrap.dedent(f"""
        import argparse, json, sys, time
        sys.path.insert(0, {str(BENCHMARKS)!r})
        from _load import add_load_option, run

        def main():
            parser = argparse.ArgumentParser()
            parser.add_argument("--n", type=int, default=1)
            add_load_option(parser)
            args = parser.parse_args()
            start = time.perf_counter()
            while time.perf_counter() - start < 0.3:  # a fixed wall time: busy processes cannot change it
                pass
            cpu = time.process_time()
            print(json.dumps({{"n": args.n, "wall_ms": [300.0, 300.0, 300.0], "cpu_s": cpu, "missing": None}}))

        if __name__ == "__main__":
            run(main, timings=("wall_ms", "n", "missing", "absent.key"))
    """))
    return script


def test_load_runs_quiet_then_loaded_and_prints_ratios(tmp_path):
    """``--load 1`` runs the script twice in fresh processes, passes the other options on, and divides
    loaded by quiet for the timings present (a list by its median); absent or null timings are left out."""
    script = _toy_script(tmp_path)
    done = subprocess.run([sys.executable, str(script), "--load", "1", "--n", "4"], capture_output=True,
                          text=True, timeout=120, check=True)
    result = json.loads(done.stdout)
    assert result["load"] == 1 and result["busy_processes"] == 1
    assert result["quiet"]["n"] == 4 and result["loaded"]["n"] == 4
    assert result["loaded_vs_quiet"] == {"wall_ms": 1.0, "n": 1.0}


def test_load_zero_runs_the_script_alone(tmp_path):
    script = _toy_script(tmp_path)
    done = subprocess.run([sys.executable, str(script), "--n", "2"], capture_output=True, text=True,
                          timeout=60, check=True)
    assert json.loads(done.stdout)["n"] == 2


def test_negative_load_is_refused(tmp_path):
    done = subprocess.run([sys.executable, str(_toy_script(tmp_path)), "--load", "-1"], capture_output=True,
                          text=True, timeout=60, check=False)
    assert done.returncode != 0 and "--load must be >= 0" in done.stderr


@pytest.mark.skipif(not os.path.exists("/proc/self/stat"), reason="reads /proc (Linux)")
def test_busy_processes_spin_and_are_stopped():
    """The busy processes use CPU while the block runs and are gone after it, also when the block raises."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        from _load import busy_processes
    finally:
        sys.path.remove(str(BENCHMARKS))
    with pytest.raises(RuntimeError), busy_processes(2) as procs:
        time.sleep(0.5)
        for proc in procs:
            with open(f"/proc/{proc.pid}/stat") as f:  # utime + stime in clock ticks
                fields = f.read().rsplit(")", 1)[1].split()
            assert int(fields[11]) + int(fields[12]) > 0
        raise RuntimeError("stop")
    assert all(proc.poll() is not None for proc in procs)

