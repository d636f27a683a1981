"""Cutouts (a Principled BSDF's Alpha, a Transparent BSDF mixed in by a mask: leaves,
fences): exported as surfaces there in part, against Cycles."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from addon.core.scene.model import COVERAGE_ALPHA, COVERAGE_INVERTED, COVERAGE_LUMINANCE
from addon.export import export_material
from tests.blender.rendering import (
    add_camera,
    assert_near_cycles,
    cycles_and_ours,
    render_linear,
    shader_material,
    sunlit_box,
)

SIZE = 64
LEAF_GREEN = (0.2, 0.6, 0.1, 1.0)


def mask_image(name: str = "Mask") -> bpy.types.Image:
    """An 8×8 byte image, packed: a seeded random mask, 1 in about 60 % of the texels, in its
    alpha and (as grey) its colour."""
    mask = (np.random.default_rng(7).random((8, 8)) < 0.6).astype(np.float32)
    image = bpy.data.images.new(name, 8, 8, alpha=True)
    image.pixels.foreach_set(np.repeat(mask[..., None], 4, axis=2).ravel())
    image.pack()
    return image


def image_node(tree, image: bpy.types.Image):
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image, node.interpolation = image, "Closest"
    return node


def principled_leaf(output: str = "Alpha") -> bpy.types.Material:
    """A green Principled BSDF whose Alpha is the mask's ``output``."""
    material = shader_material("Leaf", "ShaderNodeBsdfPrincipled", Base_Color=LEAF_GREEN)
    tree = material.node_tree
    tree.links.new(image_node(tree, mask_image()).outputs[output],
                   tree.nodes["Principled BSDF"].inputs["Alpha"])
    return material


