import numpy as np
from conftest import icosphere

from pverosion.kernels.mesh.geometry import face_normals, signed_volume
from pverosion.kernels.mesh.remesh import collapse_short_edges, short_edge_candidates
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
