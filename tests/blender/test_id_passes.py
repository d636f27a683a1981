"""The Object and Material Index passes and Cryptomatte against Cycles': a floor, two boxes
sharing a material, and a sphere parented to an empty (its asset), each object and material
with a Pass Index, read through the compositor as a user reads them (the Render Layers
node's sockets, the Cryptomatte node's matte by name). Cycles: 64 samples, a one-pixel box
filter. The index passes are one sample's, at the pixel's centre, so they differ at edges
only; Cryptomatte's coverage comes from VPL GI's 3 × 3 supersamples, Cycles' from its
samples."""

from __future__ import annotations

import json
import math
import re

import bpy
import numpy as np
import pytest

from addon.blender_compat import pass_name
from tests.blender.rendering import (
    add_camera,
    add_primitive,
    add_sun,
    configure_cycles,
    plain_world,
    render_linear,
    shader_material,
)
from tests.blender.versions import compositor_output

SIZE = 48
INDICES = {"Floor": 2, "Box": 3, "Box.001": 4, "Ball": 5}
MATERIAL_INDICES = {"Ground": 7, "Red": 8, "Blue": 9}


def id_scene() -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    ground = shader_material("Ground", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    red = shader_material("Red", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.1, 0.1, 1))
    blue = shader_material("Blue", "ShaderNodeBsdfDiffuse", Color=(0.1, 0.1, 0.8, 1))
    objects = [add_primitive("plane", ground, size=20),
               add_primitive("cube", red, size=1.0, location=(-0.9, 3.0, 0.5)),
               add_primitive("cube", red, size=1.0, location=(0.9, 4.0, 0.5)),
               add_primitive("uv_sphere", blue, radius=0.7, location=(0.0, 5.5, 0.7))]
    for obj, name in zip(objects, INDICES, strict=True):
        obj.name = name
        obj.pass_index = INDICES[name]
    for material in (ground, red, blue):
        material.pass_index = MATERIAL_INDICES[material.name]
    rig = bpy.data.objects.new("Rig", None)
    scene.collection.objects.link(rig)
    objects[3].parent = rig  # the sphere's asset is the empty
    add_sun(scene, (40, 0, 30))
    plain_world(scene, (0.2, 0.3, 0.5))
    add_camera(scene, SIZE, location=(0, -1.0, 1.8), rotation=(math.radians(75), 0, 0))
    layer = scene.view_layers[0]
    layer.use_pass_object_index = layer.use_pass_material_index = True
    layer.use_pass_cryptomatte_object = layer.use_pass_cryptomatte_material = True
    layer.use_pass_cryptomatte_asset = True
    configure_cycles(scene, 64)
    return scene


def through_compositor(scene: bpy.types.Scene, engine: str, path, source: str,
                       matte: tuple[str, str] | None = None) -> np.ndarray:
    """The Render Layers node's ``source`` socket, or with ``matte`` = (layer, names) the
    Cryptomatte node's Matte for those names, as rendered by ``engine``."""
    scene.render.engine = engine
    tree, output = compositor_output(scene)
    layers = tree.nodes.new("CompositorNodeRLayers")
    if matte is None:
        tree.links.new(layers.outputs[source], output)
    else:
        node = tree.nodes.new("CompositorNodeCryptomatteV2")
        node.source, node.scene = "RENDER", scene
        node.layer_name = f"{scene.view_layers[0].name}.{matte[0]}"
        node.matte_id = matte[1]
        tree.links.new(layers.outputs["Image"], node.inputs["Image"])
        tree.links.new(node.outputs["Matte"], output)
    return render_linear(scene, engine, path)[..., 0]


@pytest.mark.parametrize("name", ["IndexOB", "IndexMA"])
def test_the_index_passes_are_cycles(blender, tmp_path, name):
    scene = id_scene()
    socket = pass_name(name)
    reference = through_compositor(scene, "CYCLES", tmp_path / "cycles.exr", socket)
    ours = through_compositor(scene, "VPL_GI", tmp_path / "ours.exr", socket)
    same = ours == reference
    print(f"{name} vs Cycles: {same.mean():.3f} of pixels equal, values "
          f"{sorted(np.unique(ours).tolist())}")
    expected = set(INDICES.values() if name == "IndexOB" else MATERIAL_INDICES.values())
    assert set(np.unique(reference).tolist()) == expected | {0.0}  # the scene is all seen
    assert set(np.unique(ours).tolist()) == expected | {0.0}
    assert same.mean() > 0.97  # edges only


