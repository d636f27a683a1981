"""HDRI worlds against Cycles: an equirectangular .hdr made in the test (a sky gradient and a
bright sun-like blob), read through an Environment Texture with a Mapping node's Z rotation,
lighting a box on a floor; a missing image; a Sky Texture baked by Cycles."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from addon import bake
from addon.blender_compat import ensure_nodes
from addon.export import export_world
from devtools.hdr import write_hdr
from tests.blender.rendering import add_camera, against, configure_cycles, render_linear

SIZE = 64
MAP_W, MAP_H = 128, 64
SUN_ELEVATION, SUN_AZIMUTH = math.radians(35), math.radians(50)  # as seen in the image
TURN = math.radians(70)  # the Mapping node's Z rotation


def sky_pixels() -> np.ndarray:
    """(h, w, 4) RGBA: a sky gradient above a grey ground, a sun blob (σ ≈ 3°) of 40 % of the
    power."""
    v = (np.arange(MAP_H) + 0.5) / MAP_H
    u = (np.arange(MAP_W) + 0.5) / MAP_W
    elevation, phi = np.pi * (v - 0.5)[:, None], 2 * np.pi * (0.5 - u)[None, :]
    d = np.stack(np.broadcast_arrays(np.cos(elevation) * np.cos(phi),
                                     np.cos(elevation) * np.sin(phi), np.sin(elevation)), -1)
    sun = np.array([math.cos(SUN_ELEVATION) * math.cos(SUN_AZIMUTH),
                    math.cos(SUN_ELEVATION) * math.sin(SUN_AZIMUTH), math.sin(SUN_ELEVATION)])
    up = np.clip(d[..., 2:3], 0, 1)
    rgb = 0.15 * (1 - up) + up * np.array([0.2, 0.35, 0.8])
    rgb = rgb + 150.0 * np.exp((d @ sun - 1) / 1.5e-3)[..., None] * np.array([1.0, 0.85, 0.6])
    return np.concatenate([rgb, np.ones((MAP_H, MAP_W, 1))], axis=-1).astype(np.float32)


def save_hdr(path) -> None:
    write_hdr(path, sky_pixels()[..., :3])


def hdri_world(image_path: str) -> bpy.types.World:
    world = bpy.data.worlds.new("HDRI")
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(image_path, check_existing=False)
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, TURN)
    coordinates = nodes.new("ShaderNodeTexCoord")
    links.new(coordinates.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    background = nodes["Background"]
    links.new(texture.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = 1.5
    return world


def box_on_floor() -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    material = bpy.data.materials.new("Grey")
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.7, 0.7, 0.7, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.object.data.materials.append(material)
    bpy.ops.mesh.primitive_cube_add(size=1.5, location=(0, 0, 0.75))
    bpy.context.object.data.materials.append(material)
    add_camera(scene, SIZE, (0.0, -7.0, 3.5), (math.radians(70), 0.0, 0.0)).data.lens = 24
    return scene


def test_hdri_world_matches_cycles_and_a_constant_world_does_not(blender, tmp_path):
    """Direct light and background of the HDRI (64 world samples, 16 samples per pixel;
    Cycles 256). Measured (bpy 4.5, llvmpipe): energy −0.8 %, relRMSE 2.7 % (the blob's core
    taken out as a sun light; all of it in the map: +0.5 %, 2.9 %); the same world as its
    constant mean colour: energy −19 %, relRMSE 53 %."""
    scene = box_on_floor()
    save_hdr(tmp_path / "sky.hdr")
    scene.world = hdri_world(str(tmp_path / "sky.hdr"))
    warnings: list[str] = []
    exported = export_world(scene.world, warnings)
    assert exported.environment is not None and not warnings
    assert exported.environment.rotation == pytest.approx(TURN)
    configure_cycles(scene, 256, bounces=0)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = 0, 4
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")
    # The failing case: the same world as one colour, the map's mean.
    scene.world = bpy.data.worlds.new("Mean")
    scene.world.use_nodes = True
    background = scene.world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*exported.color, 1.0)
    background.inputs["Strength"].default_value = exported.strength
    constant = render_linear(scene, "VPL_GI", tmp_path / "constant.exr")

    assert np.isfinite(ours).all()
    energy, error = against(ours, reference)
    constant_energy, constant_error = against(constant, reference)
    print(f"HDRI vs Cycles: energy {energy:+.4f} relRMSE {error:.4f}; constant mean world: "
          f"energy {constant_energy:+.4f} relRMSE {constant_error:.4f}")
    assert abs(energy) < 0.03
    assert error < 0.04
    assert constant_error > 3 * error


def test_missing_environment_image_is_one_warning_and_magenta(blender, tmp_path):
    scene = box_on_floor()
    save_hdr(tmp_path / "gone.hdr")
    scene.world = hdri_world(str(tmp_path / "gone.hdr"))
    (tmp_path / "gone.hdr").unlink()
    scene.world.node_tree.nodes["Environment Texture"].image.reload()
    warnings: list[str] = []
    exported = export_world(scene.world, warnings)
    assert len(warnings) == 1 and "could not be loaded" in warnings[0]
    np.testing.assert_allclose(exported.radiance, [1.5, 0.0, 1.5])
    scene.vpl_gi.bounces = 0
    image = render_linear(scene, "VPL_GI", tmp_path / "missing.exr")
    assert np.isfinite(image).all()
    top = image[-1, :, :3].mean(axis=0)  # sky
    np.testing.assert_allclose(top, [1.5, 0.0, 1.5], atol=1e-3)


def test_srgb_images_are_decoded_and_other_mappings_use_the_mean_colour(blender, tmp_path):
    """An 8-bit sRGB image of byte 128 is radiance 0.2159 (sRGB decoded, not 0.502); a Mapping
    node that turns about X is one warning and the map's mean colour without the map."""
    box_on_floor()
    linear = 1.5 * ((128 / 255 + 0.055) / 1.055) ** 2.4  # strength × decoded byte 128
    image = bpy.data.images.new("grey", 8, 4)  # 8-bit, sRGB
    image.pixels.foreach_set(np.tile(np.float32([0.5, 0.5, 0.5, 1.0]), 8 * 4))
    image.filepath_raw, image.file_format = str(tmp_path / "grey.png"), "PNG"
    image.save()
    world = hdri_world(str(tmp_path / "grey.png"))
    warnings: list[str] = []
    exported = export_world(world, warnings)
    assert not warnings and exported.environment is not None
    np.testing.assert_allclose(exported.environment.radiance, linear, rtol=2e-3)
    np.testing.assert_allclose(exported.radiance, [linear] * 3, rtol=2e-3)
    world.node_tree.nodes["Mapping"].inputs["Rotation"].default_value = (0.3, 0.0, TURN)
    exported = export_world(world, warnings)
    assert exported.environment is None and len(warnings) == 1
    assert "Mapping" in warnings[0]
    np.testing.assert_allclose(exported.radiance, [linear] * 3, rtol=2e-3)


