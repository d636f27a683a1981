"""Interleaved sampling (gpu_shaders/interleave_lib.glsl) and the geometry-aware blur that
removes its pattern, on g-buffers built directly from numpy."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.gpu.blur import GeometryAwareBlur
from addon.core.gpu.gl import ProgramCache, draw_into_new_textures

SIZE = 128
SPACING = 0.05  # world units between pixel centres
DEPTH = 10.0  # view depth of z = 0


@pytest.fixture(scope="session")
def blur(programs) -> GeometryAwareBlur:
    b = GeometryAwareBlur(programs.ctx, programs)
    yield b
    b.release()


def run_blur(blur: GeometryAwareBlur, light: np.ndarray | list[np.ndarray],
             position: np.ndarray, normal: np.ndarray, radius: int
             ) -> np.ndarray | list[np.ndarray]:
    """Blur (h, w, 4) float arrays (a list of lights: in one draw, a list back); row 0 is the
    texture's first row."""
    lights = light if isinstance(light, list) else [light]
    h, w = lights[0].shape[:2]
    inputs = [blur.ctx.texture((w, h), 4, np.ascontiguousarray(a, np.float32).tobytes(),
                               dtype="f4") for a in (*lights, position, normal)]
    try:
        outs = blur.apply(inputs[:-2], inputs[-2], inputs[-1], radius)
        results = [np.frombuffer(out.read(), np.float32).reshape(h, w, 4) for out in outs]
        for out in outs:
            out.release()
    finally:
        for texture in inputs:
            texture.release()
    return results if isinstance(light, list) else results[0]


def grid(size: int = SIZE) -> tuple[np.ndarray, np.ndarray]:
    """World x, y of the pixel centres, centred on the origin."""
    c = (np.arange(size) - (size - 1) / 2) * SPACING
    return np.meshgrid(c, c)


