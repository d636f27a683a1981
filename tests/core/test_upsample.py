"""Geometry-aware upsampling (gpu_shaders/upsample_frag.glsl) of light gathered once per pixel
to every supersample, on g-buffers built directly from numpy."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.gpu.upsample import upsample

PIXELS = 32
FACTOR = 3
SPACING = 0.05  # world units between pixel centres
DEPTH = 10.0  # view depth of z = 0


def centres(count: int, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """World x, y of sample centres on a grid of count² samples covering the same square."""
    c = (np.arange(count) - (count - 1) / 2) * spacing
    return np.meshgrid(c, c)


def layers(height, normal, count: int, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Position (xyz, view depth) and normal (xyz, w = 1) of height field ``height(x, y)``
    with normals ``normal(x, y)`` (h, w, 3) sampled on a count² grid."""
    x, y = centres(count, spacing)
    z = height(x, y)
    n = normal(x, y)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return (np.stack([x, y, z, DEPTH - z], axis=-1),
            np.concatenate([n, np.ones_like(z)[..., None]], axis=-1))


def run(programs, light: np.ndarray, height, normal, added: np.ndarray | None = None
        ) -> np.ndarray:
    """Light (PIXELS², 4) at the pixel samples, upsampled to the supersamples of the same
    surface, plus ``added`` light at the supersamples; returns (PIXELS·FACTOR)² × 4."""
    ctx = programs.ctx
    coarse = layers(height, normal, PIXELS, SPACING)
    fine = layers(height, normal, PIXELS * FACTOR, SPACING / FACTOR)
    arrays = (light, *coarse, *fine) + (() if added is None else (added,))
    textures = [ctx.texture(a.shape[1::-1], 4, np.ascontiguousarray(a, np.float32).tobytes(),
                            dtype="f4") for a in arrays]
    try:
        out = upsample(ctx, programs, textures[:1], (textures[1], textures[2]),
                       (textures[3], textures[4]), FACTOR, textures[5:] or None)[0]
        n = PIXELS * FACTOR
        result = np.frombuffer(out.read(), np.float32).reshape(n, n, 4)
        out.release()
    finally:
        for texture in textures:
            texture.release()
    return result


def flat(x, y):
    return 0.3 * x + 0.2 * y


def flat_normal(x, y):
    return np.broadcast_to([-0.3, -0.2, 1.0], (*x.shape, 3))


def rgba(value: np.ndarray) -> np.ndarray:
    return np.stack([value, value, value, np.zeros_like(value)], axis=-1)


def test_a_linear_light_on_a_plane_is_interpolated(programs):
    """On one plane the weights are bilinear: a light linear in x, y comes back exact away
    from the border (where the outermost pixel samples are repeated)."""
    x, y = centres(PIXELS, SPACING)
    out = run(programs, rgba(1.0 + x + 0.5 * y), flat, flat_normal)
    fx, fy = centres(PIXELS * FACTOR, SPACING / FACTOR)
    inner = (slice(FACTOR, -FACTOR), slice(FACTOR, -FACTOR))
    np.testing.assert_allclose(out[inner][..., 0], (1.0 + fx + 0.5 * fy)[inner], rtol=1e-4)


def test_no_light_crosses_a_depth_edge(programs):
    """Two parallel planes 5 % of the view depth apart with their step between pixel
    centres: every supersample takes its own plane's light only."""
    step = SPACING * 0.4  # inside a pixel, not on a sample centre

    def height(x, y):
        return np.where(x < step, 0.0, -0.05 * DEPTH)

    def normal(x, y):
        return np.broadcast_to([0.0, 0.0, 1.0], (*x.shape, 3))

    x, _ = centres(PIXELS, SPACING)
    out = run(programs, rgba(np.where(x < step, 1.0, 3.0)), height, normal)
    fx, _ = centres(PIXELS * FACTOR, SPACING / FACTOR)
    np.testing.assert_allclose(out[..., 0], np.where(fx < step, 1.0, 3.0), rtol=1e-5)


def test_a_sliver_thinner_than_a_pixel_takes_its_best_match(programs):
    """A ridge one supersample wide that no pixel sample lies on (a chair leg seen from far):
    no pixel sample matches its supersamples at all (weight 0), yet they get light, from
    the best-matching pixel sample nearby, not 0."""
    fine = SPACING / FACTOR

    def sliver(x):
        return np.abs(x - fine / 2) < fine / 2  # one supersample column, no pixel centre

    def height(x, y):
        return np.where(sliver(x), 0.3, 0.0)

    def normal(x, y):
        return np.where(sliver(x)[..., None], [1.0, 0.0, 0.05], [0.0, 0.0, 1.0])  # a wall

    x, _ = centres(PIXELS, SPACING)
    out = run(programs, rgba(np.full(x.shape, 2.0)), height, normal)
    fx, _ = centres(PIXELS * FACTOR, fine)
    assert sliver(fx).any() and not sliver(x).any()
    np.testing.assert_allclose(out[..., 0], 2.0, rtol=1e-5)  # every supersample found light


def test_background_gets_nothing_and_bad_sizes_are_refused(programs):
    ctx = programs.ctx
    small, large, odd = (ctx.texture(size, 4, dtype="f4") for size in ((8, 8), (24, 24),
                                                                        (20, 24)))
    try:
        with pytest.raises(ValueError, match="not 3×"):
            upsample(ctx, programs, [small], (small, small), (odd, odd), 3)
        with pytest.raises(ValueError, match="differ in size"):
            upsample(ctx, programs, [large], (small, small), (large, large), 3)
        with pytest.raises(ValueError, match="1 to 4 light textures"):
            upsample(ctx, programs, [small] * 5, (small, small), (large, large), 3)
        out = upsample(ctx, programs, [small], (small, small), (large, large), 3)[0]
        assert not np.frombuffer(out.read(), np.float32).any()  # normal.w = 0 everywhere
        out.release()
    finally:
        for texture in (small, large, odd):
            texture.release()


def test_light_gathered_per_supersample_is_added(programs):
    """The bias compensation, gathered at every supersample, joins the upsampled light, on
    the plane and on a ridge one supersample wide (which takes its best-matching pixel)."""
    rng = np.random.default_rng(5)
    light = rgba(rng.random((PIXELS, PIXELS)))
    added = rgba(rng.random((PIXELS * FACTOR, PIXELS * FACTOR)))

    def ridge(x, y):  # no pixel centre lies on it
        return np.where(np.abs(x - 0.1) < SPACING / 6, 0.3, 0.0)

    plain, summed = run(programs, light, ridge, flat_normal), \
        run(programs, light, ridge, flat_normal, added)
    np.testing.assert_allclose(summed, plain + added, atol=1e-6)
