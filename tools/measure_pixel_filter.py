"""Whether weighting VPL GI's supersamples by Cycles' default pixel filter (Blackman-Harris,
1.5 px) brings its pixels nearer Cycles' than their plain mean (Box). The Cornell box
(two bounces) rendered by Cycles with each filter (1024 samples) and by VPL GI at three
times the size with antialiasing 1, whose pixels are the supersamples of the small image:
folded 3 × 3 into pixels by their mean and by Blackman-Harris weights over the taps within
0.75 px. Prints each against each reference (energy, relRMSE).

    .venv/bin/python tools/measure_pixel_filter.py [--size 64] [--samples 1024]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

AA = 3  # supersamples a pixel edge (the default antialiasing)


def blackman_harris(x: np.ndarray, width: float) -> np.ndarray:
    """Cycles' Blackman-Harris filter of ``width`` pixels at offsets ``x`` (pixels)."""
    t = np.clip(x / width + 0.5, 0.0, 1.0)
    w = (0.35875 - 0.48829 * np.cos(2 * np.pi * t) + 0.14128 * np.cos(4 * np.pi * t)
         - 0.01168 * np.cos(6 * np.pi * t))
    return np.where(np.abs(x) <= width / 2, w, 0.0)


def fold(supersamples: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Pixels of an (h·AA, w·AA, c) image: each the ``weights``-weighted sum of the taps
    around its centre supersample (separable; edges extended)."""
    radius = len(weights) // 2
    h, w = supersamples.shape[0] // AA, supersamples.shape[1] // AA
    padded = np.pad(supersamples, ((radius, radius), (radius, radius), (0, 0)), mode="edge")
    centre = radius + AA // 2
    out = np.zeros((h, w, supersamples.shape[2]))
    for i, wy in enumerate(weights):
        for j, wx in enumerate(weights):
            rows = slice(centre + i - radius, None, AA)
            cols = slice(centre + j - radius, None, AA)
            out += wy * wx * padded[rows, cols][:h, :w]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--samples", type=int, default=1024)
    args = parser.parse_args()
    import bpy  # noqa: F401  (Blender's module: before the add-on)

    import addon
    from devtools import metrics
    from tests.blender.rendering import configure_cycles, open_scene, render_linear

    addon.register()
    try:
        folder = Path(tempfile.mkdtemp())
        scene = open_scene("cornell_box", args.size)
        references = {}
        for name, (kind, width) in {"Box": ("BOX", 1.0),
                                    "Blackman-Harris": ("BLACKMAN_HARRIS", 1.5)}.items():
            configure_cycles(scene, args.samples, bounces=2)
            scene.cycles.pixel_filter_type, scene.cycles.filter_width = kind, width
            references[name] = render_linear(scene, "CYCLES", folder / f"{kind}.exr")[..., :3]
        scene.render.resolution_x = scene.render.resolution_y = args.size * AA
        scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = 2, 1
        supersamples = render_linear(scene, "VPL_GI", folder / "vpl_gi.exr")[..., :3]
        radius = int(np.ceil(0.75 * AA))
        taps = blackman_harris(np.arange(-radius, radius + 1) / AA, 1.5)
        box = np.zeros(2 * radius + 1)
        box[radius - AA // 2:radius + AA // 2 + 1] = 1.0
        pixels = {"mean (Box)": fold(supersamples, box / box.sum()),
                  "Blackman-Harris": fold(supersamples, taps / taps.sum())}
        a, b = references.values()
        print(f"Cycles Box vs Blackman-Harris: relRMSE {metrics.relative_rmse(a, b):.4f}")
        for name, image in pixels.items():
            for ref_name, reference in references.items():
                print(f"VPL GI {name:16s} vs Cycles {ref_name:16s}: energy "
                      f"{metrics.mean_relative_energy(image, reference):+.4f} relRMSE "
                      f"{metrics.relative_rmse(image, reference):.4f}")
    finally:
        addon.unregister()


if __name__ == "__main__":
    main()
