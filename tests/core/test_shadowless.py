"""Objects that cast no shadow (Cycles' Shadow ray visibility off): lights' shadow rays and
maps pass them and their paths' first segments go through them, while they are seen and
block the paths' diffuse bounces (a bulb round its lamp)."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene.model import AreaShape, Instance, LightKind, Material
from addon.core.settings import Settings
from tests.core.builders import floor_scene, icosphere, light, quad, rotation_x, translation


def bulb(cast_shadow: bool) -> Instance:
    """A closed sphere of 0.3 m round (0, 0, 1.5)."""
    return Instance(icosphere(0.3, 2), translation(0, 0, 1.5), [Material("bulb")],
                    cast_shadow=cast_shadow)


def lamp(kind: LightKind):
    if kind is LightKind.AREA:
        return light(kind, translation(0, 0, 1.5), power=80.0, area_shape=AreaShape.SQUARE,
                     size_x=0.2)
    return light(kind, translation(0, 0, 1.5), power=80.0)


@pytest.mark.parametrize("kind, shadows", [(LightKind.POINT, "hybrid"),
                                           (LightKind.POINT, "shadow_maps"),
                                           (LightKind.AREA, "hybrid")])
def test_a_lamp_inside_a_bulb_that_casts_no_shadow_lights_the_floor(renderer, kind, shadows):
    """Direct light: the same as without the bulb (ray traced, cube maps, an area light's
    maps); with the bulb casting shadows, none. The camera sees the bulb."""
    settings = Settings(bounces=0, antialiasing=1, direct_shadows=shadows, light_samples=16)
    bare, _ = renderer.render(floor_scene([lamp(kind)]), settings)
    inside, _ = renderer.render(floor_scene([lamp(kind)], extra=[bulb(False)]), settings)
    dark, _ = renderer.render(floor_scene([lamp(kind)], extra=[bulb(True)]), settings)
    seen = inside.passes["Depth"][..., 0] < 3.9  # the bulb's top is 3.2 m from the camera
    assert 0.005 < seen.mean() < 0.02
    np.testing.assert_allclose(inside.passes["DiffDir"][~seen], bare.passes["DiffDir"][~seen],
                               rtol=1e-4, atol=1e-7)
    assert dark.passes["DiffDir"][~seen].max() < 1e-6


def test_its_paths_go_through_it_and_bounce_off_the_room(renderer):
    """Indirect light from a wall: the lamp's paths pass the bulb (as Cycles' shadow rays from
    the wall would), so the floor gets what it gets without the bulb, less what the bulb
    blocks of the wall's light (measured 1.5 % less)."""
    wall = Instance(quad(5, 2), translation(0, 2, 2) @ rotation_x(np.pi / 2),
                    [Material("wall")])
    settings = Settings(bounces=1, antialiasing=1, vpl_count=256)
    bare, _ = renderer.render(floor_scene([lamp(LightKind.POINT)], extra=[wall]), settings)
    inside, _ = renderer.render(floor_scene([lamp(LightKind.POINT)], extra=[wall, bulb(False)]),
                                settings)
    ratio = inside.passes["DiffInd"].mean() / bare.passes["DiffInd"].mean()
    assert 0.9 < ratio <= 1.0, ratio
