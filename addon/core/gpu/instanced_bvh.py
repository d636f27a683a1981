"""One BVH over a scene whose meshes are instanced, built in two levels and traversed as one.

A mesh used k times is built once (over its first instance's triangles); each instance gets a
copy of that tree's shape with its boxes refitted to its own world triangles, so the boxes are
exact whatever the transform. The meshes used once are built together, as ``build_bvh`` would.
A top-level tree over these subtrees' root boxes joins them: each of its leaves becomes the root
of one subtree. The result is an ordinary ``BVH`` (the traversal shader does not change) whose
build costs one mesh build per shared mesh, where flattening would build over every copy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bvh import BVH, STACK_SIZE, Tree, build_bvh, build_tree


def build_instanced_bvh(triangles: np.ndarray, instanced: np.ndarray, leaf_size: int = 4
                        ) -> BVH:
    """The BVH of world ``triangles`` (T, 3, 3), where ``instanced`` rows (first triangle,
    instances, triangles per instance) mark runs of one mesh's copies (instance i holds
    triangles first + i·n .. first + (i+1)·n - 1, in the mesh's order); all other triangles
    are single. Without runs, or where the joined tree would be too deep, it is
    ``build_bvh``'s."""
    tris = np.ascontiguousarray(triangles, dtype=np.float32).reshape(-1, 3, 3)
    runs = np.asarray(instanced, np.int64).reshape(-1, 3)
    if not len(runs) or not np.isfinite(tris).all():
        return build_bvh(tris, leaf_size)
    single = np.ones(len(tris), bool)
    for first, copies, count in runs:
        single[first:first + copies * count] = False
    subtrees = []
    if single.any():
        ids = np.flatnonzero(single)
        flat = build_bvh(tris[ids], leaf_size)
        subtrees.append(_Subtrees(flat.node_min[:, None], flat.node_max[:, None],
                                  flat.node_data, ids[flat.triangle_ids][None],
                                  flat.triangles[None], flat.depth))
    subtrees += [_copies(tris, first, copies, count, leaf_size) for first, copies, count in runs]
    deepest = max(s.depth for s in subtrees)
    roots_min = np.concatenate([s.node_min[0] for s in subtrees])
    roots_max = np.concatenate([s.node_max[0] for s in subtrees])
    try:
        top = build_tree(roots_min.T.copy(), roots_max.T.copy(), 1, STACK_SIZE - deepest)
    except ValueError:
        return build_bvh(tris, leaf_size)
    return _join(top, subtrees)


@dataclass
class _Subtrees:
    """k subtrees of one shape: boxes (node-major: a node's k boxes side by side), the
    shape's node data, and each copy's triangle ids and triangles in leaf order."""

    node_min: np.ndarray  # (M, k, 3) float32
    node_max: np.ndarray  # (M, k, 3) float32
    node_data: np.ndarray  # (M, 2) int32
    triangle_ids: np.ndarray  # (k, n)
    triangles: np.ndarray  # (k, n, 3, 3) float32
    depth: int

    @property
    def copies(self) -> int:
        return self.node_min.shape[1]


def _copies(tris: np.ndarray, first: int, copies: int, count: int, leaf_size: int
            ) -> _Subtrees:
    """The subtrees of one mesh's ``copies`` instances: the first instance's tree, refitted.
    (Whole-row moves and 2-D reductions: numpy's fancy indexing of (3, 3) rows and its
    reductions along a middle axis took 2-4× as long here.)"""
    shape = build_bvh(tris[first:first + count], leaf_size)
    ids = first + np.arange(copies)[:, None] * count + shape.triangle_ids[None]
    records = tris.reshape(len(tris), 9).view("V36")[:, 0]
    world = np.take(records, ids).view(np.float32).reshape(copies, count, 3, 3)  # leaf order
    start, size = shape.node_data[:, 0], shape.node_data[:, 1]
    leaves = np.flatnonzero(size >= 0)
    leaves = leaves[np.argsort(start[leaves], kind="stable")]  # leaves tile the leaf order
    corners = world.reshape(-1, 3)
    firsts = (3 * count * np.arange(copies)[:, None] + 3 * start[leaves][None]).ravel()
    node_min = np.empty((len(shape.node_data), copies, 3), np.float32)
    node_max = np.empty_like(node_min)
    node_min[leaves] = np.minimum.reduceat(corners, firsts).reshape(
        copies, len(leaves), 3).transpose(1, 0, 2)
    node_max[leaves] = np.maximum.reduceat(corners, firsts).reshape(
        copies, len(leaves), 3).transpose(1, 0, 2)
    depth = _node_depths(shape.node_data)
    for level in range(shape.depth - 1, -1, -1):  # children before their parents
        inner = np.flatnonzero((depth == level) & (size < 0))
        left = start[inner]
        node_min[inner] = np.minimum(node_min[left], node_min[left + 1])
        node_max[inner] = np.maximum(node_max[left], node_max[left + 1])
    return _Subtrees(node_min, node_max, shape.node_data, ids, world, shape.depth)


