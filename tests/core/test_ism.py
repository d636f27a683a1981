"""Imperfect shadow maps: surface points drawn on the GPU, pull-push, and ISM visibility against the
analytic shadow of a square occluder above a floor."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.gpu import ism
from addon.core.gpu.gl import SHADER_DIR
from addon.core.gpu.ism import ImperfectShadowMaps

RESOLUTION = 128
POINTS = 8192


@pytest.fixture(scope="session")
def maps(programs) -> ImperfectShadowMaps:
    m = ImperfectShadowMaps(programs.ctx, programs)
    yield m
    m.release()


def quad(x0: float, x1: float, y0: float, y1: float, z: float) -> np.ndarray:
    """Two triangles: the rectangle [x0, x1] × [y0, y1] at height z."""
    return np.array([[[x0, y0, z], [x1, y0, z], [x1, y1, z]],
                     [[x0, y0, z], [x1, y1, z], [x0, y1, z]]], np.float32)


# -- surface points (drawn on the GPU) ----------------------------------------------------------

def test_points_are_uniform_by_area_and_stratified_in_every_set(maps):
    small = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.2, 0]], np.float32)  # area 0.01
    big = np.array([[0, 0, 1], [2, 0, 1], [0, 1, 1]], np.float32)  # area 1
    degenerate = np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2]], np.float32)
    broken = np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]], np.float32)
    tris = np.stack([small, degenerate, big, broken])
    count, sets = 1000, 16
    maps.prepare(tris, count, seed=3, version="uniform")  # the fixture is shared
    for first in (0, 5000):  # every map has its own set, however many there are
        points = maps.points(first, sets)
        assert len(points) == count * sets
        per_set = np.stack([np.bincount(t, minlength=4) for t in
                            points.triangle.reshape(sets, count)])
        expected = count * np.array([0.01, 0, 1, 0]) / 1.01
        assert (np.abs(per_set - expected) < 1).all()  # stratified: floor or ceiling
        uv = points.barycentric
        assert (uv >= 0).all() and (uv.sum(axis=1) <= 1).all()
        # Within a triangle, the four halved-edge sub-triangles get a quarter each.
        on_big = uv[points.triangle == 2].astype(np.float64)
        region = np.select([on_big[:, 0] > 0.5, on_big[:, 1] > 0.5, on_big.sum(axis=1) < 0.5],
                           [0, 1, 2], 3)
        share = np.bincount(region, minlength=4) / len(region)
        np.testing.assert_allclose(share, 0.25, atol=0.01)


def jittered_square(cells: int, rng: np.random.Generator) -> np.ndarray:
    """The unit square cut into 2 cells² triangles of unequal areas (jittered grid)."""
    g = np.linspace(0, 1, cells + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    inner = (slice(1, -1), slice(1, -1))
    x[inner] += rng.uniform(-0.4, 0.4, x[inner].shape) / cells
    y[inner] += rng.uniform(-0.4, 0.4, y[inner].shape) / cells
    v = np.stack([x, y, np.zeros_like(x)], -1)
    a, b, c, d = v[:-1, :-1], v[1:, :-1], v[1:, 1:], v[:-1, 1:]
    return np.concatenate([np.stack([a, b, c], 2), np.stack([a, c, d], 2)]).reshape(-1, 3, 3)


def test_points_are_area_uniform_over_a_surface_and_deterministic(programs):
    """On a square cut into triangles of unequal areas, each set's points fall uniformly on the
    square (chi-square of a 10 × 10 histogram below its 99.9 % quantile, for the sets pooled
    and for one), every triangle gets its share; a second instance with the same seed draws
    the same points bit for bit and renders the same atlas, another seed other points."""
    from scipy.stats import chi2

    tris = jittered_square(12, np.random.default_rng(8)).astype(np.float32)
    area = np.abs(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])[:, 2]) / 2
    count, sets = 4096, 24
    first, second, other = (ImperfectShadowMaps(programs.ctx, programs) for _ in range(3))
    try:
        atlases = []
        for m, seed in ((first, 21), (second, 21), (other, 22)):
            m.prepare(tris, count, seed=seed)
            m.render(tris, [[0.5, 0.5, 1.0], [0.2, 0.7, 0.5]], [[0.0, 0.0, -1.0]] * 2, 32, 5)
            atlases.append(m.read_atlas())
        points = first.points(0, sets)
        again = second.points(0, sets)
        np.testing.assert_array_equal(points.triangle, again.triangle)
        np.testing.assert_array_equal(points.barycentric.view(np.uint32),
                                      again.barycentric.view(np.uint32))
        np.testing.assert_array_equal(atlases[0].view(np.uint32), atlases[1].view(np.uint32))
        assert not np.array_equal(other.points(0, sets).barycentric, points.barycentric)
        assert not np.array_equal(atlases[0], atlases[2])
    finally:
        for m in (first, second, other):
            m.release()
    per_set = np.stack([np.bincount(t, minlength=len(tris)) for t in
                        points.triangle.reshape(sets, count)])
    assert (np.abs(per_set - count * area / area.sum()) < 1 + 1e-3).all()
    t = tris[points.triangle].astype(np.float64)
    uv = points.barycentric.astype(np.float64)
    xy = (t[:, 0] + uv[:, :1] * (t[:, 1] - t[:, 0]) + uv[:, 1:] * (t[:, 2] - t[:, 0]))[:, :2]
    for sample in (xy, xy[:count]):
        histogram, _, _ = np.histogram2d(sample[:, 0], sample[:, 1], bins=10,
                                         range=[[0, 1], [0, 1]])
        expected = len(sample) / 100
        statistic = ((histogram - expected) ** 2 / expected).sum()
        assert statistic < chi2.ppf(0.999, 99), statistic


def test_every_set_is_its_own(maps):
    tris = np.concatenate([quad(0, 1, 0, 1, 0), quad(0, 1, 0, 1, 1)])
    maps.prepare(tris, 500, seed=4, version="own")
    points = maps.points(0, 8)
    beyond = maps.points(512, 8)  # the sets of maps 512.. (the old pool repeated at 512)
    sets = [set(zip(t.tolist(), map(tuple, uv.tolist()), strict=True)) for p in (points, beyond)
            for t, uv in zip(p.triangle.reshape(8, -1), p.barycentric.reshape(8, -1, 2),
                             strict=True)]
    for i in range(len(sets)):
        for j in range(i):
            assert not sets[i] & sets[j]


def test_empty_and_zero_area_scenes_give_no_points(maps):
    flat = np.zeros((3, 3, 3), np.float32)
    for tris in (np.zeros((0, 3, 3), np.float32), flat):
        maps.prepare(tris, 100, seed=1, version="empty")
        points = maps.points(0, 4)
        assert len(points) == 0 and points.barycentric.shape == (0, 2)


def test_the_area_table_is_uploaded_once_per_geometry_version(maps):
    tris = occluder_scene()
    maps.prepare(np.zeros((1, 3, 3), np.float32), 16, seed=1)
    assert maps.prepare(tris, 1024, seed=2)
    assert not maps.prepare(tris * 2, 2048, seed=3)  # same version: the table is kept
    assert maps.prepare(tris * 2, 2048, seed=3, version=1)  # a new version: built again
    assert maps.prepared_triangles == len(tris)


# -- pull-push ---------------------------------------------------------------------------------

def in_disk(height: int, width: int, resolution: int) -> np.ndarray:
    """Texels of an atlas whose centres lie inside their tile's unit disk."""
    local = (np.arange(resolution) + 0.5) / resolution * 2 - 1
    disk = local[:, None] ** 2 + local[None, :] ** 2 < 1
    return np.tile(disk, (height // resolution, width // resolution))


def sparse(shape: tuple[int, int], fraction: float, rng: np.random.Generator,
           low: float = 1.0, high: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    depth = np.full(shape, np.inf, np.float32)
    valid = rng.random(shape) < fraction
    depth[valid] = rng.uniform(low, high, valid.sum())
    return depth, valid


def test_pull_push_fills_every_hole_and_keeps_valid_texels(maps):
    """Valid texels within a factor BEHIND of each other are kept bit for bit."""
    resolution = 64
    depth, valid = sparse((2 * resolution, 3 * resolution), 0.1, np.random.default_rng(5),
                          high=ism.BEHIND)
    filled = maps.pull_push(depth, resolution, 6)
    assert filled.shape == depth.shape and np.isfinite(filled).all()
    np.testing.assert_array_equal(filled.view(np.uint32)[valid], depth.view(np.uint32)[valid])
    assert (filled[in_disk(*depth.shape, resolution)] < ism.FAR).all()
    assert (filled >= 1).all() and (filled <= ism.BEHIND).all()  # averages of valid depths


def test_a_farther_surface_seen_through_gaps_of_a_nearer_one_is_a_hole(maps):
    """A wall at depth 1 splatted with gaps, a surface at depth 3 behind it showing through
    them: the gaps are filled from the wall around them, nearer than 3 / BEHIND, so the far
    surface is in its shadow there (before: 3, lit: light got through the wall); beside the
    wall's edge the far surface keeps its depth."""
    resolution = 32
    depth = np.full((resolution, resolution), 3.0, np.float32)
    wall = np.zeros(depth.shape, bool)
    wall[:, :16] = True
    gaps = wall & (np.random.default_rng(7).random(depth.shape) < 0.2)
    gaps[:, 14:16] = False  # the wall's edge column pair is whole
    depth[wall & ~gaps] = 1.0
    filled = maps.pull_push(depth, resolution, 5)
    assert (filled[wall] < 3.0 / ism.BEHIND).all(), filled[gaps]
    np.testing.assert_array_equal(filled[:, 16:], 3.0)


def test_too_few_levels_leave_far_holes(maps):
    resolution = 32
    depth = np.full((resolution, resolution), np.inf, np.float32)
    depth[0, 0] = 1.5
    raw = maps.pull_push(depth, resolution, 0)
    assert raw[0, 0] == 1.5 and (raw.ravel()[1:] == np.float32(ism.FAR)).all()
    one = maps.pull_push(depth, resolution, 1)
    near = np.zeros(one.shape, bool)
    near[:3, :3] = True  # the texels whose bilinear taps reach coarse texel (0, 0)
    np.testing.assert_array_equal(one[near], 1.5)
    assert (one[~near] == np.float32(ism.FAR)).all()
    full = maps.pull_push(depth, resolution, 5)
    np.testing.assert_array_equal(full, 1.5)


def test_pull_push_of_a_plane_is_the_plane_and_tiles_do_not_mix(maps):
    resolution = 64
    rng = np.random.default_rng(6)
    depth, valid = sparse((resolution, 2 * resolution), 0.05, rng)
    depth[:, :resolution][valid[:, :resolution]] = 1.25  # tile 0: a constant plane
    ramp = np.float32(2.0) + np.arange(resolution, dtype=np.float32) / resolution  # tile 1
    depth[:, resolution:] = np.where(valid[:, resolution:], ramp[None, :], np.inf)
    filled = maps.pull_push(depth, resolution, 6)
    np.testing.assert_allclose(filled[:, :resolution], 1.25, rtol=1e-6)
    right = filled[:, resolution:]
    assert (right >= 2.0).all() and (right < 3.0).all()
    # Filled texels follow the ramp to within a few texels' worth of its slope.
    np.testing.assert_allclose(right, np.broadcast_to(ramp, right.shape), atol=6 / resolution)


# -- visibility --------------------------------------------------------------------------------

def occluder_scene() -> np.ndarray:
    """A 2 × 2 floor at z = 0, a 0.5 × 0.5 occluder at z = 0.5 and a ceiling at z = 1."""
    return np.concatenate([quad(-1, 1, -1, 1, 0), quad(-0.25, 0.25, -0.25, 0.25, 0.5),
                           quad(-1, 1, -1, 1, 1)])


def floor_grid(n: int) -> np.ndarray:
    g = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(g, g)
    return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)


def analytic_lit(floor: np.ndarray, light: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether the segment from each floor point to the light misses the occluder, and each
    point's distance (in the occluder's plane) to the occluder's edge."""
    m = floor + (light - floor) * (0.5 / light[2])
    outside = np.abs(m[:, :2]) - 0.25
    edge = np.where((outside < 0).all(axis=1), -outside.max(axis=1),
                    np.linalg.norm(np.maximum(outside, 0), axis=1))
    return ~(outside < 0).all(axis=1), edge


VPLS = np.array([[0.0, 0.0, 0.999], [0.3, -0.2, 0.999], [-0.4, 0.1, 0.999], [0.1, 0.45, 0.999]])


def visibility_stats(m: ImperfectShadowMaps, levels: int, points: int = POINTS
                     ) -> tuple[float, float]:
    """(agreement, leak: the share of shadowed points found lit) of ISM visibility on a floor
    grid for each VPL, averaged; points within 0.02 of the shadow's edge (in the occluder's
    plane, about a texel) are left out."""
    tris = occluder_scene()
    m.prepare(tris, points, seed=11)
    m.render(tris, VPLS, np.tile([0.0, 0.0, -1.0], (len(VPLS), 1)), RESOLUTION, levels)
    floor = floor_grid(60)
    agree, leak = [], []
    for k, light in enumerate(VPLS):
        lit, edge = analytic_lit(floor, light)
        v = m.visibility(np.full(len(floor), k), floor, np.tile([0.0, 0.0, 1.0], (len(floor), 1)))
        assert np.isfinite(v).all() and ((v >= 0) & (v <= 1)).all()
        clear = edge > 0.02
        ism_lit = v[clear] > 0.5
        agree.append((ism_lit == lit[clear]).mean())
        leak.append(ism_lit[~lit[clear]].mean())
    return float(np.mean(agree)), float(np.mean(leak))


def test_visibility_matches_the_analytic_shadow(maps):
    agree, leak = visibility_stats(maps, 7)
    assert agree >= 0.95 and leak <= 0.15, (agree, leak)


def test_raw_point_splats_leak_and_pull_push_fills_them(programs):
    """The seed's step 3: single-texel splats of sparse points leave holes in the occluder
    that light leaks through, and pull-push fills them. (Floor points splatted into the
    occluder's gaps stay: pull-push never moves a valid texel. Footprints remove those.)"""
    points_only = ImperfectShadowMaps(programs.ctx, programs, footprint_scale=0)
    try:
        _, raw_leak = visibility_stats(points_only, 0, 2048)
        _, filled_leak = visibility_stats(points_only, 7, 2048)
    finally:
        points_only.release()
    assert raw_leak > 0.8 and filled_leak < 0.75 * raw_leak, (raw_leak, filled_leak)


def test_points_follow_moved_triangles_and_depth_scales(maps):
    tris = occluder_scene()
    normals = np.tile([0.0, 0.0, -1.0], (2, 1))
    maps.prepare(tris, 2048, seed=12)
    maps.render(tris, VPLS[:2], normals, 32, 5)
    base = maps.read_atlas()
    shift = np.float32([5.0, -3.0, 2.0])
    maps.prepare(tris + shift, 2048, seed=12)  # same count: the area table is kept
    maps.render(tris + shift, VPLS[:2] + shift, normals, 32, 5)
    np.testing.assert_allclose(maps.read_atlas(), base, rtol=1e-4)
    maps.render(tris * 1000, VPLS[:2] * 1000, normals, 32, 5)
    np.testing.assert_allclose(maps.read_atlas(), np.minimum(base * 1000, ism.FAR), rtol=1e-4)


def test_partial_update_equals_a_full_render(maps):
    """Re-rendering two tiles of eight (their VPLs moved) gives the atlas a full render of the
    new set gives, bit for bit, and leaves the other six tiles alone."""
    tris = occluder_scene()
    rng = np.random.default_rng(4)
    positions = np.column_stack([rng.uniform(-0.8, 0.8, (8, 2)), np.full(8, 0.05)])
    normals = np.tile([0.0, 0.0, 1.0], (8, 1))
    maps.prepare(tris, 1024, seed=3)
    maps.render(tris, positions, normals, 32, 5)
    before = maps.read_atlas()
    moved = positions.copy()
    moved[[2, 5]] += [0.3, -0.2, 0.0]
    maps.render(tris, moved[[2, 5]], normals[[2, 5]], 32, 5, tiles=np.array([2, 5]),
                tile_count=8)
    partial = maps.read_atlas()
    maps.render(tris, moved, normals, 32, 5)
    np.testing.assert_array_equal(partial, maps.read_atlas())
    changed = [not np.array_equal(tile_of(partial, k, 32, maps.columns),
                                  tile_of(before, k, 32, maps.columns)) for k in range(8)]
    assert changed == [k in (2, 5) for k in range(8)]


def test_a_taken_atlas_keeps_its_maps_while_the_next_render_fills_a_new_one(maps):
    """A frame with several atlases takes each one after its render: the taken texture keeps
    that render's maps, and the next render of the same layout fills a texture of its own."""
    tris = occluder_scene()
    normals = np.tile([0.0, 0.0, -1.0], (2, 1))
    maps.prepare(tris, 2048, seed=12)
    first = maps.render(tris, VPLS[:2], normals, 32, 5)
    expected = maps.read_atlas()
    taken = maps.take_atlas()
    assert taken is first and maps.atlas is None
    try:
        second = maps.render(tris * 2, VPLS[:2] * 2, normals, 32, 5)
        assert second is not taken
        kept = np.frombuffer(taken.read(), np.float32).reshape(expected.shape)
        np.testing.assert_array_equal(kept, expected)
        assert not np.array_equal(maps.read_atlas(), expected)
    finally:
        taken.release()


def tile_of(atlas: np.ndarray, k: int, resolution: int, columns: int) -> np.ndarray:
    row, column = divmod(k, columns)
    return atlas[row * resolution:(row + 1) * resolution,
                 column * resolution:(column + 1) * resolution]


def test_empty_scene_and_vpl_facing_nothing_are_all_lit(maps):
    lights = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 0.5]])
    normals = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])  # the second faces the empty sky
    below, above = floor_grid(8) * [0.5, 0.5, 0], floor_grid(8) * [0.5, 0.5, 0] + [0, 0, 1]
    up = np.tile([0.0, 0.0, 1.0], (len(below), 1))
    for tris, vpls, targets in ((np.zeros((0, 3, 3), np.float32), (0, 1), (below, above)),
                                (quad(-1, 1, -1, 1, 0), (1,), (above,))):
        maps.prepare(tris, 1024, seed=13)
        maps.render(tris, lights, normals, 32, 5)
        atlas = maps.read_atlas()
        assert not np.isnan(atlas).any()
        assert (atlas[:, 32:] == np.float32(ism.FAR)).all()
        for vpl, points in zip(vpls, targets, strict=True):
            v = maps.visibility(np.full(len(points), vpl), points, up)
            np.testing.assert_array_equal(v, 1.0)
    assert (atlas[:, :32] < 1).any()  # the floor is seen by the first VPL
    maps.render(tris, np.zeros((0, 3)), np.zeros((0, 3)), 32, 5)  # no VPLs: one empty tile
    assert (maps.read_atlas() == np.float32(ism.FAR)).all()


