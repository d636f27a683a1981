"""The interior sample scene with a Sky Texture world (sun disc off, the sun lamp's direction,
strength 0.02), saved to a new .blend: a world VPL GI bakes with Cycles (addon/world_bake.py).

    .venv/bin/python tools/sky_interior.py OUT.blend
    .venv/bin/python -m devtools report OUT.blend --set bounces=4 --reference-samples 64
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SKY_STRENGTH = 0.02


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    args = parser.parse_args()
    import bpy
    from mathutils import Vector

    bpy.ops.wm.open_mainfile(filepath=str(REPO / "sample_scenes" / "interior.blend"))
    scene = bpy.context.scene
    tree = scene.world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sun_disc = False
    sun = next(o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN")
    towards = sun.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    sky.sun_elevation = math.asin(towards.z)
    sky.sun_rotation = math.atan2(towards.y, towards.x)
    background = tree.nodes["Background"]
    tree.links.new(sky.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = SKY_STRENGTH
    bpy.ops.wm.save_as_mainfile(filepath=str(args.output.resolve()), copy=True)


if __name__ == "__main__":
    main()
