"""Meshes shared by several instances are traced once, in their own space: a frame renders
the same image as with every instance's triangles in one world-space tree."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene import geometry
from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings

from .builders import floor_scene, icosphere, light, rotation_x, translation


def _scattered_balls():
    """Twelve turned, scaled instances of one ball and a unique one over a lit floor."""
    ball, red = icosphere(0.4, 1), [Material("red", (0.8, 0.2, 0.1))]
    rng = np.random.default_rng(3)
    balls = []
    for x, y in rng.uniform(-3, 3, (12, 2)):
        matrix = translation(x, y, 0.5) @ rotation_x(rng.uniform(0, np.pi))
        matrix[:3, :3] *= rng.uniform(0.6, 1.4)
        balls.append(Instance(ball, matrix, red))
    balls.append(Instance(icosphere(0.7, 2), translation(0.0, 0.0, 1.0), red))
    sun = light(LightKind.SUN, rotation_x(0.5), power=3.0)
    return floor_scene([sun], extra=balls, size=48)


@pytest.mark.parametrize("shadows", ["ray_traced", "hybrid"])
def test_instanced_tracing_renders_the_flattened_image(renderer, monkeypatch, shadows):
    scene = _scattered_balls()
    settings = Settings(antialiasing=1, bounces=2, vpl_count=64, direct_shadows=shadows)
    flat = geometry.flatten_instances(scene, [])
    assert [len(mesh.matrices) for mesh in flat.instanced] == [12]
    instanced, stats = renderer.render(scene, settings)
    monkeypatch.setattr(geometry, "_traced_as_instances", lambda group: False)
    assert not geometry.flatten_instances(scene, []).instanced
    renderer.forget_frames()  # else the frame keeps the instanced BVH
    world, world_stats = renderer.render(scene, settings)
    renderer.forget_frames()
    assert "ray tracing setup" in stats.timings and "ray tracing setup" in world_stats.timings
    a, b = instanced.passes["Combined"][..., :3], world.passes["Combined"][..., :3]
    assert b.mean() > 0.05
    changed = np.abs(a - b) > 1e-3 * b.max()
    assert changed.mean() < 0.002, f"{changed.mean():.2%} of pixels differ"
