"""The ray tracer's BVH, built on the CPU with vectorised numpy (binned SAH, one pass per tree
level) in the layout ``gpu_shaders/raytrace_lib.glsl`` traverses."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STACK_SIZE = 64  # RT_STACK_SIZE in raytrace_lib.glsl: the deepest tree the GPU can traverse
SAH_BINS = 16


@dataclass
class BVH:
    """A flat BVH, ready to upload. Node 0 is the root. ``node_data[i] = (a, b)``: a leaf has
    ``b >= 0`` and holds triangles ``a .. a+b-1`` (leaf order); an interior node has ``b == -1``
    and children ``a`` and ``a + 1``. ``depth`` counts the edges from the root to the deepest
    leaf."""

    node_min: np.ndarray  # (M, 3) float32
    node_max: np.ndarray  # (M, 3) float32
    node_data: np.ndarray  # (M, 2) int32
    triangles: np.ndarray  # (T, 3, 3) float32, leaf order
    triangle_ids: np.ndarray  # (T,) int32, original index of each reordered triangle
    depth: int


def _levels_needed(counts: np.ndarray, leaf_size: int) -> np.ndarray:
    """Levels of halving splits below a node of ``counts`` triangles until leaves fit."""
    leaves = -(-counts // leaf_size)
    return np.ceil(np.log2(np.maximum(leaves, 1))).astype(np.int64)


def _exclusive_cumsum(counts: np.ndarray) -> np.ndarray:
    return np.r_[0, np.cumsum(counts)[:-1]]


# The build keeps one column per triangle of the nodes still being split, grouped by node, in
# rows (lo, -hi, centre, -centre): one minimum.reduceat then bounds boxes and centroids alike.
_BOX = slice(0, 6)
_CENTRE = slice(6, 12)


def _half_area(box: np.ndarray) -> np.ndarray:
    """Half the surface area of boxes stored as rows (lo, -hi) along axis -2."""
    e = -(box[..., 3:, :] + box[..., :3, :])
    return e[..., 0, :] * e[..., 1, :] + e[..., 1, :] * e[..., 2, :] + e[..., 2, :] * e[..., 0, :]


def _sweep(bins: np.ndarray) -> np.ndarray:
    """Bounds of bins 0..i for each i < len(bins) - 1 (a loop over bins, vectorised over
    nodes: much faster than minimum.accumulate)."""
    out = np.empty_like(bins[:-1])
    out[0] = bins[0]
    for i in range(1, len(out)):
        np.minimum(out[i - 1], bins[i], out=out[i])
    return out


def _sah_split(key: np.ndarray, box: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Triangles left of the cheapest SAH plane in each node (``key`` = node * SAH_BINS + bin,
    sorted; ``box`` (6, n) in the same order), 0 where no plane has triangles on both sides."""
    nodes = len(counts)
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    slot = key % SAH_BINS * nodes + key // SAH_BINS  # bin-major: sweeps run over whole rows
    bins = np.full((6, SAH_BINS * nodes), np.inf, np.float32)
    bins[:, slot[first]] = np.minimum.reduceat(box, first, axis=1)
    bins = bins.reshape(6, SAH_BINS, nodes).transpose(1, 0, 2)
    left_n = np.cumsum(np.bincount(slot, minlength=SAH_BINS * nodes).reshape(SAH_BINS, nodes),
                       axis=0)[:-1]
    right_n = counts - left_n
    valid = (left_n > 0) & (right_n > 0)
    with np.errstate(invalid="ignore", over="ignore"):  # empty sides: -inf extents, masked
        cost = _half_area(_sweep(bins)) * left_n + _half_area(_sweep(bins[::-1])[::-1]) * right_n
    cost = np.where(valid, cost, np.inf)
    best = cost.argmin(axis=0)
    rows = np.arange(nodes)
    return np.where(valid[best, rows], left_n[best, rows], 0)