def test_a_new_splat_image_starts_empty_when_filled_in_strips(programs, monkeypatch):
    monkeypatch.setattr(ism, "EMPTY_STRIP_TEXELS", 3 * 64 + 5)  # 3 rows of the 64² atlas
    m = ImperfectShadowMaps(programs.ctx, programs)
    try:
        tris = np.zeros((0, 3, 3), np.float32)
        m.prepare(tris, 64, seed=2)
        m.render(tris, np.zeros((3, 3)), np.tile([0.0, 0.0, 1.0], (3, 1)), 32, 0)
        assert m.read_atlas().shape == (64, 64)
        assert (m.read_atlas() == np.float32(ism.FAR)).all()  # raw splats: no pull-push
    finally:
        m.release()


def test_render_checks_its_inputs(programs):
    m = ImperfectShadowMaps(programs.ctx, programs)
    try:
        with pytest.raises(RuntimeError, match="prepare"):
            m.render(quad(0, 1, 0, 1, 0), VPLS, VPLS, 32, 1)
        m.prepare(quad(0, 1, 0, 1, 0), 16, seed=1)
        with pytest.raises(ValueError, match="4 triangles; the points were sampled on 2"):
            m.render(np.concatenate([quad(0, 1, 0, 1, 0)] * 2), VPLS, VPLS, 32, 1)
        with pytest.raises(ValueError, match="atlas; this GPU allows"):
            m.render(quad(0, 1, 0, 1, 0), VPLS, VPLS, 1 << 15, 1)
    finally:
        m.release()


