"""The GPU ray tracer against a brute-force float64 reference, and the BVH's invariants."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from addon.core.gpu import instanced_bvh, raytrace
from addon.core.gpu.bvh import BVH, STACK_SIZE, build_bvh
from addon.core.gpu.gl import (
    SHADER_DIR,
    GLUnavailableError,
    require_compute,
)
from addon.core.gpu.instanced_bvh import build_instanced_bvh
from addon.core.scene.geometry import flatten_instances
from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings
from tests.core.builders import floor_scene, icosphere, light, rotation_x, translation


def soup(count: int, rng: np.random.Generator, size: float = 0.2) -> np.ndarray:
    centres = rng.uniform(-1, 1, (count, 1, 3))
    return (centres + rng.normal(0, size, (count, 3, 3))).astype(np.float32)


def random_rays(count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return rng.uniform(-1.5, 1.5, (count, 3)), rng.normal(size=(count, 3))


def reference_t(tris: np.ndarray, origins: np.ndarray, directions: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two-sided Möller–Trumbore in float64: t, u, v for every (ray, triangle), inf for misses
    (t >= 0 only)."""
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    v0 = tris[:, 0].astype(np.float64)
    e1, e2 = tris[:, 1] - v0, tris[:, 2] - v0
    p = np.cross(d[:, None], e2[None])
    det = np.einsum("tk,rtk->rt", e1, p)
    s = origins[:, None] - v0[None]
    q = np.cross(s, e1[None])
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.einsum("rtk,rtk->rt", s, p) / det
        v = np.einsum("rk,rtk->rt", d, q) / det
        t = np.einsum("tk,rtk->rt", e2, q) / det
    hit = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0)
    return np.where(hit, t, np.inf), u, v


def closest(t: np.ndarray, t_min: float = 0.0, t_max: float = np.inf
            ) -> tuple[np.ndarray, np.ndarray]:
    t = np.where((t > t_min) & (t < t_max), t, np.inf)
    best = t.argmin(axis=1)
    distance = t[np.arange(len(t)), best]
    return distance, np.where(np.isfinite(distance), best, -1)


def assert_same_hits(hits, t: np.ndarray, u: np.ndarray, v: np.ndarray,
                     t_min: float = 0.0, t_max: float = np.inf, atol: float = 0.0) -> None:
    distance, triangle = closest(t, t_min, t_max)
    rows = np.arange(len(t))
    np.testing.assert_array_equal(hits.triangle >= 0, triangle >= 0)
    np.testing.assert_allclose(hits.distance, distance, rtol=1e-4, atol=atol)
    differ = hits.triangle != triangle  # only exact ties may differ
    np.testing.assert_allclose(t[differ, hits.triangle[differ]], distance[differ], rtol=1e-6)
    same = (triangle >= 0) & ~differ
    uv = np.stack([u[rows, triangle], v[rows, triangle]], axis=1)[same]
    np.testing.assert_allclose(hits.barycentric[same], uv, atol=1e-4)


def assert_valid_bvh(bvh: BVH, tris: np.ndarray, leaf_size: int) -> None:
    """Every triangle in exactly one leaf; every box contains its children and triangles."""
    count = len(tris)
    np.testing.assert_array_equal(np.sort(bvh.triangle_ids), np.arange(count))
    np.testing.assert_array_equal(bvh.triangles, tris[bvh.triangle_ids])
    first, size = bvh.node_data[:, 0], bvh.node_data[:, 1]
    leaf = size >= 0
    assert (size[leaf] <= leaf_size).all()
    covered = np.zeros(count, int)
    for a, b in zip(first[leaf], size[leaf], strict=True):
        covered[a:a + b] += 1
    np.testing.assert_array_equal(covered, 1)
    referenced = np.zeros(len(bvh.node_data), int)
    for node in np.flatnonzero(~leaf):
        for child in (first[node], first[node] + 1):
            referenced[child] += 1
            assert child > node
            assert (bvh.node_min[node] <= bvh.node_min[child]).all()
            assert (bvh.node_max[node] >= bvh.node_max[child]).all()
    np.testing.assert_array_equal(referenced[1:], 1)  # a tree: each node has one parent
    assert referenced[0] == 0
    for node in np.flatnonzero(leaf & (size > 0)):
        t = bvh.triangles[first[node]:first[node] + size[node]]
        assert (t >= bvh.node_min[node]).all() and (t <= bvh.node_max[node]).all()
    assert bvh.depth <= STACK_SIZE


