"""Benchmark scenes from OBJ assets (e.g. ../shared/assets' Sponza, Sibenik, Cornell box): the
mesh with its .mtl colours as pure diffuse materials, window panes open, a camera inside
looking along the longest horizontal axis, and a sun with a dim sky unless a material already
emits light."""

from __future__ import annotations

import math
from pathlib import Path

import bpy
from mathutils import Vector

from addon.blender_compat import ensure_nodes, uses_nodes

SUN_STRENGTH = 10.0
SKY = (0.03, 0.035, 0.045)


def _diffuse_only() -> bool:
    """Make every imported material pure diffuse (like for like with Cycles); True if any
    material emits light."""
    emits = False
    for material in bpy.data.materials:
        if not uses_nodes(material):
            continue
        for node in material.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                node.inputs["Roughness"].default_value = 1.0
                node.inputs["Specular IOR Level"].default_value = 0.0
                node.inputs["Metallic"].default_value = 0.0
                # the importer reads MTL transparency (Tf, d) as glass: Sibenik's stone walls
                # came in with Transmission Weight 1, its window panes (d < 1 or a coloured
                # Tf) with Alpha below 1 or a partial Transmission Weight; the panes are left
                # open (Alpha 0), so that light comes in alike in both renderers
                pane = node.inputs["Alpha"].default_value < 1.0 \
                    or 0.0 < node.inputs["Transmission Weight"].default_value < 1.0
                node.inputs["Transmission Weight"].default_value = 0.0
                node.inputs["Alpha"].default_value = 0.0 if pane else 1.0
                color = node.inputs["Emission Color"].default_value
                if node.inputs["Emission Strength"].default_value == 0 and max(color[:3]) > 1:
                    # Blender 4.2's importer puts Ke (17 12 4) in the colour and leaves the
                    # strength 0 (no emission); 4.5 and 5.x give colour Ke/17, strength 17.
                    peak = max(color[:3])
                    node.inputs["Emission Color"].default_value = (*(c / peak for c in
                                                                     color[:3]), 1.0)
                    node.inputs["Emission Strength"].default_value = peak
                strength = node.inputs["Emission Strength"].default_value
                emits |= strength > 0 and max(color[:3]) > 0
    return emits


def _bounds(objects: list[bpy.types.Object]) -> tuple[Vector, Vector]:
    corners = [o.matrix_world @ Vector(c) for o in objects for c in o.bound_box]
    low = Vector(tuple(min(c[i] for c in corners) for i in range(3)))
    high = Vector(tuple(max(c[i] for c in corners) for i in range(3)))
    return low, high


def _add_camera(scene: bpy.types.Scene, low: Vector, high: Vector) -> None:
    """Inside the bounds, a tenth from one end of the longest horizontal axis, looking along it."""
    size = high - low
    axis = 0 if size.x >= size.y else 1
    location = (low + high) / 2
    location[axis] = low[axis] + 0.1 * size[axis]
    location.z = low.z + 0.3 * size.z
    data = bpy.data.cameras.new("Camera")
    data.lens = 20.0
    camera = bpy.data.objects.new("Camera", data)
    camera.location = location
    target = Vector(location)
    target[axis] = high[axis]
    camera.rotation_euler = (target - location).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(camera)
    scene.camera = camera


def _add_sun_and_sky(scene: bpy.types.Scene) -> None:
    data = bpy.data.lights.new("Sun", "SUN")
    data.energy = SUN_STRENGTH
    sun = bpy.data.objects.new("Light.Sun", data)
    sun.rotation_euler = (math.radians(30), 0.0, math.radians(35))  # 60° high
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("Sky")
    ensure_nodes(world)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (*SKY, 1.0)
    scene.world = world


def scene_from_obj(path: Path) -> bpy.types.Scene:
    """A new file holding the OBJ asset set up as a benchmark scene (the asset is only read)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=str(path.resolve()), forward_axis="NEGATIVE_Z", up_axis="Y")
    scene = bpy.context.scene
    meshes = [o for o in scene.objects if o.type == "MESH"]
    if not meshes:
        raise ValueError(f"{path} holds no mesh")
    emits = _diffuse_only()
    _add_camera(scene, *_bounds(meshes))
    if not emits:
        _add_sun_and_sky(scene)
    return scene