def _bin_keys(items: np.ndarray, centre_bounds: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """node * SAH_BINS + the bin of each triangle's centroid along its node's longest axis of
    centroid bounds (bin 0 for all where the centroids coincide)."""
    nodes = np.arange(len(counts))
    extent = -(centre_bounds[3:] + centre_bounds[:3]).astype(np.float64)
    axis = extent.argmax(axis=0)
    extent = extent[axis, nodes]
    scale = np.divide(SAH_BINS, extent, out=np.zeros(len(counts)), where=extent > 0)
    n = items.shape[1]
    along = np.take(items.ravel(), np.repeat((axis + _CENTRE.start) * n, counts) + np.arange(n))
    along = (along - np.repeat(centre_bounds[axis, nodes], counts)) * np.repeat(scale, counts)
    return np.repeat(nodes * SAH_BINS, counts) + np.minimum(along.astype(np.int64), SAH_BINS - 1)


def _left_counts(key: np.ndarray, items: np.ndarray, counts: np.ndarray, depth: int,
                 leaf_size: int, max_depth: int) -> np.ndarray:
    """Triangles going to the left child of each node: the cheapest SAH split for nodes of more
    than SAH_BINS triangles, else (or where SAH cannot split, or could overrun ``max_depth``)
    the median of the binned order."""
    left = counts // 2
    sah = (counts > SAH_BINS) & (depth + _levels_needed(counts, leaf_size) < max_depth)
    if sah.all():
        best = _sah_split(key, items[_BOX], counts)
    elif sah.any():
        inside = np.repeat(sah, counts)
        local = np.repeat(np.arange(np.count_nonzero(sah)) * SAH_BINS, counts[sah])
        best = _sah_split(local + key[inside] % SAH_BINS, items[_BOX][:, inside], counts[sah])
    else:
        return left
    left[sah] = np.where(best > 0, best, left[sah])
    return left


def build_bvh(triangles: np.ndarray, leaf_size: int = 4, max_depth: int = STACK_SIZE) -> BVH:
    """Build a BVH over ``triangles`` (T, 3, 3) with leaves of at most ``leaf_size`` triangles.

    Each tree level is one vectorised pass over all nodes still being split: their triangles
    are binned by centroid along the longest axis of the node's centroid bounds and split at the
    cheapest SAH plane of ``SAH_BINS`` bins. Small nodes, nodes whose centroids coincide, and
    nodes so deep that SAH splits could push the tree past ``max_depth`` are split at the median
    of the binned order instead, so the depth never exceeds ``max_depth``."""
    tris = np.ascontiguousarray(triangles, dtype=np.float32).reshape(-1, 3, 3)
    if leaf_size < 1:
        raise ValueError(f"leaf_size must be at least 1, got {leaf_size}")
    if not np.isfinite(tris).all():
        raise ValueError("triangles must have finite coordinates")
    lo, hi = triangle_bounds(tris.transpose(1, 2, 0))
    tree = build_tree(lo, hi, leaf_size, max_depth)
    return BVH(tree.node_min, tree.node_max, tree.node_data, np.take(tris, tree.order, axis=0),
               tree.order.astype(np.int32), tree.depth)


def triangle_bounds(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's box corners (lo, hi) from its vertices along the first axis."""
    lo = np.minimum(np.minimum(vertices[0], vertices[1]), vertices[2])
    hi = np.maximum(np.maximum(vertices[0], vertices[1]), vertices[2])
    return lo, hi


@dataclass
class Tree:
    """A BVH's nodes over boxes (as in ``BVH``), its leaves holding ``order[a .. a+b-1]``."""

    node_min: np.ndarray  # (M, 3) float32
    node_max: np.ndarray  # (M, 3) float32
    node_data: np.ndarray  # (M, 2) int32
    order: np.ndarray  # (N,) int64, the boxes' indices in leaf order
    depth: int


def build_tree(lo: np.ndarray, hi: np.ndarray, leaf_size: int, max_depth: int = STACK_SIZE
               ) -> Tree:
    """The BVH (as ``build_bvh`` builds it) over boxes given as (3, N) float32 corners."""
    count = lo.shape[1]
    if count == 0:
        return Tree(np.zeros((1, 3), np.float32), np.zeros((1, 3), np.float32),
                    np.zeros((1, 2), np.int32), np.zeros(0, np.int64), 0)
    if int(_levels_needed(np.array([count]), leaf_size)[0]) > max_depth:
        raise ValueError(f"{count} triangles need a tree deeper than {max_depth}")

    centre = lo * 0.5 + hi * 0.5
    items = np.concatenate([lo, -hi, centre, -centre]).astype(np.float32, copy=False)
    tri = np.arange(count)
    order = np.empty(count, np.int64)
    node_box = np.empty((6, 2 * count), np.float32)
    node_data = np.empty((2 * count, 2), np.int32)
    bounds = items.min(axis=1, keepdims=True)
    node_box[:, 0] = bounds[_BOX, 0]
    ids, starts, counts = np.zeros(1, np.int64), np.zeros(1, np.int64), np.array([count])
    next_id, depth = 1, 0

    while True:
        leaf = counts <= leaf_size
        node_data[ids[leaf]] = np.stack([starts[leaf], counts[leaf]], axis=1)
        if leaf.any():
            done = np.repeat(leaf, counts)
            rank = np.arange(len(tri)) - np.repeat(_exclusive_cumsum(counts), counts)
            order[(np.repeat(starts, counts) + rank)[done]] = tri[done]
            items, tri = np.compress(~done, items, axis=1), tri[~done]
            ids, starts, counts = ids[~leaf], starts[~leaf], counts[~leaf]
            bounds = bounds[:, ~leaf]
        if len(ids) == 0:
            break
        nodes = len(ids)
        key = _bin_keys(items, bounds[_CENTRE], counts)
        perm = np.argsort(key, kind="stable")  # radix/tim sort: keys come grouped by node
        key, items, tri = key[perm], np.take(items, perm, axis=1), tri[perm]
        left = _left_counts(key, items, counts, depth, leaf_size, max_depth)

        offsets = _exclusive_cumsum(counts)
        child = next_id + np.arange(2 * nodes)
        bounds = np.minimum.reduceat(items, np.stack([offsets, offsets + left], 1).ravel(), axis=1)
        node_box[:, child] = bounds[_BOX]
        node_data[ids] = np.stack([child[::2], np.full(nodes, -1)], axis=1)
        ids = child
        starts = np.stack([starts, starts + left], axis=1).ravel()
        counts = np.stack([left, counts - left], axis=1).ravel()
        next_id += 2 * nodes
        depth += 1

    assert depth <= max_depth, (depth, max_depth)
    return Tree(node_box[:3, :next_id].T.copy(), -node_box[3:, :next_id].T, node_data[:next_id],
                order, depth)
