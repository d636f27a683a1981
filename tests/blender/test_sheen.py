"""The Principled BSDF's sheen (and the Sheen BSDF) against Cycles: a velvet sphere under a
point light, a velvet floor whose sheen lights a wall through bounces, a Sheen BSDF added to
a Diffuse BSDF. Each case is also rendered with the sheen left out of VPL GI's material
table, which must fail the bounds the real one passes.

Measured (bpy 4.5; energy, relRMSE inside, overall; without the sheen):
- velvet sphere, roughness 0.3: +0.37 %, 0.43 %, 7.6 % (−14.0 %, 4.5 %, 93.0 %)
- roughness 0.5: +0.10 %, 0.22 %, 6.4 % (−42.5 %, 36.5 %, 122 %)
- roughness 1.0: +0.03 %, 0.07 %, 2.8 % (−78.8 %, 155 %, 161 %)
- velvet floor, 2 bounces: −0.08 %, 1.5 %, 3.5 % (−1.5 %, 12.0 %, 12.4 %)
- Sheen BSDF + Diffuse BSDF: +0.06 %, 0.21 %, 3.8 % (−45.9 %, 76.4 %, 95.8 %)
- the floor's wall glowing under a sheen: +0.42 %, 4.8 %, 5.2 % (+10.9 %, 19.3 %, 20.2 %;
  dimming the light it casts on the floor as well: −4.5 %, 7.2 %, 7.5 %); bpy 5.3, which
  dims the cast light too: −0.00 %, 1.1 %, 3.5 % (+16.1 %, 20.9 %, 22.6 %)
The spheres' overall error is their rim's pixels, partly covered, where a sheen seen edge-on
shines most; the floor's, the VPLs' light through the sheen."""

from __future__ import annotations

import pytest

from addon.export import export_material
from tests.blender.rendering import shader_material
from tests.blender.test_coat import glowing_wall
from tests.blender.test_cycles_principled import compare as compare_with_cycles
from tests.blender.test_cycles_principled import (
    floor_scene,
    floor_with_two_bounces,
    principled_material,
    specular_rows_from,
    sphere_scene,
)


@pytest.fixture
def without_sheen(monkeypatch):
    """Calling it makes VPL GI render every material without its sheen."""
    return specular_rows_from(monkeypatch, 6)


def compare(scene, tmp_path, without_sheen, bounds, label: str) -> None:
    """test_cycles_principled's comparison, leaving the sheen out."""
    compare_with_cycles(scene, tmp_path, without_sheen, bounds, label, "the sheen")


def velvet(material, weight: float = 1.0, roughness: float = 0.5,
           tint: tuple[float, float, float] = (1.0, 1.0, 1.0)):
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Sheen Weight"].default_value = weight
    bsdf.inputs["Sheen Roughness"].default_value = roughness
    bsdf.inputs["Sheen Tint"].default_value = (*tint, 1.0)
    return material


@pytest.mark.parametrize("roughness, bounds", [(0.3, (0.01, 0.01, 0.1)),
                                               (0.5, (0.01, 0.01, 0.1)),
                                               (1.0, (0.01, 0.01, 0.05))])
def test_velvet_sphere_under_a_point_light(blender, tmp_path, without_sheen, roughness,
                                           bounds):
    """A dark red velvet (Principled, sheen weight 1) under a point light to its side, a
    black world."""
    scene = sphere_scene(blender, lambda: velvet(
        principled_material("Velvet", (0.2, 0.02, 0.02), 0.5), roughness=roughness))
    compare(scene, tmp_path, without_sheen, bounds, f"velvet sphere r {roughness}")


def velvet_floor(bpy) -> None:
    """The glossy floor scene's floor (``floor_scene``) under a golden sheen."""
    velvet(bpy.data.materials["Floor"], roughness=0.8, tint=(0.9, 0.8, 0.5))


