"""The Ambient Occlusion and Environment passes of a rendered frame (against Cycles:
tests/blender/test_data_passes.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from addon.core.scene.model import Instance, LightKind, Material, World
from addon.core.settings import Settings
from tests.core.builders import floor_scene, light, pixel_centres, quad, rotation_x, translation

SETTINGS = Settings(antialiasing=2, bounces=0)


def walled_floor(distance: float):
    """The floor under a sun, with a wall along y = 0 (facing -y) and the AO distance."""
    wall = Instance(quad(5, 1), translation(0, 0, 1) @ rotation_x(np.pi / 2),
                    [Material("wall")], cast_shadow=True)
    scene = floor_scene([light(LightKind.SUN, np.eye(4), power=3.0)], extra=[wall])
    scene.ao_distance = distance
    return scene


def test_ambient_occlusion_darkens_the_floor_by_the_wall_within_the_distance(renderer):
    """Within a metre of the wall the floor is partly occluded (the wall covers up to half
    its hemisphere there; the rays past the wall's top or the AO distance are open), beyond
    the AO distance it is open; a distance of 0 occludes nothing. Against Cycles:
    tests/blender/test_data_passes.py."""
    frame, _ = renderer.render(walled_floor(1.0), SETTINGS, passes=frozenset({"AO"}))
    ao = frame.passes["AO"][..., 0]
    x, y = pixel_centres()
    foot = (y > -0.25) & (y < -0.1) & (np.abs(x) < 2)
    far = (y < -1.5) & (np.abs(x) < 2)
    assert 0.5 < ao[foot].mean() < 0.75
    assert ao[far].min() == 1.0
    np.testing.assert_array_equal(frame.passes["AO"][..., 0], frame.passes["AO"][..., 2])
    frame, _ = renderer.render(walled_floor(0.0), SETTINGS, passes=frozenset({"AO"}))
    assert frame.passes["AO"][foot].min() == 1.0


def test_the_environment_pass_is_the_world_where_no_surface_is(renderer):
    """A 2 m square under a blue world: the world's colour around it, none on it, with the
    film transparent too (whose Combined has no background)."""
    scene = floor_scene([light(LightKind.SUN, np.eye(4), power=3.0)],
                        world=World(color=(0.1, 0.2, 0.4)))
    scene.instances[0] = replace(scene.instances[0], mesh=quad(1, 1))
    x, y = pixel_centres()
    inside, outside = (np.abs(x) < 0.9) & (np.abs(y) < 0.9), (np.abs(x) > 1.1) | (np.abs(y) > 1.1)
    for transparent in (False, True):
        scene.film_transparent = transparent
        frame, _ = renderer.render(scene, SETTINGS, passes=frozenset({"Env"}))
        env = frame.passes["Env"]
        assert np.all(env[inside] == 0.0)
        np.testing.assert_allclose(env[outside], np.broadcast_to((0.1, 0.2, 0.4),
                                                                 env[outside].shape), rtol=1e-6)
