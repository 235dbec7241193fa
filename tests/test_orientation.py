import numpy as np
import pytest
from conftest import height_field, icosphere, one_and_all_threads

from pverosion.kernels import orient_faces, signed_volume, winding_number
from pverosion.kernels.mesh import orientation
from pverosion.kernels._scatter import owned_rows
from pverosion.kernels.mesh.orientation import orient_sorted
from pverosion.kernels.mesh.topology import sorted_twins


def _scramble(faces, seed=0):
    rng = np.random.default_rng(seed)
    flip = rng.random(len(faces)) < 0.5
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, flip


def test_scrambled_sphere_becomes_consistent_and_outward():
    s = icosphere(1.0, 3)
    scrambled, flip = _scramble(s.regular_faces)
    o = orient_faces(s.points, scrambled)
    assert o.n_components == 1
    np.testing.assert_array_equal(o.flipped, flip)
    assert signed_volume(s.points, o.faces) > 0
    inward = orient_faces(s.points, scrambled, mode="inward")
    assert signed_volume(s.points, inward.faces) < 0
    kept = orient_faces(s.points, scrambled, mode="keep")
    np.testing.assert_array_equal(kept.faces, scrambled)
    with pytest.raises(ValueError, match="orientation must be one of"):
        orient_faces(s.points, scrambled, mode="up")


def test_bunny_scan_is_turned_outward(bunny):
    p, f = np.asarray(bunny.points, float), bunny.regular_faces
    assert signed_volume(p, f) < 0  # the file winds inward
    o = orient_faces(p, f)
    assert o.n_flipped == len(f)
    assert signed_volume(p, o.faces) > 0


def test_open_dome_faces_up_whatever_its_input_winding():
    dome = height_field(lambda x, y: 1.0 - 0.5 * (x**2 + y**2), n=21)
    for faces in (dome.regular_faces, dome.regular_faces[:, ::-1]):
        o = orient_faces(dome.points, faces)
        n = np.cross(*(dome.points[o.faces[:, k]] - dome.points[o.faces[:, 0]] for k in (1, 2)))
        assert np.all(n[:, 2] > 0)


def test_cavity_wall_points_into_the_cavity():
    outer, inner = icosphere(2.0, 2), icosphere(1.0, 2)
    p = np.vstack([outer.points, inner.points])
    f = np.vstack([outer.regular_faces, inner.regular_faces[:, ::-1] + outer.n_points])
    f, _ = _scramble(f, seed=3)
    o = orient_faces(p, f)
    n_outer = len(outer.regular_faces)
    assert signed_volume(p, o.faces[:n_outer]) > 0  # outer shell outward
    assert signed_volume(p, o.faces[n_outer:]) < 0  # cavity wall faces into the hole
    solid = signed_volume(outer.points, outer.regular_faces) - signed_volume(inner.points, inner.regular_faces)
    assert np.isclose(signed_volume(p, o.faces), solid, rtol=1e-9)


def test_winding_number_inside_and_outside():
    s = icosphere(1.0, 3)
    assert winding_number([0.1, 0.0, 0.2], s.points, s.regular_faces) == pytest.approx(1.0, abs=1e-9)
    assert winding_number([3.0, 0.0, 0.0], s.points, s.regular_faces) == pytest.approx(0.0, abs=1e-9)


def _two_shells():
    outer, inner = icosphere(2.0, 2), icosphere(1.0, 2)
    p = np.vstack([outer.points, inner.points])
    f = np.vstack([outer.regular_faces, inner.regular_faces + outer.n_points])
    return p, _scramble(f, seed=5)[0]


def test_orientation_is_invariant_under_vertex_and_face_permutations():
    p, f = _two_shells()
    o = orient_faces(p, f)
    rng = np.random.default_rng(7)
    vperm = rng.permutation(len(p))  # new vertex i is old vertex vperm[i]
    rank = np.argsort(vperm)
    fperm = rng.permutation(len(f))
    q = orient_faces(p[vperm], rank[f[fperm]])
    np.testing.assert_array_equal(q.flipped, o.flipped[fperm])
    np.testing.assert_array_equal(vperm[q.faces], o.faces[fperm])
    # components are numbered differently, but group the same faces
    pairs = set(zip(o.component[fperm].tolist(), q.component.tolist()))
    assert len(pairs) == o.n_components == q.n_components == 2


