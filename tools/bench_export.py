"""Benchmark of the scene export against Cycles' scene sync, measured in the same run.

For each scene (a tessellated grid of N triangles under a sun — "1Mngon" with one hexagon, so
that its mesh takes the n-gon path — or 10k instances of a small mesh scattered by geometry
nodes) it prints: our export time (cold, and again with a warm ExportCache), our upload time
(core.geometry.flatten_instances plus core.scene_buffers.SceneBuffers: the vertex buffer and
material tables the renderer uploads), our ray-tracing set-up (the BVH built and uploaded as a
frame that traces rays does it: a shared mesh's tree built once and refitted to each copy,
core.gpu.instanced_bvh), Cycles' time to its first sample (a 1-sample 8×8 render minus the
same render of an empty scene: its sync and BVH, median of --repeat), both ratios (without
and with our BVH), and peak RSS after building the scene and of our export + upload and of
Cycles, each measured in its own process (so each peak is its own).

    .venv/bin/python tools/bench_export.py [--scenes 100k 1M 1Mngon 5M inst10k] [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"100k": 100_000, "1M": 1_000_000, "1Mngon": 1_000_000, "5M": 5_000_000,
          "inst10k": 10_000}


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def build_scene(bpy, name: str) -> None:
    """The named benchmark scene in a fresh file: camera, sun, and the geometry."""
    import bmesh
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0, -12, 8)
    camera.rotation_euler = (0.98, 0, 0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    if name == "empty":
        return
    if name == "inst10k":
        bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, radius=0.05)  # 80 triangles
        ball = bpy.context.object
        ball.location.z = -100  # the original out of sight; its instances are on the grid
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=100, y_subdivisions=100, size=10)
        grid = bpy.context.object
        tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
        info = tree.nodes.new("GeometryNodeObjectInfo")
        info.inputs["Object"].default_value = ball
        info.inputs["As Instance"].default_value = True
        on_points = tree.nodes.new("GeometryNodeInstanceOnPoints")
        tree.links.new(group_in.outputs[0], on_points.inputs["Points"])
        tree.links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
        tree.links.new(on_points.outputs["Instances"], group_out.inputs[0])
        grid.modifiers.new("Scatter", "NODES").node_group = tree
        return
    side = max(1, round((SCENES[name] / 2) ** 0.5))  # side² quads = 2 side² triangles
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=side, y_subdivisions=side, size=10)
    if name.endswith("ngon"):  # two quads become one hexagon
        mesh = bpy.context.object.data
        editable = bmesh.new()
        editable.from_mesh(mesh)
        editable.faces.ensure_lookup_table()
        shared = next(e for e in editable.faces[0].edges if len(e.link_faces) == 2)
        bmesh.ops.dissolve_edges(editable, edges=[shared])
        editable.to_mesh(mesh)
        editable.free()


def cycles_render_seconds(bpy) -> float:
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100
    start = time.perf_counter()
    bpy.ops.render.render()
    return time.perf_counter() - start


def measure_ours(name: str, repeat: int) -> dict[str, float]:
    """Export (cold and with a warm cache) and upload of one scene, in this process."""
    import bpy

    from addon.core.gpu.gl import ProgramCache, create_context
    from addon.core.gpu.raytrace import RayTracer
    from addon.core.gpu.scene_buffers import SceneBuffers
    from addon.core.scene.geometry import flatten_instances
    from addon.export import ExportCache, export_scene

    build_scene(bpy, name)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    row: dict[str, float] = {"rss_scene": peak_rss_mib()}
    exports, cached, uploads, bvhs = [], [], [], []
    ctx = create_context()
    programs = ProgramCache(ctx)
    tracer = RayTracer(ctx, programs)
    for _ in range(repeat):
        start = time.perf_counter()
        exported = export_scene(depsgraph)
        exports.append(time.perf_counter() - start)
        start = time.perf_counter()
        geometry = flatten_instances(exported, [])
        buffers = SceneBuffers(ctx, geometry)
        ctx.finish()
        uploads.append(time.perf_counter() - start)
        start = time.perf_counter()
        try:
            tracer.upload(geometry.positions.reshape(-1, 3, 3), instanced=geometry.instanced)
            ctx.finish()
            bvhs.append(time.perf_counter() - start)
        except ValueError:  # over the storage-buffer limit: the renderer refuses to trace it
            bvhs.append(float("nan"))
        buffers.release()
        del exported, geometry
        cache = ExportCache()
        export_scene(depsgraph, cache)
        start = time.perf_counter()
        export_scene(depsgraph, cache)
        cached.append(time.perf_counter() - start)
    tracer.release()
    programs.release()
    ctx.release()
    row.update(triangles=sum(i.mesh.triangle_count for i in export_scene(depsgraph).instances),
               export=statistics.median(exports), export_cached=statistics.median(cached),
               upload=statistics.median(uploads), bvh=statistics.median(bvhs),
               rss=peak_rss_mib())
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return row


def measure_cycles(name: str, repeat: int) -> dict[str, float]:
    """Cycles' time to its first sample on one scene, in this process."""
    import bpy

    build_scene(bpy, "empty")
    empty = statistics.median(cycles_render_seconds(bpy) for _ in range(repeat))
    build_scene(bpy, name)
    bpy.context.evaluated_depsgraph_get()
    row = {"rss_scene": peak_rss_mib()}
    full = statistics.median(cycles_render_seconds(bpy) for _ in range(repeat))
    row.update(cycles_sync=full - empty, cycles_empty=empty, rss=peak_rss_mib())
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return row


