"""``python -m addon blender ARGS``: Blender's own command line, for render farms (Flamenco)
at sites that use the bpy module instead of a Blender install.

Flamenco v3 workers run ``{blender} -b -y FILE.blend --scene S --python-expr '…'
--render-output DIR/###### --render-format PNG --render-frame 1,2`` and read the
``Saved: '<path>'`` and ``Time: …`` lines Blender prints, failing the task on a non-zero exit.
This reads that subset of Blender's arguments, in Blender's order (options act on the file
opened before them), and renders through ``cli.run_render`` (the same code as
``python -m addon render``, so frames are bit-identical), printing Blender's lines.

Unlike Blender, an exception in ``--python-expr``/``--python`` fails the command (exit 2):
on a farm a setting that did not apply is an error, not a warning.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
from pathlib import Path

from . import ENGINE_ID
from .cli import CliError, run_render

# Blender's --render-format names this launcher can write, and their file extensions.
FORMAT_EXTENSIONS = {"PNG": ".png", "OPEN_EXR": ".exr", "EXR": ".exr"}
# Options that take no value and change nothing here (the bpy module is always background).
IGNORED_FLAGS = {"-b", "--background", "-y", "--enable-autoexec", "-Y", "--disable-autoexec",
                 "--factory-startup", "-noaudio", "--quiet", "-q"}
# Options whose value is ignored here.
IGNORED_WITH_VALUE = {"-t", "--threads", "--python-exit-code"}
USAGE = ("usage: python -m addon blender [-b] [-y] FILE.blend [--scene NAME] "
         "[--python-expr EXPR] [--python FILE] [-E VPL_GI] [--render-output PATH] "
         "[--render-format PNG|OPEN_EXR] (--render-frame FRAMES | --render-anim) "
         "[-s START] [-e END]")


def timecode(seconds: float) -> str:
    """Blender's BLI_timecode_string_from_time_simple: MM:SS.hh, or HH:MM:SS.hh."""
    hundredths = int(seconds * 100)
    hours, rest = divmod(hundredths, 360000)
    minutes, rest = divmod(rest, 6000)
    secs, hund = divmod(rest, 100)
    if hours:
        return f"{hours:02d}:{minutes:02d}:{secs:02d}.{hund:02d}"
    return f"{minutes:02d}:{secs:02d}.{hund:02d}"


def parse(argv: list[str]) -> argparse.Namespace:
    """Blender's arguments -> a namespace for ``cli.run_render`` plus ``steps``: the scene
    and Python actions, in order, run after the file is opened."""
    scene_file: Path | None = None
    steps: list[tuple[str, str]] = []
    output, file_format, frames = None, "PNG", None
    anim, start, end = False, None, None
    args = list(argv)
    if args and args[0] == "--":
        args = args[1:]
    i = 0

    def value(option: str) -> str:
        nonlocal i
        if i + 1 >= len(args):
            raise CliError(f"{option} needs a value")
        i += 1
        return args[i]

    while i < len(args):
        arg = args[i]
        if arg == "--":  # the rest belongs to the Python scripts (sys.argv), as in Blender
            break
        if arg in IGNORED_WITH_VALUE:
            value(arg)
        elif arg in IGNORED_FLAGS:
            pass
        elif arg in ("-S", "--scene"):
            steps.append(("scene", value(arg)))
        elif arg == "--python-expr":
            steps.append(("expr", value(arg)))
        elif arg in ("-P", "--python"):
            steps.append(("script", value(arg)))
        elif arg in ("-E", "--engine"):
            engine = value(arg)
            if engine != ENGINE_ID:
                raise CliError(f"this launcher renders with {ENGINE_ID} only, not {engine}")
        elif arg in ("-o", "--render-output"):
            output = value(arg)
        elif arg in ("-F", "--render-format"):
            file_format = value(arg).upper()
            if file_format not in FORMAT_EXTENSIONS:
                raise CliError(f"render format {file_format} is not supported here "
                               f"(use {', '.join(FORMAT_EXTENSIONS)})")
        elif arg in ("-f", "--render-frame"):
            if frames is not None or anim:
                raise CliError("only one --render-frame/--render-anim is supported")
            frames = value(arg)
        elif arg in ("-a", "--render-anim"):
            if frames is not None:
                raise CliError("only one --render-frame/--render-anim is supported")
            anim = True
        elif arg in ("-s", "--frame-start"):
            start = int(value(arg))
        elif arg in ("-e", "--frame-end"):
            end = int(value(arg))
        elif arg.startswith("-"):
            raise CliError(f"unsupported Blender option {arg}\n{USAGE}")
        elif scene_file is None:
            scene_file = Path(arg)
        else:
            raise CliError(f"a second .blend file {arg} (one file per command)\n{USAGE}")
        i += 1
    if scene_file is None:
        raise CliError(f"no .blend file given\n{USAGE}")
    if frames is None and not anim:
        raise CliError(f"nothing to render: give --render-frame or --render-anim\n{USAGE}")
    if output is None:
        output = "//######"  # Blender's default output is the scene's; Flamenco always sets it
    return argparse.Namespace(
        scene=scene_file, output=output, file_format=file_format, frames=frames, anim=anim,
        frame_start=start, frame_end=end, steps=steps, resolution=None, percentage=None,
        set=[])


