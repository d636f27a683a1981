"""Shadow catchers in the renderer: the Shadow Catcher pass is the catcher's light with the
other objects over its light without them, and Combined their matte over that shadow, as
Cycles composites them (the comparison with Cycles: tests/blender/test_shadow_catcher.py)."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.frame.result import BACKDROP, MATTE
from addon.core.frame.shadow_catcher import (
    alone_bounces,
    catchers_alone,
    composite,
    in_one_plane,
    shadow_ratio,
)
from addon.core.scene.model import Instance, LightKind, Material, Scene, World
from addon.core.settings import Settings
from addon.core.viewport_session import Changes, ViewportSession
from tests.core.builders import floor_scene, light, pixel_centres, quad, rotation_x, translation

SKY = np.array([0.2, 0.3, 0.5])
SUN = light(LightKind.SUN, rotation_x(np.radians(45)), power=3.0)  # its shadow: toward +y


def catcher_scene(transparent: bool, catcher: bool = True) -> Scene:
    """A grey floor (the catcher) under a red panel over x, y in [-1, 1] at 1 m, the sun at
    45° (the panel's shadow over y in [0, 2]), a blue sky."""
    scene = floor_scene([SUN], albedo=0.5, world=World(color=tuple(SKY)), extra=[
        Instance(quad(1, 1), translation(0, 0, 1), [Material("red", (0.8, 0.1, 0.1))])])
    scene.instances[0].shadow_catcher = catcher
    scene.film_transparent = transparent
    return scene


def regions() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pixels of the panel, of the floor, of its shadow seen beside it, and of the open floor
    (y < -1.5), each a margin off the edges."""
    x, y = pixel_centres()
    reach = np.maximum(np.abs(x), np.abs(y))
    return (reach < 0.95, reach > 1.05, (np.abs(x) < 0.9) & (y > 1.1) & (y < 1.9),
            y < -1.5)


@pytest.mark.parametrize("transparent", [False, True])
def test_the_shadow_catcher_pass_is_the_shadow(renderer, transparent):
    """The floor's light with the panel over its light without it: under the panel the sky's
    share less what the panel hides of it (the sun is blocked), near 1 far off; 1 on the
    panel, which is no catcher."""
    passes = frozenset({"Combined", "Shadow Catcher"})
    settings = Settings(bounces=0, antialiasing=2, planner=False)  # the same light samples
    frame, _ = renderer.render(catcher_scene(transparent), settings, passes=passes)
    ratio = frame.passes["Shadow Catcher"]
    assert MATTE not in frame.passes and BACKDROP not in frame.passes
    plain, _ = renderer.render(catcher_scene(transparent, catcher=False), settings,
                               passes=passes)
    floor_only = catcher_scene(transparent, catcher=False)
    floor_only.instances = floor_only.instances[:1]
    alone, _ = renderer.render(floor_only, settings, passes=passes)
    panel, floor, shadowed, open_floor = regions()
    expected = plain.passes["Combined"][..., :3][floor] / alone.passes["Combined"][..., :3][floor]
    print(f"shadow catcher pass: open floor {ratio[open_floor].mean(axis=0)}, in the "
          f"shadow {ratio[shadowed].mean(axis=0)}")
    assert np.abs(ratio[floor] - expected).max() < 1e-3
    assert np.all(ratio[panel] == 1.0)  # no catcher
    assert 0.05 < ratio[shadowed].mean() < 0.5  # the sky's share: the sun is blocked
    assert ratio[open_floor].mean() > 0.97
    assert np.all(plain.passes["Shadow Catcher"] == 1.0)  # no catcher: no shadow


def test_combined_is_the_matte_over_the_shadow(renderer):
    """Transparent film: the catcher is a hole whose alpha is the shadow's darkness (1 − the
    pass's mean); opaque: the sky seen there, dimmed by the shadow; with the Shadow Catcher
    pass asked for, the catcher is a hole either way (Cycles' matte). The panel is as
    rendered without catchers."""
    settings = Settings(bounces=0, antialiasing=2, planner=False)  # the same light samples
    panel, floor, shadowed, _ = regions()
    transparent, _ = renderer.render(catcher_scene(True), settings)
    shadow = renderer.render(catcher_scene(True), settings,
                             passes=frozenset({"Shadow Catcher"}))[0].passes["Shadow Catcher"]
    darkness = np.clip(1.0 - shadow.mean(axis=-1), 0.0, 1.0)
    combined = transparent.passes["Combined"]
    assert np.all(combined[..., :3][floor] == 0.0)
    assert np.abs(combined[..., 3][floor] - darkness[floor]).max() < 1e-5
    assert darkness[shadowed].min() > 0.5
    opaque, _ = renderer.render(catcher_scene(False), settings)
    rgb = opaque.passes["Combined"][..., :3]
    assert np.abs(rgb[floor] - SKY * (1.0 - darkness[floor])[:, None]).max() < 1e-5
    plain, _ = renderer.render(catcher_scene(False, catcher=False), settings)
    assert np.abs(rgb[panel] - plain.passes["Combined"][..., :3][panel]).max() < 1e-5
    matte, _ = renderer.render(catcher_scene(False), settings,
                               passes=frozenset({"Combined", "Shadow Catcher"}))
    assert np.all(matte.passes["Combined"][floor] == 0.0)


def test_a_scene_without_catchers_renders_as_before(renderer):
    """No second render, no hidden passes, and the Shadow Catcher pass is 1."""
    settings = Settings(bounces=1, antialiasing=2)
    frame, stats = renderer.render(catcher_scene(False, catcher=False), settings)
    assert "shadow catchers alone" not in stats.timings
    assert MATTE not in frame.passes and np.all(frame.passes["Shadow Catcher"] == 1.0)


def test_the_ratio_is_one_where_there_is_nothing_to_divide():
    """No catcher in a pixel, or none lit alone: 1 (Cycles' safe divide); a half-covered
    pixel divides its catcher light by its coverage."""
    full = {"Combined": np.array([[[0.3, 0.3, 0.3, 1.0], [0.2, 0.2, 0.2, 1.0],
                                   [0.5, 0.5, 0.5, 1.0]]], np.float32),
            MATTE: np.array([[[0.3, 0.3, 0.3, 1.0], [0.0, 0.0, 0.0, 0.0],
                              [0.4, 0.4, 0.4, 0.5]]], np.float32)}
    alone = {"Combined": np.array([[[0.4, 0.4, 0.4, 1.0], [0.0, 0.0, 0.0, 1.0],
                                    [0.4, 0.4, 0.4, 1.0]]], np.float32),
             MATTE: np.zeros((1, 3, 4), np.float32)}
    ratio = shadow_ratio(full, alone)
    assert np.allclose(ratio[0, 0], 1.0) and np.allclose(ratio[0, 1], 1.0)
    assert np.allclose(ratio[0, 2], (0.1 / 0.5) / 0.4)
    composite(full, alone, transparent=True, as_matte=False)
    assert set(full) == {"Combined"}
    assert np.allclose(full["Combined"][0, 2, 3], 0.5 + 0.5 * (1 - 0.5))


def test_the_catchers_alone_keep_the_lights_and_the_world():
    """The second render's scene: the catchers, every light, the world, the camera."""
    scene = catcher_scene(False)
    alone = catchers_alone(scene)
    assert [i.shadow_catcher for i in alone.instances] == [True]
    assert alone.lights == scene.lights and alone.world is scene.world
    assert alone.camera is scene.camera and len(scene.instances) == 2


def test_catchers_in_one_plane_are_rendered_alone_without_bounces():
    """A ground plane cannot light itself: its frame alone needs no bounces; a plane and a
    wall (or points off the plane by more than float rounding) keep them."""
    scene = catcher_scene(False)
    assert alone_bounces(scene, 3) == 0
    scene.instances.append(Instance(quad(1, 1), rotation_x(np.radians(90)) @ translation(0, 0, 2),
                                    [Material("wall")], shadow_catcher=True))
    assert alone_bounces(scene, 3) == 3
    points = np.random.default_rng(1).uniform(-5, 5, (5000, 3)).astype(np.float32)
    points[:, 2] = 0.25
    assert in_one_plane(points)
    points[4321, 2] += 1e-3
    assert not in_one_plane(points) and not in_one_plane(points[:2])


def test_the_viewport_composites_catchers_as_final_renders_do():
    """Cycles' viewport shows the approximation too: through a transparent film the floor is
    a hole whose alpha is the panel's shadow."""
    session = ViewportSession()
    try:
        scene = catcher_scene(True)
        session.edit(Changes(settings=True), scene=scene, camera=scene.camera,
                     settings=Settings(bounces=1, vpl_count=128, viewport_passes=1))
        assert session.wait_idle(300) and session.error is None, session.error
        image = session.latest().image
    finally:
        session.close()
    _, floor, shadowed, open_floor = regions()
    assert np.all(image[..., :3][floor] == 0.0)
    assert image[..., 3][shadowed].mean() > 0.5 and image[..., 3][open_floor].mean() < 0.05