def mixed_leaf(transparent_slot: int = 1, fac: float | None = None) -> bpy.types.Material:
    """A green Diffuse BSDF and a Transparent BSDF in a Mix Shader (the Transparent one in
    ``transparent_slot``), its Fac the mask's colour, or ``fac``."""
    material = shader_material("Leaf", "ShaderNodeBsdfDiffuse", Color=LEAF_GREEN)
    tree = material.node_tree
    mix = tree.nodes.new("ShaderNodeMixShader")
    transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
    tree.links.new(transparent.outputs[0], mix.inputs[transparent_slot])
    tree.links.new(tree.nodes["Diffuse BSDF"].outputs[0], mix.inputs[3 - transparent_slot])
    if fac is None:
        tree.links.new(image_node(tree, mask_image()).outputs["Color"], mix.inputs["Fac"])
    else:
        mix.inputs["Fac"].default_value = fac
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def test_alphas_and_transparent_mixes_export_as_cutouts(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    half = export_material(shader_material("Half", "ShaderNodeBsdfPrincipled", Alpha=0.5),
                           warnings)
    assert half.is_cutout and half.alpha == pytest.approx(0.5) and not half.is_clear
    for output, mode in (("Alpha", COVERAGE_ALPHA), ("Color", COVERAGE_LUMINANCE)):
        leaf = export_material(principled_leaf(output), warnings)
        assert leaf.coverage_texture is not None and leaf.coverage_mode == mode
    # Fac weighs the second slot: a Transparent BSDF there leaves 1 − Fac of the surface
    for slot, mode in ((1, COVERAGE_LUMINANCE), (2, COVERAGE_LUMINANCE | COVERAGE_INVERTED)):
        leaf = export_material(mixed_leaf(slot), warnings)
        assert leaf.coverage_texture is not None and leaf.coverage_mode == mode
        assert leaf.base_color == pytest.approx(LEAF_GREEN[:3])
    veil = export_material(mixed_leaf(2, fac=0.25), warnings)
    assert veil.alpha == pytest.approx(0.75) and veil.base_color == pytest.approx(LEAF_GREEN[:3])
    assert not warnings


def test_an_alpha_from_other_nodes_is_one_warning_and_opaque(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    material = shader_material("Fence", "ShaderNodeBsdfPrincipled")
    tree = material.node_tree
    tree.links.new(tree.nodes.new("ShaderNodeMath").outputs[0],
                   tree.nodes["Principled BSDF"].inputs["Alpha"])
    warnings: list[str] = []
    assert not export_material(material, warnings).is_cutout
    assert warnings == ["material 'Fence': Principled BSDF's Alpha not rendered (input 'Alpha' "
                        "of 'Principled BSDF' is linked to 'Math')"]


def sunlit_box_under_leaves(leaf) -> bpy.types.Scene:
    """``sunlit_box`` under a roof of the material ``leaf()`` makes (its mask's texels 0.75 m
    wide), seen from above and in front."""
    scene = sunlit_box(leaf)
    add_camera(scene, SIZE, (0.0, -7.0, 5.0), (math.radians(55), 0.0, 0.0)).data.lens = 24
    return scene


@pytest.mark.parametrize("leaf", [principled_leaf, mixed_leaf])
def test_sunlight_through_leaves_as_in_cycles(blender, tmp_path, leaf):
    """The sun through a roof of masked leaves, seen in part, with one diffuse bounce
    (Cycles 64 samples, 8 transparent bounces): a Principled BSDF's Alpha and a Transparent
    BSDF mixed in by the mask's colour. Measured (bpy 4.5, llvmpipe): see the printout; the
    roof opaque (the export before cutouts): relRMSE several times larger."""
    scene = sunlit_box_under_leaves(leaf)
    reference, ours = cycles_and_ours(scene, tmp_path, 64, 1, transparent=True)
    roof = bpy.data.materials["Leaf"].node_tree
    for link in list(roof.links):
        if link.from_node.type == "TEX_IMAGE":
            roof.links.remove(link)
    mix = roof.nodes.get("Mix Shader")
    if mix is not None:
        mix.inputs["Fac"].default_value = 1.0  # all Diffuse
    opaque = render_linear(scene, "VPL_GI", tmp_path / "opaque.exr")

    assert_near_cycles(leaf.__name__, ours, reference, (0.03, 0.10), opaque, "the roof opaque")


def translucent_leaf() -> bpy.types.Material:
    """A leaf as plant libraries build it: a Mix Shader of a Transparent BSDF and (Fac: the
    mask's alpha) a mix of a Principled BSDF and a Translucent BSDF sharing a colour
    texture."""
    material = shader_material("Leaf", "ShaderNodeBsdfPrincipled")
    tree = material.node_tree
    colour, mask = image_node(tree, mask_image("Colour")), image_node(tree, mask_image())
    principled = tree.nodes["Principled BSDF"]
    translucent = tree.nodes.new("ShaderNodeBsdfTranslucent")
    surface, outer = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeMixShader")
    transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
    tree.links.new(colour.outputs["Color"], principled.inputs["Base Color"])
    tree.links.new(colour.outputs["Color"], translucent.inputs["Color"])
    surface.inputs["Fac"].default_value = 0.3
    tree.links.new(principled.outputs[0], surface.inputs[1])
    tree.links.new(translucent.outputs[0], surface.inputs[2])
    tree.links.new(mask.outputs["Alpha"], outer.inputs["Fac"])
    tree.links.new(transparent.outputs[0], outer.inputs[1])
    tree.links.new(surface.outputs[0], outer.inputs[2])
    tree.links.new(outer.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def test_mixes_keep_a_shared_texture_and_mix_their_alphas(blender):
    """A plant library's leaf is a textured cutout letting through the Translucent BSDF's
    share of its diffuse light; Mix Shaders mix constant alphas by their weights; an Alpha
    texture on one side of a mix only is not rendered (the viewport colour, with a
    warning)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    leaf = export_material(translucent_leaf(), warnings)
    assert leaf.base_color_texture is not None and leaf.coverage_texture is not None
    assert leaf.coverage_mode == COVERAGE_ALPHA and leaf.alpha == 1.0
    assert leaf.translucency == pytest.approx((0.3,) * 3) and not warnings
    material = shader_material("Veil", "ShaderNodeBsdfPrincipled", Alpha=0.5)
    tree = material.node_tree
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    tree.links.new(tree.nodes["Principled BSDF"].outputs[0], mix.inputs[1])
    tree.links.new(tree.nodes.new("ShaderNodeBsdfDiffuse").outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    warnings.clear()
    assert export_material(material, warnings).alpha == pytest.approx(0.75) and not warnings
    tree.links.new(image_node(tree, mask_image()).outputs["Alpha"],
                   tree.nodes["Principled BSDF"].inputs["Alpha"])
    assert not export_material(material, warnings).is_cutout
    assert warnings == ["material 'Veil': an Alpha texture on one side of 'Mix Shader' is not "
                        "supported; using its viewport colour"]


def test_the_report_gives_cycles_transparent_bounces_for_cutouts(blender):
    """The report's Cycles references see through cutouts (transparent bounces), else Cycles
    renders their clear texels black: the leaf roof's report measured VPL GI 54.8 % off,
    energy +22.8 %, against such references."""
    from devtools.report import has_clear_materials
    assert has_clear_materials(sunlit_box_under_leaves(principled_leaf))
    assert not has_clear_materials(sunlit_box_under_leaves(
        lambda: shader_material("Plain", "ShaderNodeBsdfDiffuse")))
