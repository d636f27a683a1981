"""A camera's depth of field against Cycles: a checkered floor running from in front of the
plane of focus to the horizon, two boxes and a sphere at 2.5, 6 and 11 m, under a sun and a
blue sky, direct light only (Cycles: 256 samples, a one-pixel box filter; 160 × 90). Cycles'
own noise at 256 samples is 2.4–2.8 % relRMSE (two seeds), and most of VPL GI's error is at
silhouettes, where the layered blur cannot see what an object hides."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from addon.blender_compat import ensure_nodes
from tests.blender.rendering import (
    add_camera,
    add_primitive,
    add_sun,
    assert_near_cycles,
    cycles_and_ours,
    plain_world,
    render_linear,
    shader_material,
)

WIDTH, HEIGHT = 160, 90


def checker_floor() -> bpy.types.Material:
    """A Principled BSDF (roughness 1, no specular) of a 16 × 16 checker image, 4 squares a
    metre on a 30 m plane."""
    image = bpy.data.images.new("Checker", 64, 64, float_buffer=True)
    y, x = np.mgrid[0:64, 0:64]
    value = (((x // 4) + (y // 4)) % 2).astype(np.float32) * 0.75 + 0.05
    image.pixels.foreach_set(np.stack([value, value * 0.8, value * 0.6, np.ones_like(value)],
                                      -1).ravel())
    material = bpy.data.materials.new("Floor")
    ensure_nodes(material)
    tree = material.node_tree
    principled = tree.nodes["Principled BSDF"]
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image, texture.interpolation = image, "Closest"
    tree.links.new(texture.outputs[0], principled.inputs["Base Color"])
    principled.inputs["Roughness"].default_value = 1.0
    principled.inputs["Specular IOR Level"].default_value = 0.0
    return material


def depth_scene(focus: float, fstop: float, blades: int) -> bpy.types.Object:
    """The scene above with a 50 mm camera 1 m over the floor looking 10° down, focused at
    ``focus`` m with ``fstop`` and ``blades``; returns the camera."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    add_primitive("plane", checker_floor(), size=30)
    add_primitive("cube", shader_material("Red", "ShaderNodeBsdfDiffuse",
                                          Color=(0.8, 0.1, 0.1, 1)), size=0.5,
                  location=(0.4, -1.5, 0.25))
    add_primitive("cube", shader_material("Blue", "ShaderNodeBsdfDiffuse",
                                          Color=(0.1, 0.2, 0.8, 1)), size=1.0,
                  location=(-1.0, 2.0, 0.5))
    add_primitive("uv_sphere", shader_material("White", "ShaderNodeBsdfDiffuse",
                                                Color=(0.9, 0.9, 0.9, 1)), radius=0.6,
                  location=(1.2, 7.0, 0.6))
    add_sun(scene, (40, 0, 30), energy=3.0)
    plain_world(scene, (0.3, 0.4, 0.6))
    camera = add_camera(scene, WIDTH, location=(0, -4.0, 1.0),
                        rotation=(math.radians(80), 0, 0))
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    camera.data.lens = 50.0
    dof = camera.data.dof
    dof.use_dof, dof.focus_distance, dof.aperture_fstop = True, focus, fstop
    dof.aperture_blades, dof.aperture_rotation = blades, 0.3
    return camera


@pytest.mark.parametrize("focus, blades, bounds", [
    (4.0, 0, (0.01, 0.105)),  # a disc; circles of confusion up to 11 px
    (2.5, 6, (0.015, 0.10)),  # a hexagon, focused on the near box
])
def test_depth_of_field_as_in_cycles(blender, tmp_path, focus, blades, bounds):
    camera = depth_scene(focus, 0.125, blades)
    scene = bpy.context.scene
    reference, ours = cycles_and_ours(scene, tmp_path, 256, 0)
    camera.data.dof.use_dof = False
    sharp = render_linear(scene, "VPL_GI", tmp_path / "sharp.exr")
    assert_near_cycles(f"depth of field, focus {focus} m, {blades} blades", ours, reference,
                       bounds, sharp, "everything in focus")