@pytest.mark.parametrize("leaf_size", [1, 4, 7])
def test_bvh_invariants_on_a_soup(leaf_size):
    tris = soup(3000, np.random.default_rng(leaf_size))
    assert_valid_bvh(build_bvh(tris, leaf_size), tris, leaf_size)


@pytest.mark.parametrize("count", [0, 1, 2, 5, 50])
def test_bvh_invariants_on_small_and_coincident_scenes(count):
    one = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    tris = np.repeat(one, count, axis=0)  # identical triangles: no spatial split exists
    bvh = build_bvh(tris)
    assert_valid_bvh(bvh, tris, 4)
    assert len(bvh.node_data) >= 1


def skewed_scene() -> np.ndarray:
    """Thin triangles along x at geometric spacing: SAH peels them off a few at a time, so the
    tree gets deep (38 levels)."""
    x = np.float32(1.02) ** np.arange(4000, dtype=np.float32)
    tris = np.zeros((len(x), 3, 3), np.float32)
    tris[:, :, 0] = x[:, None] + [0, 1e-3, 0]
    tris[:, 2, 1] = 1e-3
    return tris


def test_bvh_depth_is_capped_on_a_skewed_scene():
    tris = skewed_scene()
    free = build_bvh(tris, 1)
    capped = build_bvh(tris, 1, max_depth=14)
    assert free.depth > capped.depth == 14
    assert_valid_bvh(capped, tris, 1)
    with pytest.raises(ValueError, match="deeper than 11"):
        build_bvh(tris, 1, max_depth=11)


def test_deep_trees_are_traversed(tracer):
    tris = skewed_scene()
    tracer.upload(tris, leaf_size=1)
    target = np.arange(300)  # the deepest part of the tree, x < 400
    origins = tris[target].mean(axis=1) + np.float32([0, 0, 1])
    hits = tracer.intersect(origins, np.broadcast_to([0.0, 0.0, -1.0], origins.shape))
    np.testing.assert_array_equal(hits.triangle, target)
    np.testing.assert_allclose(hits.distance, 1.0, rtol=1e-6)


def test_bvh_refuses_non_finite_input():
    with pytest.raises(ValueError, match="finite"):
        build_bvh(np.full((1, 3, 3), np.nan))


def test_matches_brute_force_on_a_soup(tracer):
    rng = np.random.default_rng(1)
    tris = soup(400, rng)
    origins, directions = random_rays(3000, rng)
    tracer.upload(tris)
    hits = tracer.intersect(origins, directions)
    assert (hits.triangle >= 0).mean() > 0.3
    assert_same_hits(hits, *reference_t(tris, origins, directions))


def test_t_min_and_t_max_per_ray(tracer):
    rng = np.random.default_rng(2)
    tris = soup(300, rng)
    origins, directions = random_rays(2000, rng)
    t, u, v = reference_t(tris, origins, directions)
    tracer.upload(tris)
    t_min, t_max = 0.3, 1.2
    assert_same_hits(tracer.intersect(origins, directions, t_min, t_max), t, u, v, t_min, t_max)
    per_ray = rng.uniform(0, 2, len(origins)).astype(np.float32)
    hits = tracer.intersect(origins, directions, 0.0, per_ray)
    np.testing.assert_array_equal(hits.triangle >= 0, np.isfinite(hits.distance))
    assert (hits.distance[hits.triangle >= 0] < per_ray[hits.triangle >= 0]).all()
    np.testing.assert_array_equal(tracer.occluded(origins, directions, per_ray),
                                  tracer.intersect(origins, directions).distance < per_ray)
    window = tracer.intersect(origins, directions, 0.3, per_ray)
    np.testing.assert_array_equal(tracer.occluded(origins, directions, per_ray, t_min=0.3),
                                  window.triangle >= 0)


