"""Light groups (frame/light_groups.py): the passes asked for, and the scene a group's frame
renders (only its emitters lit, every object kept). The passes against Cycles are in
tests/blender/test_light_groups.py."""

from __future__ import annotations

import numpy as np

from addon.core.frame.light_groups import group_scene, has_emitters, requested_groups
from addon.core.scene.model import Instance, LightKind, Material, World
from tests.core.builders import floor_scene, light, quad, translation


def _grouped_scene():
    """A floor, a lamp in Key and one in Fill, a glowing tile in Key and a grey world in
    Fill."""
    key, fill = (light(LightKind.POINT, translation(x, 0, 2), lightgroup=group)
                 for x, group in ((1.0, "Key"), (-1.0, "Fill")))
    tile = Instance(quad(0.5, 0.5, 0.01), np.eye(4),
                    [Material("tile", emission=(2.0, 1.0, 0.5))], lightgroup="Key")
    return floor_scene([key, fill], extra=[tile],
                       world=World((0.2, 0.2, 0.2), lightgroup="Fill"))


def test_the_passes_name_their_groups():
    passes = frozenset({"Combined", "DiffDir", "Combined_Key", "Combined_Fill", "Combined_"})
    assert requested_groups(passes) == ["Fill", "Key"]
    assert requested_groups(None) == []


def test_a_groups_scene_keeps_its_emitters_and_every_object():
    """Key's scene: its lamp and glowing tile, a black world; Fill's: its lamp and the world,
    the tile kept (it still casts shadows and reflects light) but dark."""
    scene = _grouped_scene()
    key = group_scene(scene, "Key")
    assert [lamp.lightgroup for lamp in key.lights] == ["Key"]
    assert not np.any(key.world.radiance) and key.world.environment is None
    assert key.instances[1].materials[0].emission == (2.0, 1.0, 0.5)
    fill = group_scene(scene, "Fill")
    assert [lamp.lightgroup for lamp in fill.lights] == ["Fill"]
    assert fill.world is scene.world
    assert len(fill.instances) == 2 and fill.instances[1].materials[0].emission == (0, 0, 0)
    assert scene.instances[1].materials[0].emission == (2.0, 1.0, 0.5)  # the scene's own
    assert has_emitters(key) and has_emitters(fill)
    assert not has_emitters(group_scene(scene, "Empty"))
