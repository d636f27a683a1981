"""Bad scene input through the engine (F12's path): one clear error, or a warning and a
finished, finite frame (issue 19). The command line's rows are in test_cli.py."""

from __future__ import annotations

import numpy as np
import pytest

import addon.engine
from tests.blender.rendering import render_linear
from tests.blender.test_export import add_light, add_plane, new_scene
from tests.blender.test_textures import textured_material, with_uvs


def lit_plane_scene(bpy):
    """A 3 m plane under a sun, seen from above, one bounce with exact visibility."""
    scene = new_scene(bpy, 16)
    scene.vpl_gi.bounces, scene.vpl_gi.vpl_count, scene.vpl_gi.visibility = 1, 16, "exact"
    plane = add_plane(bpy, "Plane", 3.0)
    add_light(bpy, "SUN", 2.0)
    return scene, plane


def render(scene, tmp_path) -> tuple[np.ndarray, list[str]]:
    """The finished frame and its warnings; fails on an error."""
    image = render_linear(scene, "VPL_GI", tmp_path / "frame.exr")
    assert addon.engine.monitor.last_error is None, addon.engine.monitor.last_error
    assert np.isfinite(image).all()
    return image, list(addon.engine.monitor.last_warnings)


def render_error(scene, tmp_path) -> str:
    """The engine's error message (Blender raises it from the render operator)."""
    with pytest.raises(RuntimeError):
        render_linear(scene, "VPL_GI", tmp_path / "frame.exr")
    message = addon.engine.monitor.last_error
    assert message and "internal error" not in message
    return message


def test_float_texture_with_nan_and_inf_texels_is_read_as_0_with_one_warning(blender,
                                                                             tmp_path):
    bpy = blender
    scene, plane = lit_plane_scene(bpy)
    image = bpy.data.images.new("Broken", 4, 4, float_buffer=True)
    texels = np.full((4, 4, 4), 0.5, np.float32)
    texels[0, 0, 0], texels[1, 1, 1], texels[2, 2, 2] = np.nan, np.inf, -np.inf
    image.pixels.foreach_set(texels.ravel())
    image.pack()
    with_uvs(plane)
    plane.data.materials.append(textured_material(bpy, "Textured", image,
                                                  **{"Specular IOR Level": 0.0}))
    frame, warnings = render(scene, tmp_path)
    assert warnings == ["image 'Broken': 3 NaN/Inf values read as 0 (as if black there)"]
    assert frame[..., :3].mean() > 0.1


@pytest.mark.parametrize("change, message", [
    ("scale 0", "camera 'Camera' has a transform without an inverse (a scale of 0"),
    ("empty", "the scene camera 'Empty' is not a camera but an object of type Empty"),
])
def test_camera_that_cannot_be_rendered_from_is_one_clear_error(blender, tmp_path, change,
                                                                message):
    bpy = blender
    scene, _ = lit_plane_scene(bpy)
    if change == "scale 0":
        scene.camera.scale = (0.0, 0.0, 0.0)
    else:
        empty = bpy.data.objects.new("Empty", None)
        empty.location = (0, 0, 5)
        scene.collection.objects.link(empty)
        scene.camera = empty
    assert render_error(scene, tmp_path).startswith(message)


def test_panoramic_camera_renders_as_perspective_with_a_warning(blender, tmp_path):
    bpy = blender
    scene, _ = lit_plane_scene(bpy)
    scene.camera.data.type = "PANO"
    _, warnings = render(scene, tmp_path)
    assert warnings == ["camera 'Camera' is panoramic, which VPL GI does not render: rendered "
                        "as a perspective camera of the same lens"]


@pytest.mark.parametrize("energy, warning", [
    (-5.0, "light 'PointLight' has negative power (-5 W): rendered as 0 W"),
    (float("inf"), "light 'PointLight' has NaN/Inf settings or transform and was left out"),
])
def test_negative_or_infinite_light_power_is_left_out_with_a_warning(blender, tmp_path, energy,
                                                                     warning, recwarn):
    bpy = blender
    scene, _ = lit_plane_scene(bpy)
    add_light(bpy, "POINT", energy, location=(0, 0, 1))
    bpy.data.objects.remove(bpy.data.objects["SunLight"])
    add_light(bpy, "SUN", 2.0)
    frame, warnings = render(scene, tmp_path)
    assert warnings == [warning]
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    scene.collection.objects.unlink(bpy.data.objects["PointLight"])
    without, _ = render(scene, tmp_path)
    np.testing.assert_array_equal(frame, without)


def test_negative_emission_strength_is_rendered_as_0_with_a_warning(blender, tmp_path):
    bpy = blender
    scene, plane = lit_plane_scene(bpy)
    material = bpy.data.materials.new("Dark")
    material.use_nodes = True
    node = material.node_tree.nodes["Principled BSDF"]
    node.inputs["Emission Color"].default_value = (1, 1, 1, 1)
    node.inputs["Emission Strength"].default_value = -3.0
    plane.data.materials.append(material)
    _, warnings = render(scene, tmp_path)
    assert "material 'Dark': emission (-3.0, -3.0, -3.0) is negative or not finite: rendered as " \
           "0 there" in warnings
