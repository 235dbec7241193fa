"""Binary space partitions with planes and implicit surfaces (thesis §11.4–11.5).

Inner nodes hold a splitting surface F (``d < 0``: negative child,
``d >= 0``: positive child); leaves hold a material id. Point location runs
in numba over whole point arrays when every surface is built in, and level
by level over NumPy arrays when a node holds a Python callable.

:func:`build_from_triangles` grows a tree from oriented isosurface triangles
with Algorithm 1 of the thesis: faces in a seeded Fisher–Yates order, each
descending the tree and skipped when it lies in a plane already on its path.
``method="complete"`` (C-BSP) clips a face that straddles a plane and sends
each piece down its side, so every leaf is split only by faces that reach
into it; ``method="simplified"`` (S-BSP) sends the whole face down the side
of its centre.

Inserting every marching-cubes face makes trees far larger than the volume
(on smooth data nearly every face is inserted, and a face only approximates
where the voxel centres change material). :func:`build_from_voxel_faces`
grows a C-BSP from the voxels' own boundary surface instead
(:func:`voxel_faces`: the squares between voxels of different labels, merged
into coplanar rectangles): each cell is split by the plane of some of its
faces, chosen for the most face area at the least clipping, all the cell's
faces in that plane are inserted at once, and straddling faces are clipped.
Its planes lie half-way between voxels, so it is held in the compact lattice
layout below: 0.77x the bytes of the MR head, every voxel centre right.
:func:`build_from_labels`
(``method="fitted"``) grows the tree from the labelled voxels themselves
instead. Its candidate splitters stand for runs of nearly coplanar boundary
faces: the planes half-way between lattice points, ``u . i = s + 1/2`` for
a lattice direction ``u`` (the axes, the face and body diagonals and the
directions between them, 49 in all) and an integer ``s``. Each leaf is split by the candidate that
leaves the purest children (least Gini impurity of the labels on each side,
a cost found for every plane of a direction by one sweep over a histogram),
until every leaf holds one label. The tree then gives every voxel centre its
label exactly; its size grows with the area of the material boundaries in
voxels. It is held as a :class:`LatticeBSPTree`: nodes in depth-first order
(the negative child is the next node), each a direction index (1 byte), a
plane offset or leaf material (2 bytes) and the offset of the positive child
(2 bytes), so 5 bytes a node where a general plane node takes 96: about half
the bytes of the 8-bit 48 x 62 x 42 MR head, whose boundaries are noisy, and
a few percent of a volume of tilted strata.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import prange

from pverosion.kernels._jit import njit
from pverosion.kernels.files import atomic_path
from pverosion.kernels.materials.surfaces import (
    N_PARAMS,
    PLANE,
    USER,
    ImplicitSurface,
    surface_value,
)

__all__ = [
    "AXES",
    "BSP_METHODS",
    "BSP_SURFACES",
    "LATTICE_DIRECTIONS",
    "LEAF",
    "BSPNode",
    "BSPStats",
    "BSPTree",
    "LatticeBSPTree",
    "build_from_labels",
    "build_from_triangles",
    "build_from_voxel_faces",
    "voxel_faces",
]

BSP_METHODS = ("complete", "simplified", "fitted")
"""Accepted values of the ``method`` option of the automated build."""

BSP_SURFACES = ("voxels", "isosurface")
"""Surfaces a C-BSP is grown from: the voxels' boundary faces (default) or the marching-cubes isosurfaces."""

NODE_BYTES = 24
"""Bytes per node counted in the statistics, as in the thesis (Table 11.2)."""


@dataclass(frozen=True)
class BSPNode:
    """An inner node for building trees by hand: children are nodes or material ids (leaves)."""

    surface: ImplicitSurface
    negative: BSPNode | int
    positive: BSPNode | int


@dataclass(frozen=True)
class BSPStats:
    """Statistics of an automated build (thesis Tables 11.1–11.2).

    ``tree_bytes``: for C-BSP and S-BSP, :data:`NODE_BYTES` per node as the
    thesis counts them; for the fitted tree, the real bytes of its arrays
    (:attr:`LatticeBSPTree.nbytes`). ``volume_bytes``: the input volume's.
    """

    method: str
    extracted_faces: int
    inserted_faces: int
    nodes: int
    height: int
    tree_bytes: int
    volume_bytes: int
    seed: int


