"""Benchmark for a machine with a real GPU: the interior sample scene and Sponza at 1920×1080
with default settings, frame times and where each frame's time goes.

Per scene, in one process with one OpenGL context (GL_RENDERER is printed):
- **full**: a frame from a new Renderer (programs compiled, BVH built, VPLs made, ISM points
  drawn, every map rendered): what every single command-line or farm frame pays; nothing is
  reused, so every stage is timed doing its work;
- **orbit**: the camera turned 0.5° about the scene per frame, reusing what the viewport
  reuses (BVH, ISM points, shadow atlases; VPLs where the camera does not steer them): the
  frame rate of a camera move.
Each stage's median over ``--frames`` frames is printed in milliseconds (Stats.timings).
Sponza is read from ``--sponza`` (default: ../shared/assets/sponza/sponza.obj) and set up as
``devtools.obj_scene`` sets it up (camera inside, sun and sky). On llvmpipe use a small
``--size``: the default takes minutes there; on a GPU it should finish well under 10 minutes.

    .venv/bin/python tools/bench_gpu.py [--size 1920x1080] [--frames 5] [--scenes interior sponza]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tools.bench_viewport import rotate_about  # noqa: E402

DEFAULT_SPONZA = REPO.parent / "shared" / "assets" / "sponza" / "sponza.obj"


def timed_frames(render, count: int) -> list[dict[str, float]]:
    """Stats.timings plus ``frame`` (wall seconds, GPU finished) of ``count`` frames
    ``render(i)``."""
    rows = []
    for i in range(count):
        start = time.perf_counter()
        timings = render(i)
        rows.append({**timings, "frame": time.perf_counter() - start})
    return rows


def report(name: str, runs: dict[str, list[dict[str, float]]]) -> None:
    stages = list(dict.fromkeys(k for rows in runs.values() for r in rows for k in r))
    stages.remove("frame")
    print(f"\n{name}: median milliseconds per stage")
    print("| stage | " + " | ".join(runs) + " |")
    print("|---|" + "---|" * len(runs))
    for stage in [*stages, "frame"]:
        cells = []
        for rows in runs.values():
            values = [r[stage] for r in rows if stage in r]
            cells.append(f"{statistics.median(values) * 1000:.1f}" if values else "–")
        label = "**frame**" if stage == "frame" else stage
        print(f"| {label} | " + " | ".join(cells) + " |")
    fps = 1.0 / statistics.median(r["frame"] for r in runs["orbit"])
    print(f"orbit: {fps:.1f} frames per second")


def measure(name: str, size: tuple[int, int], frames: int) -> None:
    import bpy

    from addon.core.frame.renderer import Renderer
    from addon.core.scene.geometry import bounding_sphere, flatten_instances
    from addon.export import export_scene

    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.engine = "VPL_GI"
    settings = scene.vpl_gi.to_settings()
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    centre, _ = bounding_sphere(flatten_instances(exported, []).positions)
    renderer = Renderer()

    def full(_i: int) -> dict[str, float]:
        fresh = Renderer(renderer.ctx)
        try:
            _frame, stats = fresh.render(exported, settings)
            fresh.ctx.finish()
        finally:
            fresh.release()
        return stats.timings

    def turned(i: int) -> dict[str, float]:
        view = rotate_about(exported.camera.view_matrix, centre, 0.5 * (i + 1))
        camera = replace(exported.camera, view_matrix=view)
        _frame, stats = renderer.render(replace(exported, camera=camera), settings)
        renderer.ctx.finish()
        return stats.timings

    try:
        turned(-1)  # the orbit starts from a frame whose products are kept
        runs = {"full": timed_frames(full, frames), "orbit": timed_frames(turned, frames)}
        print(f"\n{name}, {size[0]}×{size[1]}, defaults, {len(exported.instances)} instances; "
              f"{renderer.ctx.info['GL_RENDERER']}")
        report(name, runs)
    finally:
        renderer.release()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="1920x1080", help="WIDTHxHEIGHT")
    parser.add_argument("--frames", type=int, default=5, help="frames per warm measurement")
    parser.add_argument("--scenes", nargs="+", default=["interior", "sponza"],
                        choices=["interior", "sponza", "cornell_box"])
    parser.add_argument("--sponza", type=Path, default=DEFAULT_SPONZA)
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.lower().split("x"))

    import bpy

    from addon import register, unregister

    register()
    try:
        for name in args.scenes:
            if name == "sponza":
                from devtools.obj_scene import scene_from_obj

                if not args.sponza.is_file():
                    raise SystemExit(f"Sponza not found at {args.sponza} (give --sponza PATH)")
                scene_from_obj(args.sponza)
            else:
                bpy.ops.wm.open_mainfile(filepath=str(REPO / "sample_scenes" / f"{name}.blend"),
                                         load_ui=False)
            measure(name, size, args.frames)
    finally:
        unregister()


if __name__ == "__main__":
    main()
