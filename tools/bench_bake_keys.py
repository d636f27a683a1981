"""Benchmark of the bake keys an export computes: eight 22.5k-face grids with a baked Noise
Texture material (64² bakes), exported 20 times with one ExportCache after a transform edit
each (the viewport's re-export, which reads no mesh and changes nothing a bake key holds).
Prints the median export time and the time spent in bake.bake_key over the 20 exports.

    .venv/bin/python tools/bench_bake_keys.py [--root CHECKOUT ...]

Each ``--root`` (default: this checkout) runs in its own process, importing its ``addon``:
give two to compare two versions in one run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXPORTS = 20


def noise_material(bpy, name: str):
    """A Diffuse BSDF coloured by Noise Texture → ColorRamp (baked: the export cannot read it)."""
    from addon.blender_compat import ensure_nodes

    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    shader = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    ramp = nodes.new("ShaderNodeValToRGB")
    links.new(nodes.new("ShaderNodeTexNoise").outputs["Fac"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], shader.inputs["Base Color"])
    return material


def measure() -> None:
    import bpy

    import addon
    from addon import bake
    from addon.export import ExportCache, export_scene

    addon.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.vpl_gi.bake_resolution = "64"
    for i in range(8):
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=150, y_subdivisions=150, size=2,
                                        location=(i * 2.2, 0, 0))
        bpy.context.active_object.data.materials.append(noise_material(bpy, f"Noise{i}"))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    bake.bake_scene(depsgraph)
    cache = ExportCache()
    export_scene(depsgraph, cache)
    spent = [0.0]
    key = bake.bake_key

    def timed(*args):
        start = time.perf_counter()
        try:
            return key(*args)
        finally:
            spent[0] += time.perf_counter() - start
    bake.bake_key = timed
    times = []
    for _ in range(EXPORTS):
        bpy.data.objects["Grid"].location.z += 0.01
        depsgraph = bpy.context.evaluated_depsgraph_get()
        start = time.perf_counter()
        exported = export_scene(depsgraph, cache)
        times.append(time.perf_counter() - start)
    assert all(m.base_color_texture is not None for i in exported.instances
               for m in i.materials), "the bakes were not used"
    print(f"export median {statistics.median(times) * 1e3:.1f} ms, bake_key "
          f"{spent[0] * 1e3 / EXPORTS:.1f} ms per export", flush=True)
    addon.unregister()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--root", action="append", type=Path, help="checkout to measure")
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        measure()
        return
    for root in args.root or [ROOT]:
        result = subprocess.run([sys.executable, "-B", str(Path(__file__).resolve()),
                                 "--measure"], cwd=root, capture_output=True, text=True,
                                env={**os.environ, "PYTHONPATH": str(root.resolve())}, check=False)
        lines = result.stdout.strip().splitlines()
        print(f"{root}: {lines[-1] if result.returncode == 0 and lines else result.stderr}")


if __name__ == "__main__":
    main()