def test_velvet_floor_with_bounces(blender, tmp_path, without_sheen):
    """The velvet floor: its sheen seen at grazing angles, and the light it reflects onto
    the wall and back."""
    scene = floor_scene(blender, 0.5)
    velvet_floor(blender)
    floor_with_two_bounces(scene)
    compare(scene, tmp_path, without_sheen, (0.01, 0.03, 0.05), "velvet floor, 2 bounces")


def test_an_emitter_shines_through_its_sheen(blender, tmp_path, without_sheen):
    """The glossy floor's wall glowing under a sheen (roughness 1): Cycles dims emission
    under a sheen as it dims the layers below where the camera sees it, and in Blender 5.x
    the light it casts on the floor too (measured: 4.2 and 4.5 light the floor as brightly
    as without the sheen)."""
    scene, wall = glowing_wall(blender)
    velvet(wall, roughness=1.0)
    compare(scene, tmp_path, without_sheen, (0.01, 0.06, 0.07), "emitter under a sheen")


def test_sheen_bsdf_added_to_diffuse(blender, tmp_path, without_sheen):
    """A Sheen BSDF's closure dims nothing it is added to."""
    def mixed():
        material = shader_material("Cloth", "ShaderNodeBsdfDiffuse", Color=(0.1, 0.1, 0.4, 1))
        tree = material.node_tree
        diffuse = tree.nodes["Diffuse BSDF"]
        sheen = tree.nodes.new("ShaderNodeBsdfSheen")
        sheen.inputs["Roughness"].default_value = 0.7
        mix = tree.nodes.new("ShaderNodeAddShader")
        tree.links.new(diffuse.outputs[0], mix.inputs[0])
        tree.links.new(sheen.outputs[0], mix.inputs[1])
        tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
        return material
    scene = sphere_scene(blender, mixed)
    compare(scene, tmp_path, without_sheen, (0.01, 0.01, 0.06), "sheen bsdf + diffuse")


def test_what_of_a_sheen_is_not_rendered_is_one_warning(blender):
    """A sheen's weight or roughness from other nodes leaves the sheen out, a linked tint is
    white; a Sheen BSDF of the Ashikhmin distribution is rendered as Microfiber; each says
    so once."""
    blender.ops.wm.read_factory_settings(use_empty=True)
    material = velvet(shader_material("Cloth", "ShaderNodeBsdfPrincipled"), 0.6, 0.4,
                      (0.9, 0.5, 0.3))
    warnings: list[str] = []
    exported = export_material(material, warnings)
    assert (exported.sheen_weight, exported.sheen_roughness) == pytest.approx((0.6, 0.4))
    assert exported.sheen_tint == pytest.approx((0.9, 0.5, 0.3)) and exported.sheen_layered
    assert not warnings
    tree = material.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    colour = tree.nodes.new("ShaderNodeRGB")
    tree.links.new(colour.outputs[0], bsdf.inputs["Sheen Tint"])
    assert export_material(material, warnings).sheen_tint == (1.0, 1.0, 1.0)
    assert warnings == [f"material 'Cloth': Sheen Tint is not rendered (linked to "
                        f"'{colour.bl_label}')"]
    warnings.clear()
    tree.links.new(tree.nodes.new("ShaderNodeMath").outputs[0], bsdf.inputs["Sheen Roughness"])
    assert export_material(material, warnings).sheen_weight == 0.0
    assert warnings == ["material 'Cloth': Sheen is not rendered (its Sheen Roughness linked)"]
    warnings.clear()
    velour = shader_material("Velour", "ShaderNodeBsdfSheen", Color=(0.2, 0.3, 0.4, 1),
                             Roughness=0.7)
    velour.node_tree.nodes["Sheen BSDF"].distribution = "ASHIKHMIN"
    exported = export_material(velour, warnings)
    assert (exported.sheen_weight, exported.sheen_roughness) == pytest.approx((1.0, 0.7))
    assert exported.sheen_tint == pytest.approx((0.2, 0.3, 0.4))
    assert not exported.sheen_layered and exported.base_color == (0.0, 0.0, 0.0)
    assert warnings == ["material 'Velour': Sheen BSDF's Ashikhmin distribution is rendered "
                        "as Microfiber"]
