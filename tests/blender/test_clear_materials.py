"""Clear materials (Transparent, Glass and Refraction BSDFs, a Principled BSDF that is all
Alpha or Transmission): exported as light they let through, left out of the render so light
and camera rays pass them, against Cycles."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from addon.export import export_material
from tests.blender.rendering import (
    add_camera,
    against,
    assert_near_cycles,
    cycles_and_ours,
    plain_world,
    render_linear,
    shader_material,
    sunlit_box,
)

SIZE = 64


def glass_for_camera_transparent_for_shadows() -> bpy.types.Material:
    """Archviz window glass: Glass BSDF for camera rays, Transparent BSDF for shadow rays."""
    material = shader_material("Trick", "ShaderNodeBsdfGlass")
    tree = material.node_tree
    glass = tree.nodes["Glass BSDF"]
    mix = tree.nodes.new("ShaderNodeMixShader")
    path = tree.nodes.new("ShaderNodeLightPath")
    transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
    tree.links.new(path.outputs["Is Shadow Ray"], mix.inputs["Fac"])
    tree.links.new(glass.outputs[0], mix.inputs[1])
    tree.links.new(transparent.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


@pytest.mark.parametrize("kind, inputs, transmission", [
    ("ShaderNodeBsdfTransparent", {"Color": (0.9, 0.8, 0.7, 1)}, (0.9, 0.8, 0.7)),
    ("ShaderNodeBsdfGlass", {"Color": (1, 1, 1, 1), "IOR": 1.5}, (1, 1, 1)),
    ("ShaderNodeBsdfRefraction", {"Color": (0.5, 1, 1, 1)}, (0.5, 1, 1)),
    ("ShaderNodeBsdfPrincipled", {"Alpha": 0.0}, (1, 1, 1)),
    ("ShaderNodeBsdfPrincipled", {"Transmission_Weight": 1.0, "Base_Color": (0.2, 0.9, 0.9, 1)},
     (0.2, 0.9, 0.9)),
])
def test_clear_shaders_export_the_light_they_let_through(blender, kind, inputs, transmission):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    material = export_material(shader_material("Clear", kind, **inputs), warnings)
    assert material.is_clear and not warnings
    assert material.transmission == pytest.approx(transmission, abs=1e-6)


def test_glass_with_transparent_shadows_is_clear(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    material = export_material(glass_for_camera_transparent_for_shadows(), warnings)
    assert material.is_clear and not warnings


def test_partial_transmission_stays_opaque_and_says_so(blender):
    """Some Transmission short of all of it is not rendered (partial Alpha makes a cutout:
    tests/blender/test_cutouts.py)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    half = export_material(shader_material("Half", "ShaderNodeBsdfPrincipled",
                                           Transmission_Weight=0.5), warnings)
    assert not half.is_clear and not half.is_cutout
    assert warnings == ["material 'Half': Principled BSDF's Transmission Weight 0.5 is not "
                        "rendered (an opaque surface)"]


def sunlit_box_behind_clear_panes(kind: str, tint=(1.0, 1.0, 1.0, 1.0),
                                  pane_tint=(1.0, 1.0, 1.0, 1.0)) -> bpy.types.Scene:
    """``sunlit_box`` under a roof of material "Roof" (a ``kind`` node of colour ``tint``),
    with one of "Pane" (colour ``pane_tint``) between it and the camera (a window the camera
    looks through: the whole view passes it)."""
    scene = sunlit_box(lambda: shader_material("Roof", kind, Color=tint))
    pane = shader_material("Pane", kind, Color=pane_tint)
    bpy.ops.mesh.primitive_plane_add(size=6, location=(0, -4.0, 2.0),
                                     rotation=(math.radians(90), 0, 0))
    bpy.context.object.data.materials.append(pane)
    add_camera(scene, SIZE, (0.0, -7.0, 3.5), (math.radians(70), 0.0, 0.0)).data.lens = 30
    return scene


def test_light_and_the_camera_pass_a_transparent_pane_as_in_cycles(blender, tmp_path):
    """Direct sunlight through a white Transparent BSDF roof, seen through a second pane
    (Cycles 64 samples, 8 transparent bounces). Measured (bpy 4.5, llvmpipe): energy +0.0 %,
    relRMSE 1.3 %; the panes opaque (the export before clear materials): relRMSE 68 %."""
    scene = sunlit_box_behind_clear_panes("ShaderNodeBsdfTransparent")
    reference, ours = cycles_and_ours(scene, tmp_path, 64, 0, transparent=True)
    for name in ("Pane", "Roof"):
        tree = bpy.data.materials[name].node_tree
        tree.links.new(tree.nodes.new("ShaderNodeBsdfDiffuse").outputs[0],
                       tree.nodes["Material Output"].inputs["Surface"])
    opaque = render_linear(scene, "VPL_GI", tmp_path / "opaque.exr")

    assert_near_cycles("transparent panes", ours, reference, (0.02, 0.04), opaque,
                       "opaque panes", factor=10.0)


