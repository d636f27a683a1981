"""Benchmark: Incremental Instant Radiosity against regenerating every VPL each frame.

The first light of a sample scene (default: the Cornell box's ceiling area light) moves
along a slow circle for N frames (default 60). Each frame is rendered, side by side in one
process, four ways:

- ``reuse``: ``incremental=True`` (VPLs and their imperfect shadow maps kept while valid);
- ``fresh``: every VPL made afresh with the same seed each frame (the default mode);
- ``independent``: made afresh with a new seed each frame (independent VPL sets);
- ``reference``: made afresh with many more paths (the converged image).

It prints per-frame means of the time per frame, the new imperfect shadow maps per frame, the
relative RMSE of the indirect pass against the reference, and a temporal-stability metric: the
mean absolute frame-to-frame change of the indirect pass, divided by the reference sequence's
own change (1 = flickers no more than the converged sequence moves).

Run: ``.venv/bin/python tools/bench_incremental.py [--frames 60] [--vpls 256]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tools.bench_visibility import export  # noqa: E402


def moving_light(scene, frame: int, frames: int, radius: float):
    """The scene with its first light moved along a horizontal circle (one turn per run)."""
    light = scene.lights[0]
    matrix = light.matrix.copy()
    angle = 2 * np.pi * frame / frames
    matrix[:3, 3] = light.matrix[:3, 3] + radius * np.array([np.cos(angle) - 1, np.sin(angle),
                                                             0.0])
    return replace(scene, lights=[replace(light, matrix=matrix), *scene.lights[1:]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", type=Path,
                        default=REPO / "sample_scenes" / "cornell_box.blend")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--vpls", type=int, default=256, help="light paths per frame")
    parser.add_argument("--reference-vpls", type=int, default=4096)
    parser.add_argument("--circle", type=float, default=0.15,
                        help="radius of the light's circle, as a fraction of the scene radius")
    args = parser.parse_args()

    from addon.core.frame.renderer import Renderer
    from addon.core.scene.geometry import bounding_sphere, flatten_instances
    from addon.core.settings import Settings

    scene = export(args.scene, args.size)
    _, scene_radius = bounding_sphere(flatten_instances(scene, []).positions)
    base = Settings(antialiasing=1, vpl_count=args.vpls, bounces=4)
    modes = {
        "reuse": (Renderer(), replace(base, incremental=True)),
        "fresh": (Renderer(), base),
        "independent": (Renderer(), base),
        "reference": (Renderer(), replace(base, vpl_count=args.reference_vpls, seed=99991)),
    }
    images: dict[str, list[np.ndarray]] = {m: [] for m in modes}
    seconds: dict[str, list[float]] = {m: [] for m in modes}
    maps: dict[str, list[int]] = {m: [] for m in modes}
    for frame in range(args.frames + 1):  # frame 0 warms up (shaders, ISM area tables)
        current = moving_light(scene, frame, args.frames, args.circle * scene_radius)
        for mode, (renderer, settings) in modes.items():
            if mode == "independent":
                settings = replace(settings, seed=frame)
            start = time.perf_counter()
            result, stats = renderer.render(current, settings)
            if frame == 0:
                continue
            seconds[mode].append(time.perf_counter() - start)
            maps[mode].append(stats.counts.get("isms_rendered", 0))
            images[mode].append(result.passes["DiffInd"].copy())
        print(f"\rframe {frame}/{args.frames}", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)

    reference = np.stack(images["reference"])
    ref_change = np.abs(np.diff(reference, axis=0)).mean()
    print(f"{args.scene.name}: {args.frames} frames, {args.size}² px, {args.vpls} light paths "
          f"(reference {args.reference_vpls}), light circling {args.circle:.2f} × scene radius")
    print("| mode | time per frame | new ISMs per frame | rel. RMSE vs reference | "
          "frame-to-frame change / reference's |")
    print("|---|---|---|---|---|")
    for mode in modes:
        seq = np.stack(images[mode])
        rmse = np.sqrt(((seq - reference) ** 2).mean(axis=(1, 2, 3))
                       / (reference**2).mean(axis=(1, 2, 3)))
        change = np.abs(np.diff(seq, axis=0)).mean() / ref_change
        print(f"| {mode} | {np.mean(seconds[mode]) * 1000:.0f} ms | {np.mean(maps[mode]):.1f} | "
              f"{rmse.mean():.1%} | {change:.2f} |")
    for renderer, _ in modes.values():
        renderer.release()


if __name__ == "__main__":
    main()
