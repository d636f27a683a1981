"""Objects whose Diffuse ray visibility is off (Cycles): diffuse bounces pass them, so they
neither reflect light onto other surfaces nor shade others from reflected light; they are seen,
lit, and cast shadows."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings
from tests.core.builders import floor_scene, light, quad, rotation_x, translation

SUN = light(LightKind.SUN, rotation_x(np.pi / 4), power=3.0)  # towards +y and down, 45°


def red_wall(visible_to_diffuse: bool = True) -> Instance:
    """A red wall along y = 2, facing the floor in front of it (y < 2) and the sun."""
    return Instance(quad(5, 2), translation(0, 2, 2) @ rotation_x(np.pi / 2),
                    [Material("wall", (0.8, 0.1, 0.1))], visible_to_diffuse=visible_to_diffuse)


def panel(visible_to_diffuse: bool) -> Instance:
    """A grey panel 0.3 m above the floor over x in [-1, 1], y in [-1.5, -0.5], hidden from
    the camera (which sees the floor under it)."""
    return Instance(quad(1, 0.5), translation(0, -1, 0.3), [Material("panel")],
                    visible_to_camera=False, visible_to_diffuse=visible_to_diffuse)


SETTINGS = Settings(bounces=1, antialiasing=1, vpl_count=512)
UNDER_PANEL = (slice(18, 22), slice(24, 40))  # pixel rows y ≈ -1.3 to -0.9, |x| < 0.8


def test_a_wall_hidden_from_diffuse_bounces_reflects_no_light_but_shades(renderer):
    """The floor gets no red light from the wall; the wall's sun shadow on the floor behind
    it and its own light are those of the wall diffuse bounces see."""
    seen, _ = renderer.render(floor_scene([SUN], extra=[red_wall()]), SETTINGS)
    hidden, _ = renderer.render(floor_scene([SUN], extra=[red_wall(False)]), SETTINGS)
    floor = (slice(8, 40), slice(8, 56))  # y from -2.25 to 0.75
    assert seen.passes["DiffInd"][floor][..., 0].mean() > 0.02
    assert hidden.passes["DiffInd"][floor].max() < 1e-6
    np.testing.assert_allclose(hidden.passes["DiffDir"], seen.passes["DiffDir"], atol=1e-5)
    assert hidden.passes["DiffDir"][56:, :].max() < 1e-6  # y > 2.25: behind the wall


@pytest.mark.parametrize("visibility", ["ism", "classic", "exact"])
def test_a_panel_hidden_from_diffuse_bounces_lets_reflected_light_through(renderer, visibility):
    """The wall's red light reaches the floor under the panel as without the panel, in every
    visibility mode; a panel diffuse bounces see shades it."""
    settings = Settings(bounces=1, antialiasing=1, vpl_count=512, visibility=visibility)
    light_under = {}
    for name, extra in (("none", []), ("hidden", [panel(False)]), ("seen", [panel(True)])):
        frame, _ = renderer.render(floor_scene([SUN], extra=[red_wall(), *extra]), settings)
        light_under[name] = frame.passes["DiffInd"][UNDER_PANEL][..., 0].mean()
    assert light_under["hidden"] == pytest.approx(light_under["none"], rel=0.05), light_under
    assert light_under["seen"] < 0.7 * light_under["none"], light_under


def test_an_emitter_hidden_from_diffuse_bounces_lights_nothing(renderer):
    """A glowing panel over the floor (its normal up, away from the floor: emission is
    two-sided): with Diffuse visibility off, diffuse surfaces do not see its light (as in
    Cycles). One bounce: the view probe tests the panel's samples (it culled them all before
    stop 54, as if the panel emitted upwards only)."""
    glow = Material("glow", (0.0, 0.0, 0.0), emission=(2.0, 2.0, 2.0))
    light_on_floor = []
    for seen in (True, False):
        panel = Instance(quad(1.5, 1.5), translation(0, 0, 1), [glow], visible_to_camera=False,
                         visible_to_diffuse=seen)
        frame, _ = renderer.render(floor_scene([], extra=[panel]), SETTINGS)
        light_on_floor.append(frame.passes["DiffDir"][20:44, 20:44].mean())
    assert light_on_floor[0] > 0.1 and light_on_floor[1] == 0.0


def test_materials_hide_from_the_camera_or_shadow_rays_like_their_objects(renderer):
    """A material the camera sees through (Material.camera_sees_through) or shadow rays pass
    (shadow_rays_pass) renders as an object whose Camera or Shadow visibility is off."""
    wall = red_wall().materials[0]
    hidden = Instance(red_wall().mesh, red_wall().matrix,
                      [replace(wall, camera_sees_through=True)])
    passed = Instance(red_wall().mesh, red_wall().matrix, [replace(wall, shadow_rays_pass=True)])
    by_object = {"camera": Instance(red_wall().mesh, red_wall().matrix, [wall],
                                    visible_to_camera=False),
                 "shadow": Instance(red_wall().mesh, red_wall().matrix, [wall],
                                    cast_shadow=False)}
    for kind, by_material in (("camera", hidden), ("shadow", passed)):
        frames = [renderer.render(floor_scene([SUN], extra=[wall_instance]), SETTINGS)[0]
                  for wall_instance in (by_material, by_object[kind])]
        np.testing.assert_allclose(frames[0].passes["Combined"], frames[1].passes["Combined"],
                                   atol=1e-6)
    seen, _ = renderer.render(floor_scene([SUN], extra=[red_wall()]), SETTINGS)
    assert not np.allclose(seen.passes["Combined"], frames[1].passes["Combined"], atol=1e-3)
