"""Cold start: every CLI subcommand once with an empty numba cache, then once warm, each in a fresh process.

Prints one JSON object of wall times (seconds, the whole process: start-up,
reading, compiling, running, writing) and, as ``*_cpu_s``, the CPU seconds
(user + system) of the same processes, and the functions numba compiled
with the seconds it took (``cold_compiled``; a warm run should compile none). "cold" runs with ``NUMBA_CACHE_DIR``
pointing at a new empty folder, as after a fresh install; "warm" repeats the
same command with the cache the cold run filled. A cold run includes the
compile helper process the command line starts (:mod:`pverosion._precompile`;
``PVEROSION_PRECOMPILE=0`` in the environment turns it off), and its CPU
seconds count in ``cold_cpu_s``. Also timed: ``import
pverosion``, ``pverosion --help``, and ``pverosion warmup`` of every stage
(parallel processes) into another empty cache, after which every stage's
first run is timed again ("after_warmup").

Inputs: the Stanford bunny scan (``--data``), closed and turned outward
where a stage needs a closed surface (shards, booleans, hydraulic), and
small procedural volumes and spheres.

    python benchmarks/bench_cold_start.py [--data ../shared/data/bunny.ply] [--stages curvature,weather]
        [--skip-warmup] [--load N]

``--per-kernel`` instead runs each chosen stage once cold and prints, per
stage, the CPU seconds numba spent on each function and signature it
compiled: ``self_s`` excludes the functions compiled for it as callees,
``total_s`` includes them; ``llvm_s`` is the part of ``self_s`` spent in
LLVM (optimising and emitting machine code). The list is sorted by ``self_s``; ``numba_s`` is
the whole compile time and ``process_cpu_s`` the CPU seconds of the process.

    python benchmarks/bench_cold_start.py --per-kernel --stages curvature [--top 25]

``--write-plan`` runs the chosen stages cold the same way and stores, per
stage, the kernels it compiled with their argument types and compile
seconds, in the order it compiled them, in ``pverosion/compile_plan.json``: the plan of the compile
helper process (:mod:`pverosion._precompile`). Run it after changing the
kernels or the argument types a stage passes them.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyvista as pv
from _load import add_load_option, run

from pverosion._stages import STAGE_INDEX
from pverosion.examples import data_path
from pverosion.scenes.hydraulic import pour_scene
from pverosion.scenes.intersection import two_spheres
from pverosion.scenes.voxel import meander_grid

ROOT = Path(__file__).resolve().parents[1]
PLAN_FILE = ROOT / "pverosion" / "compile_plan.json"
DEFAULT = data_path("bunny.ply")
COMPILED = re.compile(r"compiled (\d+) functions in ([\d.]+) s")
TARGETS_S = {"curvature_cold": 8.0, "curvature_warm": 2.0, "weather_cold": 10.0, "boolean_cold": 15.0,
             "import": 0.7, "help": 0.7}


def _inputs(folder: Path, data: Path) -> dict[str, list[str]]:
    """Write the inputs; the command line (after ``pverosion``) of each stage."""
    scan = folder / "bunny.ply"
    scan.write_bytes(data.read_bytes())
    scene = pour_scene(mesh=pv.read(data), up=(0.0, 1.0, 0.0))  # closed, outward, z up
    closed = folder / "bunny_closed.vtp"
    scene.mesh.save(closed)
    shifted = folder / "bunny_shifted.vtp"
    size = float(np.ptp(scene.mesh.points[:, 0]))
    scene.mesh.translate((0.3 * size, 0.1 * size, 0.0)).save(shifted)
    n = 48
    axis = np.linspace(-1.0, 1.0, n)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    ball = pv.ImageData(dimensions=(n, n, n), origin=(-1.0, -1.0, -1.0), spacing=(2 / (n - 1),) * 3)
    ball["density"] = (1.0 - np.sqrt(x**2 + y**2 + z**2)).transpose(2, 1, 0).ravel()
    ball.save(folder / "ball.vti")
    grid, _ = meander_grid((64, 32, 32), spacing=0.05, depth=5, half_width=3.0, amplitude=2.0)
    grid.save(folder / "meander.vti")
    a, b = two_spheres()
    (a + b).save(folder / "two_spheres.vtp")
    out = str(folder / "out")
    return {
        "curvature": ["curvature", str(scan), "-o", f"{out}.vtp"],
        "weather": ["weather", str(scan), "-o", f"{out}.vtp", "--iterations", "20"],
        "hydraulic": ["hydraulic", str(closed), "-o", f"{out}.vtm", "--iterations", "5", "--radius",
                      repr(scene.radius), *[f"--emitter={e}" for e in scene.emitters[:1]],
                      *[f"--drain={d}" for d in scene.drains[:1]]],
        "materials": ["materials", str(folder / "ball.vti"), "-o", f"{out}.vti", "--thresholds", "0.2,0.6",
                      "--tree-file", str(folder / "tree.json")],
        "sample-materials": ["sample-materials", str(folder / "ball.vti"), "-o", f"{out}_sampled.vti",
                             "--tree-file", str(folder / "tree.json")],
        "voxel": ["voxel", str(folder / "meander.vti"), "-o", f"{out}.vtm", "--iterations", "3",
                  "--source-velocity", "1.5,0,0"],
        "shard-graph": ["shard-graph", str(closed), "-o", f"{out}.vtm", "--cells", "200"],
        "shards": ["freeze-thaw", str(closed), "-o", f"{out}.vtm", "--cells", "200", "--iterations", "2",
                   "--paths-per-step", "100"],
        "repair": ["repair", str(folder / "two_spheres.vtp"), "-o", f"{out}.vtp"],
        "boolean": ["boolean", str(closed), str(shifted), "--operation", "union", "-o", f"{out}.vtp"],
    }


def _wall(args: list[str], cache: Path, cpu: dict | None = None, key: str = "", compiled: dict | None = None) -> float:
    """Wall seconds of ``python args`` with numba's cache in ``cache``; raises on failure.

    The process's CPU seconds (user + system) go to ``cpu[key]``: on a shared
    machine they vary less than the wall time. The functions numba compiled and
    the seconds it took, as the stages' compile notices report them, go to
    ``compiled[key]``.
    """
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(cache)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed:\n{done.stderr[-2000:]}")
    if cpu is not None:
        cpu[key] = round(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, 2)
    if compiled is not None:
        notices = [(int(n), float(t)) for n, t in COMPILED.findall(done.stderr)]
        compiled[key] = {"functions": sum(n for n, _ in notices), "seconds": round(sum(t for _, t in notices), 1)}
    print(f"{' '.join(args[:3])}: {seconds:.2f} s", file=sys.stderr, flush=True)  # progress of a long run
    return round(seconds, 2)


PROFILE = r"""
import atexit, json, os, sys, time
from numba.core import event

