"""Benchmark: VPL visibility with imperfect shadow maps against classic triangle shadow maps.

Renders one frame of a scene (default: the ~78k-triangle interior sample scene) with ~1024 VPLs
twice in one process — ``visibility=ism`` and ``visibility=classic``, the same VPLs — and prints
the time of the visibility stage of each and their ratio, the time of every stage of the ISM
frame, and the memory of the ISM atlas. Each timed frame starts with ``forget_frames()``, so it
renders every map afresh instead of reusing the previous frame's (a timed stage that reports
itself skipped or ~0 s stops the benchmark with an error); the ISM area table the points are
drawn from on the GPU, built once per geometry version, is timed in the warm-up frame and
reported beside the ratio.
Run: ``.venv/bin/python tools/bench_visibility.py``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

if TYPE_CHECKING:
    from addon.core.frame import Stats


def export(scene_file: Path, size: int):
    """The core Scene of a .blend file at size × size pixels."""
    import bpy

    from addon import register, unregister
    from addon.export import export_scene

    register()
    try:
        bpy.ops.wm.open_mainfile(filepath=str(scene_file), load_ui=False)
        render = bpy.context.scene.render
        render.resolution_x = render.resolution_y = size
        render.resolution_percentage = 100
        return export_scene(bpy.context.evaluated_depsgraph_get())
    finally:
        unregister()


VISIBILITY_STAGE = "indirect light maps"


def check_full_work(stats: Stats, what: str) -> None:
    """Stop unless the visibility stage of a timed frame ran in full: no map reused."""
    seconds = stats.timings.get(VISIBILITY_STAGE, 0.0)
    reused = {k: v for k, v in stats.skipped.items() if k in ("ism", "shadow maps")}
    if seconds < 1e-3 or reused or stats.counts.get("isms_rendered", 0) < \
            stats.counts.get("isms", 0):
        raise SystemExit(f"error: the timed {what} frame did not do the full work "
                         f"({VISIBILITY_STAGE} {seconds:.4f} s, skipped {reused}, "
                         f"{stats.counts.get('isms_rendered', 0)} of "
                         f"{stats.counts.get('isms', 0)} ISMs rendered)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", type=Path, default=REPO / "sample_scenes" / "interior.blend")
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--vpls", type=int, default=1024, help="VPLs wanted (about)")
    args = parser.parse_args()

    from addon.core.frame.renderer import Renderer
    from addon.core.settings import Settings

    scene = export(args.scene, args.size)
    renderer = Renderer()
    base = Settings(bounces=1, antialiasing=1, vpl_count=args.vpls)
    _, probe = renderer.render(scene, replace(base, bounces=1, visibility="exact",
                                              vpl_count=256, interleave=1))
    paths = max(1, round(256 * args.vpls / max(1, probe.counts["vpls"])))
    settings = replace(base, vpl_count=paths)
    _, warm = renderer.render(scene, replace(settings, visibility="ism"))  # shaders, area table
    renderer.forget_frames()  # no VPLs, ISM atlas or shadow atlases kept from the warm-up
    _, ism = renderer.render(scene, replace(settings, visibility="ism"))
    check_full_work(ism, "ISM")
    renderer.forget_frames()
    _, classic = renderer.render(scene, replace(settings, visibility="classic", interleave=1))
    check_full_work(classic, "classic")

    print(f"scene {args.scene.name}: {ism.counts['triangles']} triangles, {ism.counts['vpls']} "
          f"VPLs ({paths} light paths, 1 bounce), {args.size}² pixels, "
          f"GL: {renderer.ctx.info['GL_RENDERER']}")
    ism_maps = ism.timings[VISIBILITY_STAGE]
    classic_maps = classic.timings[VISIBILITY_STAGE]
    points = warm.timings.get("ism points", 0.0)
    print("timed frames: forget_frames() before each, every map rendered "
          f"({ism.counts['isms_rendered']} ISMs, {classic.counts['shadow_maps']} classic maps)")
    print(f"visibility stage: ISM {ism_maps:.3f} s ({settings.ism_points} points/VPL, "
          f"{settings.ism_resolution}² maps, {settings.pull_push_levels} pull-push levels) vs "
          f"classic {classic_maps:.3f} s ({settings.vpl_shadow_resolution}² cube maps): "
          f"{classic_maps / ism_maps:.1f}x faster; with the ISM area table (built once per "
          f"geometry version, {points:.3f} s in the warm-up frame): "
          f"{classic_maps / (ism_maps + points):.1f}x")
    print("ISM frame stages:")
    for stage, seconds in ism.timings.items():
        print(f"  {stage:<22} {seconds * 1000:9.1f} ms")
    print(f"ISM atlas and pull-push levels: {renderer.ism.memory_bytes() / 2**20:.1f} MiB; "
          f"classic cube-map atlas: up to 128 MiB per batch")
    renderer.release()


if __name__ == "__main__":
    main()
