"""Cost of hair: a square metre of fur (hair particles, 30 cm, root radius 2.5 mm, with
interpolated children) on a floor under a sun, at 640×360 with default settings. Prints
the strands, the triangles of their tubes, the time to read them (the particle system's
paths, one ``co_hair`` call a key: the viewport's children and steps) and the frame's time
(a final render exports the scene afresh, its hair included), the first frame untimed,
timed around ``bpy.ops.render.render()``. ``--save FILE`` saves the scene instead (for
``python -m devtools report FILE``).

    .venv/bin/python tools/bench_hair.py [--parents 1000] [--children 20] [--repeat 2]
        [--save fur.blend]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parents", type=int, default=1000)
    parser.add_argument("--children", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--save", type=Path, help="save the scene to this .blend and stop")
    args = parser.parse_args()

    import bpy

    from addon.engine import monitor
    from addon.export_hair import read_particle_hair
    from devtools.registered import run_registered
    from tests.blender.rendering import add_primitive, shader_material
    from tests.blender.test_hair import sunlit_floor

    def measure() -> None:
        scene, grey = sunlit_floor(640)
        patch = add_primitive("plane", grey, size=1.0)
        patch.data.materials.append(shader_material("Fur", "ShaderNodeBsdfDiffuse",
                                                    Color=(0.8, 0.4, 0.1, 1)))
        fur = patch.modifiers.new("Fur", "PARTICLE_SYSTEM").particle_system.settings
        fur.type, fur.count, fur.hair_length, fur.material = "HAIR", args.parents, 0.3, 2
        fur.child_type = "INTERPOLATED" if args.children else "NONE"
        fur.rendered_child_count = max(args.children, 1)
        fur.root_radius, fur.tip_radius, fur.radius_scale = 1.0, 0.2, 0.005
        scene.render.engine = "VPL_GI"
        scene.render.resolution_x, scene.render.resolution_y = 640, 360
        scene.render.resolution_percentage = 100
        if args.save is not None:
            bpy.ops.wm.save_as_mainfile(filepath=str(args.save.resolve()))
            return
        depsgraph = bpy.context.evaluated_depsgraph_get()
        start = time.perf_counter()
        mesh, _ = read_particle_hair(patch.evaluated_get(depsgraph), False, "fur")
        print(f"viewport: {mesh.triangle_count:,} triangles read in "
              f"{time.perf_counter() - start:.2f} s")
        frames = []
        for frame in range(args.repeat + 1):
            start = time.perf_counter()
            bpy.ops.render.render()
            if frame:
                frames.append(f"{time.perf_counter() - start:.2f} s")
        stats = monitor.last_stats
        print(f"render: {args.parents * (args.children or 1):,} strands, "
              f"{stats.counts.get('triangles', 0):,} triangles in the scene; frames "
              f"{', '.join(frames)}")
    run_registered(measure)


if __name__ == "__main__":
    main()
