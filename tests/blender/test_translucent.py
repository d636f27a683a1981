"""A Translucent BSDF against Cycles: the diffuse light it lets through leaves the surface's
other side (core/transport/vpl.py's far-side VPLs, gather_frag.glsl's TRANSLUCENT)."""

from __future__ import annotations

import math

import numpy as np

from tests.blender.rendering import (
    add_camera,
    assert_near_cycles,
    cycles_and_ours,
    open_scene,
    render_linear,
    sunlit_box,
)


def diffuser(bpy, translucent_share: float):
    """A diffuser material: a Mix Shader of a white Diffuse BSDF and (Fac ``translucent_share``)
    a warm Translucent BSDF."""
    material = bpy.data.materials.new("Diffuser")
    material.use_nodes = True
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    translucent = tree.nodes.new("ShaderNodeBsdfTranslucent")
    diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    translucent.inputs["Color"].default_value = (0.9, 0.7, 0.4, 1.0)
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = translucent_share
    tree.links.new(diffuse.outputs[0], mix.inputs[1])
    tree.links.new(translucent.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def test_a_diffuser_under_the_light_lets_its_light_through_as_in_cycles(blender, tmp_path):
    """The Cornell box with a 0.9 m diffuser 0.6 m under its area light, half of it a
    Translucent BSDF, two bounces (48², Cycles 1024 samples): the room below is lit through
    it. Measured (bpy 4.5, llvmpipe): energy +1.1 %, relRMSE 18.8 %; the diffuser all Diffuse
    BSDF (as a Translucent BSDF rendered before stop 68: its underside dark, the room's light
    coming around it) 92.9 %."""
    bpy = blender
    scene = open_scene("cornell_box", 48)
    light = next(o for o in scene.objects if o.type == "LIGHT")
    bpy.ops.mesh.primitive_plane_add(size=0.9, location=(*light.location.xy,
                                                         light.location.z - 0.6))
    bpy.context.object.data.materials.append(diffuser(bpy, 0.5))
    reference, ours = cycles_and_ours(scene, tmp_path, 1024, 2)
    scene.vpl_gi.bounces = 2
    bpy.context.object.active_material.node_tree.nodes["Mix Shader"].inputs["Fac"] \
        .default_value = 0.0
    reflecting = render_linear(scene, "VPL_GI", tmp_path / "reflecting.exr")

    assert_near_cycles("diffuser", ours[..., :3], reference[..., :3], (0.03, 0.25),
                       reflecting[..., :3], "reflecting only", factor=2.0)


def test_a_translucent_mix_keeps_each_colours_share(blender):
    """A Translucent BSDF alone lets all its diffuse light through; mixed with a Diffuse BSDF
    of another colour, per channel the share of the mix's colour that is the Translucent
    BSDF's."""
    from addon.export import export_material
    bpy = blender
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    mixed = export_material(diffuser(bpy, 0.5), warnings)
    np.testing.assert_allclose(mixed.base_color, (0.85, 0.75, 0.6), rtol=1e-6)
    np.testing.assert_allclose(mixed.translucency, (0.45 / 0.85, 0.35 / 0.75, 0.2 / 0.6),
                               rtol=1e-6)
    material = diffuser(bpy, 1.0)
    assert export_material(material, warnings).translucency == (1.0, 1.0, 1.0)
    assert not warnings


def test_sunlit_leaves_glow_from_below_as_in_cycles(blender, tmp_path):
    """A plant library's leaf (a Transparent BSDF masked in, a Principled and a Translucent
    BSDF sharing its colour texture, 0.3 translucent) roofing ``sunlit_box``, seen from under
    the roof, one bounce (48², Cycles 64 samples, 8 transparent bounces): the leaves'
    undersides glow with the sun let through. Measured (bpy 4.5, llvmpipe): energy −2.8 %,
    relRMSE 10.9 %; the leaf all Principled BSDF (as the Translucent BSDF rendered before
    stop 68: its light reflected on the lit side) −22 %, 35.9 %."""
    from tests.blender.test_cutouts import translucent_leaf
    bpy = blender
    scene = sunlit_box(translucent_leaf)
    add_camera(scene, 48, (0.0, -2.6, 0.6), (math.radians(115), 0.0, 0.0)).data.lens = 18
    reference, ours = cycles_and_ours(scene, tmp_path, 64, 1, transparent=True)
    bpy.data.materials["Leaf"].node_tree.nodes["Mix Shader"].inputs["Fac"].default_value = 0.0
    reflecting = render_linear(scene, "VPL_GI", tmp_path / "reflecting.exr")

    assert_near_cycles("leaves from below", ours[..., :3], reference[..., :3], (0.05, 0.25),
                       reflecting[..., :3], "reflecting only", factor=2.0)
