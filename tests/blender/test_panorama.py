"""Panoramic cameras against Cycles: a grey floor with two boxes and a sphere round the camera,
a box above it, a sun and a blue sky, seen through each panorama type VPL GI renders (Cycles:
128 samples, a one-pixel box filter). The same scene through a perspective camera of the
same lens, what VPL GI rendered before, is 61–121 % off (relRMSE)."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

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


def panorama_scene(kind: str, width: int, height: int) -> bpy.types.Object:
    """The scene above with a panoramic camera of ``kind`` 1.2 m over the floor, looking
    level and turned 20° (fisheyes of 200°); returns the camera."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    red = shader_material("Red", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.1, 0.1, 1))
    blue = shader_material("Blue", "ShaderNodeBsdfDiffuse", Color=(0.1, 0.2, 0.8, 1))
    add_primitive("plane", grey, size=20)
    add_primitive("cube", red, size=1.0, location=(2.5, 0.5, 0.5))
    add_primitive("cube", blue, size=1.5, location=(-1.0, 3.0, 0.75))
    add_primitive("uv_sphere", grey, radius=0.7, location=(-2.0, -2.5, 0.7))
    add_primitive("cube", red, size=0.6, location=(0.3, -0.2, 3.0))
    add_sun(scene, (35, 0, 30), energy=3.0)
    plain_world(scene, (0.3, 0.4, 0.6))
    camera = add_camera(scene, width, location=(0.2, 0.1, 1.2),
                        rotation=(math.radians(90), 0, math.radians(20)))
    scene.render.resolution_x, scene.render.resolution_y = width, height
    camera.data.type, camera.data.panorama_type = "PANO", kind
    camera.data.fisheye_fov = math.radians(200)
    return camera


@pytest.mark.parametrize("kind, width, height, bounces, bounds", [
    ("EQUIRECTANGULAR", 128, 64, 2, (0.01, 0.045)),
    ("FISHEYE_EQUIDISTANT", 96, 64, 0, (0.01, 0.045)),
    ("FISHEYE_EQUISOLID", 96, 96, 0, (0.01, 0.045)),
    ("MIRRORBALL", 96, 96, 0, (0.01, 0.045)),
])
def test_panoramic_cameras_as_in_cycles(blender, tmp_path, kind, width, height, bounces,
                                        bounds):
    camera = panorama_scene(kind, width, height)
    scene = bpy.context.scene
    reference, ours = cycles_and_ours(scene, tmp_path, 128, bounces)
    camera.data.type = "PERSP"
    perspective = render_linear(scene, "VPL_GI", tmp_path / "perspective.exr")
    assert_near_cycles(f"{kind.lower()} panorama, {bounces} bounces", ours, reference, bounds,
                       perspective, "a perspective camera")


def test_the_automatic_mode_is_not_applied_to_a_panorama_and_says_so(blender, tmp_path):
    import addon.engine

    panorama_scene("EQUIRECTANGULAR", 64, 32)
    scene = bpy.context.scene
    scene.vpl_gi.auto_parameters = "time"
    image = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")
    assert addon.engine.monitor.last_error is None
    assert np.isfinite(image).all() and image[..., :3].mean() > 0.05
    assert addon.engine.monitor.last_warnings == [
        "automatic parameters are not applied to a panoramic camera: rendered with the "
        "settings as set"]
