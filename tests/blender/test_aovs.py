"""Shader AOVs (View Layer > Shader AOV, a material's AOV Output node): each AOV's pass holds,
per pixel, the value (or colour) the materials seen there write, as Cycles' does; read
through the compositor's Render Layers node (48², Cycles 16 samples with a one-pixel box
filter: the pixel's average, as VPL GI's supersamples)."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from tests.blender.rendering import (
    add_camera,
    configure_cycles,
    lamp_over_floor,
    render_linear,
)
from tests.blender.versions import compositor_output

SIZE = 48


def _write_aov(material: bpy.types.Material, name: str, color=None, value=None) -> None:
    node = material.node_tree.nodes.new("ShaderNodeOutputAOV")
    node.aov_name = name
    if color is not None:
        node.inputs["Color"].default_value = (*color, 1.0)
    if value is not None:
        node.inputs["Value"].default_value = value


def aov_scene() -> bpy.types.Scene:
    """The lamp-over-floor scene: the floor writes mask 0.3 and tint orange, the box mask
    1 and no tint; the view layer has both AOVs."""
    lamp_over_floor("POINT", 100.0, (0.5, 0.5, 2.0), (0, 0, 0), SIZE)
    scene = bpy.context.scene
    floor, box = (o for o in scene.objects if o.type == "MESH")
    box.data.materials.clear()
    box_material = floor.data.materials[0].copy()
    box.data.materials.append(box_material)
    _write_aov(floor.data.materials[0], "mask", value=0.3)
    _write_aov(floor.data.materials[0], "tint", color=(1.0, 0.5, 0.2))
    _write_aov(box_material, "mask", value=1.0)
    layer = scene.view_layers[0]
    for name, kind in (("mask", "VALUE"), ("tint", "COLOR")):
        aov = layer.aovs.add()
        aov.name, aov.type = name, kind
    add_camera(scene, SIZE, location=(0.3, -0.2, 5))  # the floor's edge in view
    scene.camera.data.lens = 20
    configure_cycles(scene, 16)
    return scene


def _aov(scene: bpy.types.Scene, engine: str, path, socket: str) -> np.ndarray:
    scene.render.engine = engine
    tree, output = compositor_output(scene)
    layers = tree.nodes.new("CompositorNodeRLayers")
    tree.links.new(layers.outputs[socket], output)
    return render_linear(scene, engine, path)


@pytest.mark.parametrize("socket", ["mask", "tint"])
def test_an_aovs_pass_is_cycles(blender, tmp_path, socket):
    scene = aov_scene()
    channels = 4 if socket == "tint" else 3  # a colour's alpha: where it is written
    reference = _aov(scene, "CYCLES", tmp_path / "cycles.exr", socket)[..., :channels]
    ours = _aov(scene, "VPL_GI", tmp_path / "ours.exr", socket)[..., :channels]
    off = np.abs(ours - reference)
    print(f"AOV {socket}: values {np.unique(reference.round(2))[:6]}, mean abs {off.mean():.4f}, "
          f"{(off > 0.05).mean():.3f} of pixels over 0.05 off (edges)")
    assert len(np.unique(reference.round(2))) >= 3  # the background, the floor and the box
    assert off.mean() < 0.01 and (off > 0.05).mean() < 0.05


def test_a_linked_aov_input_is_named(blender):
    """An AOV Output whose Color comes from a texture is written as the socket's own colour,
    with a warning that names the material and the AOV."""
    from addon.export import export_scene

    scene = aov_scene()
    floor = next(o for o in scene.objects if o.type == "MESH")
    tree = floor.data.materials[0].node_tree
    node = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputAOV"
                and n.aov_name == "tint")
    tree.links.new(tree.nodes.new("ShaderNodeTexNoise").outputs["Color"], node.inputs["Color"])
    exported = export_scene(blender.context.evaluated_depsgraph_get())
    assert any("AOV 'tint''s Color is linked" in w for w in exported.warnings)
    written = dict(next(i for i in exported.instances if i.materials[0].aovs).materials[0].aovs)
    assert written["tint"] == pytest.approx((1.0, 0.5, 0.2, 0.0))