records, stack = [], []

class Profile(event.Listener):
    def on_start(self, ev):
        dispatcher = ev.data["dispatcher"]
        name = f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}"
        stack.append([time.process_time(), 0.0, name, 0.0, dispatcher.py_func.__module__,
                      dispatcher.py_func.__qualname__])

    def on_end(self, ev):
        started, children, name, llvm, module, qualname = stack.pop()
        total = time.process_time() - started
        if stack:
            stack[-1][1] += total
        records.append({"function": name, "signature": str(tuple(ev.data["args"])),
                        "self_s": round(total - children, 3), "total_s": round(total, 3), "llvm_s": round(llvm, 3),
                        "caller": stack[-1][2] if stack else None, "module": module, "name": qualname})

class Llvm(event.Listener):
    depth, started = 0, 0.0

    def on_start(self, ev):
        if self.depth == 0:
            self.started = time.process_time()
        self.depth += 1

    def on_end(self, ev):
        self.depth -= 1
        if self.depth == 0 and stack:
            stack[-1][3] += time.process_time() - self.started

event.register("numba:compile", Profile())
event.register("numba:llvm_lock", Llvm())
atexit.register(lambda: open(os.environ["PVEROSION_COMPILE_PROFILE"], "w").write(json.dumps(records)))
sys.argv = ["pverosion", *sys.argv[1:]]
from pverosion.cli import main
raise SystemExit(main())
"""


def per_kernel(stage: str, command: list[str], folder: Path, top: int) -> dict:
    """Compile seconds per function and signature of one cold run of ``stage`` (see the module docstring)."""
    cache = folder / f"cache_profile_{stage}"
    out = folder / f"profile_{stage}.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(cache), "PVEROSION_COMPILE_PROFILE": str(out),
           "PVEROSION_PRECOMPILE": "0"}  # everything compiled in this process, without the helper
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([sys.executable, "-c", PROFILE, *command], env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"{stage} failed:\n{done.stderr[-2000:]}")
    records = json.loads(out.read_text())
    plan = [[r["module"], r["name"], r["signature"], r["total_s"]] for r in records  # top-level, in order of use
            if r["caller"] is None and r["module"].startswith("pverosion.") and "<" not in r["name"]]
    records.sort(key=lambda r: -r["self_s"])
    signatures: dict[str, int] = {}
    for record in records:
        signatures[record["function"]] = signatures.get(record["function"], 0) + 1
    return {"process_cpu_s": round(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, 2),
            "numba_s": round(sum(r["total_s"] for r in records if r["caller"] is None), 2),
            "llvm_s": round(sum(r["llvm_s"] for r in records), 2),
            "compiled": len(records),
            "several_signatures": {name: n for name, n in signatures.items() if n > 1},
            "kernels": records[:top] if top > 0 else records, "plan": plan}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT)
    parser.add_argument("--stages", default="", help="comma-separated stages (default: all)")
    parser.add_argument("--skip-warmup", action="store_true", help="do not time pverosion warmup")
    parser.add_argument("--per-kernel", action="store_true",
                        help="only the cold runs, with the compile seconds of every function and signature")
    parser.add_argument("--top", type=int, default=30, help="with --per-kernel: functions listed per stage (0: all)")
    parser.add_argument("--write-plan", action="store_true",
                        help="run the stages cold and write the kernels each compiles, in order, to "
                             "pverosion/compile_plan.json (the compile helper's plan)")
    add_load_option(parser)
    args = parser.parse_args()
    stages = [s for s in args.stages.split(",") if s] or [s.command for s in STAGE_INDEX]
    if "sample-materials" in stages and "materials" not in stages:
        stages.insert(stages.index("sample-materials"), "materials")  # it reads the tree materials writes
    with tempfile.TemporaryDirectory(prefix="pverosion_cold_") as tmp:
        folder = Path(tmp)
        commands = _inputs(folder, args.data)
        if args.per_kernel or args.write_plan:
            profiles = {stage: per_kernel(stage, commands[stage], folder, args.top)
                        for stage in stages}
            if args.write_plan:
                plans = json.loads(PLAN_FILE.read_text()) if PLAN_FILE.exists() else {}
                plans.update({stage: profile.pop("plan") for stage, profile in profiles.items()})
                PLAN_FILE.write_text(json.dumps(dict(sorted(plans.items())), indent=1) + "\n")
                return
            for profile in profiles.values():
                del profile["plan"]
            print(json.dumps({"benchmark": "cold_start_per_kernel", "mesh": args.data.name, "stages": profiles},
                             indent=1))
            return
        result: dict = {"benchmark": "cold_start", "cpus": os.cpu_count(), "mesh": args.data.name,
                        "numba_num_threads": os.environ.get("NUMBA_NUM_THREADS", "default")}
        warm_cache = folder / "cache_warm"
        result["import_s"] = _wall(["-c", "import pverosion"], warm_cache)
        result["help_s"] = _wall(["-m", "pverosion", "--help"], warm_cache)
        cold, warm, cold_cpu, warm_cpu, compiled, warm_compiled = {}, {}, {}, {}, {}, {}
        for stage in stages:
            cache = folder / f"cache_{stage}"  # new and empty: nothing compiled yet
            cold[stage] = _wall(["-m", "pverosion", *commands[stage]], cache, cold_cpu, stage, compiled)
            warm[stage] = _wall(["-m", "pverosion", *commands[stage]], cache, warm_cpu, stage, warm_compiled)
        result.update(cold_s=cold, warm_s=warm, cold_cpu_s=cold_cpu, warm_cpu_s=warm_cpu, cold_compiled=compiled,
                      warm_compiled_functions=sum(c["functions"] for c in warm_compiled.values()))
        if not args.skip_warmup:
            cache = folder / "cache_warmup"
            warmup_compiled = {}
            result["warmup_all_s"] = _wall(["-m", "pverosion", "warmup", *stages], cache, None, "all", warmup_compiled)
            result["warmup_compiled"] = warmup_compiled["all"]
            after, after_cpu = {}, {}
            for stage in stages:
                after[stage] = _wall(["-m", "pverosion", *commands[stage]], cache, after_cpu, stage)
            result.update(after_warmup_s=after, after_warmup_cpu_s=after_cpu)
        result["targets_s"] = TARGETS_S
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    run(main, timings=("import_s", "help_s", "cold_s.curvature", "warm_s.curvature", "cold_s.weather",
                       "warm_s.weather", "cold_s.boolean", "warm_s.boolean"))
