"""Nearly degenerate faces: the pre-pass of the repair removes needles and caps (an exactly degenerate face on an
intersection curve cannot be cut otherwise), and the optional improvement afterwards cleans up the slivers the
cutting makes while the curves stay."""

import numpy as np
import pytest
import pyvista as pv
from test_mesh_repair import _reference, _volume, assert_clean
from test_topology_repair import _closed

from pverosion.kernels.mesh.degenerate import remove_degenerate_faces
from pverosion.kernels.mesh.geometry import average_edge_length
from pverosion.kernels.repair.mesh_repair import IMPROVE_EDGE_RATIO, boolean_meshes, repair_intersections

A = pv.Icosphere(radius=1.0, nsub=3)
B = pv.Icosphere(radius=0.6, nsub=2).rotate_z(17.0).translate((0.95, 0.2, 0.1))


def _arrays(mesh):
    return np.asarray(mesh.points, dtype=float), mesh.regular_faces.copy()


def with_cap(points, faces, f):
    """Face f = (a, b, c) split at the midpoint m of a-b into (a, m, c), (m, b, c) and the flat face (a, b, m),
    which closes the mesh again: a cap with its corner exactly on its longest edge."""
    a, b, c = faces[f]
    points = np.vstack([points, 0.5 * (points[a] + points[b])])
    m = len(points) - 1
    return points, np.vstack([np.delete(faces, f, axis=0), [[a, m, c], [m, b, c], [a, b, m]]])


def with_needle(points, faces, f, gap):
    """Face f = (a, b, c) split at a point m ``gap`` from a on a-b, and its neighbour across a-b likewise."""
    a, b, c = faces[f]
    g = next(g for g in range(len(faces)) if g != f and a in faces[g] and b in faces[g])
    d = int(sum(faces[g]) - a - b)
    points = np.vstack([points, points[a] + gap * (points[b] - points[a]) / np.linalg.norm(points[b] - points[a])])
    m = len(points) - 1
    rest = np.delete(faces, [f, g], axis=0)
    return points, np.vstack([rest, [[a, m, c], [m, b, c], [b, m, d], [m, a, d]]])


def _heights_and_edges(points, faces):
    t = points[faces]
    edges = np.linalg.norm(t - np.roll(t, 1, axis=1), axis=2)
    area2 = np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    return area2 / edges.max(axis=1), edges


def test_needles_collapse_and_caps_flip_without_changing_the_shape():
    points, faces = _arrays(A)
    points, faces = with_cap(points, faces, 10)
    points, faces = with_needle(points, faces, 400, 1e-12)
    height, edge = _heights_and_edges(points, faces)
    assert height.min() < 1e-12 and edge.min() < 1e-11
    before = (points.copy(), faces.copy())
    out = remove_degenerate_faces(points, faces, needle_length=1e-9, cap_height=1e-9)
    assert np.array_equal(points, before[0]) and np.array_equal(faces, before[1])  # inputs untouched
    assert out.collapsed >= 1 and out.flipped >= 1
    assert _closed(out.faces)
    height, edge = _heights_and_edges(out.points, out.faces)
    assert height.min() > 1e-9 and edge.min() > 1e-9
    assert _volume(out.points, out.faces) == pytest.approx(_volume(points, faces), rel=1e-12)
    # every vertex is one of the input's, moved by no more than the collapsed edge
    assert np.all(out.vertex_source >= 0)
    assert np.abs(out.points - points[out.vertex_source]).max() <= 1e-12
    assert len(out.face_source) == len(out.faces) and out.face_source.max() < len(faces)


def test_a_degenerate_face_on_the_curve_needs_the_pre_pass():
    a_points, a_faces = _arrays(A)
    b_points, b_faces = _arrays(B)
    plain = boolean_meshes(a_points, a_faces, b_points, b_faces, "union")
    on_curve = int(plain.curves.pairs[0, 0])  # a face of A that the intersection curve crosses
    a_points, a_faces = with_cap(a_points, a_faces, on_curve)
    with pytest.raises(RuntimeError, match="could not be cut"):
        boolean_meshes(a_points, a_faces, b_points, b_faces, "union", tolerance=0.0)
    for operation in ("union", "difference"):
        result = boolean_meshes(a_points, a_faces, b_points, b_faces, operation)
        assert_clean(result.points, result.faces)
        assert _volume(result.points, result.faces) == pytest.approx(_reference(A, B, operation), rel=1e-3)
        assert result.source_face.max() < len(a_faces) + len(b_faces)
        kept = result.source_vertex >= 0
        inputs = np.vstack([a_points, b_points])
        assert np.abs(result.points[kept] - inputs[result.source_vertex[kept]]).max() <= 1e-9


