"""Light groups (View Layer > Light Groups) against Cycles: each group's Combined_<group> pass
holds the light of its emitters alone, through two bounces (frame/light_groups.py). The scene:
a grey floor and box, a warm lamp and an upright emissive panel in group Key, a blue lamp in group
Fill, a grey world in neither (48², 256 samples, read through the compositor's Render Layers
node as a user reads them). Each pass must miss Cycles' by far less than the full image
(every emitter's light) does."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from tests.blender.rendering import (
    add_camera,
    add_primitive,
    assert_near_cycles,
    configure_cycles,
    plain_world,
    render_linear,
    shader_material,
)
from tests.blender.versions import compositor_output

SIZE, SAMPLES, BOUNCES = 48, 256, 2


def _lamp(scene: bpy.types.Scene, name: str, power: float, colour: tuple, location: tuple,
          group: str) -> None:
    data = bpy.data.lights.new(name, "POINT")
    data.energy, data.color, data.shadow_soft_size = power, colour, 0.0
    lamp = bpy.data.objects.new(name, data)
    lamp.location = location
    scene.collection.objects.link(lamp)
    lamp.lightgroup = group


def grouped_scene() -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    add_primitive("plane", grey, size=8)
    add_primitive("cube", grey, size=0.8, location=(-0.4, 0.2, 0.4))
    glow = shader_material("Glow", "ShaderNodeEmission", Color=(1.0, 0.5, 0.2, 1),
                           Strength=8.0)
    panel = add_primitive("plane", glow, size=0.8, location=(1.6, -0.4, 0.6),
                          rotation=(0.0, math.radians(90.0), 0.0))
    panel.lightgroup = "Key"
    plain_world(scene, (0.1, 0.1, 0.1))
    add_camera(scene, SIZE, location=(0, 0, 5))
    _lamp(scene, "Key", 150.0, (1.0, 0.8, 0.6), (0.8, 0.3, 2.0), "Key")
    _lamp(scene, "Fill", 200.0, (0.4, 0.6, 1.0), (-1.2, -0.6, 2.4), "Fill")
    for group in ("Key", "Fill"):
        bpy.ops.scene.view_layer_add_lightgroup(name=group)
    configure_cycles(scene, SAMPLES, bounces=BOUNCES)
    scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = BOUNCES, 4
    return scene


def rendered_pass(scene: bpy.types.Scene, engine: str, path, socket: str) -> np.ndarray:
    """The Render Layers node's ``socket`` as ``engine`` renders it (RGB)."""
    scene.render.engine = engine  # first: the node's sockets are the engine's passes
    tree, output = compositor_output(scene)
    layers = tree.nodes.new("CompositorNodeRLayers")
    tree.links.new(layers.outputs[socket], output)
    return render_linear(scene, engine, path)[..., :3]


@pytest.mark.parametrize("group", ["Key", "Fill"])
def test_a_light_groups_pass_is_cycles(blender, tmp_path, group):
    scene = grouped_scene()
    reference = rendered_pass(scene, "CYCLES", tmp_path / "cycles.exr", f"Combined_{group}")
    ours = rendered_pass(scene, "VPL_GI", tmp_path / "ours.exr", f"Combined_{group}")
    everything = rendered_pass(scene, "VPL_GI", tmp_path / "all.exr", "Image")
    assert_near_cycles(f"Combined_{group}", ours, reference, (0.03, 0.08), everything,
                       "the full image")


def test_a_group_with_nothing_in_it_is_black(blender, tmp_path):
    """A light group no emitter is in: its pass is black, as in Cycles, and the frame is
    rendered."""
    scene = grouped_scene()
    bpy.ops.scene.view_layer_add_lightgroup(name="Empty")
    ours = rendered_pass(scene, "VPL_GI", tmp_path / "ours.exr", "Combined_Empty")
    assert ours.shape == (SIZE, SIZE, 3) and not ours.any()
