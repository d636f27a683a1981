"""Ray tracing of triangle scenes: a BVH built on the CPU with vectorised numpy (binned SAH, one
pass per tree level), traversed on the GPU by ``gpu_shaders/raytrace_lib.glsl``.

Use it as a batch query (``RayTracer.intersect`` / ``occluded``) or from another shader: include
``raytrace_lib.glsl`` in a GLSL 4.30 shader, call ``RayTracer.bind()`` before its
dispatch or draw, and call ``rt_closest_hit`` / ``rt_occluded``.

Triangles are two-sided. A hit counts when ``t_min < t < t_max`` (open interval), ``t`` being
the distance along the normalised ray direction. The triangle test is watertight (Woop et al.
2013), so rays through shared edges and vertices of a closed mesh never slip through.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from .gl import ProgramCache, require_compute

BINDING_NODES = 10  # RT_BINDING_NODES in raytrace_lib.glsl
BINDING_TRIANGLES = 11  # RT_BINDING_TRIANGLES in raytrace_lib.glsl
BINDING_RAYS = 12  # RT_BINDING_RAYS in raytrace_comp.glsl
BINDING_RESULTS = 13  # RT_BINDING_RESULTS in raytrace_comp.glsl
STACK_SIZE = 64  # RT_STACK_SIZE in raytrace_lib.glsl: the deepest tree the GPU can traverse
LOCAL_SIZE = 64  # local_size_x of raytrace_comp.glsl
MAX_BATCH = 1 << 20  # rays per dispatch
SAH_BINS = 16

NODE_DTYPE = np.dtype([("lo", "<f4", 3), ("a", "<i4"), ("hi", "<f4", 3), ("b", "<i4")])
TRIANGLE_DTYPE = np.dtype([("v0", "<f4", 3), ("id", "<i4"), ("v1", "<f4", 3), ("pad1", "<f4"),
                           ("v2", "<f4", 3), ("pad2", "<f4")])
RAY_DTYPE = np.dtype([("origin", "<f4", 3), ("t_min", "<f4"), ("dir", "<f4", 3),
                      ("t_max", "<f4")])
RESULT_DTYPE = np.dtype([("t", "<f4"), ("triangle", "<i4"), ("uv", "<f4", 2)])


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


@dataclass
class Hits:
    """Closest hits of a batch of rays."""

    distance: np.ndarray  # (R,) float32, inf where missed
    triangle: np.ndarray  # (R,) int32 original triangle index, -1 where missed
    barycentric: np.ndarray  # (R, 2) float32 weights of vertices 1 and 2, 0 where missed


# -- BVH build -------------------------------------------------------------------------------

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
    count = len(tris)
    if count == 0:
        return BVH(np.zeros((1, 3), np.float32), np.zeros((1, 3), np.float32),
                   np.zeros((1, 2), np.int32), tris, np.zeros(0, np.int32), 0)
    if int(_levels_needed(np.array([count]), leaf_size)[0]) > max_depth:
        raise ValueError(f"{count} triangles need a tree deeper than {max_depth}")

    corners = tris.transpose(1, 2, 0)  # (vertex, xyz, triangle)
    lo = np.minimum(np.minimum(corners[0], corners[1]), corners[2])
    hi = np.maximum(np.maximum(corners[0], corners[1]), corners[2])
    centre = lo * 0.5 + hi * 0.5
    items = np.concatenate([lo, -hi, centre, -centre])
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
    return BVH(node_box[:3, :next_id].T.copy(), -node_box[3:, :next_id].T, node_data[:next_id],
               np.take(tris, order, axis=0), order.astype(np.int32), depth)


# -- GPU queries -----------------------------------------------------------------------------

def _pack_rays(origins: np.ndarray, directions: np.ndarray, t_min: float | np.ndarray,
               t_max: float | np.ndarray) -> np.ndarray:
    """Rays in the GPU layout, directions normalised. Rays with a zero or non-finite direction
    or origin get an empty interval, so they miss."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    if len(o) != len(d):
        raise ValueError(f"{len(o)} origins but {len(d)} directions")
    with np.errstate(invalid="ignore", over="ignore"):
        length = np.linalg.norm(d, axis=1)
    ok = np.isfinite(o).all(axis=1) & np.isfinite(length) & (length > 0)
    rays = np.zeros(len(o), RAY_DTYPE)
    rays["origin"] = np.where(ok[:, None], o, 0.0)
    rays["dir"] = np.where(ok[:, None], d / np.where(ok, length, 1.0)[:, None], [0.0, 0.0, 1.0])
    rays["t_min"] = np.where(ok, t_min, 0.0)
    rays["t_max"] = np.where(ok, t_max, 0.0)
    return rays