def sky_world() -> bpy.types.World:
    """The running Blender's default Sky Texture (its sun disc on), the sun 35° high."""
    world = bpy.data.worlds.new("Sky")
    ensure_nodes(world)
    nodes, links = world.node_tree.nodes, world.node_tree.links
    sky = nodes.new("ShaderNodeTexSky")
    sky.sun_elevation, sky.sun_rotation = SUN_ELEVATION, SUN_AZIMUTH
    background = nodes["Background"]
    links.new(sky.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = 0.05
    return world


def test_sky_texture_world_is_baked_and_matches_cycles(blender, tmp_path):
    """A Sky Texture is baked by Cycles and lit like an HDRI, its sun disc as a sun light of
    the disc's size, height and azimuth (Blender's sun rotation counts from +Y towards +X);
    without the bake it is one colour, far off (64 world samples, 16 samples per pixel;
    Cycles 256). Measured (bpy 4.5, llvmpipe): energy −0.5 %, relRMSE 1.2 % (the disc left
    in the map, shadowed by the world samples' maps: +0.8 %, 8.5 %); the sun turned to −50°
    or 140° for our render only: 31 % both; the unbaked colour: energy −99.7 %, relRMSE
    112 %."""
    scene = box_on_floor()
    scene.world = sky_world()
    warnings: list[str] = []
    unbaked: set[str] = set()
    unread = export_world(scene.world, warnings, [], unbaked)
    assert unread.environment is None and unbaked == {"world 'Sky'"}
    assert len(warnings) == 1 and "'Sky Texture'" in warnings[0] and "not baked" in warnings[0]
    configure_cycles(scene, 256, bounces=0)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = 0, 4
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")  # bakes before it renders
    warnings, notes, lights = [], [], []
    baked = export_world(scene.world, warnings, notes, None, lights)
    assert baked.environment is not None and not warnings
    assert len(notes) == 1 and "baked by Cycles" in notes[0] and "sun disc" in notes[0]
    (sun,) = lights
    towards = sun.matrix[:3, 2]
    assert math.asin(towards[2]) == pytest.approx(SUN_ELEVATION, abs=math.radians(0.1))
    assert math.atan2(towards[1], towards[0]) == pytest.approx(math.pi / 2 - SUN_AZIMUTH,
                                                               abs=math.radians(0.1))
    sky = scene.world.node_tree.nodes["Sky Texture"]
    assert sun.sun_angle == pytest.approx(sky.sun_size, rel=0.05)
    assert np.isfinite(ours).all()
    energy, error = against(ours, reference)
    scene.world = bpy.data.worlds.new("One colour")
    ensure_nodes(scene.world)
    background = scene.world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*unread.color, 1.0)
    background.inputs["Strength"].default_value = unread.strength
    constant = render_linear(scene, "VPL_GI", tmp_path / "constant.exr")
    constant_energy, constant_error = against(constant, reference)
    print(f"Sky Texture vs Cycles: energy {energy:+.4f} relRMSE {error:.4f}; unbaked: energy "
          f"{constant_energy:+.4f} relRMSE {constant_error:.4f}")
    assert abs(energy) < 0.02
    assert error < 0.03
    assert constant_error > 3 * error


