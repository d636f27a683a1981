"""Render cases with one source tree's own code, for tools/compare_images.py.

Run with cwd and PYTHONPATH set to the tree under test; this file may come from another tree.
Every render goes through the tree's ``Renderer.render`` (found wherever the tree defines it),
which is wrapped to keep a float copy of every pass of every frame, or the error it raised.

    python compare_runner.py scene FILE.blend OUT.npz [--size N]
        FILE rendered by the command line (``python -m addon render FILE -o X.exr``) with
        every optional pass enabled; OUT holds the core's passes and the linear EXR image.
    python compare_runner.py stability OUT_DIR [--only PATTERN ...] [--skip FILE.json]
        the tree's stability suite (tests/stability) under pytest; one OUT_DIR/<case>.npz per
        test and OUT_DIR/index.json listing every collected case.

Each .npz holds ``NNN/PASS`` arrays (render NNN of the case), ``NNN/error`` for a render that
raised, and ``meta/outcome``, ``meta/seconds``.
"""

from __future__ import annotations

import argparse
import fnmatch
import functools
import hashlib
import importlib
import json
import os
import pkgutil
import re
import runpy
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

# Blender's view-layer toggles of the passes the engine can fill (Blender's names, not ours).
PASS_TOGGLES = ("use_pass_z", "use_pass_normal", "use_pass_diffuse_direct",
                "use_pass_diffuse_indirect", "use_pass_diffuse_color", "use_pass_emit")


def case_file(case: str) -> str:
    """A file name for a case name: readable, and unique through a short hash."""
    readable = re.sub(r"[^A-Za-z0-9._-]+", "_", case)[:80]
    return f"{readable}-{hashlib.sha1(case.encode()).hexdigest()[:8]}.npz"


def matches(case: str, patterns: list[str] | None) -> bool:
    """True if no patterns are given, or one is a glob matching ``case`` or a substring of it."""
    return not patterns or any(fnmatch.fnmatchcase(case, p) or p in case for p in patterns)


def find_renderer_class() -> type:
    """The tree's Renderer: addon.core.pipeline.Renderer, else the first class of that name
    defined in a module anywhere under addon.core."""
    try:
        return importlib.import_module("addon.core.pipeline").Renderer
    except (ImportError, AttributeError):
        pass
    core = importlib.import_module("addon.core")
    for info in pkgutil.walk_packages(core.__path__, "addon.core."):
        module = importlib.import_module(info.name)
        cls = getattr(module, "Renderer", None)
        if isinstance(cls, type) and cls.__module__ == module.__name__:
            return cls
    raise SystemExit("compare_runner: no Renderer class under addon.core")


class Capture:
    """Wraps ``Renderer.render`` to keep each frame's passes (or the error raised)."""

    def __init__(self) -> None:
        self.renders: list[dict[str, np.ndarray] | str] = []

    def install(self, cls: type) -> None:
        original = cls.render

        @functools.wraps(original)
        def render(renderer: Any, *args: Any, **kwargs: Any) -> Any:
            try:
                result = original(renderer, *args, **kwargs)
            except Exception as exc:
                self.renders.append(f"{type(exc).__name__}: {exc}")
                raise
            frame = result[0] if isinstance(result, tuple) else result
            self.renders.append({name: np.array(image, copy=True)
                                 for name, image in frame.passes.items()})
            return result

        cls.render = render

    def save(self, path: Path, outcome: str, seconds: float,
             extra: dict[str, np.ndarray] | None = None) -> None:
        """Write the captured renders (and ``extra`` arrays) to ``path`` atomically."""
        arrays: dict[str, np.ndarray] = dict(extra or {})
        for index, render in enumerate(self.renders):
            if isinstance(render, str):
                arrays[f"{index:03d}/error"] = np.array(render)
            else:
                arrays.update({f"{index:03d}/{name}": image for name, image in render.items()})
        arrays["meta/outcome"] = np.array(outcome)
        arrays["meta/seconds"] = np.array(seconds)
        partial = path.with_name(path.name + ".partial")
        with partial.open("wb") as stream:
            np.savez(stream, **arrays)
        os.replace(partial, path)
        self.renders.clear()


def read_image(path: Path) -> np.ndarray:
    """An image file's float pixels as Blender loads them (rows bottom-up, RGBA)."""
    import bpy

    image = bpy.data.images.load(str(path))
    pixels = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(pixels)
    width, height = image.size
    bpy.data.images.remove(image)
    return pixels.reshape(height, width, -1)