def _node_depths(node_data: np.ndarray) -> np.ndarray:
    """Each node's distance from the root (interior nodes have children a and a + 1)."""
    depth = np.zeros(len(node_data), np.int64)
    level, frontier = 0, np.zeros(1, np.int64)
    while len(frontier):
        depth[frontier] = level
        inner = frontier[node_data[frontier, 1] < 0]
        frontier = np.stack([node_data[inner, 0], node_data[inner, 0] + 1], 1).ravel()
        level += 1
    return depth


def _join(top: Tree, subtrees: list[_Subtrees]) -> BVH:
    """The top tree with each leaf (one subtree root each) replaced by its subtree: subtree
    nodes but the root follow the top's nodes, their triangles follow one another."""
    top_count = len(top.node_data)
    total = top_count + sum((len(s.node_data) - 1) * s.copies for s in subtrees)
    node_min = np.empty((total, 3), np.float32)
    node_max = np.empty_like(node_min)
    node_data = np.empty((total, 2), np.int32)
    node_min[:top_count], node_max[:top_count] = top.node_min, top.node_max
    node_data[:top_count] = top.node_data
    roots, node_next, tri_next = [], top_count, 0
    for s in subtrees:  # copies of one shape: consecutive blocks of M - 1 nodes and n triangles
        inner = len(s.node_data) - 1
        rows = _remap(s.node_data, node_next + inner * np.arange(s.copies),
                      tri_next + s.triangle_ids.shape[1] * np.arange(s.copies))  # (k, M, 2)
        block = slice(node_next, node_next + inner * s.copies)
        node_min[block] = s.node_min[1:].transpose(1, 0, 2).reshape(-1, 3)
        node_max[block] = s.node_max[1:].transpose(1, 0, 2).reshape(-1, 3)
        node_data[block] = rows[:, 1:].reshape(-1, 2)
        roots.append(rows[:, 0])
        node_next, tri_next = block.stop, tri_next + s.triangle_ids.size
    top_leaves = np.flatnonzero(top.node_data[:, 1] >= 0)
    items = top.order[top.node_data[top_leaves, 0]]  # the subtree at each top leaf
    node_data[top_leaves] = np.concatenate(roots)[items]
    item_depth = np.repeat([s.depth for s in subtrees], [s.copies for s in subtrees])
    depth = _node_depths(top.node_data)[top_leaves] + item_depth[items]
    triangle_ids = np.concatenate([s.triangle_ids.ravel() for s in subtrees])
    triangles = np.concatenate([s.triangles.reshape(-1, 3, 3) for s in subtrees])
    return BVH(node_min, node_max, node_data, triangles, triangle_ids.astype(np.int32),
               int(depth.max()))


def _remap(node_data: np.ndarray, node_bases: np.ndarray, tri_bases: np.ndarray) -> np.ndarray:
    """One shape's node data for each copy: children moved to the copy's node block (which
    leaves out the root, so node j lands at base + j - 1), leaf triangle starts to its
    triangles."""
    start, size = node_data[:, 0].astype(np.int64), node_data[:, 1]
    inner = size < 0
    moved = np.where(inner[None], node_bases[:, None] + start[None] - 1,
                     tri_bases[:, None] + start[None])
    return np.stack([moved, np.broadcast_to(size, moved.shape)], axis=2).astype(np.int32)
