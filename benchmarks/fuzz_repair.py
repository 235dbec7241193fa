"""Nightly-size fuzz run of the repair and the Booleans against manifold3d; prints one JSON object of outcomes.

The seeded corpus of ``tests/test_repair_guarantees.py``, larger: Booleans of
two rigid copies of small shapes and of the bunny (``../shared/data/bunny.ply``,
decimated, holes filled, when present), half of the copies on a grid of exact
moves (shared planes, edges, vertices; touching and nested parts), and repaired
soups of three overlapping parts. Every case must give a closed, oriented
2-manifold without self-intersections (:func:`~pverosion.kernels.repair.mesh_repair.mesh_problems`
finds nothing) whose volume is manifold3d's within ``--rtol``, or raise
``RepairError``; faces overlapping in a common plane are cut like any others. Failures are listed by case number
(rerun one with ``--first N --cases 1``).

Usage: ``python benchmarks/fuzz_repair.py [--cases 20000] [--seed 1] [--first 0] [--rtol 1e-6]``
"""

from __future__ import annotations

import argparse
import json
import time

import manifold3d
import numpy as np

from pverosion.examples import data_path
from pverosion.kernels.mesh.geometry import signed_volume
from pverosion.kernels.repair.mesh_repair import (
    OPERATIONS,
    RepairError,
    boolean_meshes,
    mesh_problems,
    repair_intersections,
)
from pverosion.scenes.intersection import fuzz_operands, fuzz_primitives

DATA = data_path()


def _solid(mesh):
    solid = manifold3d.Manifold(manifold3d.Mesh(vert_properties=np.asarray(mesh.points, np.float32),
                                                tri_verts=np.asarray(mesh.regular_faces, np.uint32)))
    return solid if solid.status() == manifold3d.Error.NoError else None


def run_case(parts, operation: str | None, rtol: float) -> str:
    """Outcome of one case: "ok", "refused", "manifold3d refused" or a failure's description."""
    arrays = [(np.asarray(m.points, np.float64), np.asarray(m.regular_faces, np.int64)) for m in parts]
    try:
        if operation is None:
            offsets = np.cumsum([0] + [len(p) for p, _ in arrays[:-1]])
            points = np.concatenate([p for p, _ in arrays])
            faces = np.concatenate([f + o for (_, f), o in zip(arrays, offsets)])
            result = repair_intersections(points, faces)
        else:
            result = boolean_meshes(*arrays[0], *arrays[1], operation)
    except RepairError:
        return "refused"
    if len(result.faces):
        problems = mesh_problems(result.points, result.faces)
        if problems:
            return "broken: " + "; ".join(problems)
    solids = [_solid(m) for m in parts]
    if any(s is None for s in solids):
        return "manifold3d refused"
    if operation is None:
        reference = manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add)
    else:
        a, b = solids
        reference = {"union": a + b, "intersection": a ^ b, "difference": a - b, "reverse_difference": b - a}[operation]
    volume = signed_volume(result.points, result.faces) if len(result.faces) else 0.0
    if abs(volume - reference.volume()) > rtol * max(abs(reference.volume()), 1e-12):
        return f"volume {volume!r} against manifold3d's {reference.volume()!r}"
    return "ok"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=20000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--first", type=int, default=0, help="skip the cases before this one")
    parser.add_argument("--rtol", type=float, default=1e-6)
    args = parser.parse_args()
    bunny = DATA / "bunny.ply"
    shapes = fuzz_primitives(bunny=bunny if bunny.exists() else None)
    rng = np.random.default_rng(args.seed)
    outcomes: dict[str, int] = {}
    failures = []
    start = time.perf_counter()
    for case in range(args.first + args.cases):
        soup = case % 5 == 4
        parts = fuzz_operands(rng, shapes, count=3 if soup else 2)
        if case < args.first:
            continue
        outcome = run_case(parts, None if soup else OPERATIONS[case % 4], args.rtol)
        key = outcome if outcome in ("ok", "refused", "manifold3d refused") else "failed"
        outcomes[key] = outcomes.get(key, 0) + 1
        if key == "failed":
            failures.append({"case": case, "what": outcome})
    print(json.dumps({"cases": args.cases, "seed": args.seed, "bunny": bunny.exists(), "outcomes": outcomes,
                      "failures": failures[:50], "seconds": round(time.perf_counter() - start, 1)}, indent=2))


if __name__ == "__main__":
    main()
