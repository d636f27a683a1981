"""The interior sample scene with its sky built as users build it, saved to a new .blend:

- ``sky`` (default): a Sky Texture world (the sun lamp's direction, its sun disc off,
  strength 0.02), which VPL GI bakes with Cycles (addon/world_bake.py);
- ``sun-disc``: the same with its sun disc on, strength 0.05, and the lamp removed;
- ``hdri``: an equirectangular HDRI written beside OUT.blend (a sky gradient and a 0.53° sun
  disc of the lamp's irradiance in its direction) through an Environment Texture, the lamp
  removed: the disc becomes a sun light (core/scene/sun_disc.py).

``--glass glass`` glazes the window with an 8 mm pane of Glass BSDF (IOR 1.5); ``--glass
transparent`` with a pane of white Transparent BSDF; ``--glass trick`` with archviz glass:
Glass BSDF for camera and bounce rays, Transparent BSDF for shadow rays (Light Path's Is
Shadow Ray).

    .venv/bin/python tools/sky_interior.py OUT.blend [--world sky|sun-disc|hdri]
    .venv/bin/python -m devtools report OUT.blend --set bounces=4 --reference-samples 64
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SKY_STRENGTH = 0.02
SUN_DISC_STRENGTH = 0.05  # the disc's light on the floor about the lamp's (4 W/m²)
HDRI_SIZE = (2048, 1024)
HDRI_SUN_ANGLE = math.radians(0.53)
WINDOW_X, WINDOW_Y, WINDOW_Z = (-0.4, 1.2), (-2.104, -2.096), (0.9, 2.3)  # build_scenes.py
HDRI_ZENITH, HDRI_HORIZON, HDRI_GROUND = (0.02, 0.035, 0.08), (0.06, 0.065, 0.07), 0.02


def hdri_pixels(towards: np.ndarray, irradiance: float) -> np.ndarray:
    """(h, w, 3) linear RGB rows bottom-up in Blender's equirectangular layout: a gradient
    from the horizon to the zenith, a grey ground, and a disc of ``irradiance`` (W/m²) around
    ``towards``."""
    from addon.core.scene.environment import equirect_directions

    width, height = HDRI_SIZE
    d = equirect_directions(((np.arange(width) + 0.5) / width)[None, :],
                            ((np.arange(height) + 0.5) / height)[:, None])
    up = np.clip(d[..., 2:3], 0.0, 1.0)
    sky = np.array(HDRI_HORIZON) * (1 - up) + np.array(HDRI_ZENITH) * up
    rgb = np.where(d[..., 2:3] > 0, sky, HDRI_GROUND)
    half = HDRI_SUN_ANGLE / 2
    rgb[d @ towards > math.cos(half)] = irradiance / (2 * np.pi * (1 - math.cos(half))) * \
        np.array([1.0, 0.95, 0.85])
    return rgb.astype(np.float32)


def add_pane(kind: str) -> None:
    """An 8 mm box filling the window, of Glass BSDF (IOR 1.5), white Transparent BSDF, or
    the two mixed by Is Shadow Ray (``trick``)."""
    import bpy

    from addon.blender_compat import ensure_nodes

    centre = [sum(span) / 2 for span in (WINDOW_X, WINDOW_Y, WINDOW_Z)]
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=centre)
    pane = bpy.context.active_object
    pane.name = "Window.Pane"
    pane.scale = [span[1] - span[0] for span in (WINDOW_X, WINDOW_Y, WINDOW_Z)]
    material = bpy.data.materials.new(f"Window {kind}")
    ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    glass, transparent = (tree.nodes.new("ShaderNodeBsdfGlass"),
                          tree.nodes.new("ShaderNodeBsdfTransparent"))
    glass.inputs["IOR"].default_value = 1.5
    glass.inputs["Roughness"].default_value = 0.0
    shader = glass if kind == "glass" else transparent
    if kind == "trick":
        shader = tree.nodes.new("ShaderNodeMixShader")
        tree.links.new(tree.nodes.new("ShaderNodeLightPath").outputs["Is Shadow Ray"],
                       shader.inputs["Fac"])
        tree.links.new(glass.outputs[0], shader.inputs[1])
        tree.links.new(transparent.outputs[0], shader.inputs[2])
    tree.links.new(shader.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    pane.data.materials.append(material)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    parser.add_argument("--world", choices=("sky", "sun-disc", "hdri"), default="sky")
    parser.add_argument("--glass", choices=("none", "glass", "transparent", "trick"),
                        default="none")
    args = parser.parse_args()
    import bpy
    from mathutils import Vector

    from devtools.hdr import write_hdr

    bpy.ops.wm.open_mainfile(filepath=str(REPO / "sample_scenes" / "interior.blend"))
    scene = bpy.context.scene
    tree = scene.world.node_tree
    sun = next(o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN")
    towards = sun.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    background = tree.nodes["Background"]
    if args.world == "hdri":
        path = args.output.resolve().with_suffix(".hdr")
        write_hdr(path, hdri_pixels(np.array(towards), sun.data.energy))
        texture = tree.nodes.new("ShaderNodeTexEnvironment")
        texture.image = bpy.data.images.load(str(path))
        tree.links.new(texture.outputs["Color"], background.inputs["Color"])
        background.inputs["Strength"].default_value = 1.0
    else:
        sky = tree.nodes.new("ShaderNodeTexSky")
        sky.sun_disc = args.world == "sun-disc"
        sky.sun_elevation = math.asin(towards.z)
        sky.sun_rotation = math.pi / 2 - math.atan2(towards.y, towards.x)  # from +Y to +X
        tree.links.new(sky.outputs["Color"], background.inputs["Color"])
        background.inputs["Strength"].default_value = SUN_DISC_STRENGTH if sky.sun_disc \
            else SKY_STRENGTH
    if args.world != "sky":
        bpy.data.objects.remove(sun)
    if args.glass != "none":
        add_pane(args.glass)
    bpy.ops.wm.save_as_mainfile(filepath=str(args.output.resolve()), copy=True)


if __name__ == "__main__":
    main()
