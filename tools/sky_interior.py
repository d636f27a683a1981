"""The interior sample scene with a Sky Texture world (the sun lamp's direction; its sun disc
off, strength 0.02; or with ``--sun-disc`` the disc on, strength 0.05, and the lamp removed),
saved to a new .blend: a world VPL GI bakes with Cycles (addon/world_bake.py).

    .venv/bin/python tools/sky_interior.py OUT.blend [--sun-disc]
    .venv/bin/python -m devtools report OUT.blend --set bounces=4 --reference-samples 64
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SKY_STRENGTH = 0.02
SUN_DISC_STRENGTH = 0.05  # the disc's light on the floor about the lamp's (4 W/m²)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", type=Path)
    parser.add_argument("--sun-disc", action="store_true",
                        help="the sky's sun disc instead of the sun lamp")
    args = parser.parse_args()
    import bpy
    from mathutils import Vector

    bpy.ops.wm.open_mainfile(filepath=str(REPO / "sample_scenes" / "interior.blend"))
    scene = bpy.context.scene
    tree = scene.world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sun_disc = args.sun_disc
    sun = next(o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN")
    towards = sun.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    sky.sun_elevation = math.asin(towards.z)
    sky.sun_rotation = math.pi / 2 - math.atan2(towards.y, towards.x)  # from +Y towards +X
    background = tree.nodes["Background"]
    tree.links.new(sky.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = SUN_DISC_STRENGTH if args.sun_disc \
        else SKY_STRENGTH
    if args.sun_disc:
        bpy.data.objects.remove(sun)
    bpy.ops.wm.save_as_mainfile(filepath=str(args.output.resolve()), copy=True)


if __name__ == "__main__":
    main()