@njit(cache=True, error_model="numpy", parallel=True)
def _locate(points, kind, params, negative, positive, leaf):
    n = points.shape[0]
    material = np.empty(n, np.int64)
    distance = np.empty(n)
    for i in prange(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        node = 0
        nearest = np.inf
        while leaf[node] < 0:
            d = surface_value(kind[node], params[node], x, y, z)
            nearest = min(nearest, abs(d))
            node = negative[node] if d < 0.0 else positive[node]
        material[i] = leaf[node]
        distance[i] = nearest
    return material, distance


@njit(cache=True, error_model="numpy", parallel=True)
def _locate_planes(points, planes, children, leaf):
    """Plane-only trees: compact node records, no surface-kind dispatch."""
    n = points.shape[0]
    material = np.empty(n, np.int64)
    distance = np.empty(n)
    for i in prange(n):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        node = 0
        nearest = np.inf
        while leaf[node] < 0:
            d = planes[node, 0] * x + planes[node, 1] * y + planes[node, 2] * z + planes[node, 3]
            nearest = min(nearest, abs(d))
            node = children[node, 0] if d < 0.0 else children[node, 1]
        material[i] = leaf[node]
        distance[i] = nearest
    return material, distance


@njit(cache=True, error_model="numpy")
def _preorder(negative, positive, leaf):
    """Depth-first order (negative child right after its parent): paths stay close in memory."""
    n = leaf.shape[0]
    order = np.empty(n, np.int64)
    stack = np.empty(n, np.int64)
    stack[0] = 0
    top = 1
    k = 0
    while top > 0:
        top -= 1
        node = stack[top]
        order[k] = node
        k += 1
        if leaf[node] < 0:
            stack[top] = positive[node]
            stack[top + 1] = negative[node]
            top += 2
    return order[:k]


def _morton_order(points: np.ndarray) -> np.ndarray:
    """Permutation of points along a 10-bit-per-axis Morton curve of their bounding box."""
    lo = points.min(axis=0)
    size = np.maximum(np.ptp(points, axis=0), 1e-300)
    cells = np.minimum((points - lo) / size * 1024, 1023).astype(np.uint64)
    code = np.zeros(len(points), np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cells[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(code, kind="stable")


def _points_array(points) -> np.ndarray:
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3); got {pts.shape}")
    return pts


def _in_space_order(pts: np.ndarray, kernel) -> tuple[np.ndarray, np.ndarray]:
    """``kernel(pts)`` -> (material, distance), run on large point sets in Morton order.

    Nearby points follow nearby paths: visiting them together keeps the nodes cached.
    """
    if len(pts) < 65536:
        return kernel(pts)
    order = _morton_order(pts)
    material, distance = kernel(pts[order])
    material[order], distance[order] = material.copy(), distance.copy()
    return material, distance


class BSPTree:
    """A BSP tree stored as flat arrays (one row per node).

    Parameters
    ----------
    kind : numpy.ndarray, shape (n,), int64
        Surface kind of each inner node (see :mod:`pverosion.kernels.materials.surfaces`).
    params : numpy.ndarray, shape (n, 8)
        Surface parameters of each inner node.
    negative, positive : numpy.ndarray, shape (n,), int64
        Children of each inner node (-1 for leaves).
    leaf : numpy.ndarray, shape (n,), int64
        Material id of each leaf, -1 for inner nodes.
    user : dict, optional
        ``{node: UserSurface}`` for nodes evaluated in Python.
    """

    def __init__(self, kind, params, negative, positive, leaf, user: dict | None = None) -> None:
        self.kind = np.ascontiguousarray(kind, dtype=np.int64)
        self.params = np.ascontiguousarray(params, dtype=np.float64).reshape(-1, N_PARAMS)
        self.negative = np.ascontiguousarray(negative, dtype=np.int64)
        self.positive = np.ascontiguousarray(positive, dtype=np.int64)
        self.leaf = np.ascontiguousarray(leaf, dtype=np.int64)
        self.user = dict(user or {})
        self.domain: tuple[float, ...] | None = None  # bounds of the volume it was built for, when read from a file
        self.materials: dict | None = None  # hardness and falloff saved with the tree, when read from a file
        n = len(self.kind)
        if n == 0:
            raise ValueError("a BSP tree needs at least one node")
        for name in ("params", "negative", "positive", "leaf"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"BSP arrays must all have {n} rows; {name} has {len(getattr(self, name))}")
        inner = self.leaf < 0
        for child in (self.negative[inner], self.positive[inner]):
            if np.any(child <= np.flatnonzero(inner)) or np.any(child >= n):
                raise ValueError("BSP children must point forward to existing nodes (no cycles)")
        self._planes = None
        if not self.user and np.all(self.kind[inner] == PLANE):
            self._planes = np.ascontiguousarray(self.params[:, :4])
            self._children = np.ascontiguousarray(np.stack([self.negative, self.positive], axis=1), dtype=np.int32)

    def preordered(self) -> BSPTree:
        """The same tree with nodes renumbered depth first (faster location on big trees)."""
        order = _preorder(self.negative, self.positive, self.leaf)
        new_id = np.full(self.n_nodes, -1, np.int64)
        new_id[order] = np.arange(len(order))
        inner = self.leaf[order] < 0
        negative = np.where(inner, new_id[self.negative[order]], -1)
        positive = np.where(inner, new_id[self.positive[order]], -1)
        user = {int(new_id[k]): v for k, v in self.user.items()}
        return BSPTree(self.kind[order], self.params[order], negative, positive, self.leaf[order], user)

    @classmethod
    def from_nodes(cls, root: BSPNode | int) -> BSPTree:
        """Flatten a hand-built tree of :class:`BSPNode` (leaves are material ids)."""
        kind, params, negative, positive, leaf, user = [], [], [], [], [], {}

        def add(node) -> int:
            index = len(kind)
            kind.append(0)
            params.append(np.zeros(N_PARAMS))
            negative.append(-1)
            positive.append(-1)
            if isinstance(node, BSPNode):
                if not isinstance(node.surface, ImplicitSurface):
                    raise TypeError(f"BSPNode.surface must be an ImplicitSurface; got {node.surface!r}")
                leaf.append(-1)
                kind[index] = node.surface.KIND
                params[index] = node.surface.params()
                if node.surface.KIND == USER:
                    user[index] = node.surface
                negative[index] = add(node.negative)
                positive[index] = add(node.positive)
            else:
                if int(node) != node or node < 0:
                    raise ValueError(f"leaves must be material ids >= 0; got {node!r}")
                leaf.append(int(node))
            return index

        add(root)
        return cls(kind, params, negative, positive, leaf, user)

    @property
    def n_nodes(self) -> int:
        """Number of nodes (inner and leaves)."""
        return len(self.kind)

    @property
    def height(self) -> int:
        """Number of inner nodes on the longest root-to-leaf path."""
        depth = np.zeros(self.n_nodes, np.int64)
        for node in range(self.n_nodes):  # children always come after their parent
            if self.leaf[node] < 0:
                depth[self.negative[node]] = depth[self.positive[node]] = depth[node] + 1
        return int(depth.max())

    def locate(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Material id of the leaf containing each point, and the smallest ``|d|`` met on the way.

        Parameters
        ----------
        points : array_like, shape (N, 3)

        Returns
        -------
        material_id : numpy.ndarray, shape (N,), int64
        distance : numpy.ndarray, shape (N,)
            ``min |F(x)|`` over the splitting surfaces on the point's path (the
            distance to the nearest bounding plane for plane trees), which
            drives gradual materials.
        """
        pts = _points_array(points)
        if self.user:
            return self._locate_by_level(pts)
        if self._planes is not None:
            return _in_space_order(pts, lambda p: _locate_planes(p, self._planes, self._children, self.leaf))
        return _in_space_order(pts, lambda p: _locate(p, self.kind, self.params, self.negative, self.positive,
                                                      self.leaf))

    def _locate_by_level(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Level-synchronous location: every surface evaluated once per level on all its points."""
        node = np.zeros(len(pts), np.int64)
        distance = np.full(len(pts), np.inf)
        active = np.flatnonzero(self.leaf[node] < 0)
        while active.size:
            for current in np.unique(node[active]):
                rows = active[node[active] == current]
                if current in self.user:
                    d = self.user[current].evaluate(pts[rows])
                else:
                    d = np.array([surface_value(self.kind[current], self.params[current], *p) for p in pts[rows]])
                distance[rows] = np.minimum(distance[rows], np.abs(d))
                node[rows] = np.where(d < 0.0, self.negative[current], self.positive[current])
            active = active[self.leaf[node[active]] < 0]
        return self.leaf[node], distance

    def to_json(self, path: str | Path, *, domain=None, materials: dict | None = None) -> Path:
        """Save the tree to a small JSON file (built-in surfaces only), with the ``domain`` it was built for
        (bounds ``(xmin, xmax, ymin, ymax, zmin, zmax)``, optional) and its ``materials`` (optional:
        ``{"hardness": [h0, h1, ...], "gradual_scale": s}``, ``s`` 0 for none); :meth:`from_json` sets them as
        ``domain`` and ``materials``."""
        if self.user:
            raise TypeError("a tree with Python-callable surfaces cannot be saved")
        data = {"format": "pverosion-bsp", "version": 1, "kind": self.kind.tolist(),
                "params": self.params.tolist(), "negative": self.negative.tolist(),
                "positive": self.positive.tolist(), "leaf": self.leaf.tolist()}
        return _write_json(path, data, domain, materials)

    @classmethod
    def from_json(cls, path: str | Path) -> BSPTree | LatticeBSPTree:
        """Load a tree written by :meth:`to_json`, or by :meth:`LatticeBSPTree.to_json` (a :class:`LatticeBSPTree`)."""
        data = _read_json(path)
        if data.get("format") == LatticeBSPTree.FORMAT:
            return LatticeBSPTree.from_json(path)
        if data.get("format") != "pverosion-bsp":
            raise ValueError(f"{path} is not a pverosion BSP file")
        try:
            tree = cls(data["kind"], data["params"], data["negative"], data["positive"], data["leaf"])
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"{path}: damaged pverosion BSP file ({error})") from error
        tree.domain = _read_domain(data, path)
        tree.materials = _read_materials(data, path)
        return tree

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays that define the tree (kind, params, children, leaves)."""
        return sum(a.nbytes for a in (self.kind, self.params, self.negative, self.positive, self.leaf))


def split(surface: ImplicitSurface, negative: int, positive: int) -> BSPTree:
    """Division by one surface: material ``negative`` where F < 0, ``positive`` elsewhere."""
    return BSPTree.from_nodes(BSPNode(surface, negative, positive))


# -- automated build (Algorithm 1) ---------------------------------------------------------

_MAX_POLY = 32


@njit(cache=True, error_model="numpy")
def _grow(arrays_f, arrays_i, capacity):
    new_f = np.zeros((capacity, arrays_f.shape[1]))
    new_f[: arrays_f.shape[0]] = arrays_f
    new_i = np.full((capacity, arrays_i.shape[1]), -1, np.int64)
    new_i[: arrays_i.shape[0]] = arrays_i
    return new_f, new_i


@njit(cache=True, error_model="numpy")
def _clip(poly, n, normal, offset, keep_negative, out):
    """Part of convex polygon ``poly[:n]`` on one side of a plane into ``out``; returns its size."""
    m = 0
    for a in range(n):
        b = (a + 1) % n
        da = normal[0] * poly[a, 0] + normal[1] * poly[a, 1] + normal[2] * poly[a, 2] + offset
        db = normal[0] * poly[b, 0] + normal[1] * poly[b, 1] + normal[2] * poly[b, 2] + offset
        if not keep_negative:
            da, db = -da, -db
        if da <= 0.0 and m < _MAX_POLY:
            out[m] = poly[a]
            m += 1
        if (da < 0.0 < db or db < 0.0 < da) and m < _MAX_POLY:
            t = da / (da - db)
            out[m] = poly[a] + t * (poly[b] - poly[a])
            m += 1
    return m


@njit(cache=True, error_model="numpy")
def _build(tri, inside, outside, complete, eps):
    n_tri = tri.shape[0]
    capacity = 2 * n_tri + 16
    plane = np.zeros((capacity, 4))  # normal, offset
    links = np.full((capacity, 3), -1, np.int64)  # negative, positive, leaf material (-1 inner)
    links[0, 2] = -2  # empty root
    n_nodes = 1
    inserted = 0
    stack_poly = np.zeros((256, _MAX_POLY, 3))
    stack_n = np.zeros(256, np.int64)
    stack_node = np.zeros(256, np.int64)
    poly = np.zeros((_MAX_POLY, 3))
    piece = np.zeros((_MAX_POLY, 3))
    for f in range(n_tri):
        p0, p1, p2 = tri[f, 0], tri[f, 1], tri[f, 2]
        normal = np.cross(p1 - p0, p2 - p0)
        length = np.sqrt(normal @ normal)
        if length == 0.0:
            continue
        normal /= length
        offset = -(normal @ p0)
        centre = (p0 + p1 + p2) / 3.0
        stack_poly[0, :3] = tri[f]
        stack_n[0] = 3
        stack_node[0] = 0
        top = 1
        placed = False
        while top > 0:
            top -= 1
            node = stack_node[top]
            n = stack_n[top]
            poly[:n] = stack_poly[top, :n]
            while links[node, 2] == -1:  # inner node: which side(s)?
                nrm = plane[node, :3]
                off = plane[node, 3]
                neg = 0
                pos = 0
                for k in range(n):
                    d = nrm[0] * poly[k, 0] + nrm[1] * poly[k, 1] + nrm[2] * poly[k, 2] + off
                    if d < -eps:
                        neg += 1
                    elif d > eps:
                        pos += 1
                if neg == 0 and pos == 0:
                    node = -1  # lies in a plane already on its path: skipped
                    break
                if not complete:
                    node = links[node, 0] if nrm @ centre + off < 0.0 else links[node, 1]  # S-BSP: the centre
                elif pos == 0:
                    node = links[node, 0]
                elif neg == 0:
                    node = links[node, 1]
                else:  # C-BSP: clip, and send each piece down its own side
                    if top + 2 > stack_n.shape[0]:
                        grown = np.zeros((2 * stack_n.shape[0], _MAX_POLY, 3))
                        grown[:top] = stack_poly[:top]
                        stack_poly = grown
                        stack_n = np.concatenate((stack_n, np.zeros_like(stack_n)))
                        stack_node = np.concatenate((stack_node, np.zeros_like(stack_node)))
                    for keep_negative in (True, False):
                        m = _clip(poly, n, nrm, off, keep_negative, piece)
                        if m >= 3:
                            stack_poly[top, :m] = piece[:m]
                            stack_n[top] = m
                            stack_node[top] = links[node, 0] if keep_negative else links[node, 1]
                            top += 1
                    node = -1
                    break
            if node < 0:
                continue
            # a leaf: it becomes an inner node split by the face's plane
            if n_nodes + 2 > capacity:
                capacity *= 2
                plane, links = _grow(plane, links, capacity)
            plane[node, :3] = normal
            plane[node, 3] = offset
            links[node, 0] = n_nodes
            links[node, 1] = n_nodes + 1
            links[node, 2] = -1
            links[n_nodes, 2] = inside[f]
            links[n_nodes + 1, 2] = outside[f]
            n_nodes += 2
            placed = True
        if placed:
            inserted += 1
    return plane[:n_nodes].copy(), links[:n_nodes].copy(), inserted


def build_from_triangles(
    triangles: np.ndarray,
    inside: np.ndarray,
    outside: np.ndarray,
    *,
    method: str = "complete",
    seed: int = 0,
) -> tuple[BSPTree, int]:
    """Grow a plane BSP tree from oriented triangles (Algorithm 1).

    Parameters
    ----------
    triangles : numpy.ndarray, shape (T, 3, 3)
        Triangle corners, wound so the right-hand normal points to the
        ``outside`` material.
    inside, outside : numpy.ndarray, shape (T,), int
        Material ids behind (negative side) and in front of each triangle.
    method : {"complete", "simplified"}
        C-BSP (clip straddling faces) or S-BSP (route by the centre).
    seed : int
        Seed of the Fisher–Yates insertion order; the same seed gives the same tree.

    Returns
    -------
    tree : BSPTree
    inserted : int
        Faces that created at least one node (the others lay in planes already
        on their path).
    """
    if method not in BSP_METHODS[:2]:
        raise ValueError(f"method must be one of {BSP_METHODS[:2]}; got {method!r}")
    tri = np.ascontiguousarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3) or len(tri) == 0:
        raise ValueError(f"triangles must have shape (T, 3, 3) with T > 0; got {tri.shape}")
    order = np.random.default_rng(seed).permutation(len(tri))  # Fisher–Yates (Durstenfeld)
    extent = float(np.ptp(tri.reshape(-1, 3), axis=0).max()) or 1.0
    plane, links, inserted = _build(tri[order], np.asarray(inside, np.int64)[order],
                                    np.asarray(outside, np.int64)[order], method == "complete", 1e-9 * extent)
    links[links[:, 2] == -2, 2] = 0  # a tree that received no face: one leaf of material 0
    params = np.zeros((len(plane), N_PARAMS))
    params[:, :4] = plane
    tree = BSPTree(np.full(len(plane), PLANE), params, links[:, 0], links[:, 1], links[:, 2])
    return tree.preordered(), int(inserted)


# -- fitted build: lattice planes chosen by the purity of the voxel labels -------------------------------

def _lattice_directions(reach: int) -> np.ndarray:
    """Integer directions with components in [-reach, reach], one per line (coprime, first non-zero > 0).

    Sorted by their L1 length, so the axes come first, then the face and body diagonals.
    """
    grid = np.stack(np.meshgrid(*[np.arange(-reach, reach + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)
    grid = grid[np.gcd.reduce(np.abs(grid), axis=1) == 1]
    first = grid[np.arange(len(grid)), np.argmax(grid != 0, axis=1)]
    grid = grid[first > 0]
    return grid[np.lexsort((-grid[:, 2], -grid[:, 1], -grid[:, 0], np.abs(grid).sum(axis=1)))]


LATTICE_DIRECTIONS = _lattice_directions(2)
"""Normals, in voxel index space, of the planes :func:`build_from_labels` splits with: the 49 directions
with components in {-2, ..., 2} (axes, face and body diagonals, and the directions between them)."""


@njit(cache=True)
def _fit(keys, labels, n_class):
    """Grow a tree over lattice points with keys ``keys[p, u] = u . i_p``, splitting until each leaf is pure.

    Returns per node: split direction and key (the plane ``u . i = key + 1/2``, lower keys on the negative
    side), children (-1 for leaves) and the leaf label (-1 for inner nodes).
    """
    n, n_dir = keys.shape
    index = np.arange(n)
    scratch = np.empty(n, np.int64)
    capacity = 2 * n + 1
    direction = np.full(capacity, -1, np.int64)
    key = np.zeros(capacity, np.int64)
    children = np.full((capacity, 2), -1, np.int64)
    leaf = np.full(capacity, -1, np.int64)
    stack = np.empty((capacity, 3), np.int64)  # (first, end, node)
    stack[0, 0], stack[0, 1], stack[0, 2] = 0, n, 0
    top = 1
    n_nodes = 1
    counts = np.zeros(n_class, np.int64)
    left = np.zeros(n_class, np.int64)
    while top > 0:
        top -= 1
        a, b, node = stack[top, 0], stack[top, 1], stack[top, 2]
        m = b - a
        counts[:] = 0
        for q in range(a, b):
            counts[labels[index[q]]] += 1
        majority = np.argmax(counts)
        if counts[majority] == m:
            leaf[node] = majority
            continue
        best = np.inf
        best_dir = -1
        best_key = 0
        for u in range(n_dir):
            lo = keys[index[a], u]
            hi = lo
            for q in range(a + 1, b):
                k = keys[index[q], u]
                lo = min(lo, k)
                hi = max(hi, k)
            if hi == lo:
                continue
            hist = np.zeros((hi - lo + 1, n_class), np.int64)
            for q in range(a, b):
                hist[keys[index[q], u] - lo, labels[index[q]]] += 1
            left[:] = 0
            n_left = 0
            for s in range(hi - lo):
                for c in range(n_class):
                    left[c] += hist[s, c]
                    n_left += hist[s, c]
                n_right = m - n_left
                if n_left == 0 or n_right == 0:
                    continue
                sq_left = 0.0
                sq_right = 0.0
                for c in range(n_class):
                    sq_left += float(left[c]) * left[c]
                    sq_right += float(counts[c] - left[c]) * (counts[c] - left[c])
                impurity = (n_left - sq_left / n_left) + (n_right - sq_right / n_right)  # weighted Gini
                if impurity < best:
                    best = impurity
                    best_dir = u
                    best_key = lo + s
        # split: keys <= best_key to the negative child
        i = a
        k = 0
        for q in range(a, b):
            p = index[q]
            if keys[p, best_dir] <= best_key:
                index[i] = p
                i += 1
            else:
                scratch[k] = p
                k += 1
        index[i:b] = scratch[:k]
        direction[node] = best_dir
        key[node] = best_key
        children[node, 0] = n_nodes
        children[node, 1] = n_nodes + 1
        stack[top, 0], stack[top, 1], stack[top, 2] = a, i, n_nodes
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = i, b, n_nodes + 1
        top += 2
        n_nodes += 2
    return direction[:n_nodes].copy(), key[:n_nodes].copy(), children[:n_nodes].copy(), leaf[:n_nodes].copy()


LEAF = 255
"""Direction code of a leaf in :class:`LatticeBSPTree` (inner nodes hold a direction index < 255)."""


@njit(cache=True, error_model="numpy", parallel=True)
def _locate_lattice(points, origin, inv_spacing, directions, inv_norm, direction, value, right):
    """Lattice trees in preorder: a node's negative child is the next node, its positive child ``right`` on."""
    n = points.shape[0]
    material = np.empty(n, np.int64)
    distance = np.empty(n)
    for i in prange(n):
        gx = (points[i, 0] - origin[0]) * inv_spacing[0]  # lattice coordinates
        gy = (points[i, 1] - origin[1]) * inv_spacing[1]
        gz = (points[i, 2] - origin[2]) * inv_spacing[2]
        node = 0
        nearest = np.inf
        while direction[node] != LEAF:
            u = direction[node]
            g = directions[u, 0] * gx + directions[u, 1] * gy + directions[u, 2] * gz - (value[node] + 0.5)
            nearest = min(nearest, abs(g) * inv_norm[u])
            node = node + 1 if g < 0.0 else node + right[node]
        material[i] = value[node]
        distance[i] = nearest
    return material, distance


@njit(cache=True)
def _preorder_height(direction, right):
    """Height of a preorder tree, or -1 when the offsets do not describe one tree over all nodes."""
    n = direction.shape[0]
    pending = np.empty(n, np.int64)  # positive children still to visit, and their depths
    pending_depth = np.empty(n, np.int64)
    top = 0
    depth = 0
    height = 0
    for node in range(n):
        if direction[node] != LEAF:
            child = node + np.int64(right[node])
            if child <= node + 1 or child >= n:
                return -1
            pending[top] = child
            pending_depth[top] = depth + 1
            top += 1
            depth += 1
        else:
            height = max(height, depth)
            if top == 0:
                return height if node == n - 1 else -1
            top -= 1
            if pending[top] != node + 1:
                return -1
            depth = pending_depth[top]
    return -1


def _write_json(path: str | Path, data: dict, domain, materials: dict | None = None) -> Path:
    if materials is not None:
        data = {**data, "materials": _checked_materials(materials, "materials")}
    if domain is not None:
        bounds = np.asarray(domain, dtype=np.float64).reshape(-1)
        if bounds.shape != (6,) or not np.isfinite(bounds).all() or np.any(bounds[1::2] < bounds[::2]):
            raise ValueError(f"domain must be finite bounds (xmin, xmax, ymin, ymax, zmin, zmax); got {domain!r}")
        data = {**data, "domain": bounds.tolist()}
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data), encoding="utf-8")
    return path


