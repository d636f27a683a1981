"""Benchmark: VPL visibility with imperfect shadow maps against classic triangle shadow maps.

Renders one frame of a scene (default: the ~78k-triangle interior sample scene) with ~1024 VPLs
twice in one process — ``visibility=ism`` and ``visibility=classic``, the same VPLs — and prints
the time of the visibility stage of each and their ratio, the time of every stage of the ISM
frame, and the memory of the ISM atlas. Run: ``.venv/bin/python tools/bench_visibility.py``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


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
    renderer.render(scene, replace(settings, visibility="ism"))  # warm-up: shaders, point pool
    _, ism = renderer.render(scene, replace(settings, visibility="ism"))
    _, classic = renderer.render(scene, replace(settings, visibility="classic", interleave=1))

    print(f"scene {args.scene.name}: {ism.counts['triangles']} triangles, {ism.counts['vpls']} "
          f"VPLs ({paths} light paths, 1 bounce), {args.size}² pixels, "
          f"GL: {renderer.ctx.info['GL_RENDERER']}")
    ism_maps = ism.timings["indirect light maps"]
    classic_maps = classic.timings["indirect light maps"]
    print(f"visibility stage: ISM {ism_maps:.3f} s ({settings.ism_points} points/VPL, "
          f"{settings.ism_resolution}² maps, {settings.pull_push_levels} pull-push levels) vs "
          f"classic {classic_maps:.3f} s ({settings.vpl_shadow_resolution}² cube maps): "
          f"{classic_maps / ism_maps:.1f}x faster")
    print("ISM frame stages:")
    for stage, seconds in ism.timings.items():
        print(f"  {stage:<22} {seconds * 1000:9.1f} ms")
    print(f"ISM atlas and pull-push levels: {renderer.ism.memory_bytes() / 2**20:.1f} MiB; "
          f"classic cube-map atlas: up to 128 MiB per batch")
    renderer.release()


if __name__ == "__main__":
    main()