def test_orienting_an_outward_mesh_is_a_no_op():
    p, f = _two_shells()
    outward = orient_faces(p, f).faces
    again = orient_faces(p, outward)
    assert again.n_flipped == 0
    np.testing.assert_array_equal(again.faces, outward)
    assert again.faces is not outward  # a new array, the input stays the caller's
    inward = orient_faces(p, outward, mode="inward")
    assert inward.n_flipped == len(f)


def test_sorted_orientation_matches_the_input_order_result():
    p, f = _two_shells()
    o = orient_faces(p, f)
    s = orient_sorted(p, f)
    np.testing.assert_array_equal(np.sort(s.order), np.arange(len(f)))
    np.testing.assert_array_equal(s.faces, o.faces[s.order])
    np.testing.assert_array_equal(s.flip, o.flipped[s.order])
    np.testing.assert_array_equal(s.component, o.component[s.order])
    np.testing.assert_array_equal(s.input_faces(f), o.faces)
    assert s.n_flipped == o.n_flipped
    lo = s.faces.min(axis=1)
    assert np.all(np.diff(lo) >= 0)  # sorted by smallest vertex
    counted = owned_rows(s.faces, len(p))  # the rows the curvature's face chunks own, counted on the way
    np.testing.assert_array_equal(s.owned.owners, counted.owners)
    np.testing.assert_array_equal(s.owned.outside, counted.outside)
    assert counted.n_outside > 0
    with pytest.raises(ValueError, match="orientation must be"):
        orient_sorted(p, f, mode="keep")


def _touching_spheres():
    """Two unit spheres side by side that share one vertex (a non-manifold vertex, no shared edge)."""
    s = icosphere(1.0, 2)
    p, f = np.asarray(s.points), s.regular_faces
    touch = int(np.argmax(p[:, 0]))  # the right sphere's rightmost vertex ...
    mirrored = p * [-1.0, 1.0, 1.0] + [2.0 * p[touch, 0], 0.0, 0.0]  # ... is the left one of its mirror image
    second = f[:, ::-1] + len(p)  # mirroring reverses the winding: reversed again, still outward
    second[second == touch + len(p)] = touch
    return np.vstack([p, mirrored]), f, second


@pytest.mark.parametrize("inward_shell", [0, 1])
def test_shells_touching_at_a_vertex_are_turned_outward_each(inward_shell):
    p, first, second = _touching_spheres()
    shells = [first, second]
    shells[inward_shell] = shells[inward_shell][:, ::-1]
    f = np.vstack(shells)
    assert abs(signed_volume(p, f)) < 1e-9 * signed_volume(p, first)  # the two windings cancel
    o = orient_faces(p, f)
    assert o.n_components == 2  # connected through a vertex only: two components
    n = len(first)
    assert signed_volume(p, o.faces[:n]) > 0 and signed_volume(p, o.faces[n:]) > 0
    expected = np.zeros(len(f), bool)
    expected[inward_shell * n:(inward_shell + 1) * n] = True
    np.testing.assert_array_equal(o.flipped, expected)
    inward = orient_faces(p, f, mode="inward")
    np.testing.assert_array_equal(inward.flipped, ~expected)


def test_consistent_shells_of_opposite_windings_are_turned_outward_each():
    a, b = icosphere(1.0, 2), icosphere(0.5, 2)
    p = np.vstack([a.points, np.asarray(b.points) + [3.0, 0.0, 0.0]])
    f = np.vstack([a.regular_faces[:, ::-1], b.regular_faces + a.n_points])  # first inward, second outward
    o = orient_faces(p, f)
    n = len(a.regular_faces)
    assert o.n_components == 2
    np.testing.assert_array_equal(o.flipped, np.arange(len(f)) < n)
    assert signed_volume(p, o.faces[:n]) > 0 and signed_volume(p, o.faces[n:]) > 0