def camera_ray_world(grey: float) -> bpy.types.World:
    """The Sky Texture world whose camera rays see ``grey`` instead (Light Path's Is Camera
    Ray mixing the two: a backdrop unlike the light)."""
    world = sky_world()
    nodes, links = world.node_tree.nodes, world.node_tree.links
    mix = nodes.new("ShaderNodeMixRGB")
    mix.inputs["Color2"].default_value = (grey, grey, grey, 1.0)
    links.new(nodes.new("ShaderNodeLightPath").outputs["Is Camera Ray"], mix.inputs["Fac"])
    links.new(nodes["Sky Texture"].outputs["Color"], mix.inputs["Color1"])
    links.new(mix.outputs["Color"], nodes["Background"].inputs["Color"])
    return world


def test_world_showing_the_camera_a_backdrop_is_baked_twice(blender, tmp_path):
    """A world reading the ray type is baked as its light (Light Path's outputs 0, as direct
    light sampling evaluates it) and as the camera sees it: the box is lit by the sky, the
    background is the backdrop's grey, as in Cycles. Measured (bpy 4.5): energy −0.6 %,
    relRMSE 1.4 %. The Light Path node inside a node group is not baked: one colour and a
    warning."""
    scene = box_on_floor()
    scene.world = camera_ray_world(0.4)
    configure_cycles(scene, 256, bounces=0)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = 0, 4
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")
    exported = export_world(scene.world, [], [])
    assert exported.background is not None and exported.visible_sun is None
    np.testing.assert_allclose(exported.background.radiance, 0.4 * 0.05, rtol=1e-3)
    energy, error = against(ours, reference)
    print(f"camera backdrop vs Cycles: energy {energy:+.4f} relRMSE {error:.4f}")
    np.testing.assert_allclose(ours[-1, :, :3], 0.02, rtol=1e-3)  # the top row: backdrop
    assert abs(energy) < 0.02 and error < 0.03

    group = bpy.data.node_groups.new("Ray type", "ShaderNodeTree")
    group.interface.new_socket("Camera", in_out="OUTPUT", socket_type="NodeSocketFloat")
    output = group.nodes.new("NodeGroupOutput")
    group.links.new(group.nodes.new("ShaderNodeLightPath").outputs["Is Camera Ray"],
                    output.inputs["Camera"])
    nodes, links = scene.world.node_tree.nodes, scene.world.node_tree.links
    grouped = nodes.new("ShaderNodeGroup")
    grouped.node_tree = group
    links.new(grouped.outputs["Camera"], next(n for n in nodes if n.type == "MIX_RGB").inputs[0])
    nodes.remove(next(n for n in nodes if n.type == "LIGHT_PATH"))
    bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    warnings: list[str] = []
    unbaked: set[str] = set()
    exported = export_world(scene.world, warnings, [], unbaked)
    assert exported.environment is None and not unbaked
    assert len(warnings) == 1 and "node group" in warnings[0] and "Light Path" in warnings[0]


