"""Adaptive shadow rays (frame/shadow_hints.py): ray-traced direct light traced once per pixel
first, and at every supersample only where the pixels around disagree."""

from __future__ import annotations

import numpy as np

from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings
from devtools import metrics
from tests.core.builders import floor_scene, light, quad, rotation_x, translation


def blocked_scene(lights):
    blocker = Instance(quad(0.4, 0.4, z=1.0), np.eye(4), [Material("blocker")])
    return floor_scene(lights, extra=[blocker])


def render_both(renderer, scene, **settings):
    common = {"bounces": 0, "antialiasing": 3, "direct_shadows": "ray_traced", **settings}
    every, _ = renderer.render(scene, Settings(adaptive_shadows=False, **common))
    adaptive, stats = renderer.render(scene, Settings(adaptive_shadows=True, **common))
    return every.passes["DiffDir"], adaptive.passes["DiffDir"], stats


def test_hard_shadows_come_out_as_with_a_ray_per_supersample(renderer):
    """Three point lights (one bit each): shadows wider than a pixel are found at every
    supersample where the answer differs from the pixels', so the image is the same."""
    lights = [light(LightKind.POINT, translation(x, 0.5, 2.0), power=50.0) for x in (-1, 0, 1)]
    every, adaptive, stats = render_both(renderer, blocked_scene(lights))
    assert "shadow hints" in stats.timings
    edges = np.ptp(every[..., 0]) * 0.05 < np.abs(np.gradient(every[..., 0])[0])
    assert edges.any()  # the image has shadow edges, partly covered pixels
    np.testing.assert_array_equal(adaptive, every)


def test_a_sun_with_an_angle_keeps_its_penumbra(renderer):
    """Interleaved sun samples (each supersample traces one): the pixels' hints hold one
    sample each, so penumbrae, where they disagree, keep their rays; where 3×3 pixels agree
    by chance the outer fringe is off by at most the share of samples it misses."""
    sun = light(LightKind.SUN, rotation_x(0.5), power=3.0, sun_angle=0.3)
    scene = blocked_scene([sun])
    every, adaptive, stats = render_both(renderer, scene, light_samples=16)
    assert "shadow hints" in stats.timings
    assert abs(metrics.mean_relative_energy(adaptive, every)) < 0.002  # measured 1e-6
    assert metrics.relative_rmse(adaptive, every) < 0.01  # measured 0.45 %


def test_antialiasing_one_and_the_setting_off_trace_every_ray(renderer):
    lights = [light(LightKind.POINT, translation(0, 0.5, 2.0), power=50.0)]
    _, stats = renderer.render(blocked_scene(lights), Settings(bounces=0, antialiasing=1))
    assert "shadow hints" not in stats.timings
    _, stats = renderer.render(blocked_scene(lights), Settings(bounces=0,
                                                               adaptive_shadows=False))
    assert "shadow hints" not in stats.timings
