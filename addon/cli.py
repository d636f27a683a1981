"""Command line: ``python -m addon render SCENE.blend -o OUT`` renders like
``blender -b SCENE.blend -E VPL_GI -o OUT -f N``, with a progress bar and clear errors."""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

from . import ENGINE_ID
from .core.settings import SettingsError
from .interrupts import interrupts

FORMATS = {".png": "PNG", ".exr": "OPEN_EXR", ".jpg": "JPEG", ".jpeg": "JPEG",
           ".tif": "TIFF", ".tiff": "TIFF", ".bmp": "BMP", ".tga": "TARGA", ".hdr": "HDR",
           ".webp": "WEBP"}
"""Image formats by file extension: what Blender writes for each."""
MIN_RESOLUTION = 4  # Blender's smallest resolution_x/y: it silently raises smaller values


class CliError(Exception):
    """A problem with the command line's input; printed as one line, exit code 2."""


def parse_frames(text: str) -> list[int]:
    """'5' -> [5]; '1..10' or '1-10' -> 1..10 inclusive; '1,4,7' -> those frames."""
    frames: list[int] = []
    for part in text.split(","):
        part = part.strip()
        sep = ".." if ".." in part else ("-" if "-" in part.lstrip("-") else None)
        try:
            if sep:
                start_text, end_text = part.lstrip("-").split(sep, 1) if part.startswith("-") \
                    else part.split(sep, 1)
                start = -int(start_text) if part.startswith("-") else int(start_text)
                end = int(end_text)
                if end < start:
                    raise CliError(f"frame range '{part}' ends before it starts")
                frames.extend(range(start, end + 1))
            else:
                frames.append(int(part))
        except ValueError:
            raise CliError(f"cannot read frames '{text}' (use 5, 1..10 or 1,4,7)") from None
    return frames


