"""Shadow linking (Object Properties › Shading › Shadow Linking: an emitter's blocker
collection) rendered as Cycles renders it: an emitter's shadows are cast only by the objects
its collection includes, or by every object but those it excludes, in its direct light and
in the light its paths carry to their first surface."""

from __future__ import annotations

import bpy
import numpy as np

from addon.core.scene.model import EVERY_RECEIVER_SET
from addon.export import export_scene
from tests.blender.rendering import assert_near_where, cycles_and_ours, render_linear
from tests.blender.test_light_linking import linked_stage, receivers, unlink


def shadow_linked_stage() -> bpy.types.Scene:
    """test_light_linking's stage unlinked: the floor, the red box, the white ball, the key
    and fill lights and the emissive panel; the key's shadows cast by the ball alone, the
    fill's by all but the box, the panel's by all but the ball."""
    scene = linked_stage()
    unlink(scene)
    objects = bpy.data.objects
    box, ball = objects["Box"], objects["Ball"]
    objects["Key"].light_linking.blocker_collection = receivers("Key shadows",
                                                                {ball: "INCLUDE"})
    objects["Fill"].light_linking.blocker_collection = receivers("Fill shadows",
                                                                 {box: "EXCLUDE"})
    objects["Panel"].light_linking.blocker_collection = receivers("Panel shadows",
                                                                  {ball: "EXCLUDE"})
    return scene


def unlink_shadows(scene: bpy.types.Scene) -> None:
    for obj in scene.objects:
        obj.light_linking.blocker_collection = None


def test_shadow_linked_emitters_are_shadowed_by_their_blockers_as_in_cycles(blender,
                                                                            tmp_path):
    """Direct light and one bounce (Cycles 256 samples): the whole image, and the pixels
    whose light shadow linking changes (where every object casting every shadow is over a
    tenth of the image's mean off), where ignoring it is off by three times as much or
    more."""
    scene = shadow_linked_stage()
    reference, ours = cycles_and_ours(scene, tmp_path, 256, 1)
    unlink_shadows(scene)
    unlinked = render_linear(scene, "VPL_GI", tmp_path / "unlinked.exr")
    rgb = reference[..., :3]
    changed = np.abs(unlinked[..., :3] - rgb).mean(axis=-1) > 0.1 * rgb.mean()
    assert_near_where("shadow linking", ours, reference, unlinked, changed, (0.03, 0.08),
                      "every object casting every shadow")


def test_blocker_sets_are_exported(blender):
    """Each object's blocker set and each emitter's blockers, as Blender's rules give them;
    no warning."""
    shadow_linked_stage()
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    assert not any("linking" in warning for warning in exported.warnings)
    sets = {inst.identity.name: inst.blocker_set for inst in exported.instances}
    assert sets["Floor"] == 0 and sets["Panel"] == 0
    assert len({sets["Box"], sets["Ball"], sets["Floor"]}) == 3
    by_name = {light.name: light.blockers for light in exported.lights}

    def casts(blockers: int, name: str) -> bool:
        return bool(blockers >> sets[name] & 1)

    assert [casts(by_name["Key"], n) for n in ("Box", "Ball", "Floor")] == [False, True, False]
    assert [casts(by_name["Fill"], n) for n in ("Box", "Ball", "Floor")] == [False, True, True]
    panel, = (inst for inst in exported.instances if inst.identity.name == "Panel")
    assert [casts(panel.emission_blockers, n) for n in ("Box", "Ball", "Floor")] == \
        [True, False, True]
    assert all(inst.receiver_set == 0 and inst.emission_receivers == EVERY_RECEIVER_SET
               for inst in exported.instances)