def render_scene(blend: Path, out: Path, size: int | None) -> int:
    """Render ``blend`` through ``python -m addon render`` in this process."""
    import bpy

    @bpy.app.handlers.persistent
    def prepare(*_args: object) -> None:
        scene = bpy.context.scene
        for layer in scene.view_layers:
            for toggle in PASS_TOGGLES:
                setattr(layer, toggle, True)
        if size:
            render = scene.render
            scale = size / max(render.resolution_x, render.resolution_y)
            render.resolution_x = max(1, round(render.resolution_x * scale))
            render.resolution_y = max(1, round(render.resolution_y * scale))
            render.resolution_percentage = 100

    capture = Capture()
    capture.install(find_renderer_class())
    bpy.app.handlers.load_post.append(prepare)
    exr = out.with_suffix(".exr")
    sys.argv = ["addon", "render", str(blend), "-o", str(exr)]
    start = time.perf_counter()
    try:
        runpy.run_module("addon", run_name="__main__", alter_sys=True)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    seconds = time.perf_counter() - start
    extra = {"000/exr": read_image(exr)} if code == 0 and exr.is_file() else {}
    capture.save(out, "passed" if code == 0 else f"exit code {code}", seconds, extra)
    exr.unlink(missing_ok=True)
    return 0


class StabilityPlugin:
    """A pytest plugin: selects cases, and saves each test's renders as it finishes."""

    def __init__(self, tree: Path, out: Path, only: list[str] | None, skip: set[str]) -> None:
        self.tree, self.out, self.only, self.skip = tree, out, only, skip
        self.capture = Capture()
        self.capture.install(find_renderer_class())

    def case(self, item: Any) -> str:
        return f"{Path(item.path).relative_to(self.tree).as_posix()}::{item.name}"

    def pytest_collection_modifyitems(self, config: Any, items: list[Any]) -> None:
        names = [self.case(item) for item in items]
        (self.out / "index.json").write_text(json.dumps(names, indent=1), encoding="utf-8")
        keep = [matches(n, self.only) and n not in self.skip for n in names]
        config.hook.pytest_deselected(items=[i for i, k in zip(items, keep, strict=True)
                                             if not k])
        items[:] = [i for i, k in zip(items, keep, strict=True) if k]

    def pytest_collection_finish(self, session: Any) -> None:
        """Send the suite's results table (a module-level Path TABLE) to OUT_DIR, not the tree."""
        for module in list(sys.modules.values()):
            if isinstance(getattr(module, "TABLE", None), Path) and \
                    str(getattr(module, "__file__", "")).startswith(str(self.tree)):
                module.TABLE = self.out / "stability_table.md"

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_call(self, item: Any) -> Iterator[None]:
        """Start each case from a clean renderer (nothing reused from the previous test), so
        a case renders the same whichever cases ran before it."""
        renderer = item.funcargs.get("renderer")
        forget: Callable[[], None] | None = getattr(renderer, "forget_frames", None)
        if forget:
            forget()
        self.capture.renders.clear()
        start = time.perf_counter()
        outcome = yield
        excinfo = outcome.excinfo
        self.capture.save(self.out / case_file(self.case(item)),
                          "passed" if excinfo is None else excinfo[0].__name__,
                          time.perf_counter() - start)


def run_stability(out: Path, only: list[str] | None, skip: set[str]) -> int:
    tree = Path.cwd().resolve()
    out.mkdir(parents=True, exist_ok=True)
    # --rootdir=tests: pytest's importlib mode would otherwise import the repository's own
    # __init__.py as a package named after its folder, which fails for folder names that are
    # not identifiers.
    return pytest.main(["tests/stability", "-q", "-p", "no:cacheprovider", "--rootdir=tests"],
                       plugins=[StabilityPlugin(tree, out, only, skip)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    scene = sub.add_parser("scene")
    scene.add_argument("blend", type=Path)
    scene.add_argument("out", type=Path)
    scene.add_argument("--size", type=int)
    stability = sub.add_parser("stability")
    stability.add_argument("out", type=Path)
    stability.add_argument("--only", action="append")
    stability.add_argument("--skip", type=Path, help="JSON list of cases not to run")
    args = parser.parse_args()
    if args.mode == "scene":
        code = render_scene(args.blend.resolve(), args.out.resolve(), args.size)
    else:
        skip = set(json.loads(args.skip.read_text(encoding="utf-8"))) if args.skip else set()
        code = run_stability(args.out.resolve(), args.only, skip)
    # bpy 4.5 can hang in interpreter teardown (see tests/conftest.py): leave at once.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(int(code))


if __name__ == "__main__":
    main()