def surface(z: np.ndarray, n: np.ndarray, covered: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """Position (xyz, view depth DEPTH - z from a camera looking down -z) and normal (xyz, w)
    textures of height field z with per-pixel normals n (h, w, 3)."""
    x, y = grid(z.shape[0])
    covered = np.ones_like(z) if covered is None else covered.astype(np.float32)
    position = np.stack([x, y, z, DEPTH - z], axis=-1) * covered[..., None]
    normal = np.concatenate([n / np.linalg.norm(n, axis=-1, keepdims=True),
                             np.ones_like(z)[..., None]], axis=-1) * covered[..., None]
    return position, normal


def tilted_plane(size: int = SIZE) -> tuple[np.ndarray, np.ndarray]:
    x, y = grid(size)
    n = np.broadcast_to([-0.6, -0.4, 1.0], (size, size, 3))
    return surface(0.6 * x + 0.4 * y, n)


def rgba(value: np.ndarray) -> np.ndarray:
    """A grey light texture (alpha 0, as in the accumulators) of a scalar field."""
    return np.stack([value, value, value, np.zeros_like(value)], axis=-1)


def pattern(k: int, rng: np.random.Generator, size: int = SIZE) -> np.ndarray:
    """A K×K tiled pattern of positive factors averaging 1, like interleaving leaves."""
    cell = rng.gamma(1.0, size=(k, k))
    return np.tile(cell / cell.mean(), (size // k, size // k))


# -- blur: the pattern ---------------------------------------------------------------------
@pytest.mark.parametrize(("k", "radius"), [(2, 1), (4, 2), (4, 4), (8, 4), (8, 8)])
def test_the_pattern_cancels_exactly_on_a_plane(blur, k, radius):
    """With K dividing 2·radius a constant times the pattern comes back constant (separable
    half-weighted ends: any 2r consecutive pixels hold every pattern column equally often)."""
    position, normal = tilted_plane()
    out = run_blur(blur, rgba(2.0 * pattern(k, np.random.default_rng(k))), position, normal,
                   radius)
    inner = out[radius:-radius, radius:-radius, :3]
    np.testing.assert_allclose(inner, 2.0, rtol=1e-5)


def test_a_smooth_signal_is_restored(blur):
    """K = 4, default radius K: a smooth signal times the pattern comes back within 2 % RMS."""
    k = 4
    x, y = np.meshgrid(np.arange(SIZE), np.arange(SIZE))
    smooth = 1.0 + 0.5 * np.sin(2 * np.pi * x / SIZE) * np.cos(2 * np.pi * y / SIZE + 1.0)
    position, normal = tilted_plane()
    out = run_blur(blur, rgba(smooth * pattern(k, np.random.default_rng(1))), position, normal,
                   k)
    inner = (slice(k, -k), slice(k, -k))
    error = out[inner][..., 0] / smooth[inner] - 1.0
    assert np.sqrt(np.mean(error**2)) < 0.02
    assert np.sqrt(np.mean((pattern(k, np.random.default_rng(1)) - 1.0) ** 2)) > 0.3


# -- blur: edges ---------------------------------------------------------------------------
def two_sided(blur, position, normal, left: np.ndarray, radius: int) -> tuple[np.ndarray, ...]:
    out = run_blur(blur, rgba(np.where(left, 1.0, 3.0)), position, normal, radius)[..., 0]
    return out[left], out[~left]


@pytest.mark.parametrize("radius", [4, 8])
def test_no_leak_across_a_depth_edge(blur, radius):
    """Parallel planes 5 % of the view depth apart, side by side."""
    x, _ = grid()
    left = x < 0
    position, normal = surface(np.where(left, 0.0, -0.05 * DEPTH),
                               np.broadcast_to([0.0, 0.0, 1.0], (SIZE, SIZE, 3)))
    near, far = two_sided(blur, position, normal, left, radius)
    np.testing.assert_allclose(near, 1.0, rtol=0.01)
    np.testing.assert_allclose(far, 3.0, rtol=0.01)


@pytest.mark.parametrize("ridge", [False, True])
def test_no_leak_across_a_normal_edge(blur, ridge):
    """Two planes at 90° meeting in a crease (valley) or ridge: positions are continuous."""
    x, _ = grid()
    left = x < 0
    sign = -1.0 if ridge else 1.0
    n = np.zeros((SIZE, SIZE, 3))
    n[..., 0] = np.where(left, sign, -sign)
    n[..., 2] = 1.0
    position, normal = surface(sign * np.abs(x), n)
    a, b = two_sided(blur, position, normal, left, 8)
    np.testing.assert_allclose(a, 1.0, rtol=0.01)
    np.testing.assert_allclose(b, 3.0, rtol=0.01)


def test_background_is_untouched_and_never_contributes(blur):
    x, y = grid()
    covered = x**2 + y**2 < (0.3 * SIZE * SPACING) ** 2
    position, normal = surface(np.zeros((SIZE, SIZE)),
                               np.broadcast_to([0.0, 0.0, 1.0], (SIZE, SIZE, 3)), covered)
    garbage = np.where(np.random.default_rng(2).random((SIZE, SIZE)) < 0.5, np.nan, 1e6)
    light = rgba(np.where(covered, 2.0, garbage))
    out = run_blur(blur, light, position, normal, 8)
    np.testing.assert_array_equal(out[~covered], light[~covered])
    np.testing.assert_allclose(out[covered][:, :3], 2.0, rtol=1e-6)


def test_lights_blurred_together_come_out_as_each_alone(blur):
    """Indirect and soft direct light, diffuse and glossy, share one draw per axis: the same
    weights, so each comes out bit for bit as if blurred alone (here across a crease)."""
    x, _ = grid()
    n = np.zeros((SIZE, SIZE, 3))
    n[..., 0] = np.where(x < 0, 1.0, -1.0)
    n[..., 2] = 1.0
    position, normal = surface(np.abs(x), n)
    rng = np.random.default_rng(5)
    lights = [rgba(pattern(k, rng) * (1.0 + i)) for i, k in enumerate((2, 4, 8, 4))]
    together = run_blur(blur, lights, position, normal, 4)
    for light, out in zip(lights, together, strict=True):
        np.testing.assert_array_equal(out, run_blur(blur, light, position, normal, 4))


def test_radius_zero_is_a_copy_and_bad_input_is_refused(blur):
    position, normal = tilted_plane(16)
    light = rgba(pattern(4, np.random.default_rng(3), 16)).astype(np.float32)
    np.testing.assert_array_equal(run_blur(blur, light, position, normal, 0), light)
    with pytest.raises(ValueError, match="radius"):
        run_blur(blur, light, position, normal, -1)
    small, large = (blur.ctx.texture(size, 4, dtype="f4") for size in ((8, 8), (16, 16)))
    with pytest.raises(ValueError, match="size"):
        blur.apply([large], small, large, 2)
    with pytest.raises(ValueError, match="1 to 4 light textures"):
        blur.apply([large] * 5, large, large, 2)
    small.release()
    large.release()


# -- interleave_lib.glsl ---------------------------------------------------------------------
def interleave(programs: ProgramCache, k: int, count: int, first: int, origin: tuple[int, int],
               size: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """interleave_test_frag.glsl's two outputs, (size, size, 4) each."""
    ctx = programs.ctx
    program = programs.get("fullscreen_vert.glsl", "interleave_test_frag.glsl")
    program["u_interleave"].value = k
    program["u_count"].value = count
    program["u_first"].value = first
    program["u_origin"].value = origin
    vao = ctx.vertex_array(program, [])
    targets = draw_into_new_textures(ctx, vao, (size, size), 2)
    try:
        return tuple(np.frombuffer(t.read(), np.float32).reshape(size, size, 4)
                     for t in targets)
    finally:
        for obj in (vao, *targets):
            obj.release()


@pytest.mark.parametrize("k", [1, 2, 3, 4, 8])
def test_each_block_uses_every_vpl_once(programs, k):
    n = k * k
    count, first = 3 * n + 5, 7 if k & (k - 1) == 0 else 0  # K = 3 counts from first
    uses, loop = interleave(programs, k, count, first, (0, 0))
    index = uses[..., 0].astype(int)
    np.testing.assert_array_equal(uses[..., 3], n)
    for oy in range(k):  # every K×K block, aligned or not, holds each subset once
        for ox in range(k):
            blocks = index[oy:oy + 2 * k, ox:ox + 2 * k].reshape(2, k, 2, k).swapaxes(1, 2)
            for block in blocks.reshape(4, n):
                np.testing.assert_array_equal(np.sort(block), np.arange(n))
    members = [np.arange(count)[np.arange(count) % n == i] for i in range(n)]
    np.testing.assert_array_equal(uses[..., 1], [[len(members[i]) for i in r] for r in index])
    np.testing.assert_array_equal(uses[..., 2], [[members[i].sum() for i in r] for r in index])
    start = first + (index - first) % n
    np.testing.assert_array_equal(loop[..., 0], start)
    np.testing.assert_array_equal(loop[..., 1], [[len(m[m >= first]) for m in
                                                   (members[i] for i in r)] for r in index])
    np.testing.assert_array_equal(loop[..., 2], 0)
    far, _ = interleave(programs, k, count, first, (3 * 1024, 3 * 2048))  # where K divides
    np.testing.assert_array_equal(far, uses)


def test_a_pattern_of_the_antialiasing_factor_gives_each_pixel_every_subset_once(programs):
    """K = 3, the antialiasing factor: each pixel's aligned 3×3 supersamples (tiles start on
    pixel edges) take the 9 subsets once each, from the centre out in mirrored pairs, so that
    the subsets holding one sample more (the first count % 9 of a draw's) lie symmetrically
    about the pixel's centre. Indices count from the draw's first sample."""
    ranks = [[1, 3, 5], [7, 0, 8], [6, 4, 2]]  # rows are y
    uses, loop = interleave(programs, 3, 16, 5, (0, 0), size=6)
    np.testing.assert_array_equal(uses[..., 0], np.tile(ranks, (2, 2)))
    np.testing.assert_array_equal(loop[..., 0], 5 + uses[..., 0])  # the draw's own indices
    cells = np.argwhere(np.array(ranks) < 7)  # 16 = 9 + 7: the seven subsets of two samples
    np.testing.assert_array_equal(cells.mean(axis=0), [1, 1])


def test_the_pattern_is_a_bayer_matrix(programs):
    """Neighbouring pixels use subsets far apart (rows are y, columns x)."""
    bayer4 = [[0, 8, 2, 10], [12, 4, 14, 6], [3, 11, 1, 9], [15, 7, 13, 5]]
    uses, _ = interleave(programs, 4, 16, 0, (0, 0), size=4)
    np.testing.assert_array_equal(uses[..., 0], bayer4)
