"""Benchmark for a machine with a real GPU: the interior sample scene and Sponza at 1920×1080
with default settings (``--set`` changes one) and the passes their view layer asks for, as a
final render renders them (``--passes`` names others), frame times and where each frame's time
goes.

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

A GPU machine without Blender (or without a Blender for its Python) renders scenes exported
elsewhere: ``--save DIR`` exports each scene and its settings at ``--size`` to
``DIR/NAME.pickle.xz`` and renders nothing; ``--load DIR`` renders those files without
importing bpy (numpy, scipy and moderngl are all it needs). The files are pickles: load only
files you made.

    .venv/bin/python tools/bench_gpu.py [--size 1920x1080] [--frames 5] [--scenes interior sponza]
    .venv/bin/python tools/bench_gpu.py --save DIR      # here, with Blender
    python3 tools/bench_gpu.py --load DIR               # on the GPU machine
"""

from __future__ import annotations

import argparse
import lzma
import math
import pickle
import statistics
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from addon.cli import CliError, parse_overrides  # noqa: E402
from addon.core.frame.result import PASS_CHANNELS  # noqa: E402
from addon.core.settings import DEFAULTS, Settings  # noqa: E402
from tools.bench_viewport import rotate_about  # noqa: E402

if TYPE_CHECKING:
    from addon.core.scene.model import Scene

DEFAULT_SPONZA = REPO.parent / "shared" / "assets" / "sponza" / "sponza.obj"


def differs(value: object, default: object) -> bool:
    """Whether a setting differs from its default (floats beyond Blender's single precision)."""
    if isinstance(value, float) and isinstance(default, float):
        return not math.isclose(value, default, rel_tol=1e-6)
    return value != default


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


def export_current(size: tuple[int, int]) -> tuple[Scene, Settings, frozenset[str]]:
    """The open Blender scene exported at ``size`` with VPL GI's settings and the passes its
    view layer asks for (what a final render renders)."""
    import bpy

    from addon.export import export_scene
    from addon.layer_passes import layer_passes

    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.engine = "VPL_GI"
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return (export_scene(depsgraph), scene.vpl_gi.to_settings(),
            layer_passes(depsgraph.view_layer))


def measure(name: str, exported: Scene, settings: Settings, passes: frozenset[str],
            frames: int) -> None:
    """Print the full and orbit frames' stage medians of ``exported`` rendered with
    ``settings``, Combined and ``passes``."""
    from addon.core.frame.renderer import Renderer
    from addon.core.scene.geometry import bounding_sphere, flatten_instances

    size = (exported.camera.width, exported.camera.height)
    centre, _ = bounding_sphere(flatten_instances(exported, []).positions)
    renderer = Renderer()

    def full(_i: int) -> dict[str, float]:
        fresh = Renderer(renderer.ctx)
        try:
            _frame, stats = fresh.render(exported, settings, passes=passes)
            fresh.ctx.finish()
        finally:
            fresh.release()
        return stats.timings

    def turned(i: int) -> dict[str, float]:
        view = rotate_about(exported.camera.view_matrix, centre, 0.5 * (i + 1))
        camera = replace(exported.camera, view_matrix=view)
        _frame, stats = renderer.render(replace(exported, camera=camera), settings,
                                        passes=passes)
        renderer.ctx.finish()
        return stats.timings

    try:
        first = timed_frames(lambda _i: turned(-1), 1)[0]["frame"]  # the orbit's start, kept
        runs = {"full": timed_frames(full, frames), "orbit": timed_frames(turned, frames)}
        print(f"\n{name}, {size[0]}×{size[1]}, {len(exported.instances)} instances; "
              f"{renderer.ctx.info['GL_RENDERER']}; the process's first frame (programs "
              f"compiled) {first:.2f} s")
        changed = {k: v for k, v in vars(settings).items() if differs(v, getattr(DEFAULTS, k))}
        print(f"settings other than the defaults: {changed or 'none'}; passes: Combined"
              + "".join(f", {name}" for name in sorted(passes)))
        report(name, runs)
    finally:
        renderer.release()