def _seconds(value: float) -> str:
    """A time column: 'over' where the tracer refused the scene (NaN)."""
    return f"{'over':>8}" if math.isnan(value) else f"{value:>7.3f}s"


def run_part(part: str, name: str, repeat: int) -> dict[str, float]:
    """One measurement in its own process, so that each peak RSS is its own."""
    out = subprocess.run([sys.executable, __file__, "--part", part, name, "--repeat",
                          str(repeat)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", choices=list(SCENES), default=list(SCENES))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--part", nargs=2, metavar=("PART", "SCENE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.part:
        sys.path.insert(0, str(ROOT))
        part, name = args.part
        measure = measure_ours if part == "ours" else measure_cycles
        print(json.dumps(measure(name, args.repeat)))
        return
    header = (f"{'scene':>8} {'triangles':>10} {'export':>8} {'cached':>9} {'upload':>8} "
              f"{'ours':>8} {'BVH':>8} {'Cycles':>8} {'ratio':>6} {'+BVH':>6} "
              f"{'RSS scene':>10} {'RSS ours':>9} {'RSS Cycles':>10}")
    print(header)
    print("-" * len(header))
    for name in args.scenes:
        row = run_part("ours", name, args.repeat)
        cycles = run_part("cycles", name, args.repeat)
        ours, sync = row["export"] + row["upload"], cycles["cycles_sync"]
        print(f"{name:>8} {int(row['triangles']):>10,} {row['export']:>7.3f}s "
              f"{row['export_cached'] * 1e3:>7.2f}ms {row['upload']:>7.3f}s {ours:>7.3f}s "
              f"{_seconds(row['bvh'])} {sync:>7.3f}s {ours / sync:>6.2f} "
              f"{(ours + row['bvh']) / sync:>6.2f} {row['rss_scene']:>7.0f}MiB "
              f"{row['rss']:>6.0f}MiB {cycles['rss']:>7.0f}MiB", flush=True)
    print("export/cached: export_scene cold / with a warm ExportCache (which returns unchanged "
          "meshes as they were: milliseconds); upload: "
          "flatten_instances + SceneBuffers; ours = export + upload; BVH: the ray tracer's "
          "build + upload (RayTracer.upload; over: beyond the GPU's storage-buffer limit, "
          "which the renderer refuses to trace); Cycles: 1-sample 8×8 render minus an empty "
          "scene's (its sync + BVH); ratio = ours / Cycles; +BVH = (ours + BVH) / Cycles; RSS: "
          "peak after building the scene, and peak of the process that ran ours / Cycles "
          "(separate processes)")


if __name__ == "__main__":
    main()