def _max_angles(points, faces):
    t = points[faces]
    cos = []
    for k in range(3):
        u, w = t[:, (k + 1) % 3] - t[:, k], t[:, (k + 2) % 3] - t[:, k]
        cos.append(np.einsum("ij,ij->i", u, w) / np.linalg.norm(u, axis=1) / np.linalg.norm(w, axis=1))
    return np.degrees(np.arccos(np.clip(np.min(cos, axis=0), -1.0, 1.0)))


def _distance_to_segments(p, segments):
    a, b = segments[:, 0], segments[:, 1]
    t = np.clip(np.einsum("ij,ij->i", p - a, b - a) / np.einsum("ij,ij->i", b - a, b - a), 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * (b - a) - p, axis=1).min()


@pytest.mark.parametrize("operation", ["union", "difference"])
def test_improvement_removes_the_slivers_and_keeps_the_curves(operation):
    a_points, a_faces = _arrays(A)
    b_points, b_faces = _arrays(B)
    plain = boolean_meshes(a_points, a_faces, b_points, b_faces, operation)
    better = boolean_meshes(a_points, a_faces, b_points, b_faces, operation, improve=True)
    assert_clean(better.points, better.faces)
    assert _volume(better.points, better.faces) == pytest.approx(_reference(A, B, operation), rel=1e-3)
    edge = average_edge_length(np.vstack([a_points, b_points]), np.vstack([a_faces, b_faces + len(a_points)]))
    short = [np.count_nonzero(_heights_and_edges(r.points, r.faces)[1] < IMPROVE_EDGE_RATIO * edge)
             for r in (plain, better)]
    assert short[0] > 50 and short[1] <= short[0] // 10
    assert _max_angles(better.points, better.faces).max() <= _max_angles(plain.points, plain.faces).max()
    # the curves stay: closed polylines along mesh edges, every point on the unimproved curves
    edges = {tuple(sorted(e)) for f in better.faces.tolist() for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    segments = np.concatenate([np.stack([plain.points[line[:-1]], plain.points[line[1:]]], axis=1)
                               for line in plain.polylines])
    for line in better.polylines:
        assert line[0] == line[-1] and better.on_curve[line].all()
        assert all(tuple(sorted(e)) in edges for e in zip(line[:-1].tolist(), line[1:].tolist()))
        assert max(_distance_to_segments(p, segments) for p in better.points[line]) < 1e-12
    assert len(better.source_face) == len(better.faces)


def test_repair_options_are_checked():
    points, faces = _arrays(A)
    for bad in (-1e-9, np.nan):
        with pytest.raises(ValueError, match="tolerance"):
            repair_intersections(points, faces, tolerance=bad)


@pytest.mark.parametrize("seed", range(3))
def test_the_screen_finds_a_face_exactly_when_the_pass_would_fix_one(seed):
    """A mesh without candidates stays as it is; random triangles straddle every threshold."""
    from pverosion.kernels.mesh.degenerate import _candidates, _has_candidate

    rng = np.random.default_rng(seed)
    points, faces = _arrays(A)
    edge = average_edge_length(points, faces)
    assert not _has_candidate(points, faces, 0.01 * edge, 0.01 * edge, -2.0)
    clean = remove_degenerate_faces(points, faces, needle_length=0.01 * edge, cap_height=0.01 * edge)
    assert np.array_equal(clean.faces, faces) and np.array_equal(clean.points, points)
    assert np.array_equal(clean.face_source, np.arange(len(faces))) and clean.collapsed == clean.flipped == 0
    flagged = 0
    for _ in range(300):
        tri = rng.normal(size=(3, 3))
        tri[2] = tri[0] + rng.uniform(0.0, 1.0) * (tri[1] - tri[0]) + rng.normal(scale=10.0 ** rng.uniform(-9, 0),
                                                                                  size=3)
        one = np.array([[0, 1, 2]])
        lengths = np.linalg.norm(tri - np.roll(tri, -1, axis=0), axis=1)
        needle, cap, cap_cos = lengths.min() * rng.uniform(0.5, 1.5), rng.uniform(0.0, 1e-3), rng.uniform(-1.0, -0.9)
        found = len(_candidates(tri, one, needle, cap, cap_cos)[0]) > 0
        assert _has_candidate(tri, one, needle, cap, cap_cos) == found
        flagged += found
    assert 30 < flagged < 300  # both outcomes occur