def _read_domain(data: dict, path) -> tuple[float, ...] | None:
    if "domain" not in data:
        return None
    try:
        bounds = np.asarray(data["domain"], dtype=np.float64).reshape(6)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{path}: damaged domain in the BSP file ({error})") from error
    return tuple(bounds.tolist())


def _checked_materials(materials, where: str) -> dict:
    """``{"hardness": [...], "gradual_scale": s}`` with finite hardness > 0 and a finite scale >= 0; ``ValueError``
    naming ``where`` otherwise."""
    try:
        hardness = np.asarray(materials["hardness"], dtype=np.float64).reshape(-1)
        scale = float(materials.get("gradual_scale", 0.0))
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise ValueError(f"{where}: needs hardness (one number per material) and gradual_scale ({error})") from None
    if hardness.size == 0 or not np.isfinite(hardness).all() or np.any(hardness <= 0):
        raise ValueError(f"{where}: hardness must be finite numbers > 0; got {hardness.tolist()}")
    if not (math.isfinite(scale) and scale >= 0):
        raise ValueError(f"{where}: gradual_scale must be a finite number >= 0; got {scale!r}")
    return {"hardness": hardness.tolist(), "gradual_scale": scale}


def _read_materials(data: dict, path) -> dict | None:
    return _checked_materials(data["materials"], f"{path}: damaged materials") if "materials" in data else None


