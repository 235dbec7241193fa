import numpy as np
from conftest import icosphere

from pverosion.kernels.mesh.geometry import average_edge_length, face_normals, signed_volume
from pverosion.kernels.mesh.remesh import (
    CollapseTopology,
    apply_collapses,
    collapse_short_edges,
    plan_collapses,
    short_edge_candidates,
    short_edges_and_mean_length,
)
from pverosion.kernels.mesh.topology import edge_topology


def _sphere_with_short_edges(n_short=40, seed=0):
    s = icosphere(1.0, 3)
    points = np.array(s.points)
    faces = s.regular_faces.astype(np.int64)
    rng = np.random.default_rng(seed)
    edges = edge_topology(faces, len(points)).edges
    for a, b in edges[rng.choice(len(edges), n_short, replace=False)]:
        points[b] = points[a] + 0.05 * (points[b] - points[a])
    return points, faces


def _inward(points, faces):
    normals, _ = face_normals(points, faces)
    return int(np.count_nonzero(np.einsum("ij,ij->i", normals, points[faces].mean(axis=1)) <= 0))


def test_collapse_keeps_a_closed_manifold_without_flips_or_added_volume():
    points, faces = _sphere_with_short_edges()
    topo = edge_topology(faces, len(points))
    candidates = short_edge_candidates(points, topo.edges, topo.face_count == 2, 0.02)
    assert len(candidates) > 0
    lengths = np.linalg.norm(points[candidates[:, 0]] - points[candidates[:, 1]], axis=1)
    assert np.all(np.diff(lengths) >= 0) and lengths.max() < 0.02
    before = (points.copy(), faces.copy())
    result = collapse_short_edges(points, faces, candidates, np.zeros(len(points), bool))
    assert np.array_equal(points, before[0]) and np.array_equal(faces, before[1])  # inputs untouched
    assert result.n_collapsed > 0
    assert len(result.points) == len(points) - result.n_collapsed
    assert len(result.faces) == len(faces) - 2 * result.n_collapsed
    after = edge_topology(result.faces, len(result.points))
    assert after.n_boundary_edges == 0 and after.n_nonmanifold_edges == 0
    assert signed_volume(result.points, result.faces) <= signed_volume(points, faces)
    # no face turns inward (the perturbation itself folded a few thin ones)
    assert _inward(result.points, result.faces) <= _inward(points, faces)
    # survivors keep their input coordinates unless they absorbed a neighbour
    moved = np.any(result.points != points[result.kept], axis=1)
    assert moved.sum() <= result.n_collapsed


def test_locked_vertices_stay():
    points, faces = _sphere_with_short_edges()
    topo = edge_topology(faces, len(points))
    candidates = short_edge_candidates(points, topo.edges, topo.face_count == 2, 0.02)
    locked = np.zeros(len(points), bool)
    locked[candidates.ravel()] = True
    result = collapse_short_edges(points, faces, candidates, locked)
    assert result.n_collapsed == 0
    assert np.array_equal(result.faces, faces)


def _noisy_sphere(open_it: bool, seed: int):
    """A sphere with jittered vertices (many edges far below the mean length), open or closed."""
    s = icosphere(1.0, 3)
    points, faces = np.array(s.points), s.regular_faces.astype(np.int64)
    rng = np.random.default_rng(seed)
    if open_it:
        faces = faces[rng.random(len(faces)) > 0.05]
    return points + rng.normal(scale=0.03, size=points.shape), faces