@pytest.mark.parametrize("file, name, value", [
    ("ism_points_lib.glsl", "ISM_BINDING_CDF", ism.BINDING_CDF),
    ("ism_points_lib.glsl", "ISM_BINDING_GUIDE", ism.BINDING_GUIDE),
    ("ism_points_comp.glsl", "ISM_BINDING_POINT_OUT", ism.BINDING_POINT_OUT),
    ("ism_points_comp.glsl", "local_size_x =", ism.POINT_LOCAL_SIZE),
    ("ism_splat_comp.glsl", "ISM_BINDING_VERTICES", ism.BINDING_VERTICES),
    ("ism_splat_comp.glsl", "ISM_BINDING_VPLS", ism.BINDING_VPLS),
    ("ism_lookup_comp.glsl", "ISM_BINDING_VPLS", ism.BINDING_VPLS),
    ("ism_lookup_comp.glsl", "ISM_BINDING_QUERIES", ism.BINDING_QUERIES),
    ("ism_lookup_comp.glsl", "ISM_BINDING_RESULTS", ism.BINDING_RESULTS),
    ("ism_splat_comp.glsl", "local_size_x =", ism.POINT_LOCAL_SIZE),
    ("ism_lookup_comp.glsl", "local_size_x =", ism.POINT_LOCAL_SIZE),
    ("ism_pull_comp.glsl", "local_size_x =", ism.IMAGE_LOCAL_SIZE),
    ("ism_push_comp.glsl", "local_size_y =", ism.IMAGE_LOCAL_SIZE),
    ("ism_lib.glsl", "ISM_FAR", "3.0e38"),
    ("ism_pull_comp.glsl", "ISM_EMPTY_BITS", "0xFFFFFFFFu"),
    ("ism_push_comp.glsl", "ISM_EMPTY_BITS", "0xFFFFFFFFu"),
    ("ism_push_comp.glsl", "ISM_BEHIND", repr(ism.BEHIND))])
def test_glsl_constants_match_python(file, name, value):
    assert f"{name} {value}" in (SHADER_DIR / file).read_text(encoding="utf-8")