def _read_json(path: str | Path) -> dict:
    """The JSON object in file ``path``; ``FileNotFoundError`` or a ``ValueError`` naming the file."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a folder, not a BSP file")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"no such file: {path}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path} is not a pverosion BSP file (not JSON text: {error})") from error
    if not isinstance(data, dict):
        raise ValueError(f"{path} is not a pverosion BSP file")
    return data


def _encode(array: np.ndarray) -> dict:
    return {"dtype": array.dtype.str, "data": base64.b64encode(zlib.compress(array.tobytes(), 9)).decode("ascii")}


def _decode(entry: dict) -> np.ndarray:
    return np.frombuffer(zlib.decompress(base64.b64decode(entry["data"])), dtype=np.dtype(entry["dtype"]))


class LatticeBSPTree:
    """A BSP tree of lattice planes in a compact preorder layout (the trees of :func:`build_from_labels`).

    Nodes are stored depth first, so the negative child of an inner node is
    the node right after it and only the positive child's offset is stored.
    Inner node ``k`` splits by the plane ``u . (x - origin) / spacing =
    value[k] + 1/2`` with ``u = directions[direction[k]]`` (lower side
    negative); a leaf has ``direction[k] == 255`` and material id
    ``value[k]``. These arrays are the tree: :attr:`nbytes` counts them all,
    :meth:`locate` walks them, :meth:`to_json` saves them.

    Parameters
    ----------
    direction : numpy.ndarray, shape (n,), uint8
        Index into ``directions`` of each inner node, 255 for leaves.
    value : numpy.ndarray, shape (n,), int16 or int32
        Plane key of inner nodes, material id (>= 0) of leaves.
    right : numpy.ndarray, shape (n,), uint16 or uint32
        Offset from an inner node to its positive child (0 for leaves).
    directions : numpy.ndarray, shape (d, 3), int8
        Integer plane normals in voxel index space (d < 255).
    origin, spacing : array_like, shape (3,)
        World position of voxel (0, 0, 0) and the voxel size.

    Raises
    ------
    ValueError
        Arrays of other shapes or dtypes, or offsets that do not describe one
        preorder tree over all nodes.
    """

    FORMAT = "pverosion-lattice-bsp"

    def __init__(self, direction, value, right, *, directions, origin, spacing) -> None:
        self.direction = np.ascontiguousarray(direction)
        self.value = np.ascontiguousarray(value)
        self.right = np.ascontiguousarray(right)
        self.directions = np.ascontiguousarray(directions)
        self.origin = np.ascontiguousarray(origin, dtype=np.float64).reshape(3)
        self.spacing = np.ascontiguousarray(spacing, dtype=np.float64).reshape(3)
        self.domain: tuple[float, ...] | None = None  # as BSPTree.domain
        self.materials: dict | None = None  # as BSPTree.materials
        n = len(self.direction)
        if (self.direction.dtype != np.uint8 or self.value.dtype not in (np.int16, np.int32)
                or self.right.dtype not in (np.uint16, np.uint32) or self.directions.dtype != np.int8):
            raise ValueError("lattice tree arrays must be direction uint8, value int16/int32, right uint16/uint32, "
                             f"directions int8; got {self.direction.dtype}, {self.value.dtype}, {self.right.dtype}, "
                             f"{self.directions.dtype}")
        if n == 0 or self.value.shape != (n,) or self.right.shape != (n,) or self.direction.ndim != 1:
            raise ValueError(f"lattice tree arrays must be 1-D with the same length > 0; got {self.direction.shape}, "
                             f"{self.value.shape}, {self.right.shape}")
        if self.directions.ndim != 2 or self.directions.shape[1] != 3 or not 0 < len(self.directions) < LEAF:
            raise ValueError(f"directions must have shape (d, 3) with 0 < d < 255; got {self.directions.shape}")
        if not (np.isfinite(self.origin).all() and np.isfinite(self.spacing).all() and (self.spacing > 0).all()):
            raise ValueError(f"origin must be finite and spacing > 0; got {self.origin.tolist()}, "
                             f"{self.spacing.tolist()}")
        leaf = self.direction == LEAF
        if np.any(self.direction[~leaf] >= len(self.directions)) or np.any(self.value[leaf] < 0):
            raise ValueError("lattice tree nodes name unknown directions or negative materials")
        self.height = int(_preorder_height(self.direction, self.right))
        if self.height < 0:
            raise ValueError("lattice tree offsets do not describe one preorder tree over all nodes")
        normal = self.directions / self.spacing  # world normal of each direction
        self._inv_norm = 1.0 / np.linalg.norm(normal, axis=1)

    @property
    def n_nodes(self) -> int:
        """Number of nodes (inner and leaves)."""
        return len(self.direction)

    @property
    def leaf(self) -> np.ndarray:
        """Material id of each leaf, -1 for inner nodes, shape (n,), int64 (derived, as :attr:`BSPTree.leaf`)."""
        return np.where(self.direction == LEAF, self.value, -1).astype(np.int64)

    @property
    def nbytes(self) -> int:
        """Bytes of every array that defines the tree (nodes, direction table, origin and spacing)."""
        return sum(a.nbytes for a in (self.direction, self.value, self.right, self.directions, self.origin,
                                      self.spacing))

    def locate(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Material id of the leaf containing each point, and the distance to the nearest plane on its path.

        Parameters
        ----------
        points : array_like, shape (N, 3)

        Returns
        -------
        material_id : numpy.ndarray, shape (N,), int64
        distance : numpy.ndarray, shape (N,)
            Smallest distance, in world units, to the splitting planes on the point's path.
        """
        pts = _points_array(points)
        return _in_space_order(pts, lambda p: _locate_lattice(
            p, self.origin, 1.0 / self.spacing, self.directions.astype(np.float64), self._inv_norm,
            self.direction, self.value, self.right))

    def to_bsp_tree(self) -> BSPTree:
        """The same tree with a general plane (unit normal, offset in world units) in every node."""
        n = self.n_nodes
        inner = self.direction != LEAF
        index = np.arange(n)
        normal = self.directions[np.where(inner, self.direction, 0)] / self.spacing
        offset = -(normal @ self.origin) - (self.value + 0.5)  # u . (x - origin) / spacing - (value + 1/2)
        scale = np.linalg.norm(normal, axis=1)
        params = np.zeros((n, N_PARAMS))
        params[inner, :3] = normal[inner] / scale[inner, None]
        params[inner, 3] = offset[inner] / scale[inner]
        negative = np.where(inner, index + 1, -1)
        positive = np.where(inner, index + self.right.astype(np.int64), -1)
        return BSPTree(np.full(n, PLANE), params, negative, positive, self.leaf)

    def to_dict(self) -> dict:
        """JSON-ready description: the arrays' raw little-endian bytes, zlib-compressed and base64-encoded."""
        return {"format": self.FORMAT, "version": 1, "origin": self.origin.tolist(), "spacing": self.spacing.tolist(),
                **{name: _encode(getattr(self, name).astype(getattr(self, name).dtype.newbyteorder("<")))
                   for name in ("direction", "value", "right", "directions")},
                "shape": list(self.directions.shape)}

    @classmethod
    def from_dict(cls, data: dict) -> LatticeBSPTree:
        """Tree from :meth:`to_dict`'s description."""
        if data.get("format") != cls.FORMAT or data.get("version") != 1:
            raise ValueError(f"not a pverosion lattice BSP description, version 1 (format {data.get('format')!r}, "
                             f"version {data.get('version')!r})")
        try:
            arrays = {name: _decode(data[name]) for name in ("direction", "value", "right", "directions")}
            arrays = {name: a.astype(a.dtype.newbyteorder("=")) for name, a in arrays.items()}
            directions = arrays["directions"].reshape(data["shape"])
            origin, spacing = data["origin"], data["spacing"]
        except (KeyError, TypeError, ValueError, zlib.error, binascii.Error) as error:
            raise ValueError(f"damaged lattice BSP description: {error}") from error
        return cls(arrays["direction"], arrays["value"], arrays["right"], directions=directions, origin=origin,
                   spacing=spacing)

    def to_json(self, path: str | Path, *, domain=None, materials: dict | None = None) -> Path:
        """Save the tree to a JSON file of its compressed arrays (read by :meth:`BSPTree.from_json` too), with the
        ``domain`` it was built for and its ``materials`` (as :meth:`BSPTree.to_json`)."""
        return _write_json(path, self.to_dict(), domain, materials)

    @classmethod
    def from_json(cls, path: str | Path) -> LatticeBSPTree:
        """Load a tree written by :meth:`to_json`."""
        data = _read_json(path)
        tree = cls.from_dict(data)
        tree.domain = _read_domain(data, path)
        tree.materials = _read_materials(data, path)
        return tree