@pytest.mark.parametrize(("layer", "names"), [
    ("CryptoObject", "Box"), ("CryptoObject", "Ball, Floor"),
    ("CryptoMaterial", "Red"), ("CryptoAsset", "Rig")])
def test_cryptomatte_mattes_are_cycles(blender, tmp_path, layer, names):
    scene = id_scene()
    reference = through_compositor(scene, "CYCLES", tmp_path / "cycles.exr", "",
                                   (layer, names))
    ours = through_compositor(scene, "VPL_GI", tmp_path / "ours.exr", "", (layer, names))
    error = np.abs(ours - reference)
    print(f"{layer} '{names}' matte vs Cycles: covers {reference.mean():.3f} "
          f"(ours {ours.mean():.3f}), mean abs {error.mean():.4f}, "
          f"pixels over 0.2: {(error > 0.2).mean():.3f}")
    assert reference.mean() > 0.02 and reference.max() == pytest.approx(1.0)
    assert abs(ours.mean() - reference.mean()) < 0.01
    assert error.mean() < 0.01
    assert (error > 0.2).mean() < 0.02  # edges only: 9 supersamples against 64 samples


def exr_attribute(path, key: str) -> str:
    """A string attribute of an EXR file's header."""
    data = path.read_bytes()
    start = data.index(key.encode() + b"\0string\0") + len(key) + 8
    length = int.from_bytes(data[start:start + 4], "little")
    return data[start + 4:start + 4 + length].decode()


def test_cryptomatte_metadata_is_cycles(blender, tmp_path):
    """A multilayer EXR of VPL GI's render carries the same layer names and hashes as Cycles':
    the keys compositors (Blender's, Nuke's) find the manifest by."""
    scene = id_scene()
    images = scene.render.image_settings
    if hasattr(images, "media_type"):  # 5.x
        images.media_type = "MULTI_LAYER_IMAGE"
    else:
        images.file_format = "OPEN_EXR_MULTILAYER"
    manifests = {}
    for engine in ("CYCLES", "VPL_GI"):
        scene.render.engine = engine
        bpy.ops.render.render()
        path = tmp_path / f"{engine}.exr"
        bpy.data.images["Render Result"].save_render(filepath=str(path), scene=scene)
        header = path.read_bytes()[:200_000]
        keys = sorted(set(re.findall(rb"cryptomatte/[0-9a-f]{7}/name", header)))
        names = {exr_attribute(path, k.decode()) for k in keys}
        assert names == {"ViewLayer.CryptoObject", "ViewLayer.CryptoMaterial",
                         "ViewLayer.CryptoAsset"}
        manifests[engine] = {exr_attribute(path, k.decode()): exr_attribute(
            path, k.decode().replace("/name", "/manifest")) for k in keys}
    for layer, manifest in manifests["VPL_GI"].items():
        ours, cycles = json.loads(manifest), json.loads(manifests["CYCLES"][layer])
        print(f"{layer}: ours {ours}")
        assert ours and all(cycles.get(name) == value for name, value in ours.items())


def test_a_panorama_has_the_id_passes_of_cycles(blender, tmp_path):
    """An equirectangular camera in the middle of the scene: the faces' IDs are read at the
    nearest face pixel, never blended (a blend of two ids is a third, wrong id)."""
    scene = id_scene()
    scene.camera.location, scene.camera.rotation_euler = (0, 3.5, 1.0), (math.radians(90), 0, 0)
    scene.camera.data.type, scene.camera.data.panorama_type = "PANO", "EQUIRECTANGULAR"
    scene.render.resolution_x, scene.render.resolution_y = 96, 48
    socket = pass_name("IndexOB")
    reference = through_compositor(scene, "CYCLES", tmp_path / "cycles.exr", socket)
    ours = through_compositor(scene, "VPL_GI", tmp_path / "ours.exr", socket)
    same = (ours == reference).mean()
    matte = [through_compositor(scene, engine, tmp_path / f"{engine}.exr", "",
                                ("CryptoObject", "Box")) for engine in ("CYCLES", "VPL_GI")]
    error = np.abs(matte[1] - matte[0])
    print(f"panorama: IndexOB {same:.3f} of pixels equal; 'Box' matte covers "
          f"{matte[0].mean():.3f} (ours {matte[1].mean():.3f}), mean abs {error.mean():.4f}")
    assert set(np.unique(ours).tolist()) == set(np.unique(reference).tolist())
    assert same > 0.95
    assert matte[0].mean() > 0.02 and abs(matte[1].mean() - matte[0].mean()) < 0.01
    assert error.mean() < 0.01
