"""Measure Cycles' rough diffuse lobe against core/scene/oren_nayar.py: renders a plane of a
Principled BSDF of Diffuse Roughness σ (a Diffuse BSDF's Roughness on Blender 4.2, which has
no Diffuse Roughness) and colour ρ under a uniform white world, seen at cosine μ by an
orthographic camera, so that every pixel reads the lobe's albedo ρ × albedo_factor; prints
it beside each multiple-scattering mode's prediction and the mode that is this Blender's
(blender_compat.OREN_NAYAR_MULTISCATTER).

    .venv/bin/python tools/measure_oren_nayar.py [--samples 1024]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=1024)
    args = parser.parse_args()

    import bpy

    from addon.blender_compat import OREN_NAYAR_MULTISCATTER
    from addon.core.scene import oren_nayar
    from tests.blender.rendering import configure_cycles, shader_material

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    configure_cycles(scene, args.samples, bounces=0)
    scene.render.resolution_x = scene.render.resolution_y = 4
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("White")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1, 1, 1, 1)
    scene.world = world
    bpy.ops.mesh.primitive_plane_add(size=1000.0)
    principled = shader_material("Rough", "ShaderNodeBsdfPrincipled")
    node = principled.node_tree.nodes["Principled BSDF"]
    if "Diffuse Roughness" in node.inputs:
        node.inputs["Specular IOR Level"].default_value = 0.0
        color, roughness = node.inputs["Base Color"], node.inputs["Diffuse Roughness"]
        material = principled
    else:
        material = shader_material("Rough", "ShaderNodeBsdfDiffuse")
        node = material.node_tree.nodes["Diffuse BSDF"]
        color, roughness = node.inputs["Color"], node.inputs["Roughness"]
    bpy.context.object.data.materials.append(material)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type, camera.data.ortho_scale = "ORTHO", 0.1
    scene.collection.objects.link(camera)
    scene.camera = camera
    path = Path(bpy.app.tempdir or "/tmp") / "oren_nayar_measure.exr"
    scene.render.filepath = str(path)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    print(f"Blender {bpy.app.version_string}: {node.bl_label}, this version's mode "
          f"{OREN_NAYAR_MULTISCATTER}")
    for rho in (0.5, 0.8):
        for sigma in (0.5, 1.0):
            color.default_value = (rho, rho, rho, 1.0)
            roughness.default_value = sigma
            for mu in (0.2, 0.5, 0.9):
                theta = math.acos(mu)
                camera.location = (0.0, -10.0 * math.sin(theta), 10.0 * math.cos(theta))
                camera.rotation_euler = (theta, 0.0, 0.0)
                bpy.ops.render.render(write_still=True)
                image = bpy.data.images.load(str(path))
                measured = float(np.asarray(image.pixels[:]).reshape(-1, 4)[:, 0].mean())
                bpy.data.images.remove(image)
                modes = [rho * oren_nayar.albedo_factor(np.full((1, 3), rho), sigma,
                                                        np.array([mu]), mode)[0, 0]
                         for mode in range(3)]
                print(f"ρ {rho} σ {sigma} μ {mu}: Cycles {measured:.4f}; modes "
                      + ", ".join(f"{m:.4f}" for m in modes))


if __name__ == "__main__":
    main()