def output_pattern(output: str, file_format: str, scene_file: Path) -> str:
    """Blender's rules: '//' is the .blend's folder, a name without '#' gets '####' appended,
    and the format's extension is added unless the name already has it."""
    if output.startswith("//"):
        output = str(scene_file.resolve().parent / output[2:])
    head, name = os.path.split(output)
    extension = FORMAT_EXTENSIONS[file_format]
    if name.lower().endswith(extension):
        name = name[: -len(extension)]
    if "#" not in name:
        name += "####"
    return os.path.join(head, name + extension)


def make_prepare(args: argparse.Namespace):
    """The steps to run once the file is open: scene choice and Python, in order."""

    def prepare(bpy) -> None:
        for kind, text in args.steps:
            if kind == "scene":
                scene = bpy.data.scenes.get(text)
                if scene is None:
                    raise CliError(f"no scene '{text}' in {args.scene}")
                for window in bpy.context.window_manager.windows:
                    window.scene = scene
            else:
                source = Path(text).read_text() if kind == "script" else text
                namespace = {"__name__": "__main__", "bpy": bpy,
                             "__file__": text if kind == "script" else "<string>"}
                try:
                    exec(compile(source, namespace["__file__"], "exec"), namespace)
                except Exception:
                    traceback.print_exc()
                    raise CliError(f"--python{'-expr' if kind == 'expr' else ''} failed") \
                        from None
        scene = bpy.context.scene
        if args.anim:
            start = scene.frame_start if args.frame_start is None else args.frame_start
            end = scene.frame_end if args.frame_end is None else args.frame_end
            args.frames = f"{start}..{end}"

    return prepare


def report_saved(path: Path, seconds: float, saving: float) -> None:
    """Blender's lines after a written frame (Flamenco reads them at a line's start)."""
    print(f"Saved: '{path.resolve()}'")
    print(f"Time: {timecode(seconds)} (Saving: {timecode(saving)})")
    print(flush=True)


def run_blender(args: argparse.Namespace) -> int:
    """The ``blender`` subcommand: Blender's arguments are in ``args.blender_args``."""
    try:
        render_args = parse(args.blender_args)
        render_args.output = output_pattern(render_args.output, render_args.file_format,
                                            render_args.scene)
        render_args.prepare = make_prepare(render_args)
        render_args.report_saved = report_saved
        return run_render(render_args)
    except CliError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def add_subcommand(sub) -> None:
    """Register ``blender`` on the CLI's subparsers (one line in cli.build_parser)."""
    blender = sub.add_parser(
        "blender", help="Blender's command line (-b FILE.blend --render-frame ...) for farms",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        add_help=False, prefix_chars="\0")
    blender.add_argument("blender_args", nargs=argparse.REMAINDER)
    blender.set_defaults(run=run_blender)