def test_a_pass_equals_its_collapses_made_one_at_a_time():
    """The pass decides all collapses on the unchanged mesh; making the same candidates one by one, each on the
    mesh the earlier ones left (and freezing what they touched), gives the same mesh bit for bit."""
    for seed, open_it in ((0, False), (1, True)):
        points, faces = _noisy_sphere(open_it, seed)
        topo = CollapseTopology.build(faces, len(points))
        mean = np.linalg.norm(points[topo.edges[:, 0]] - points[topo.edges[:, 1]], axis=1).mean()
        candidates = short_edge_candidates(points, topo.edges, topo.usable, 0.8 * mean)
        batch = collapse_short_edges(points, faces, candidates, topo.fixed)
        assert batch.n_collapsed > 50
        pts, fcs, where = points, faces, np.arange(len(points))  # where: current index of every input vertex
        frozen = topo.fixed.copy()  # by input vertex
        for a, b in candidates:
            if frozen[a] or frozen[b]:
                continue
            locked = np.zeros(len(pts), bool)
            pairs, positions = plan_collapses(pts, fcs, [[where[a], where[b]]], locked)
            if len(pairs) == 0:
                continue
            ring = CollapseTopology.build(fcs, len(pts)).ring
            current = np.flatnonzero(where >= 0)
            for v in (where[a], where[b]):
                frozen[current[np.isin(where[current], ring[1][ring[0][v]:ring[0][v + 1]])]] = True
            result, _ = apply_collapses(pts, fcs, pairs, positions)
            pts, fcs = result.points, result.faces
            remap = np.full(len(where), -1)
            remap[result.kept] = np.arange(len(result.kept))
            where = np.where(where >= 0, remap[np.maximum(where, 0)], -1)
        assert np.array_equal(pts, batch.points) and np.array_equal(fcs, batch.faces)


def test_topology_after_collapses_equals_a_rebuild():
    for seed, open_it in ((2, False), (3, True)):
        points, faces = _noisy_sphere(open_it, seed)
        topo = CollapseTopology.build(faces, len(points))
        for _ in range(4):
            mean = np.linalg.norm(points[topo.edges[:, 0]] - points[topo.edges[:, 1]], axis=1).mean()
            candidates = short_edge_candidates(points, topo.edges, topo.usable, 0.6 * mean)
            pairs, positions = plan_collapses(points, faces, candidates, topo.fixed, incidence=topo.incidence)
            assert len(pairs) > 0
            result, new_face = apply_collapses(points, faces, pairs, positions)
            assert np.array_equal(result.faces, _new_face_rows(faces, new_face, result))
            topo = topo.collapsed(result, new_face)
            points, faces = result.points, result.faces
            rebuilt = CollapseTopology.build(faces, len(points))
            for name in ("edges", "usable", "fixed"):
                assert np.array_equal(getattr(topo, name), getattr(rebuilt, name))
            for mine, theirs in zip((*topo.ring, *topo.incidence), (*rebuilt.ring, *rebuilt.incidence)):
                assert np.array_equal(mine, theirs)
            reference = edge_topology(faces, len(points))
            assert np.array_equal(topo.fixed, reference.irregular_vertices(len(points)))
            assert len(topo.edges) == len(reference.edges)
            usable = reference.edges[reference.face_count == 2]
            assert set(map(tuple, topo.edges[topo.usable])) == set(map(tuple, usable))


def _new_face_rows(faces, new_face, result):
    """The faces that survive, renumbered by hand: every merged vertex b replaced by its a."""
    target = np.arange(faces.max() + 1)
    target[result.pairs[:, 1]] = result.pairs[:, 0]
    remap = np.full(len(target), -1)
    remap[result.kept] = np.arange(len(result.kept))
    return remap[target[faces[new_face >= 0]]]


def test_short_edges_and_mean_length_equal_the_two_passes_bit_for_bit_on_any_thread_count():
    """One pass over the edges gives the candidates of :func:`short_edge_candidates` and, bit for bit, the mean of
    :func:`average_edge_length` (a step's threshold and the next step's mean come from it), with one thread and
    with all."""
    from conftest import one_and_all_threads

    points, faces = _sphere_with_short_edges(n_short=40, seed=3)
    topo = edge_topology(faces, len(points))
    usable = np.ones(len(topo.edges), bool)
    usable[::7] = False  # unusable edges are measured but never candidates
    mean = average_edge_length(points, faces, edges=topo.edges)
    for threshold, expect_short in ((0.1 * mean, True), (1e-6 * mean, False)):
        one, every = one_and_all_threads(
            lambda t=threshold: short_edges_and_mean_length(points, topo.edges, usable, t))
        for candidates, mean_length in (one, every):
            assert mean_length == mean
            assert np.array_equal(candidates, short_edge_candidates(points, topo.edges, usable, threshold))
            assert (len(candidates) > 0) == expect_short
