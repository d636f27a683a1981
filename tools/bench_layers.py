"""Cost of a Principled BSDF's layer: a clear coat (the coated floor of
tests/blender/test_coat.py), a sheen (the velvet floor of tests/blender/test_sheen.py) or a
rough diffuse layer (the floor scene's floor and wall of Diffuse Roughness 1) at 640×360
with two bounces, rendered with the layer on and off in turns (its weight or roughness 1
and 0),
warm in one process (one untimed frame of each first), timed around
``bpy.ops.render.render()``; prints each variant's frames and their sum. ``--save FILE``
saves the scene, its layer on, instead (for ``python -m devtools report FILE``).

    .venv/bin/python tools/bench_layers.py [--layer coat|sheen|rough] [--repeat 6]
        [--save FILE]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def layered_floor(bpy, layer: str):
    """The test's floor scene with its layer, and the Principled inputs that turn it on."""
    from tests.blender.test_cycles_principled import floor_scene

    if layer == "coat":
        from tests.blender.test_coat import coated_floor

        scene = coated_floor(bpy, 0.5)
    else:
        from tests.blender.test_sheen import velvet_floor

        scene = floor_scene(bpy, 0.5)
        if layer == "sheen":
            velvet_floor(bpy)
    names = ("Floor", "Wall") if layer == "rough" else ("Floor",)
    socket = "Diffuse Roughness" if layer == "rough" else f"{layer.title()} Weight"
    return scene, [bpy.data.materials[name].node_tree.nodes["Principled BSDF"].inputs[socket]
                   for name in names]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--layer", choices=("coat", "sheen", "rough"), default="coat")
    parser.add_argument("--repeat", type=int, default=6)
    parser.add_argument("--save", type=Path, help="save the scene to this .blend and stop")
    args = parser.parse_args()

    import bpy

    from devtools.registered import run_registered

    def measure() -> None:
        scene, inputs = layered_floor(bpy, args.layer)
        scene.render.engine = "VPL_GI"
        scene.render.resolution_x, scene.render.resolution_y = 640, 360
        scene.render.resolution_percentage = 100
        scene.vpl_gi.bounces = 2
        if args.save is not None:
            for socket in inputs:
                socket.default_value = 1.0
            bpy.ops.wm.save_as_mainfile(filepath=str(args.save.resolve()))
            return
        seconds: dict[bool, list[float]] = {True: [], False: []}
        for frame in range(2 * (args.repeat + 1)):
            on = frame % 2 == 0
            for socket in inputs:
                socket.default_value = 1.0 if on else 0.0
            start = time.perf_counter()
            bpy.ops.render.render()
            if frame >= 2:
                seconds[on].append(time.perf_counter() - start)
        for on, times in seconds.items():
            print(f"{args.layer} {'on' if on else 'off'}: "
                  f"{', '.join(f'{t:.2f}' for t in times)} s; sum {sum(times):.1f} s")
        print(f"on / off: {sum(seconds[True]) / sum(seconds[False]):.2f}")
    run_registered(measure)


if __name__ == "__main__":
    main()