def instanced_scene(rng: np.random.Generator, singles: int, meshes: list[tuple[int, int]]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``singles`` soup triangles, then per (triangles, copies) a soup mesh's copies, each
    turned, scaled and moved: the triangles and their runs (first, copies, triangles each)."""
    parts, runs, first = [soup(singles, rng)], [], singles
    for count, copies in meshes:
        mesh = soup(count, rng, 0.3) * 0.6
        turn = np.linalg.qr(rng.normal(size=(copies, 3, 3)))[0]
        turn *= rng.uniform(0.5, 2, (copies, 1, 1))
        moved = np.einsum("kij,tvj->ktvi", turn, mesh) + rng.uniform(-1, 1, (copies, 1, 1, 3))
        parts.append(moved.reshape(-1, 3, 3).astype(np.float32))
        runs.append((first, copies, count))
        first += copies * count
    return np.concatenate(parts), np.array(runs, np.int64).reshape(-1, 3)


@pytest.mark.parametrize("singles, meshes", [
    (200, [(30, 12), (3, 40)]),  # a 3-triangle mesh's tree is one leaf
    (0, [(25, 20)]),  # nothing but copies
    (1, [(2, 3)])])
def test_an_instanced_bvh_is_valid_and_traced_like_brute_force(tracer, singles, meshes):
    rng = np.random.default_rng(len(meshes) + singles)
    tris, runs = instanced_scene(rng, singles, meshes)
    bvh = build_instanced_bvh(tris, runs)
    assert_valid_bvh(bvh, tris, 4)
    origins, directions = random_rays(3000, rng)
    tracer.upload(tris, instanced=runs)
    hits = tracer.intersect(origins, directions)
    assert (hits.triangle >= 0).sum() >= 20
    t, u, v = reference_t(tris, origins, directions)
    assert_same_hits(hits, t, u, v, atol=2e-6)  # float32 at hits 1e-3 from a ray's origin
    np.testing.assert_array_equal(tracer.occluded(origins, directions, 1.0), closest(t)[0] < 1.0)


def test_an_instanced_bvh_builds_each_mesh_once_and_falls_back_when_too_deep(monkeypatch):
    rng = np.random.default_rng(7)
    tris, runs = instanced_scene(rng, 50, [(40, 30)])
    built = []
    real_build = instanced_bvh.build_bvh
    monkeypatch.setattr(instanced_bvh, "build_bvh", lambda t, *a: built.append(len(t)) or
                        real_build(t, *a))
    build_instanced_bvh(tris, runs)
    assert built == [50, 40]  # the single triangles, then the shared mesh's first copy
    built.clear()
    monkeypatch.setattr(instanced_bvh, "STACK_SIZE", build_bvh(tris[:50]).depth + 2)
    bvh = build_instanced_bvh(tris, runs)  # 31 subtrees need 5 levels above them: too deep
    assert built[-1] == len(tris)
    assert_valid_bvh(bvh, tris, 4)


def planes(heights: list[float]) -> np.ndarray:
    """Two triangles per height: the square [-1, 1]^2 at z = h."""
    square = np.array([[[-1, -1, 0], [1, -1, 0], [1, 1, 0]], [[-1, -1, 0], [1, 1, 0], [-1, 1, 0]]],
                      np.float32)
    return np.concatenate([square + np.float32([0, 0, h]) for h in heights])


def test_the_interval_is_open_and_exact(tracer):
    tracer.upload(planes([1.0, 2.0, 3.0]))
    origin, up = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    below_one = float(np.nextafter(np.float32(1), np.float32(0)))
    cases = [((0.0, np.inf), 1.0), ((1.0, np.inf), 2.0), ((below_one, np.inf), 1.0),
             ((0.0, 1.0), np.inf), ((0.5, 1.5), 1.0), ((1.0, 2.0), np.inf), ((2.5, 3.5), 3.0)]
    for (t_min, t_max), expected in cases:
        hits = tracer.intersect(origin, up, t_min, t_max)
        assert hits.distance[0] == expected, (t_min, t_max)
        assert tracer.occluded(origin, up, t_max, t_min)[0] == np.isfinite(expected)


def fresnel(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised dielectric Fresnel reflectance, entering a medium of IOR ``eta``."""
    cos_t = np.sqrt(1 - (1 - cos_i**2) / eta**2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return (rs**2 + rp**2) / 2


def test_clear_triangles_are_never_hit_and_dim_what_crosses_them(tracer):
    """A pane (two clear faces, IOR 1.5, tinted) at z = 0.5 and 0.6 over an opaque floor at
    z = 2: rays find the floor, dimmed by the pane's colour squared and (1 - F)² at their
    angle; occlusion sees the floor only."""
    tint = np.array([1.0, 0.8, 0.4])
    wide = np.float32([4, 4, 1])
    tracer.upload(planes([2.0]) * wide, clear=planes([0.5, 0.6]) * wide,
                  transmission=np.tile([*tint, 1.5], (4, 1)))
    angles = np.radians([0.0, 30.0, 60.0])
    directions = np.stack([np.sin(angles), np.zeros(3), np.cos(angles)], axis=1)
    origins = np.tile([0.1, 0.3, 0.0], (3, 1))  # off the squares' diagonals
    hits = tracer.intersect(origins, directions)
    assert (hits.triangle >= 0).all() and (hits.triangle < 2).all()  # the floor's two
    np.testing.assert_allclose(hits.distance, 2.0 / np.cos(angles), rtol=1e-6)
    expected = (tint[None] * (1 - fresnel(np.cos(angles), 1.5))[:, None]) ** 2
    np.testing.assert_allclose(hits.transmittance, expected, rtol=2e-2)  # colour in 8 bits
    assert expected[0, 0] == pytest.approx(0.9216, abs=1e-4)  # (1 - 0.04)²
    np.testing.assert_array_equal(tracer.occluded(origins, directions, 1.9), [False] * 3)
    np.testing.assert_array_equal(tracer.occluded(origins, directions, np.inf), [True] * 3)
    beyond = tracer.intersect(origins, -directions)  # nothing behind: a miss, undimmed
    np.testing.assert_array_equal(beyond.triangle, [-1] * 3)
    np.testing.assert_array_equal(beyond.transmittance, np.ones((3, 3)))
    tracer.upload(planes([2.0]) * wide)  # no clear triangles: nothing dims
    np.testing.assert_array_equal(tracer.intersect(origins, directions).transmittance,
                                  np.ones((3, 3)))


def test_both_sides_of_a_triangle_are_hit(tracer):
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float32)
    for scene in (tri, tri[:, ::-1]):
        tracer.upload(scene)
        origins = np.array([[0.2, 0.3, 1.0], [0.2, 0.3, -2.0]])
        hits = tracer.intersect(origins, np.array([[0.0, 0.0, -3.0], [0.0, 0.0, 0.5]]))
        np.testing.assert_array_equal(hits.triangle, [0, 0])
        np.testing.assert_allclose(hits.distance, [1.0, 2.0], rtol=1e-6)
    np.testing.assert_allclose(hits.barycentric, [[0.2, 0.5]] * 2, atol=1e-6)  # reversed


def test_closed_box_is_watertight(tracer):
    n = 8  # each face an n × n grid of quads; rays aimed at grid vertices and edge midpoints
    g = np.linspace(-1, 1, n + 1)
    a, b = np.meshgrid(g[:-1], g[:-1], indexing="ij")
    quads = np.stack([np.stack([a, b], -1), np.stack([a + 2 / n, b], -1),
                      np.stack([a + 2 / n, b + 2 / n], -1), np.stack([a, b + 2 / n], -1)],
                     axis=2).reshape(-1, 4, 2)
    faces = [np.insert(quads, axis, side, axis=2) for axis in range(3) for side in (-1.0, 1.0)]
    quads3 = np.concatenate(faces)
    tris = np.concatenate([quads3[:, [0, 1, 2]], quads3[:, [0, 2, 3]]]).astype(np.float32)
    tracer.upload(tris)
    midpoints = (quads3 + np.roll(quads3, 1, axis=1)) / 2
    targets = np.concatenate([quads3.reshape(-1, 3), midpoints.reshape(-1, 3),
                              quads3.mean(axis=1)])
    rng = np.random.default_rng(3)
    for origins in (np.zeros((1, 3)), rng.uniform(-0.9, 0.9, (3, 3)), np.full((1, 3), 0.25)):
        for origin in origins:
            hits = tracer.intersect(np.broadcast_to(origin, targets.shape), targets - origin)
            assert (hits.triangle >= 0).all()
            assert not tracer.occluded(np.broadcast_to(origin, targets.shape), targets - origin,
                                       0.05).any()


def test_degenerate_triangles_and_rays_give_no_nan(tracer):
    rng = np.random.default_rng(4)
    good = soup(100, rng)
    points = np.repeat(rng.uniform(-1, 1, (20, 1, 3)), 3, axis=1)  # 100..119
    lines = rng.uniform(-1, 1, (20, 1, 3)) + np.linspace(0, 1, 3)[None, :, None] * [1, 2, 3]
    needles = good[:20].copy()
    needles[:, 2] = needles[:, 1] + 1e-7 * (needles[:, 0] - needles[:, 1])
    huge = np.float32(1e30) * good[:5]
    tris = np.concatenate([good, points, lines, needles, huge]).astype(np.float32)
    tracer.upload(tris)
    aimed_origins = rng.uniform(-2, 2, (len(tris), 3))
    aimed = tracer.intersect(aimed_origins, tris.mean(axis=1) - aimed_origins)
    origins, directions = random_rays(2000, rng)
    origins = np.concatenate([origins, np.zeros((3, 3))])
    tiny = 1e-30 * good[0].mean(axis=0)
    directions = np.concatenate([directions, [[0, 0, 0], [np.nan, 0, 1], tiny]])
    hits = tracer.intersect(origins, directions)
    for h in (aimed, hits):
        assert not np.isnan(h.distance).any() and not np.isnan(h.barycentric).any()
        assert not np.isin(h.triangle, np.arange(100, 120)).any()
    # A ray aimed exactly at a line may touch it after rounding; others never do.
    assert not np.isin(hits.triangle, np.arange(120, 140)).any()
    assert hits.triangle[-3] == hits.triangle[-2] == -1  # zero and NaN directions miss
    assert hits.triangle[-1] >= 0  # a tiny direction is a direction


def test_empty_scene_and_no_rays(tracer):
    tracer.upload(np.zeros((0, 3, 3), np.float32))
    origins, directions = random_rays(100, np.random.default_rng(5))
    hits = tracer.intersect(origins, directions)
    assert (hits.triangle == -1).all() and np.isinf(hits.distance).all()
    assert not tracer.occluded(origins, directions, np.inf).any()
    tracer.upload(soup(10, np.random.default_rng(5)))
    none = tracer.intersect(np.zeros((0, 3)), np.zeros((0, 3)))
    assert none.distance.shape == (0,) and none.barycentric.shape == (0, 2)
    assert tracer.occluded(np.zeros((0, 3)), np.zeros((0, 3)), 1.0).shape == (0,)


def test_batches_give_the_same_hits(tracer, monkeypatch):
    rng = np.random.default_rng(6)
    tracer.upload(soup(200, rng))
    origins, directions = random_rays(1000, rng)
    whole = tracer.intersect(origins, directions)
    monkeypatch.setattr(tracer, "batch_size", 130)
    batched = tracer.intersect(origins, directions)
    np.testing.assert_array_equal(batched.triangle, whole.triangle)
    np.testing.assert_array_equal(batched.distance, whole.distance)


def spread_scene(rng: np.random.Generator, count: int = 300) -> np.ndarray:
    """Fairly regular triangles of sizes 1e-3 to 1e3 (10^6 : 1), each within about ten of its
    sizes of the origin."""
    size = 10.0 ** rng.uniform(-3, 3, (count, 1, 1))
    shape = np.eye(3) + 0.3 * rng.normal(size=(count, 3, 3))
    return (size * (shape + rng.uniform(-10, 10, (count, 1, 3)))).astype(np.float32)


@pytest.mark.parametrize("scale", [1e-4, 1e4])
def test_hits_are_scale_invariant(tracer, scale):
    rng = np.random.default_rng(7)
    tris = spread_scene(rng)
    pick = rng.integers(0, len(tris), 2000)
    targets = tris.mean(axis=1)[pick]
    size = np.linalg.norm(tris[:, 1] - tris[:, 0], axis=1)[pick, None]
    away = rng.normal(size=targets.shape)
    away *= size * 10.0 ** rng.uniform(0.5, 2, (len(pick), 1)) / np.linalg.norm(away, axis=1,
                                                                                 keepdims=True)
    origins = targets + away
    tracer.upload(tris)
    base = tracer.intersect(origins, -away, 1e-6)
    assert (base.triangle >= 0).all()
    tracer.upload(tris * np.float32(scale))
    scaled = tracer.intersect(origins * scale, -away * scale, 1e-6 * scale)
    np.testing.assert_array_equal(scaled.triangle, base.triangle)
    np.testing.assert_allclose(scaled.distance, base.distance * scale, rtol=1e-4)
    np.testing.assert_allclose(scaled.barycentric, base.barycentric, atol=1e-3)


def test_the_library_works_from_another_shader(tracer):
    """raytrace_test_comp.glsl includes raytrace_lib.glsl next to its own buffers 0 and 1."""
    tracer.upload(planes([1.0, 2.0]))
    points = np.array([[0.5, 0.5, 0.0, 0], [0.5, 0.5, 1.5, 0], [0.5, 0.5, 2.5, 0],
                       [5.0, 0.0, 0.0, 0]], np.float32)
    ctx = tracer.ctx
    shader = tracer.programs.compute("raytrace_test_comp.glsl")
    inputs, outputs = ctx.buffer(points), ctx.buffer(reserve=len(points) * 8)
    try:
        inputs.bind_to_storage_buffer(0)
        outputs.bind_to_storage_buffer(1)
        tracer.bind()
        shader["u_direction"].value = (0.0, 0.0, 1.0)  # up
        shader.run(1)
        ctx.memory_barrier()
        result = np.frombuffer(outputs.read(), np.int32).reshape(-1, 2)
    finally:
        inputs.release()
        outputs.release()
    up, down = result[:, 0], result[:, 1]
    assert up[0] in (0, 1) and up[1] in (2, 3) and up[2] == up[3] == -1
    np.testing.assert_array_equal(down, [0, 1, 1, 0])


def test_compute_needs_opengl_4_3():
    old_driver = SimpleNamespace(version_code=410, info={"GL_RENDERER": "an old driver"})
    with pytest.raises(GLUnavailableError,
                       match=r"OpenGL 4\.3 \(compute shaders\); an old driver offers 4\.1"):
        require_compute(old_driver)


@pytest.mark.parametrize("file, name, value", [
    ("raytrace_lib.glsl", "RT_BINDING_NODES", raytrace.BINDING_NODES),
    ("raytrace_lib.glsl", "RT_BINDING_TRIANGLES", raytrace.BINDING_TRIANGLES),
    ("raytrace_lib.glsl", "RT_STACK_SIZE", STACK_SIZE),
    ("raytrace_comp.glsl", "RT_BINDING_RAYS", raytrace.BINDING_RAYS),
    ("raytrace_comp.glsl", "RT_BINDING_RESULTS", raytrace.BINDING_RESULTS),
    ("raytrace_comp.glsl", "local_size_x =", raytrace.LOCAL_SIZE)])
def test_glsl_constants_match_python(file, name, value):
    assert f"{name} {value}" in (SHADER_DIR / file).read_text(encoding="utf-8")


@pytest.mark.parametrize("visibility", ["exact", "ism"])
def test_a_frame_of_instanced_copies_is_the_frame_of_the_same_copies_each_its_own_mesh(
        renderer, visibility):
    """Sixteen turned, scaled copies of a sphere on a lit floor: traced through the instanced
    BVH (one mesh's tree refitted to sixteen copies) and the ordinary one (sixteen meshes),
    with every ray-traced part of a frame on (VPL paths, exact visibility or ISM, the hybrid
    direct light's rays, bias compensation's rays)."""
    ball = icosphere(0.45, 2)
    turns = [rotation_x(0.4 * i) @ np.diag([1.0 + 0.1 * (i % 3), 1.0, 0.8, 1.0])
             for i in range(16)]
    places = [translation(-3 + 2 * (i % 4), -3 + 2 * (i // 4), 0.5) @ turn
              for i, turn in enumerate(turns)]
    red = [Material("red", (0.8, 0.2, 0.1))]
    shared = [Instance(ball, place, red) for place in places]
    copied = [Instance(replace(ball), place, red) for place in places]  # each its own mesh
    sun = light(LightKind.SUN, rotation_x(0.5), power=3.0)
    lamp = light(LightKind.POINT, translation(0.5, 0.3, 2.5), power=300.0)
    settings = Settings(bounces=2, vpl_count=256, antialiasing=1, visibility=visibility,
                        bias_compensation="image", seed=3)
    frames = []
    for instances in (shared, copied):
        renderer.forget_frames()
        frame, _ = renderer.render(floor_scene([sun, lamp], extra=instances), settings)
        frames.append(frame.passes["Combined"][..., :3])
    geometry = flatten_instances(floor_scene([sun, lamp], extra=shared), [])
    assert geometry.instanced.tolist() == [[2, 16, 320]]  # the floor's 2 triangles first
    instanced, flattened = frames
    assert flattened.mean() > 0.05
    np.testing.assert_allclose(instanced.mean(), flattened.mean(), rtol=2e-3)
    assert np.mean(np.abs(instanced - flattened) > 0.02 * flattened.max()) < 2e-3