def test_world_bake_leaves_nothing_behind_even_when_interrupted(blender):
    """The bake's scene, sphere, material and image are removed after it and after Ctrl-C
    inside it, and the user's world is unchanged (its node tree's hash)."""
    from addon import world_bake
    from addon.bake_tree import tree_hash
    from tests.blender.test_bake import bake_interrupted, datablock_names

    scene = box_on_floor()
    scene.world = sky_world()
    before, tree = datablock_names(bpy), tree_hash(scene.world.node_tree)
    world_bake.clear()
    bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    assert world_bake.cached(scene.world) is not None
    assert datablock_names(bpy) == before and tree_hash(scene.world.node_tree) == tree

    scene.world.node_tree.nodes["Sky Texture"].sun_elevation = 0.3
    bake_interrupted(bpy, world_bake)
    assert datablock_names(bpy) == before and world_bake.cached(scene.world) is None


def test_gradient_world_is_baked_texel_by_texel_and_has_no_sun(blender):
    """A Gradient Texture (linear, on the world's default coordinates: the direction) gives
    each texel max(0, min(1, x)) of its centre's direction × strength, in Blender's
    equirectangular layout (core/scene/environment.py); no peak there is a sun disc."""
    from addon.core.scene.environment import pixel_solid_angles

    scene = box_on_floor()
    scene.world = bpy.data.worlds.new("Gradient")
    ensure_nodes(scene.world)
    nodes, links = scene.world.node_tree.nodes, scene.world.node_tree.links
    links.new(nodes.new("ShaderNodeTexGradient").outputs["Color"],
              nodes["Background"].inputs["Color"])
    nodes["Background"].inputs["Strength"].default_value = 2.0
    bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    warnings: list[str] = []
    lights: list = []
    exported = export_world(scene.world, warnings, [], None, lights)
    assert exported.environment is not None and not warnings and not lights
    radiance = exported.environment.radiance
    height, width = radiance.shape[:2]
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    x = np.cos(np.pi * (v[:, None] - 0.5)) * np.cos(2 * np.pi * (0.5 - u[None, :]))
    expected = 2.0 * np.clip(x, 0.0, 1.0)
    weight = pixel_solid_angles(height, width)[:, None]
    error = np.abs(radiance.mean(axis=2) - expected)
    assert float((error * weight).sum() / (expected * weight).sum()) < 0.01
    # the sphere's mean of max(0, x) is 1/4
    np.testing.assert_allclose(exported.radiance, [0.5, 0.5, 0.5], rtol=0.01)


def test_a_failed_world_bake_is_one_clear_problem_and_one_colour(blender, monkeypatch):
    """Cycles refusing the bake: the bake pass names the world and why, the export lights
    with one colour and says the bake failed, and no bake pass is asked for again."""
    from addon import world_bake

    def refused(*_args, **_kwargs):
        raise RuntimeError("Cycles' bake returned {'CANCELLED'}")
    scene = box_on_floor()
    scene.world = sky_world()
    world_bake.clear()
    monkeypatch.setattr(world_bake, "run_bake", refused)
    cache = bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    assert cache.world_seconds == 0.0
    assert cache.problems == ["world 'Sky': not baked: the bake failed: Cycles' bake returned "
                              "{'CANCELLED'}"]
    warnings: list[str] = []
    unbaked: set[str] = set()
    exported = export_world(scene.world, warnings, [], unbaked)
    assert exported.environment is None and not unbaked
    assert len(warnings) == 1 and "the bake failed" in warnings[0]
    world_bake.clear()
