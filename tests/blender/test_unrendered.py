"""What Cycles renders and VPL GI does not (volumes, a Principled BSDF's subsurface,
anisotropy and thin film) is named in one warning each, and an object
with only a Volume shader lets light through as in Cycles instead of rendering as a black
surface."""

from __future__ import annotations

import math

import bpy
import pytest

from addon.blender_compat import ensure_nodes
from addon.export import export_material, export_scene
from tests.blender.rendering import (
    add_camera,
    add_primitive,
    assert_near_cycles,
    cycles_and_ours,
    render_linear,
    shader_material,
    sunlit_box,
)

SIZE = 64


def volume_only(density: float = 0.0) -> bpy.types.Material:
    """A material whose output has a Principled Volume of ``density`` and no Surface."""
    material = bpy.data.materials.new("Fog")
    ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Density"].default_value = density
    tree.links.new(volume.outputs[0], tree.nodes["Material Output"].inputs["Volume"])
    return material


def test_a_volume_only_material_is_clear_and_a_volume_beside_a_surface_warns(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    fog = export_material(volume_only(), warnings)
    assert fog.is_clear and fog.name == "Fog"
    smoke = shader_material("Smoke", "ShaderNodeBsdfDiffuse", Color=(0.5, 0.5, 0.5, 1.0))
    tree = smoke.node_tree
    tree.links.new(tree.nodes.new("ShaderNodeVolumeAbsorption").outputs[0],
                   tree.nodes["Material Output"].inputs["Volume"])
    surface = export_material(smoke, warnings)
    assert not surface.is_clear and surface.base_color == pytest.approx((0.5, 0.5, 0.5))
    assert warnings == [
        "material 'Fog': its Volume shader is not rendered; without a Surface, light passes "
        "through it (as in Cycles)",
        "material 'Smoke': its Volume shader is not rendered"]


def test_sunlight_through_a_volume_only_box_as_in_cycles(blender, tmp_path):
    """The sunlit box's roof made a volume of density 0 (so that Cycles renders only what
    VPL GI does), one bounce, against Cycles (64², 64 samples, 8 transparent bounces: Cycles
    counts crossing a volume's boundary as one). Measured (bpy 4.5, llvmpipe): energy
    −0.3 %, relRMSE 1.1 %; the roof black and opaque (the export before): 76 %."""
    scene = sunlit_box(volume_only)
    add_camera(scene, SIZE, location=(0.0, -6.5, 5.0), rotation=(math.radians(50), 0, 0))
    reference, ours = cycles_and_ours(scene, tmp_path, 64, 1, transparent=True)
    roof = bpy.data.materials["Fog"].node_tree
    roof.links.new(roof.nodes.new("ShaderNodeBsdfDiffuse").outputs[0],
                   roof.nodes["Material Output"].inputs["Surface"])
    roof.nodes["Diffuse BSDF"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    opaque = render_linear(scene, "VPL_GI", tmp_path / "opaque.exr")
    assert_near_cycles("volume-only roof", ours[..., :3], reference[..., :3], (0.02, 0.04),
                       opaque[..., :3], "a black roof")


def test_volumes_and_a_world_volume_are_named(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    for index in range(4):
        scene.collection.objects.link(bpy.data.objects.new(
            f"Smoke{index}", bpy.data.volumes.new(f"S{index}")))
    scene.world = bpy.data.worlds.new("Misty")
    ensure_nodes(scene.world)
    tree = scene.world.node_tree
    tree.links.new(tree.nodes.new("ShaderNodeVolumeScatter").outputs[0],
                   tree.nodes["World Output"].inputs["Volume"])
    warnings = export_scene(bpy.context.evaluated_depsgraph_get()).warnings
    assert "volume objects are not rendered: 'Smoke0', 'Smoke1', 'Smoke2' and 1 more" \
        in warnings
    assert "world 'Misty': its Volume shader (fog) is not rendered" in warnings


def test_shadow_catchers_and_light_and_shadow_linking_are_not_named(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    floor = add_primitive("plane", shader_material("Grey", "ShaderNodeBsdfDiffuse"), size=4)
    floor.is_shadow_catcher = True
    add_camera(scene, 16, location=(0, 0, 5)).data.dof.use_dof = True  # rendered: no warning
    scene.render.use_motion_blur = True
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    scene.collection.objects.link(lamp)
    lamp.light_linking.receiver_collection = bpy.data.collections.new("Lit")
    lamp.light_linking.blocker_collection = bpy.data.collections.new("Blockers")
    warnings = export_scene(bpy.context.evaluated_depsgraph_get()).warnings
    assert not any("depth of field" in w for w in warnings)
    assert not any("motion blur" in w for w in warnings)  # rendered (test_motion.py)
    assert not any("linking" in w for w in warnings)  # rendered (test_light_linking.py,
    # test_shadow_linking.py)
    assert not any("catcher" in w for w in warnings)  # rendered (test_shadow_catcher.py)


def test_principled_layers_left_out_are_named_once_per_material(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    export_material(shader_material("Plain", "ShaderNodeBsdfPrincipled"), warnings)
    assert warnings == []
    varnish = shader_material("Varnish", "ShaderNodeBsdfPrincipled", Coat_Weight=1.0,
                              Sheen_Weight=0.3)
    tree = varnish.node_tree
    tree.links.new(tree.nodes.new("ShaderNodeTexNoise").outputs["Fac"],
                   tree.nodes["Principled BSDF"].inputs["Subsurface Weight"])
    exported = export_material(varnish, warnings)
    assert exported.coat_weight == 1.0  # rendered (test_coat.py)
    assert exported.sheen_weight == pytest.approx(0.3)  # rendered (test_sheen.py)
    assert warnings == ["material 'Varnish': Subsurface is rendered as diffuse"]