def build_from_labels(labels: np.ndarray, *, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0)) -> LatticeBSPTree:
    """Grow a lattice BSP tree that gives every voxel centre of ``labels`` its label.

    Parameters
    ----------
    labels : numpy.ndarray, shape (nx, ny, nz), int
        Material id (>= 0) of every voxel, indexed ``[i, j, k]`` along x, y, z.
    origin, spacing : array_like, shape (3,)
        World position of voxel (0, 0, 0) and the voxel size.

    Returns
    -------
    LatticeBSPTree
        Planes between voxel centres along :data:`LATTICE_DIRECTIONS`, in
        the compact preorder layout (about 5 bytes a node); the material of
        voxel ``(i, j, k)`` is found at ``origin + (i, j, k) * spacing``. The
        tree is the same for any thread count: it is grown serially, ties
        going to the first direction and the lowest plane.

    Raises
    ------
    ValueError
        ``labels`` not a 3-D array of non-negative integers, or bad
        ``origin``/``spacing``.
    """
    lab = np.asarray(labels)
    if lab.ndim != 3 or lab.size == 0 or not np.issubdtype(lab.dtype, np.integer) or lab.min() < 0:
        raise ValueError(f"labels must be a non-empty 3-D array of integers >= 0; got {lab.dtype} {lab.shape}")
    origin = np.asarray(origin, dtype=np.float64).reshape(3)
    spacing = np.asarray(spacing, dtype=np.float64).reshape(3)
    if not (np.isfinite(origin).all() and np.isfinite(spacing).all() and (spacing > 0).all()):
        raise ValueError(f"origin must be finite and spacing > 0; got {origin.tolist()}, {spacing.tolist()}")
    grid = np.stack(np.meshgrid(*[np.arange(n) for n in lab.shape], indexing="ij"), axis=-1).reshape(-1, 3)
    keys = np.ascontiguousarray(grid @ LATTICE_DIRECTIONS.T)
    direction, key, children, leaf = _fit(keys, np.ascontiguousarray(lab.ravel(), dtype=np.int64),
                                          int(lab.max()) + 1)
    return _lattice_tree(direction, key, children, leaf, LATTICE_DIRECTIONS, origin, spacing)


