"""Light linking (Object Properties › Shading › Light Linking: an emitter's receiver
collection) rendered as Cycles renders it: an emitter lights only the objects its collection
includes, or every object but those it excludes, directly and through their bounces; the
objects it does not light still receive the others' bounce light."""

from __future__ import annotations

import math

import bpy
import numpy as np

from addon.core.scene.model import EVERY_RECEIVER_SET
from addon.export import export_scene
from addon.export_light_linking import scene_light_linking
from tests.blender.rendering import (
    add_camera,
    add_primitive,
    assert_near_cycles,
    cycles_and_ours,
    plain_world,
    render_linear,
    shader_material,
)

SIZE = 64


def receivers(name: str, entries: dict[bpy.types.Object, str]) -> bpy.types.Collection:
    """A receiver collection of ``entries`` (object: "INCLUDE" or "EXCLUDE")."""
    collection = bpy.data.collections.new(name)
    for obj, state in entries.items():
        collection.objects.link(obj)
        collection.collection_objects[-1].light_linking.link_state = state
    return collection


def linked_stage() -> bpy.types.Scene:
    """A grey floor, a red box and a white ball: a key light that lights only the box, an
    area fill that lights all but the ball, an emissive panel that lights only the ball."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    red = shader_material("Red", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.1, 0.1, 1))
    white = shader_material("White", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.8, 0.8, 1))
    glow = shader_material("Glow", "ShaderNodeEmission", Strength=6.0)
    add_primitive("plane", grey, size=8).name = "Floor"
    box = add_primitive("cube", red, size=1.0, location=(-0.9, 0.2, 0.5))
    box.name = "Box"
    ball = add_primitive("uv_sphere", white, radius=0.5, location=(0.9, 0.0, 0.5))
    ball.name = "Ball"
    panel = add_primitive("plane", glow, size=0.8, location=(2.0, 0.0, 0.8),
                          rotation=(0.0, math.radians(-90), 0.0))
    panel.name = "Panel"
    plain_world(scene, (0.0, 0.0, 0.0))
    add_camera(scene, SIZE, (0.0, -6.0, 4.0), (math.radians(58), 0.0, 0.0))
    key = bpy.data.objects.new("Key", bpy.data.lights.new("Key", "POINT"))
    key.data.energy, key.data.shadow_soft_size = 400.0, 0.0
    key.location = (-0.5, -1.5, 3.0)
    fill = bpy.data.objects.new("Fill", bpy.data.lights.new("Fill", "AREA"))
    fill.data.energy, fill.data.size = 150.0, 1.0
    fill.location = (0.5, 0.5, 3.5)
    for light in (key, fill):
        scene.collection.objects.link(light)
    key.light_linking.receiver_collection = receivers("Key lights", {box: "INCLUDE"})
    fill.light_linking.receiver_collection = receivers("Fill lights", {ball: "EXCLUDE"})
    panel.light_linking.receiver_collection = receivers("Panel lights", {ball: "INCLUDE"})
    return scene


def unlink(scene: bpy.types.Scene) -> None:
    for obj in scene.objects:
        obj.light_linking.receiver_collection = None


def test_linked_lights_and_emission_light_only_their_receivers_as_in_cycles(blender, tmp_path):
    """Direct light and one bounce (Cycles 256 samples)."""
    scene = linked_stage()
    reference, ours = cycles_and_ours(scene, tmp_path, 256, 1)
    unlink(scene)
    unlinked = render_linear(scene, "VPL_GI", tmp_path / "unlinked.exr")
    assert_near_cycles("light linking", ours, reference, (0.05, 0.12), unlinked,
                       "every emitter lighting every object")


def test_receiver_sets_follow_blenders_include_and_exclude_rules(blender):
    """Objects reached through a child collection take its entry's state; an emitter whose
    collection includes some object lights only the included ones, one that only excludes
    lights every object but those; an unlinked emitter lights all."""
    linked_stage()
    children = bpy.data.collections.new("Props")
    extra = bpy.data.objects.new("Extra", bpy.data.meshes.new("Extra"))
    children.objects.link(extra)
    key = bpy.data.objects["Key"]
    key.light_linking.receiver_collection.children.link(children)
    key.light_linking.receiver_collection.collection_children[0].light_linking.link_state = \
        "EXCLUDE"
    linking = scene_light_linking(bpy.context.evaluated_depsgraph_get())
    objects = bpy.data.objects

    def lit(emitter: str, receiver: str) -> bool:
        return bool(linking.receivers_of(objects[emitter])
                    >> linking.receiver_set(objects[receiver]) & 1)

    assert [lit("Key", name) for name in ("Box", "Ball", "Floor", "Extra")] == \
        [True, False, False, False]
    assert [lit("Fill", name) for name in ("Box", "Ball", "Floor", "Extra")] == \
        [True, False, True, True]
    assert [lit("Panel", name) for name in ("Box", "Ball", "Floor", "Extra")] == \
        [False, True, False, False]
    assert linking.receivers_of(objects["Floor"]) == EVERY_RECEIVER_SET

    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    assert not any("linking" in warning for warning in exported.warnings)
    sets = {inst.identity.name: inst.receiver_set for inst in exported.instances}
    assert sets["Floor"] == 0 and len({sets["Box"], sets["Ball"], sets["Floor"]}) == 3
    by_name = {light.name: light.receivers for light in exported.lights}
    assert by_name["Key"] >> sets["Box"] & 1 and not by_name["Key"] >> sets["Floor"] & 1
    panel, = (inst for inst in exported.instances if inst.identity.name == "Panel")
    assert panel.emission_receivers >> sets["Ball"] & 1
    assert not np.uint64(panel.emission_receivers) >> np.uint64(sets["Box"]) & np.uint64(1)
