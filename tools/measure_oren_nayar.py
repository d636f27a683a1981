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
    from devtools.furnace import Furnace
    from tests.blender.rendering import shader_material

    bpy.ops.wm.read_factory_settings(use_empty=True)
    material = shader_material("Rough", "ShaderNodeBsdfPrincipled")
    node = material.node_tree.nodes["Principled BSDF"]
    if "Diffuse Roughness" in node.inputs:
        node.inputs["Specular IOR Level"].default_value = 0.0
        color, roughness = node.inputs["Base Color"], node.inputs["Diffuse Roughness"]
    else:
        material = shader_material("Rough", "ShaderNodeBsdfDiffuse")
        node = material.node_tree.nodes["Diffuse BSDF"]
        color, roughness = node.inputs["Color"], node.inputs["Roughness"]
    furnace = Furnace(material, 4, args.samples)
    print(f"Blender {bpy.app.version_string}: {node.bl_label}, this version's mode "
          f"{OREN_NAYAR_MULTISCATTER}")
    for rho in (0.5, 0.8):
        for sigma in (0.5, 1.0):
            color.default_value = (rho, rho, rho, 1.0)
            roughness.default_value = sigma
            for mu in (0.2, 0.5, 0.9):
                furnace.view_at(mu)
                measured = furnace.render()
                modes = [rho * oren_nayar.albedo_factor(np.full((1, 3), rho), sigma,
                                                        np.array([mu]), mode)[0, 0]
                         for mode in range(3)]
                print(f"ρ {rho} σ {sigma} μ {mu}: Cycles {measured:.4f}; modes "
                      + ", ".join(f"{m:.4f}" for m in modes))


if __name__ == "__main__":
    main()
