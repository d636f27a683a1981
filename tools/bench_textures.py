"""Cost of the texture path: the Cornell box rendered as it is and with every material's base
colour replaced by a 512×512 image of the same average colour (planar UVs), in one run.

The variants take turns rendering --repeat fresh frames each (nothing reused) with the default
settings; it prints the median frame time, the geometry, g-buffer and VPL-generation stages,
and whether the texture path (the TEXTURED g-buffer variant) was used.

    .venv/bin/python tools/bench_textures.py [--size 128] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from addon.core.frame.renderer import Renderer  # noqa: E402
from addon.core.scene.geometry import flatten_instances  # noqa: E402
from addon.core.scene.model import Scene, Texture  # noqa: E402
from addon.core.settings import Settings  # noqa: E402


def textured(scene: Scene, size: int = 512) -> Scene:
    """The scene with UVs from object-space x, y and a noisy texture per material whose
    average is the material's base colour."""
    rng = np.random.default_rng(0)
    for inst in scene.instances:
        mesh = inst.mesh
        mesh.uvs, mesh.uv_index = mesh.positions[:, :2].astype(np.float32), mesh.position_index
        for material in inst.materials:
            if material.base_color_texture is None:
                noise = rng.uniform(0.8, 1.2, size=(size, size, 1))
                pixels = np.ones((size, size, 4), np.float32)
                pixels[..., :3] = np.clip(np.asarray(material.base_color) * noise, 0, 1)
                material.base_color_texture = Texture(material.name, pixels)
    return scene


STAGES = ("geometry", "g-buffer", "vpl generation")


def measure(renderer: Renderer, scenes: dict[str, Scene], settings: Settings, repeat: int
            ) -> dict[str, dict[str, float]]:
    """Median frame and stage times per scene; the scenes take turns, so load from other
    processes falls on both alike."""
    times: dict[str, dict[str, list[float]]] = {
        name: {key: [] for key in ("frame", *STAGES)} for name in scenes}
    for _ in range(repeat):
        for name, scene in scenes.items():
            renderer.forget_frames()
            start = time.perf_counter()
            _, stats = renderer.render(scene, settings)
            times[name]["frame"].append(time.perf_counter() - start)
            for stage in STAGES:
                times[name][stage].append(sum(  # with variants: 'vpl generation (…)'
                    t for k, t in stats.timings.items() if k.split(" (")[0] == stage))
    return {name: {k: statistics.median(v) for k, v in t.items()} for name, t in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    import bpy

    from addon.export import export_scene

    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "sample_scenes" / "cornell_box.blend"),
                             load_ui=False)
    scene_data = bpy.context.scene
    scene_data.render.resolution_x = scene_data.render.resolution_y = args.size
    scene_data.render.resolution_percentage = 100
    plain = export_scene(bpy.context.evaluated_depsgraph_get())
    textured_scene = textured(export_scene(bpy.context.evaluated_depsgraph_get()))
    renderer = Renderer()
    try:
        scenes = {"untextured": plain, "textured": textured_scene}
        measure(renderer, scenes, Settings(), 1)  # warm-up: shader compilation
        results = measure(renderer, scenes, Settings(), args.repeat)
    finally:
        renderer.release()
    for name, s in scenes.items():
        r = results[name]
        print(f"{name:10s} texture path {flatten_instances(s, []).has_textures!s:5s} "
              f"frame {r['frame']:.3f} s, geometry {r['geometry'] * 1000:.1f} ms, "
              f"g-buffer {r['g-buffer'] * 1000:.1f} ms, "
              f"vpl generation {r['vpl generation'] * 1000:.1f} ms")
    ratio = results["textured"]["frame"] / results["untextured"]["frame"]
    print(f"textured / untextured frame time: {ratio:.3f} ({args.size}², default settings, "
          f"median of {args.repeat})")


if __name__ == "__main__":
    main()