@pytest.mark.parametrize("reverse", [False, True])
def test_consistent_open_hemisphere_is_turned_to_face_out(reverse):
    s = icosphere(1.0, 3)
    p, f = np.asarray(s.points), s.regular_faces
    cap = f[p[f].mean(axis=1)[:, 2] > 0.05]  # an open cap, its rim a hole
    faces = cap[:, ::-1] if reverse else cap
    o = orient_faces(p, faces)
    assert o.n_flipped == (len(cap) if reverse else 0)
    np.testing.assert_array_equal(o.faces, faces[:, [0, 2, 1]] if reverse else cap)  # a flip swaps the last two
    normals = np.cross(p[o.faces[:, 1]] - p[o.faces[:, 0]], p[o.faces[:, 2]] - p[o.faces[:, 0]])
    assert np.all(np.einsum("ij,ij->i", normals, p[o.faces].mean(axis=1)) > 0)  # away from the centre


def _moebius_strip(n: int = 1200, w: int = 2):
    """A Möbius strip of ``n`` x ``w`` quads (2 n w triangles), its ends glued with a half twist."""
    u = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)[:, None]
    t = np.linspace(-0.3, 0.3, w + 1)[None, :]
    r = 1.0 + t * np.cos(u / 2)
    p = np.stack([r * np.cos(u), r * np.sin(u), t * np.sin(u / 2)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(w), indexing="ij")
    a, b = i * (w + 1) + j, i * (w + 1) + j + 1
    last = i == n - 1  # the glued quads meet the first column upside down
    c = np.where(last, w - j - 1, (i + 1) * (w + 1) + j + 1)
    d = np.where(last, w - j, (i + 1) * (w + 1) + j)
    f = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return p, f


def _serial_propagation(faces, partner):
    flip = np.zeros(len(faces), bool)
    component = np.full(len(faces), -1, np.int64)
    n = orientation._propagate(faces, partner, flip, component, np.empty(len(faces), partner.dtype))
    return flip, component, n


@pytest.mark.parametrize("case", ["shells", "moebius"])
def test_propagation_in_parts_equals_one_serial_pass_whatever_the_threads(case, monkeypatch):
    monkeypatch.setattr(orientation, "SPLIT_FACES", 4096)  # split these small meshes too
    if case == "shells":  # 10 scrambled spheres in shuffled face order: several parts, components across parts
        s = icosphere(1.0, 3)
        p = np.vstack([np.asarray(s.points) + [3.0 * k, 0.0, 0.0] for k in range(10)])
        f = np.vstack([_scramble(s.regular_faces, k)[0] + k * s.n_points for k in range(10)])
        f = f[np.random.default_rng(11).permutation(len(f))]
    else:
        p, f = _moebius_strip()
        f = _scramble(f, 12)[0]
    one, many = one_and_all_threads(lambda: orient_sorted(p, f))
    for name in ("order", "faces", "flip", "component"):
        np.testing.assert_array_equal(getattr(one, name), getattr(many, name))
    _, local, partner, _ = sorted_twins(f, len(p))
    flip, component, n_comp = _serial_propagation(local, partner)
    h = np.flatnonzero(partner >= 0)
    same = local.ravel()[h] == local.ravel()[partner[h]]  # twins that start at the same vertex
    assert np.any((flip[h // 3] ^ flip[partner[h] // 3]) != same) == (case == "moebius")  # non-orientable
    state, labels, root_comp, root_flip, n_split = one_and_all_threads(
        lambda: orientation._propagate_split(local, partner))[1]
    assert n_split == n_comp == (10 if case == "shells" else 1)
    np.testing.assert_array_equal(root_comp[labels], component)
    np.testing.assert_array_equal((state & orientation._FLIP != 0) ^ root_flip[labels], flip)