def test_light_through_a_tinted_roof_is_tinted_direct_and_indirect(blender, tmp_path):
    """The sun through an orange Transparent BSDF roof, with one diffuse bounce (Cycles 128
    samples): the ray-traced sun and the light paths are tinted by it. Measured (bpy 4.5,
    llvmpipe): energy per channel +0.1, +1.1, +1.9 %, relRMSE 2.5 %; the tint left out (the
    roof white): relRMSE 31 %."""
    scene = sunlit_box_behind_clear_panes("ShaderNodeBsdfTransparent", (0.9, 0.5, 0.2, 1.0))
    reference, ours = cycles_and_ours(scene, tmp_path, 128, 1, transparent=True)
    roof = bpy.data.materials["Roof"].node_tree.nodes["Transparent BSDF"]
    roof.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    white = render_linear(scene, "VPL_GI", tmp_path / "white.exr")

    assert np.isfinite(ours).all()
    channels = [against(ours[..., c:c + 1], reference[..., c:c + 1])[0] for c in range(3)]
    error = against(ours, reference)[1]
    white_error = against(white, reference)[1]
    print(f"tinted roof vs Cycles: energy per channel "
          f"{', '.join(f'{e:+.4f}' for e in channels)} relRMSE {error:.4f}; white roof: "
          f"relRMSE {white_error:.4f}")
    assert max(abs(e) for e in channels) < 0.03
    assert error < 0.05
    assert white_error > 5 * error


def test_the_camera_sees_through_a_tinted_pane_as_in_cycles(blender, tmp_path):
    """The whole view through a blue Transparent BSDF pane (Cycles 64 samples, 8 transparent
    bounces). Measured (bpy 4.5, llvmpipe): energy per channel +1.6, +0.8, +0.4 %, relRMSE
    2.3 %; the view through the pane not dimmed (the render before it was): red +239 %."""
    scene = sunlit_box_behind_clear_panes("ShaderNodeBsdfTransparent",
                                          pane_tint=(0.3, 0.6, 0.9, 1.0))
    reference, ours = cycles_and_ours(scene, tmp_path, 64, 0, transparent=True)
    undimmed = ours[..., :3] / np.array([0.3, 0.6, 0.9], np.float32)

    assert np.isfinite(ours).all()
    channels = [against(ours[..., c:c + 1], reference[..., c:c + 1])[0] for c in range(3)]
    error = against(ours, reference)[1]
    red_undimmed = against(undimmed[..., :1], reference[..., :1])[0]
    print(f"through a tinted pane vs Cycles: energy per channel "
          f"{', '.join(f'{e:+.4f}' for e in channels)} relRMSE {error:.4f}; the view not "
          f"dimmed: red {red_undimmed:+.4f}")
    assert max(abs(e) for e in channels) < 0.03
    assert error < 0.04
    assert red_undimmed > 1.0


def test_sky_light_through_a_tinted_roof_is_tinted(blender, tmp_path):
    """A white world's light through an orange Transparent BSDF roof, no sun (Cycles 128
    samples): the world's shadow-mapped samples (the default hybrid shadows) are dimmed by the
    shadow atlases' clear layers. Measured (bpy 4.5, llvmpipe): energy per channel +0.2,
    −0.1, −0.4 %, relRMSE 3.3 % (ray traced −0.2, +0.0, +0.2 %, 3.2 %); before the clear
    layers (the roof left out of the maps): blue +13.4 %."""
    scene = sunlit_box_behind_clear_panes("ShaderNodeBsdfTransparent", (0.9, 0.5, 0.2, 1.0))
    bpy.data.objects.remove(bpy.data.objects["Sun"])
    plain_world(scene, (1.0, 1.0, 1.0))
    reference, hybrid = cycles_and_ours(scene, tmp_path, 128, 0, transparent=True)
    scene.vpl_gi.direct_shadows = "ray_traced"
    traced = render_linear(scene, "VPL_GI", tmp_path / "traced.exr")
    results = {}
    for mode, ours in (("hybrid", hybrid), ("ray_traced", traced)):
        assert np.isfinite(ours).all()
        results[mode] = ([against(ours[..., c:c + 1], reference[..., c:c + 1])[0]
                          for c in range(3)], against(ours, reference)[1])
    for mode, (channels, error) in results.items():
        print(f"sky through a tinted roof vs Cycles, {mode}: energy per channel "
              f"{', '.join(f'{e:+.4f}' for e in channels)} relRMSE {error:.4f}")
        assert max(abs(e) for e in channels) < 0.03
        assert error < 0.06