class RayTracer:
    """One uploaded triangle scene and its GPU queries (needs OpenGL 4.3)."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache) -> None:
        require_compute(ctx)
        self.ctx = ctx
        self.programs = programs
        self.batch_size = MAX_BATCH
        self._nodes: moderngl.Buffer | None = None
        self._triangles: moderngl.Buffer | None = None
        self._rays: moderngl.Buffer | None = None
        self._results: moderngl.Buffer | None = None
        self.upload(np.zeros((0, 3, 3), np.float32))

    def upload(self, triangles: np.ndarray, leaf_size: int = 4) -> None:
        """Build the BVH of ``triangles`` (T, 3, 3) and upload it; T = 0 is an empty scene.
        Raises ValueError before building when the triangles cannot fit a storage buffer."""
        count = len(np.asarray(triangles).reshape(-1, 3, 3))
        self._check_size(count, count * TRIANGLE_DTYPE.itemsize)
        self.upload_bvh(build_bvh(triangles, leaf_size))

    def _check_size(self, triangles: int, nbytes: int) -> None:
        limit = int(self.ctx.info["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
        if nbytes > limit:
            raise ValueError(f"{triangles} triangles need {nbytes >> 20} MiB of storage buffer; "
                             f"this GPU allows {limit >> 20} MiB")

    def upload_bvh(self, bvh: BVH) -> None:
        """Upload a BVH from ``build_bvh``, replacing the scene."""
        nodes = np.zeros(len(bvh.node_data), NODE_DTYPE)
        nodes["lo"], nodes["hi"] = bvh.node_min, bvh.node_max
        nodes["a"], nodes["b"] = bvh.node_data[:, 0], bvh.node_data[:, 1]
        tris = np.zeros(max(1, len(bvh.triangles)), TRIANGLE_DTYPE)  # GL has no empty buffers
        used = tris[:len(bvh.triangles)]
        used["v0"], used["v1"], used["v2"] = bvh.triangles.transpose(1, 0, 2)
        used["id"] = bvh.triangle_ids
        self._check_size(len(bvh.triangles), max(nodes.nbytes, tris.nbytes))
        self._release_scene()
        self._nodes, self._triangles = self.ctx.buffer(nodes), self.ctx.buffer(tris)

    def bind(self) -> None:
        """Bind the scene at RT_BINDING_NODES / RT_BINDING_TRIANGLES for another program's
        dispatch or draw (again after each upload: it makes new buffers)."""
        self._nodes.bind_to_storage_buffer(BINDING_NODES)
        self._triangles.bind_to_storage_buffer(BINDING_TRIANGLES)

    def intersect(self, origins: np.ndarray, directions: np.ndarray,
                  t_min: float | np.ndarray = 0.0, t_max: float | np.ndarray = np.inf) -> Hits:
        """Closest hit of each ray (R, 3) with ``t_min < t < t_max`` (per ray or shared)."""
        out = self._run(_pack_rays(origins, directions, t_min, t_max), 0, RESULT_DTYPE)
        hit = out["triangle"] >= 0
        return Hits(np.where(hit, out["t"], np.float32(np.inf)), out["triangle"].copy(),
                    np.where(hit[:, None], out["uv"], np.float32(0.0)))

    def occluded(self, origins: np.ndarray, directions: np.ndarray, t_max: float | np.ndarray,
                 t_min: float | np.ndarray = 0.0) -> np.ndarray:
        """Whether each ray hits anything with ``t_min < t < t_max`` (any hit, early exit)."""
        return self._run(_pack_rays(origins, directions, t_min, t_max), 1, np.dtype("<i4")) != 0

    def release(self) -> None:
        self._release_scene()
        for buffer in (self._rays, self._results):
            if buffer is not None:
                buffer.release()
        self._rays = self._results = None

    def _release_scene(self) -> None:
        for buffer in (self._nodes, self._triangles):
            if buffer is not None:
                buffer.release()
        self._nodes = self._triangles = None

    def _run(self, rays: np.ndarray, any_hit: int, out_dtype: np.dtype) -> np.ndarray:
        """Trace ``rays`` in batches of at most ``batch_size`` with raytrace_comp.glsl."""
        shader = self.programs.compute("raytrace_comp.glsl", {"RT_ANY_HIT": any_hit})
        out = np.empty(len(rays), out_dtype)
        self.bind()
        for start in range(0, len(rays), self.batch_size):
            batch = rays[start:start + self.batch_size]
            self._reserve(len(batch))
            self._rays.write(batch.tobytes())
            self._rays.bind_to_storage_buffer(BINDING_RAYS)
            self._results.bind_to_storage_buffer(BINDING_RESULTS)
            shader["rt_ray_count"] = len(batch)
            shader.run(-(-len(batch) // LOCAL_SIZE))
            self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
            data = self._results.read(len(batch) * out_dtype.itemsize)
            out[start:start + len(batch)] = np.frombuffer(data, out_dtype)
        return out

    def _reserve(self, rays: int) -> None:
        """Grow the ray and result buffers to hold ``rays`` rays."""
        if self._rays is not None and self._rays.size >= rays * RAY_DTYPE.itemsize:
            return
        if self._rays is not None:
            self._rays.release()
            self._results.release()
        self._rays = self.ctx.buffer(reserve=rays * RAY_DTYPE.itemsize)
        self._results = self.ctx.buffer(reserve=rays * RESULT_DTYPE.itemsize)
