"""GPU memory and upload time of the frame's image textures (gpu/texture_array.py) for sets
of image sizes, 8-bit and float: the array texture's size as uploaded (its width × height ×
pages × 16 bytes) against what one layer per image, each as large as the largest, took
before stop 67 (computed). Each upload is of new Texture objects, so the 8-bit images' byte
codes are made again every time (a render's later passes reuse them).

    .venv/bin/python tools/bench_texture_memory.py [--repeat 3]
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

from addon.core.gpu.gl import create_context  # noqa: E402
from addon.core.gpu.texture_array import upload  # noqa: E402
from addon.core.scene.model import Texture  # noqa: E402

SETS = {
    "one 4096² and twenty 1024²": [4096] + [1024] * 20,
    "forty 2048²": [2048] * 40,
    "one 8192² and sixty 512²": [8192] + [512] * 60,
}
GIB = float(1 << 30)


def textures(sides: list[int], eight_bit: bool) -> list[Texture]:
    """Square images of ``sides``, random byte values (as 8-bit images hold them)."""
    rng = np.random.default_rng(0)
    made = []
    for k, side in enumerate(sides):
        pixels = (rng.integers(0, 256, size=(side, side, 4), dtype=np.uint8)
                  / np.float32(255.0)).astype(np.float32)
        made.append(Texture(f"image {k}", pixels, eight_bit=eight_bit))
    return made


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    ctx = create_context()
    print(f"{'images':30s} {'kind':6s} {'layers before':>14s} {'packed':>10s} {'upload':>8s}")
    for name, sides in SETS.items():
        before = len(sides) * max(sides) ** 2 * 16 / GIB
        for eight_bit in (True, False):
            seconds, size = [], 0.0
            for _ in range(args.repeat):
                images = textures(sides, eight_bit)
                start = time.perf_counter()
                array, table = upload(ctx, images)
                ctx.finish()
                seconds.append(time.perf_counter() - start)
                size = array.width * array.height * array.layers * 16 / GIB
                array.release()
                table.release()
            kind = "8-bit" if eight_bit else "float"
            print(f"{name:30s} {kind:6s} {before:11.2f} GiB {size:6.2f} GiB "
                  f"{statistics.median(seconds):6.2f} s", flush=True)


if __name__ == "__main__":
    main()
