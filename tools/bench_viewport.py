"""Benchmark: the interactive viewport, driven headlessly through a scripted edit session.

Blender's background mode has no viewport, so this replays what the Rendered viewport does
with the same pieces the engine uses: each edit is made with bpy, Blender's own depsgraph
updates (caught by a ``depsgraph_update_post`` handler) are classified, changed geometry is
forgotten by the export cache, the scene is exported again (only when more than the view
changed) and handed to a ``ViewportSession``, whose worker thread renders the refinement levels.

Edits, per sample scene: open (first frame), orbit the view 3 times, drag the first light 3
times (2 cm, or 1° for a sun), move a mesh object, change a material colour. For each it
prints the export time and meshes read/reused, the latency to the first frame, the time to
the last refinement level, which expensive stages ran in the first frame (ray-tracing setup,
VPL generation, imperfect shadow maps and how many were rendered), and the refinement frame
rate, and where each first frame's time went, stage by stage.

Run: ``.venv/bin/python tools/bench_viewport.py [--scenes cornell_box interior] [--size 640]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import traceback
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

STAGE_SHOWN = 0.005  # seconds: a first frame's stages that took less are not listed
HEAVY_STAGES = ("ray tracing setup", "vpl generation", "vpl generation (incremental)",
                "ism splat", "ism pull_push")


def rotate_about(view: np.ndarray, centre: np.ndarray, degrees: float) -> np.ndarray:
    """The view matrix of a camera orbited about the vertical axis through ``centre``."""
    a = np.radians(degrees)
    rotation = np.eye(4)
    rotation[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    to_centre, back = np.eye(4), np.eye(4)
    to_centre[:3, 3], back[:3, 3] = -centre, centre
    return view @ back @ rotation @ to_centre


def replay(scene_file: Path, size: int) -> None:
    import bpy

    from addon.core.scene.geometry import bounding_sphere, flatten_instances
    from addon.core.viewport_session import Changes, Update, ViewportSession, classify
    from addon.export import ExportCache, export_camera, export_scene
    from addon.viewport import depsgraph_updates

    bpy.ops.wm.open_mainfile(filepath=str(scene_file), load_ui=False)
    caught: list[Update] = []

    def catch(_scene, depsgraph) -> None:
        caught.extend(depsgraph_updates(depsgraph))
    bpy.app.handlers.depsgraph_update_post.append(catch)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    # latency and refinement levels: no idle passes, whose CPU time would follow each edit
    settings = bpy.context.scene.vpl_gi.to_settings()
    if hasattr(settings, "viewport_passes"):  # older checkouts (--repo) had no idle passes
        settings = replace(settings, viewport_passes=1)
    cache = ExportCache()
    height = max(1, size * 9 // 16)
    camera = export_camera(depsgraph, bpy.context.scene.camera, size, height, [])
    session = ViewportSession()
    rows = []
    first_frames: list[tuple[str, dict[str, float]]] = []

    def run(label: str, changes: Changes, **kwargs) -> None:
        start = time.perf_counter()
        scene = None
        if changes.needs_export or "camera" not in kwargs:
            for name in changes.geometry:
                cache.forget(name)
            scene = export_scene(depsgraph, cache)
        export = time.perf_counter() - start
        meshes = dict(cache.stats)
        session.edit(changes, scene=scene, settings=settings, **kwargs)
        if not session.wait_idle(600):
            raise RuntimeError(f"{label}: the viewport did not converge")
        if session.error:
            raise RuntimeError(f"{label}: {session.error}")
        record = session.records[-1]
        heavy = [k for k in HEAVY_STAGES if k in record.ran]
        rendered = record.counts.get("isms_rendered", "-")
        levels = session.latest().levels
        rate = (levels - 1) / (record.converged - record.latency) if levels > 1 else float("nan")
        rows.append((label, record.kind, f"{export * 1000:.0f} ms "
                     f"({meshes.get('meshes_read', 0)} read, "
                     f"{meshes.get('meshes_reused', 0)} reused)",
                     f"{record.latency * 1000:.0f} ms", f"{record.converged * 1000:.0f} ms",
                     f"{rate:.1f}/s", ", ".join(heavy) or "none", str(rendered)))
        first_frames.append((label, record.ran))
        cache.stats.clear()

    def edited(action) -> Changes:
        caught.clear()
        action()
        depsgraph.update()
        return classify(caught)

    geometry = flatten_instances(export_scene(depsgraph), [])
    centre, _ = bounding_sphere(geometry.positions)
    run("open", Changes(settings=True), camera=camera)
    view = camera.view_matrix
    for step in range(1, 4):
        view = rotate_about(view, centre, 3.0)
        moved = type(camera)(view, camera.projection_matrix, camera.width, camera.height,
                             camera.is_orthographic)
        run(f"orbit {step}", Changes(camera=True), camera=moved)
    light = next(o for o in bpy.context.scene.objects if o.type == "LIGHT")

    def drag() -> None:  # a sun only has a direction: turn it by 1°, else move it by 2 cm
        if light.data.type == "SUN":
            light.rotation_euler.z += np.radians(1.0)
        else:
            light.location.x += 0.02
    for step in range(1, 4):
        run(f"drag light {step}", edited(drag))
    mesh = max((o for o in bpy.context.scene.objects if o.type == "MESH"),
               key=lambda o: len(o.data.polygons) if o.data.polygons else 0)
    run("move object", edited(lambda: setattr(mesh.location, "z", mesh.location.z + 0.01)))
    material = next(m for m in bpy.data.materials if m.node_tree and
                    "Principled BSDF" in m.node_tree.nodes)
    colour = material.node_tree.nodes["Principled BSDF"].inputs["Base Color"]
    run("material colour", edited(lambda: setattr(colour, "default_value", (0.2, 0.5, 0.8, 1))))
    session.close()
    bpy.app.handlers.depsgraph_update_post.remove(catch)

    triangles = geometry.vertex_count // 3
    print(f"\n{scene_file.name}: {triangles} triangles, viewport {size}×{height}, "
          f"{settings.vpl_count} light paths, {settings.bounces} bounces, "
          f"visibility {settings.visibility}")
    print("| edit | classified as | export | first frame | last level | refinement | "
          "heavy stages in first frame | ISMs rendered |")
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print("\nWhere each first frame's time went (stages over 5 ms, ms; nested stages, such "
          "as the ISM splat inside its maps, are in both):")
    for label, ran in first_frames:
        spent = sorted(((v, k) for k, v in ran.items() if v >= STAGE_SHOWN), reverse=True)
        print(f"- {label}: " + ", ".join(f"{k} {v * 1000:.0f}" for v, k in spent))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["cornell_box", "interior"])
    parser.add_argument("--size", type=int, default=640, help="viewport width in pixels")
    parser.add_argument("--repo", type=Path, default=REPO,
                        help="the VPL GI checkout to measure (default: this one)")
    args = parser.parse_args()
    sys.path.insert(0, str(args.repo.resolve()))

    from addon import register, unregister

    code = 1
    register()
    try:
        for name in args.scenes:
            replay(args.repo / "sample_scenes" / f"{name}.blend", args.size)
        code = 0
    except Exception:
        traceback.print_exc()
    finally:
        unregister()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)  # bpy can hang in its exit handlers after an error


if __name__ == "__main__":
    main()