def measure_as_asked(args: argparse.Namespace, name: str, exported: Scene, settings: Settings,
                     passes: frozenset[str]) -> None:
    """``measure`` with the command line's ``--set`` and ``--passes`` instead of the scene's
    (``--save`` writes the scene's own)."""
    measure(name, exported, replace(settings, **args.overrides),
            passes if args.passes is None else frozenset(args.passes), args.frames)


def open_scene(name: str, sponza: Path) -> None:
    """Open sample scene ``name`` in Blender, or set Sponza up from its OBJ."""
    import bpy

    if name == "sponza":
        from devtools.obj_scene import scene_from_obj

        if not sponza.is_file():
            raise SystemExit(f"Sponza not found at {sponza} (give --sponza PATH)")
        scene_from_obj(sponza)
    else:
        bpy.ops.wm.open_mainfile(filepath=str(REPO / "sample_scenes" / f"{name}.blend"),
                                 load_ui=False)


def saved_path(folder: Path, name: str) -> Path:
    """Where ``--save`` writes scene ``name`` and ``--load`` reads it."""
    return folder / f"{name}.pickle.xz"


def from_blender(args: argparse.Namespace, size: tuple[int, int]) -> None:
    """Open each scene in Blender, then measure it, or with ``--save`` write it out."""
    from addon import register, unregister

    register()
    try:
        for name in args.scenes:
            open_scene(name, args.sponza)
            exported, settings, passes = export_current(size)
            if args.save is None:
                measure_as_asked(args, name, exported, settings, passes)
                continue
            args.save.mkdir(parents=True, exist_ok=True)
            path = saved_path(args.save, name)
            path.write_bytes(lzma.compress(pickle.dumps((exported, settings, passes), protocol=5)))
            print(f"{name}: {size[0]}×{size[1]} written to {path} "
                  f"({path.stat().st_size / 2**20:.1f} MiB)")
    finally:
        unregister()


def from_files(args: argparse.Namespace) -> None:
    """Measure each scene ``--save`` wrote to ``--load`` (no Blender needed)."""
    for name in args.scenes:
        path = saved_path(args.load, name)
        if not path.is_file():
            raise SystemExit(f"{path} not found: write it with --save on a machine with Blender")
        with warnings.catch_warnings():  # a numpy 1 pickle read by numpy 2: numpy.core's alias
            warnings.simplefilter("ignore", DeprecationWarning)
            exported, settings, passes = pickle.loads(lzma.decompress(path.read_bytes()))
        measure_as_asked(args, name, exported, settings, passes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="1920x1080", help="WIDTHxHEIGHT")
    parser.add_argument("--frames", type=int, default=5, help="frames per warm measurement")
    parser.add_argument("--scenes", nargs="+", default=["interior", "sponza"],
                        choices=["interior", "sponza", "cornell_box"])
    parser.add_argument("--sponza", type=Path, default=DEFAULT_SPONZA)
    parser.add_argument("--passes", nargs="*", choices=sorted(set(PASS_CHANNELS) - {"Combined"}),
                        metavar="PASS", help="passes besides Combined instead of the view "
                        "layer's, e.g. --passes Depth (none: Combined alone)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a VPL GI setting instead of the scene's, e.g. --set bounces=1")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--save", type=Path, metavar="DIR",
                       help="export the scenes at --size to DIR and render nothing")
    where.add_argument("--load", type=Path, metavar="DIR",
                       help="render the scenes --save wrote to DIR, without Blender")
    args = parser.parse_args()
    try:
        args.overrides = parse_overrides(args.set)
    except CliError as exc:
        parser.error(str(exc))
    if args.load is not None:
        from_files(args)
    else:
        from_blender(args, tuple(int(v) for v in args.size.lower().split("x")))


if __name__ == "__main__":
    main()
