"""The Combined pass composed on the GPU (gpu/combined.py) against Blender's pass algebra
written out in numpy: (direct + soft + indirect) × albedo + glossy + emission, the background
where a supersample sees no surface, nothing (alpha 0) where it sees a holdout, the mean of
each pixel's supersamples."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.gpu.combined import combined_pass

PIXELS = (5, 3)  # width, height
FACTOR = 3


def expected(light: dict[str, np.ndarray], layers: dict[str, np.ndarray],
             background: np.ndarray | None, holdouts: bool) -> np.ndarray:
    """The Combined pass of the supersample arrays, one mean per pixel."""
    diffuse = light["direct"] + light["indirect"] + light.get("soft", 0.0)
    rgb = diffuse[..., :3] * layers["albedo"][..., :3] + layers["emission"][..., :3]
    for name in ("direct_glossy", "indirect_glossy", "soft_glossy"):
        rgb = rgb + light[name][..., :3] if name in light else rgb
    covered = layers["normal"][..., 3:4]
    if background is None:
        alpha = covered
    else:
        rgb = rgb + (1.0 - covered) * np.broadcast_to(background, rgb.shape)
        alpha = np.ones_like(covered)
    image = np.concatenate([rgb, alpha], axis=-1)
    if holdouts:
        image[layers["geometric"][..., 3] < -0.5] = 0.0
    h, w = image.shape[0] // FACTOR, image.shape[1] // FACTOR
    return image.reshape(h, FACTOR, w, FACTOR, 4).mean(axis=(1, 3))


@pytest.mark.parametrize("soft", [False, True])
@pytest.mark.parametrize("glossy", [False, True])
@pytest.mark.parametrize("film", ["transparent", "colour", "image"])
@pytest.mark.parametrize("holdouts", [False, True])
def test_combined_matches_the_pass_algebra(programs, soft, glossy, film, holdouts):
    ctx, rng = programs.ctx, np.random.default_rng(7)
    shape = (PIXELS[1] * FACTOR, PIXELS[0] * FACTOR, 4)
    names = ["direct", "indirect", *(["soft"] if soft else [])]
    names += [f"{n}_glossy" for n in names] if glossy else []
    light = {name: rng.uniform(0.0, 2.0, shape).astype(np.float32) for name in names}
    layers = {name: rng.uniform(0.0, 1.0, shape).astype(np.float32)
              for name in ("albedo", "emission", "normal", "geometric")}
    layers["normal"][..., 3] = rng.choice([0.0, 0.5, 1.0], shape[:2])  # partial coverage
    layers["geometric"][..., 3] = rng.choice([0.0, 3.0, -1.0], shape[:2])  # holdouts (-1)
    background = {"transparent": None, "colour": np.array([0.2, 0.3, 0.4], np.float32),
                  "image": rng.uniform(0.0, 3.0, (*shape[:2], 3)).astype(np.float32)}[film]
    textures = {name: ctx.texture(shape[1::-1], 4, array.tobytes(), dtype="f4")
                for name, array in {**light, **layers}.items()}

    def pair(kind: str) -> list:
        return [textures[kind], *([textures[f"{kind}_glossy"]] if glossy else [])]

    try:
        result = combined_pass(ctx, programs, pair("direct"), pair("indirect"),
                               pair("soft") if soft else [], textures, background, FACTOR,
                               holdouts=holdouts)
    finally:
        for texture in textures.values():
            texture.release()
    assert result.shape == (PIXELS[1], PIXELS[0], 4)
    np.testing.assert_allclose(result, expected(light, layers, background, holdouts), rtol=1e-5,
                               atol=1e-6)


def test_a_transparent_film_seen_through_a_tinted_pane_is_as_opaque_as_the_pane_dims(programs):
    """Cycles (measured, bpy 4.5): the background through a (1, 0.5, 0.25) Transparent BSDF
    pane on a transparent film has alpha 1 − their mean, 0.417; a surface behind it alpha 1,
    a holdout behind it 0."""
    ctx = programs.ctx
    shape = (PIXELS[1] * FACTOR, PIXELS[0] * FACTOR, 4)
    zero = np.zeros(shape, np.float32)
    layers = {"albedo": zero, "emission": zero, "normal": zero.copy(), "geometric": zero.copy()}
    layers["normal"][:, :FACTOR, 3] = 1.0  # the first column of pixels: a surface
    layers["geometric"][:, FACTOR:2 * FACTOR, 3] = -1.0  # the second: a holdout
    through = np.broadcast_to(np.array([1.0, 0.5, 0.25, 1.0], np.float32), shape)
    arrays = {"direct": zero, "indirect": zero, "through": np.ascontiguousarray(through),
              **layers}
    textures = {name: ctx.texture(shape[1::-1], 4, array.tobytes(), dtype="f4")
                for name, array in arrays.items()}
    try:
        result = combined_pass(ctx, programs, [textures["direct"]], [textures["indirect"]], [],
                               textures, None, FACTOR, textures["through"], holdouts=True)
    finally:
        for texture in textures.values():
            texture.release()
    np.testing.assert_allclose(result[:, 0, 3], 1.0)
    np.testing.assert_allclose(result[:, 1, 3], 0.0)
    np.testing.assert_allclose(result[:, 2:, 3], 1.0 - 1.75 / 3, rtol=1e-6)
