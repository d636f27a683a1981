"""Measure Cycles' sheen (the Principled BSDF's microfiber sheen layer, Blender 4.0+) for
core/scene/sheen.py, on a 17 × 17 grid of roughness r × the view's cosine μ:

- its albedo R(μ, r): the share of light a sheen of weight 1 and white tint reflects
  towards the view, from a render of a plane of that sheen alone (black base, Specular IOR
  Level 0) seen at μ by an orthographic camera under a uniform white world, so that every
  pixel reads the albedo;
- its lobe: the same plane under a sun of angle 0 from LIGHTS directions (a sun's light is
  sampled exactly: one sample a pixel), fitted by a linearly transformed cosine
  D(ω) = D_o(M⁻¹ω / |M⁻¹ω|) a² / |M⁻¹ω|³, M⁻¹ = (a x + b z, a y, z) in the frame whose x
  is the view's projection on the surface (Zeltner et al. 2022's form), so that the BRDF
  times the light's cosine is R(μ) D(ω).

Writes addon/core/scene/sheen_table.json (about a minute).

    .venv/bin/python tools/measure_sheen.py [--samples 1024] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
OUT = ROOT / "addon" / "core" / "scene" / "sheen_table.json"
NODES = 17  # roughness and cos(view) nodes
SIZE = 8  # pixels across each render
LIGHT_COSINES = (0.05, 0.2, 0.4, 0.6, 0.8, 0.95)
LIGHT_AZIMUTHS = (0.0, 45.0, 90.0, 135.0, 180.0)  # degrees from the view's side


def light_directions() -> np.ndarray:
    """The suns' directions (n, 3) in the frame of the view's projection (x) and the normal
    (z): the lobe is symmetric about the plane of view and normal, so y ≥ 0."""
    out = [(math.sqrt(1 - c * c) * math.cos(math.radians(a)),
            math.sqrt(1 - c * c) * math.sin(math.radians(a)), c)
           for c in LIGHT_COSINES for a in LIGHT_AZIMUTHS]
    return np.array([*out, (0.0, 0.0, 1.0)])


def sheen_furnace(bpy, samples: int):
    """A plane of sheen alone in a furnace (devtools/furnace.py), a sun of angle 0 (off),
    and the sheen's Principled BSDF."""
    from devtools.furnace import Furnace
    from tests.blender.test_cycles_principled import principled_material
    from tests.blender.test_sheen import velvet

    bpy.ops.wm.read_factory_settings(use_empty=True)
    material = velvet(principled_material("Sheen", (0.0, 0.0, 0.0), 0.5, level=0.0))
    furnace = Furnace(material, SIZE, samples)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.angle, sun.data.energy = 0.0, 0.0
    furnace.scene.collection.objects.link(sun)
    return furnace, sun, material.node_tree.nodes["Principled BSDF"]


def ltc(a: float, b: float, light: np.ndarray) -> np.ndarray:
    """The transformed cosine D at local light directions (n, 3)."""
    o = np.stack([a * light[:, 0] + b * light[:, 2], a * light[:, 1], light[:, 2]], axis=1)
    length = np.linalg.norm(o, axis=1)
    return np.maximum(o[:, 2] / length, 0.0) / math.pi * a * a / length**3


def fit(values: np.ndarray, albedo: float, lights: np.ndarray) -> tuple[float, float, float]:
    """(a, b, relative RMS residual) of the lobe through ``values`` (BRDF × cosine)."""
    from scipy.optimize import least_squares

    if albedo < 1e-4:
        return 1.0, 0.0, 0.0
    result = least_squares(lambda p: albedo * ltc(p[0], p[1], lights) - values, [0.5, 0.0],
                           bounds=([0.01, -2.0], [4.0, 2.0]))
    residual = math.sqrt(np.mean(result.fun**2) / max(np.mean(values**2), 1e-30))
    return float(result.x[0]), float(result.x[1]), residual


def measure(samples: int) -> dict:
    """The tables: rows by roughness, columns by the view's cosine."""
    import bpy
    from mathutils import Vector

    from devtools.furnace import GRAZING

    furnace, sun, bsdf = sheen_furnace(bpy, samples)
    nodes = np.linspace(0.0, 1.0, NODES)
    albedo, a, b, residual = (np.zeros((NODES, NODES)) for _ in range(4))
    lights = light_directions()
    start = time.perf_counter()
    for i, r in enumerate(nodes):
        bsdf.inputs["Sheen Roughness"].default_value = float(r)
        for j, mu in enumerate(nodes):
            furnace.view_at(mu)  # the view's projection is -y: local x = -y, y = +x, z = z
            furnace.world_color.default_value = (1, 1, 1, 1)
            sun.data.energy = 0.0
            furnace.scene.cycles.samples = samples
            albedo[i, j] = furnace.render()
            furnace.world_color.default_value = (0, 0, 0, 1)
            sun.data.energy = 1.0
            furnace.scene.cycles.samples = 1
            values = []
            for light in lights:
                world_direction = Vector((light[1], -light[0], light[2]))
                sun.rotation_euler = world_direction.to_track_quat("Z", "Y").to_euler()
                values.append(furnace.render())
            a[i, j], b[i, j], residual[i, j] = fit(np.array(values), albedo[i, j], lights)
        print(f"roughness {r:.3f}: albedo " + " ".join(f"{v:.3f}" for v in albedo[i])
              + f"; a {a[i].min():.2f}–{a[i].max():.2f}, b {b[i].min():+.2f}–"
              f"{b[i].max():+.2f}, residual ≤ {residual[i].max():.3f}"
              f"  ({time.perf_counter() - start:.0f} s)", flush=True)
    return {"blender": bpy.app.version_string, "samples": samples, "grazing_cosine": GRAZING,
            "roughness": nodes.round(6).tolist(), "cos_view": nodes.round(6).tolist(),
            "albedo": albedo.round(5).tolist(), "ltc_a": a.round(5).tolist(),
            "ltc_b": b.round(5).tolist(), "fit_residual": residual.round(4).tolist()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=1024)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    table = measure(args.samples)
    args.out.write_text(json.dumps(table, indent=1) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