def _lattice_tree(direction, key, children, leaf, directions, origin, spacing) -> LatticeBSPTree:
    """Node arrays of a grown tree (children (n, 2), -1 for leaves) in the compact preorder layout."""
    order = _preorder(children[:, 0], children[:, 1], leaf)  # negative child right after its parent
    new_id = np.empty(len(order), np.int64)
    new_id[order] = np.arange(len(order))
    inner = leaf[order] < 0
    value = np.where(inner, key[order], leaf[order])
    right = np.where(inner, new_id[children[order, 1]] - np.arange(len(order)), 0)
    value_type = np.int16 if np.abs(value).max() <= np.iinfo(np.int16).max else np.int32
    right_type = np.uint16 if right.max() <= np.iinfo(np.uint16).max else np.uint32
    return LatticeBSPTree(np.where(inner, direction[order], LEAF).astype(np.uint8), value.astype(value_type),
                          right.astype(right_type), directions=np.asarray(directions, np.int8), origin=origin,
                          spacing=spacing)


# -- C-BSP of the voxels' boundary surface: coplanar faces merged, splitters chosen by cost ---------------------

AXES = np.eye(3, dtype=np.int8)
"""Plane normals of the C-BSP of voxel boundary faces, in voxel index space (the three axes)."""


@njit(cache=True)
def _greedy_rectangles(code):
    """Cover the non-zero cells of a 2-D array by rectangles of equal code, greedily (row-major, grown along v, then u).

    Returns rows ``(u0, u1, v0, v1, code)``: cells ``u0 <= u < u1``, ``v0 <= v < v1``.
    """
    nu, nv = code.shape
    used = np.zeros((nu, nv), np.bool_)
    out = np.empty((nu * nv, 5), np.int64)
    n = 0
    for u in range(nu):
        for v in range(nv):
            c = code[u, v]
            if c == 0 or used[u, v]:
                continue
            v1 = v + 1
            while v1 < nv and code[u, v1] == c and not used[u, v1]:
                v1 += 1
            u1 = u + 1
            while u1 < nu:
                row_ok = True
                for w in range(v, v1):
                    if code[u1, w] != c or used[u1, w]:
                        row_ok = False
                        break
                if not row_ok:
                    break
                u1 += 1
            used[u:u1, v:v1] = True
            out[n, 0], out[n, 1], out[n, 2], out[n, 3], out[n, 4] = u, u1, v, v1, c
            n += 1
    return out[:n]


