"""Cost of a clear coat: the coated floor of tests/blender/test_coat.py at 640×360 with two
bounces, rendered with its coat on and off in turns, warm in one process (one untimed frame
of each first), timed around ``bpy.ops.render.render()``; prints each variant's frames and
their sum.

    .venv/bin/python tools/bench_coat.py [--repeat 6]
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
    parser.add_argument("--repeat", type=int, default=6)
    args = parser.parse_args()

    import bpy

    from devtools.registered import run_registered
    from tests.blender.test_coat import coated_floor

    def measure() -> None:
        scene = coated_floor(bpy, 0.5)
        scene.render.engine = "VPL_GI"
        scene.render.resolution_x, scene.render.resolution_y = 640, 360
        scene.render.resolution_percentage = 100
        scene.vpl_gi.bounces = 2
        weight = bpy.data.materials["Floor"].node_tree.nodes["Principled BSDF"].inputs[
            "Coat Weight"]
        seconds: dict[bool, list[float]] = {True: [], False: []}
        for frame in range(2 * (args.repeat + 1)):
            coated = frame % 2 == 0
            weight.default_value = 1.0 if coated else 0.0
            start = time.perf_counter()
            bpy.ops.render.render()
            if frame >= 2:
                seconds[coated].append(time.perf_counter() - start)
        for coated, times in seconds.items():
            print(f"{'coated' if coated else 'uncoated'}: "
                  f"{', '.join(f'{t:.2f}' for t in times)} s; sum {sum(times):.1f} s")
        print(f"coated / uncoated: {sum(seconds[True]) / sum(seconds[False]):.2f}")
    run_registered(measure)


if __name__ == "__main__":
    main()
