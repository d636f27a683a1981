"""Blender's passes from a tile's supersamples (frame/compose.py)."""

from __future__ import annotations

import numpy as np

from addon.core.frame.compose import BACKGROUND_DEPTH, SEEN_THROUGH, compose
from addon.core.frame.result import PASS_CHANNELS
from addon.core.scene.model import Camera, Mist

AA, H, W = 2, 4, 6  # a 4×6 supersampled tile: 2×3 pixels


def tile_gbuffer() -> dict[str, np.ndarray]:
    """A g-buffer whose upper supersample rows are covered, at depth 2 + x."""
    rng = np.random.default_rng(7)
    gbuffer = {name: rng.random((H, W, 4), dtype=np.float32)
               for name in ("normal", "albedo", "emission", "position", "geometric")}
    gbuffer["geometric"][..., 3] = 0.0  # no holdouts
    gbuffer["normal"][..., 3] = 0.0
    gbuffer["normal"][:2, :, 3] = 1.0
    gbuffer["position"][..., 3] = 2.0 + np.arange(W, dtype=np.float32)
    return gbuffer


def empty_output() -> dict[str, np.ndarray]:
    return {name: np.zeros((H // AA, W // AA, c), np.float32) for name, c in PASS_CHANNELS.items()}


def test_passes_of_the_gbuffer_alone_read_no_light_back():
    def read_light():
        raise AssertionError("the light was read back for passes that do not need it")

    output, gbuffer = empty_output(), tile_gbuffer()
    compose(output, gbuffer, read_light, AA, 0, 0, frozenset({"Depth", "Normal", "DiffCol"}))
    np.testing.assert_allclose(output["Depth"][0, :, 0], [3.0, 5.0, 7.0])  # the centre's
    np.testing.assert_allclose(output["Depth"][1, :, 0], BACKGROUND_DEPTH)
    albedo = gbuffer["albedo"][..., :3].reshape(H // AA, AA, W // AA, AA, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(output["DiffCol"], albedo, rtol=1e-6)


def test_light_passes_read_the_light_back_once():
    calls = []
    direct = np.full((H, W, 4), 0.25, np.float32)
    indirect = np.zeros((H, W, 4), np.float32)
    indirect[0, 0, :3] = 4.0  # one supersample of the first pixel

    def read_light():
        calls.append(1)
        return direct, indirect

    output = empty_output()
    compose(output, tile_gbuffer(), read_light, AA, 0, 0,
            frozenset({"DiffDir", "DiffInd", "GlossCol"}))
    assert len(calls) == 1
    np.testing.assert_allclose(output["DiffDir"], 0.25)
    np.testing.assert_allclose(output["DiffInd"][0, 0], 1.0)  # 4 / AA²
    np.testing.assert_allclose(output["DiffInd"][1:, 1:], 0.0)
    np.testing.assert_allclose(output["GlossCol"], 0.0)  # no glossy channels: zero


def test_through_clear_surfaces_colour_passes_are_dimmed_and_holdouts_get_nothing():
    """As Cycles writes them (measured, bpy 4.5): through a tinted Transparent BSDF DiffCol and
    Emit carry the tint and DiffDir does not; on a holdout every pass is empty, Depth the
    background's."""
    light = np.full((H, W, 4), 0.5, np.float32), np.zeros((H, W, 4), np.float32)
    tint = np.array([1.0, 0.5, 0.25, 1.0], np.float32)
    gbuffer = tile_gbuffer()
    gbuffer["albedo"][..., :3] = gbuffer["emission"][..., :3] = 0.8
    gbuffer["geometric"][0:2, 4:6, 3] = -1.0  # the top right pixel: a holdout
    output = empty_output()
    passes = frozenset({"DiffCol", "Emit", "DiffDir", "Normal", "Depth"})
    assert {"DiffCol", "Emit"} <= SEEN_THROUGH and "DiffDir" not in SEEN_THROUGH
    compose(output, gbuffer, lambda: light, AA, 0, 0, passes,
            lambda: np.broadcast_to(tint, (H, W, 4)), holdouts=True)
    for name in ("DiffCol", "Emit"):
        np.testing.assert_allclose(output[name][0, :2], [[0.8, 0.4, 0.2]] * 2, rtol=1e-6)
    np.testing.assert_allclose(output["DiffDir"][0, :2], 0.5)
    for name in passes - {"Depth"}:
        np.testing.assert_allclose(output[name][0, 2], 0.0, err_msg=name)
    np.testing.assert_allclose(output["Depth"][0, :, 0], [3.0, 5.0, BACKGROUND_DEPTH])


def test_mist_is_cycles_distance_falloff_and_position_the_surface_s():
    """Mist (the camera at the origin, start 1 m, depth 4 m, quadratic): per supersample
    ((|p| - 1) / 4)² clamped, 1 where no surface is, averaged over each pixel's supersamples;
    Position the world position at each pixel's centre, 0 on the background."""
    gbuffer = tile_gbuffer()
    gbuffer["position"][..., :3] = 0.0
    gbuffer["position"][..., 2] = np.linspace(0.5, 6.0, W, dtype=np.float32)[None, :]
    camera = Camera(np.eye(4), np.eye(4), W // AA, H // AA)
    output = empty_output()
    compose(output, gbuffer, lambda: None, AA, 0, 0, frozenset({"Mist", "Position"}),
            view=(camera, Mist(1.0, 4.0, 2.0)))
    per_sample = np.clip((np.linspace(0.5, 6.0, W) - 1.0) / 4.0, 0.0, 1.0) ** 2
    np.testing.assert_allclose(output["Mist"][0, :, 0], per_sample.reshape(3, 2).mean(axis=1),
                               rtol=1e-6)
    np.testing.assert_allclose(output["Mist"][1], 1.0)  # no surface
    np.testing.assert_allclose(output["Position"][0, :, 2],  # AA 2: the upper right's
                               np.linspace(0.5, 6.0, W)[1::2], rtol=1e-6)
    np.testing.assert_allclose(output["Position"][1], 0.0)