def voxel_faces(labels: np.ndarray) -> tuple[np.ndarray, ...]:
    """The boundary surface of labelled voxels as rectangles of coplanar faces with the same two materials.

    The faces between face-adjacent voxels of different labels (the volume padded
    by one layer of material 0, so the surface is closed) are merged, plane by
    plane and material pair by material pair, into rectangles by a greedy sweep.
    Coordinates are doubled voxel indices (voxel ``i`` spans ``2i - 1 .. 2i + 1``),
    so every face and every cut is exact in integers.

    Parameters
    ----------
    labels : numpy.ndarray, shape (nx, ny, nz), int

    Returns
    -------
    axis : numpy.ndarray, shape (F,), int64
        Normal axis of each rectangle.
    lo, hi : numpy.ndarray, shape (F, 3), int64
        Doubled corners; ``lo[f, axis] == hi[f, axis]`` is the rectangle's plane (odd).
    below, above : numpy.ndarray, shape (F,), int64
        Material on the lower and on the upper side of each rectangle along its axis.
    """
    padded = np.pad(np.asarray(labels, dtype=np.int64), 1)
    n_materials = int(padded.max()) + 1
    empty = np.zeros(0, np.int64)
    parts = [(empty, empty.reshape(0, 3), empty.reshape(0, 3), empty, empty)]  # a volume of material 0: no faces
    for ax in range(3):
        n = padded.shape[ax] - 1
        a, b = np.take(padded, np.arange(n), axis=ax), np.take(padded, np.arange(1, n + 1), axis=ax)
        code = np.moveaxis(np.where(a != b, a * n_materials + b + 1, 0), ax, 0)
        others = [k for k in range(3) if k != ax]
        for s in np.flatnonzero(code.reshape(n, -1).any(axis=1)):
            rect = _greedy_rectangles(np.ascontiguousarray(code[s]))
            lo, hi = np.empty((len(rect), 3), np.int64), np.empty((len(rect), 3), np.int64)
            lo[:, ax] = hi[:, ax] = 2 * s - 1  # between padded voxels s and s + 1: unpadded s - 1 and s
            for k, (first, last) in zip(others, ((0, 1), (2, 3))):
                lo[:, k], hi[:, k] = 2 * (rect[:, first] - 1) - 1, 2 * (rect[:, last] - 1) - 1
            pair = rect[:, 4] - 1
            parts.append((np.full(len(rect), ax), lo, hi, pair // n_materials, pair % n_materials))
    return tuple(np.concatenate(column) for column in zip(*parts))


@njit(cache=True)
def _area(lo, hi, k):
    """Area of piece ``k`` in doubled units (4 per voxel face)."""
    return max(hi[k, 0] - lo[k, 0], 1) * max(hi[k, 1] - lo[k, 1], 1) * max(hi[k, 2] - lo[k, 2], 1)


@njit(cache=True)
def _top_planes(lo, hi, plane, source, pieces, count, n_candidates):
    """Up to ``n_candidates`` planes holding the most area of pieces (ties: lower plane id); ``count`` gets each
    plane's area (4 per voxel face)."""
    distinct = np.empty(len(pieces), np.int64)
    n = 0
    for k in pieces:
        p = plane[source[k]]
        if count[p] == 0:
            distinct[n] = p
            n += 1
        count[p] += _area(lo, hi, k)
    distinct = distinct[:n]
    most = 0
    for p in distinct:
        most = max(most, count[p])
    rank = np.argsort((most - count[distinct]) * count.shape[0] + distinct)
    return distinct[rank[:n_candidates]]


@njit(cache=True)
def _side(lo, hi, piece, a, c):
    """-1 if piece ``piece`` lies below the plane ``x_a = c`` (or in it), +1 above, 0 if it straddles it."""
    if hi[piece, a] <= c:
        return -1
    if lo[piece, a] >= c:
        return 1
    return 0


@njit(cache=True)
def _best_plane(lo, hi, plane, source, plane_axis, plane_pos, pieces, count, n_candidates, split_weight):
    """The candidate plane of greatest ``coplanar pieces - split_weight * straddling pieces``."""
    candidates = _top_planes(lo, hi, plane, source, pieces, count, n_candidates)
    best, best_score = -1, -np.inf
    for p in candidates:
        splits = 0
        for k in pieces:
            if _side(lo, hi, k, plane_axis[p], plane_pos[p]) == 0:
                splits += 1
        score = count[p] - 4.0 * split_weight * splits
        if score > best_score:
            best, best_score = p, score
    for k in pieces:
        count[plane[source[k]]] = 0
    return best


@njit(cache=True)
def _cut(lo, hi, source, k, a, c, n_pieces):
    """Split piece ``k`` by ``x_a = c``: it keeps the lower part, the upper part becomes piece ``n_pieces``."""
    if n_pieces == lo.shape[0]:
        lo = np.concatenate((lo, np.empty_like(lo)))
        hi = np.concatenate((hi, np.empty_like(hi)))
        source = np.concatenate((source, np.empty_like(source)))
    lo[n_pieces], hi[n_pieces], source[n_pieces] = lo[k], hi[k], source[k]
    hi[k, a] = c
    lo[n_pieces, a] = c
    return lo, hi, source


@njit(cache=True)
def _autopartition(lo, hi, plane, below, above, plane_axis, plane_pos, n_materials, n_candidates,
                   split_weight):
    """Grow a C-BSP over axis-aligned rectangles: each cell is split by the plane of some of its pieces (chosen by
    :func:`_best_plane`), which are consumed; straddling pieces are cut and sent down both sides; a cell left
    without pieces becomes a leaf of the material its parent's coplanar pieces give that side.

    Returns per node: plane id (-1 for leaves), children (n, 2) and leaf material (-1 for inner nodes).
    """
    n_faces = len(plane)
    lo, hi, source = lo.copy(), hi.copy(), np.arange(n_faces)
    n_pieces = n_faces
    capacity = 2 * n_faces + 1
    node_plane = np.full(capacity, -1, np.int64)
    children = np.full((capacity, 2), -1, np.int64)
    leaf = np.full(capacity, -1, np.int64)
    count = np.zeros(len(plane_axis), np.int64)
    votes = np.zeros((2, n_materials), np.int64)
    work = [(np.arange(n_faces), 0, 0)]  # (pieces, node, material if no pieces)
    n_nodes = 1
    while work:
        pieces, node, material = work.pop()
        if len(pieces) == 0:
            leaf[node] = material
            continue
        p = _best_plane(lo, hi, plane, source, plane_axis, plane_pos, pieces, count, n_candidates, split_weight)
        a, c = plane_axis[p], plane_pos[p]
        negative, positive = [], []
        votes[:] = 0
        for i in range(len(pieces)):
            k = pieces[i]
            if plane[source[k]] == p:
                votes[0, below[source[k]]] += 1
                votes[1, above[source[k]]] += 1
                continue
            side = _side(lo, hi, k, a, c)
            if side == 0:
                lo, hi, source = _cut(lo, hi, source, k, a, c, n_pieces)
                positive.append(n_pieces)
                n_pieces += 1
                negative.append(k)
            elif side < 0:
                negative.append(k)
            else:
                positive.append(k)
        if n_nodes + 2 > len(leaf):  # clipped pieces can outnumber the faces
            node_plane = np.concatenate((node_plane, np.full(len(leaf), -1, np.int64)))
            children = np.concatenate((children, np.full((len(leaf), 2), -1, np.int64)))
            leaf = np.concatenate((leaf, np.full(len(leaf), -1, np.int64)))
        node_plane[node] = p
        children[node, 0], children[node, 1] = n_nodes, n_nodes + 1
        work.append((np.array(positive, np.int64), n_nodes + 1, np.argmax(votes[1])))
        work.append((np.array(negative, np.int64), n_nodes, np.argmax(votes[0])))
        n_nodes += 2
    return node_plane[:n_nodes].copy(), children[:n_nodes].copy(), leaf[:n_nodes].copy()


def build_from_voxel_faces(labels: np.ndarray, *, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0),
                           candidates: int = 64, split_weight: float = 4.0) -> tuple[LatticeBSPTree, int, int]:
    """C-BSP of the boundary surface of labelled voxels, coplanar faces merged, splitters chosen by cost.

    The surface is :func:`voxel_faces` (the squares between face-adjacent voxels of
    different materials, closed by a layer of material 0). Each cell of the tree
    is split by the plane of some of the faces reaching into it, and all its
    faces in that plane are inserted at once (merged into one node); faces that
    straddle the plane are clipped and each part sent down its side (C-BSP).
    The plane is chosen among the ``candidates`` planes holding the most faces
    of the cell, by the greatest ``faces in the plane - split_weight * faces
    it clips`` (ties: the first plane in x, y, z order). A cell that no face
    reaches into is a leaf of the material its parent's faces give that side.
    Every voxel centre gets its own label (the surface passes half-way between
    voxels), and the build does not depend on the order of anything.

    Parameters
    ----------
    labels : numpy.ndarray, shape (nx, ny, nz), int
        Material id (>= 0) of every voxel, indexed ``[i, j, k]`` along x, y, z.
    origin, spacing : array_like, shape (3,)
        World position of voxel (0, 0, 0) and the voxel size.
    candidates : int
        Planes considered per cell (those holding the most of its faces), >= 1.
    split_weight : float
        Cost of a clipped face against a face inserted, >= 0.

    Returns
    -------
    tree : LatticeBSPTree
        In the compact preorder layout, directions :data:`AXES`.
    faces : int
        Squares of the boundary surface.
    inserted : int
        Merged coplanar polygons inserted (the inner nodes).

    Raises
    ------
    ValueError
        ``labels`` not a non-empty 3-D array of integers >= 0, bad ``origin``/``spacing``,
        ``candidates < 1`` or ``split_weight < 0``.
    """
    lab = np.asarray(labels)
    if lab.ndim != 3 or lab.size == 0 or not np.issubdtype(lab.dtype, np.integer) or lab.min() < 0:
        raise ValueError(f"labels must be a non-empty 3-D array of integers >= 0; got {lab.dtype} {lab.shape}")
    if int(candidates) != candidates or candidates < 1 or not split_weight >= 0:
        raise ValueError(f"candidates must be an integer >= 1 and split_weight >= 0; got {candidates}, "
                         f"{split_weight}")
    axis, lo, hi, below, above = voxel_faces(lab)
    n_faces = len(axis)
    if n_faces == 0:  # one material everywhere, and it is 0
        return _lattice_tree(np.zeros(1, np.int64), np.zeros(1, np.int64), np.full((1, 2), -1),
                             np.zeros(1, np.int64), AXES, origin, spacing), 0, 0
    position = lo[np.arange(n_faces), axis]
    keys, plane = np.unique(np.stack([axis, position]), axis=1, return_inverse=True)
    node_plane, children, leaf = _autopartition(lo, hi, plane.ravel(), below, above, keys[0], keys[1],
                                                int(lab.max()) + 1, int(candidates), float(split_weight))
    inner = leaf < 0
    direction = np.where(inner, keys[0][node_plane], -1)
    key = np.where(inner, (keys[1][node_plane] - 1) // 2, 0)  # doubled 2i + 1 is the plane x = i + 1/2
    return _lattice_tree(direction, key, children, leaf, AXES, origin, spacing), n_faces, int(inner.sum())