def parse_resolution(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise CliError(f"cannot read resolution '{text}' (use WIDTHxHEIGHT, e.g. 640x480)") \
            from None
    if not (MIN_RESOLUTION <= width <= 65536 and MIN_RESOLUTION <= height <= 65536):
        raise CliError(f"resolution {width}x{height} is outside {MIN_RESOLUTION}..65536 "
                       f"(Blender's limits)")
    return width, height


def check_output_pattern(pattern: str) -> None:
    """Refuse an output that names a folder or an image format Blender cannot write."""
    path = Path(pattern).expanduser()
    if pattern.endswith(("/", os.sep)) or path.is_dir():
        raise CliError(f"-o names a folder: {pattern} (give an image path, e.g. "
                       f"{path / 'frame_####.png'})")
    suffix = path.suffix.lower()
    if suffix and not suffix[1:].isdigit() and suffix not in FORMATS:
        raise CliError(f"cannot write '{path.suffix}' images (use one of "
                       f"{', '.join(sorted(FORMATS))}, or no extension for .png)")


def output_path(pattern: str, frame: int, many: bool) -> Path:
    """Blender's rule: '#'s become the zero-padded frame; otherwise several frames get
    _NNNN before the extension. A path without an image extension gets .png."""
    path = Path(pattern).expanduser()
    if path.suffix.lower() not in FORMATS:
        path = path.with_name(path.name + ".png")
    name = path.stem
    if "#" in name:
        width = name.count("#")
        first = name.index("#")
        name = name[:first] + f"{frame:0{width}d}" + name[first:].replace("#", "")
    elif many:
        name = f"{name}_{frame:04d}"
    return path.with_name(name + path.suffix)


def check_output(path: Path, scene_file: Path) -> None:
    """Refuse outputs that would overwrite the scene or cannot be written."""
    if path.resolve() == scene_file.resolve():
        raise CliError(f"refusing to write the image over the scene file: {path}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f"cannot create output folder {path.parent}: {exc.strerror}") from None
    if path.is_dir():
        raise CliError(f"output is a folder: {path}")
    if not os.access(path.parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise CliError(f"output is not writable: {path}")


def check_image_size(render) -> None:
    """Refuse a render whose image (resolution × percentage, cut by the render border) has
    no pixels, as Blender computes it, before anything renders."""
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    size = f"{render.resolution_x}x{render.resolution_y} at {render.resolution_percentage} %"
    if width < 1 or height < 1:
        raise CliError(f"the image has no pixels: {size} is {width}x{height}")
    if render.use_border:
        width = int(render.border_max_x * width) - int(render.border_min_x * width)
        height = int(render.border_max_y * height) - int(render.border_min_y * height)
        if width < 1 or height < 1:
            raise CliError(f"the render border leaves no pixels of the {size} image "
                           f"(turn the border off or widen it)")




def view_paths(render, path: Path) -> list[Path]:
    """The files Blender writes a render to: ``path``, or with stereoscopy and individual
    views one per view, its suffix (_L, _R, or each view's) before the extension."""
    if not render.use_multiview or render.image_settings.views_format != "INDIVIDUAL":
        return [path]
    suffixes = ["_L", "_R"] if render.views_format == "STEREO_3D" else \
        [view.file_suffix for view in render.views if view.use]
    return [path.with_name(path.stem + suffix + path.suffix) for suffix in suffixes]


def save_result(image, scene, path: Path, since: float) -> list[Path]:
    """Save the Render Result to ``path`` (per view_paths); the files written. Blender
    writes each view's file and then reports the plain path unsaved: that is no error where
    every view's file was written after ``since``."""
    paths = view_paths(scene.render, path)
    if paths == [path]:
        image.save_render(filepath=str(path.resolve()), scene=scene)
        return paths
    try:
        with quiet_output():  # Blender's own report of the plain path, which is not an error
            image.save_render(filepath=str(path.resolve()), scene=scene)
    except RuntimeError as exc:
        if not all(p.exists() and p.stat().st_mtime >= since for p in paths):
            raise CliError(f"could not save {path}: {str(exc).strip()}") from None
    return paths


@contextmanager
def quiet_output() -> Iterator[None]:
    """The process's standard output and error (Blender's C reports too) sent nowhere
    while inside."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            os.dup2(null.fileno(), 2)
            yield
    finally:
        for fd, copy in zip((1, 2), saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)


class ProgressBar:
    """A one-line progress bar on stderr for frames and the stages within a frame; in a log
    (not a terminal) one line per stage, as Blender 5.x no longer prints its own stats lines
    in the background."""

    def __init__(self, frames: int, stream=sys.stderr) -> None:
        self.frames, self.frame_index, self.stream = frames, 0, stream
        self.interactive = stream.isatty()
        self.last_message: str | None = None

    def update(self, fraction: float, message: str) -> None:
        total = (self.frame_index + max(0.0, min(1.0, fraction))) / self.frames
        filled = int(total * 30)
        line = (f"\r[{'#' * filled}{'.' * (30 - filled)}] {total * 100:5.1f}% "
                f"frame {self.frame_index + 1}/{self.frames} {message[:40]:<40}")
        if self.interactive:
            self.stream.write(line)
        elif message != self.last_message or fraction >= 1.0:
            self.stream.write(line.lstrip("\r").rstrip() + "\n")
        else:
            return
        self.last_message = message
        self.stream.flush()

    def finish_frame(self) -> None:
        self.frame_index += 1
        self.last_message = None
        if self.interactive:
            self.stream.write("\n")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m addon", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    render = sub.add_parser("render", help="render frames of a .blend file with VPL GI")
    render.add_argument("scene", type=Path, help="the .blend file (never modified)")
    render.add_argument("-o", "--output", required=True,
                        help="image path; '#' marks the frame number; .png (view transform "
                             "applied) or .exr (linear)")
    render.add_argument("-f", "--frames", help="frames: 5, 1..10 or 1,4,7 (default: current)")
    render.add_argument("-r", "--resolution", help="override resolution, WIDTHxHEIGHT")
    render.add_argument("-p", "--percentage", type=int, help="override resolution percentage")
    render.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="override a VPL GI setting, e.g. --set light_samples=64 "
                             "(repeatable; names as in core/settings.py)")
    render.add_argument("--gpu", type=int, metavar="N",
                        help="render on EGL device N where there are several (default: "
                             "$VPLGI_GPU, else the first); `gpus` lists them")
    render.set_defaults(run=run_render)
    gpus = sub.add_parser("gpus", help="list the OpenGL (EGL) devices VPL GI can render on")
    gpus.set_defaults(run=run_gpus)
    from .blender_args import add_subcommand  # after CliError and run_render exist
    add_subcommand(sub)
    return parser


def parse_overrides(pairs: list[str]) -> dict[str, int | float | str | bool]:
    """'name=value' pairs read by the settings schema, checked together."""
    from .core.settings import Settings

    overrides: dict[str, int | float | str | bool] = {}
    try:
        for pair in pairs:
            name, sep, text = pair.partition("=")
            if not sep:
                raise CliError(f"--set {pair}: expected NAME=VALUE, e.g. light_samples=64")
            overrides[name.strip()] = Settings.parse(name.strip(), text)
        replace(Settings(), **overrides).validate()
    except SettingsError as exc:
        raise CliError(str(exc)) from None
    return overrides


def run_gpus(_args: argparse.Namespace) -> int:
    """Print one line per EGL device; the first is the default."""
    from .core.gpu.gl import GLUnavailableError, list_devices

    try:
        devices = list_devices()
    except GLUnavailableError as exc:
        raise CliError(str(exc)) from None
    if not devices:
        raise CliError("EGL finds no device: no GPU driver and no Mesa software renderer "
                       "(install libegl-mesa0 and libgl1-mesa-dri)")
    print("\n".join(devices))
    return 0


def select_gpu(device: int | None) -> None:
    """Make ``device`` the EGL device of this process's renders (before the first render)."""
    if device is None:
        return
    from .core.gpu.gl import GPU_VARIABLE

    if device < 0:
        raise CliError(f"--gpu {device}: device numbers start at 0 (`gpus` lists them)")
    os.environ[GPU_VARIABLE] = str(device)


def run_render(args: argparse.Namespace) -> int:
    scene_file: Path = args.scene
    if not scene_file.is_file():
        raise CliError(f"scene file not found: {scene_file}")
    if scene_file.suffix.lower() != ".blend":
        raise CliError(f"not a .blend file: {scene_file}")
    resolution = parse_resolution(args.resolution) if args.resolution else None
    if args.percentage is not None and not 1 <= args.percentage <= 1000:
        raise CliError(f"percentage {args.percentage} is outside 1..1000")
    overrides = parse_overrides(args.set)
    if Path(args.output).suffix.lower() == ".blend":
        raise CliError(f"refusing to write an image to a .blend path: {args.output}")
    check_output_pattern(args.output)
    select_gpu(getattr(args, "gpu", None))

    import bpy  # imported late: argument errors are reported without starting Blender

    from . import register, unregister
    from .engine import monitor
    from .export import TransformError, check_camera

    register()
    try:
        try:
            bpy.ops.wm.open_mainfile(filepath=str(scene_file.resolve()), load_ui=False)
        except RuntimeError as exc:
            raise CliError(f"cannot open {scene_file}: {str(exc).strip()}") from None
        if getattr(args, "prepare", None):  # the blender subcommand's --scene/--python-expr
            args.prepare(bpy)
        scene = bpy.context.scene
        if scene.camera is None:
            raise CliError(f"scene '{scene.name}' in {scene_file} has no active camera")
        frames = parse_frames(args.frames) if args.frames else [scene.frame_current]
        paths = [output_path(args.output, f, len(frames) > 1) for f in frames]
        for path in paths:
            check_output(path, scene_file)
        render = scene.render
        render.engine = ENGINE_ID
        if resolution:
            render.resolution_x, render.resolution_y = resolution
        if args.percentage is not None:
            render.resolution_percentage = args.percentage
        check_image_size(render)
        scene.vpl_gi.assign(overrides)
        bar = ProgressBar(len(frames))
        monitor.progress_listeners.append(bar.update)
        for frame, path in zip(frames, paths, strict=True):
            scene.frame_set(frame)
            try:
                check_camera(scene.camera)
            except TransformError as exc:
                raise CliError(f"frame {frame}: {exc}") from None
            settings = render.image_settings
            settings.file_format = FORMATS[path.suffix.lower()]
            if settings.file_format == "OPEN_EXR":
                settings.color_depth = "32"
            start = time.perf_counter()
            try:
                bpy.ops.render.render()
            except RuntimeError as exc:  # Blender's own refusal, or the engine's reported error
                monitor.last_error = monitor.last_error or str(exc).strip()
            bar.finish_frame()
            if monitor.last_error:
                print(f"error: frame {frame}: {monitor.last_error}", file=sys.stderr)
                return 1
            for warning in monitor.last_warnings:
                print(f"warning: {warning}", file=sys.stderr)
            if monitor.last_stats is not None:
                for note in monitor.last_stats.notes:
                    print(f"note: {note}")
                print(f"stages: {monitor.last_stats.summary()}")
            # Written only after a finished render, with the scene's colour management for
            # PNG (as Blender's -o does) and linear float for EXR.
            saving = time.perf_counter()
            with interrupts.saving:
                written = save_result(bpy.data.images["Render Result"], scene, path,
                                      time.time() - 1.0)
                for saved in written:
                    if getattr(args, "report_saved", None):  # the blender subcommand's lines
                        args.report_saved(saved, time.perf_counter() - start,
                                          time.perf_counter() - saving)
                    else:
                        print(f"Saved {saved} ({time.perf_counter() - start:.2f} s)",
                              flush=True)
        return 0
    finally:
        monitor.progress_listeners.clear()
        unregister()


def run_command(parser: argparse.ArgumentParser, argv: list[str] | None) -> int:
    """Parse ``argv`` and run the chosen command; a CliError is one ``error:`` line, exit 2."""
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except CliError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv)


def exit_process(code: int) -> None:
    """End a command-line process with ``code``. Once bpy is imported, without Python's
    teardown: bpy 4.2 then crashes (SIGSEGV, exit 139: its static destructors free registered
    classes after Python has finalized) and bpy 4.5 can hang (tests/conftest.py); every
    image is saved and every line printed by now."""
    sys.stdout.flush()
    sys.stderr.flush()
    if "bpy" in sys.modules:
        os._exit(code)
    sys.exit(code)
