"""OpenGL context and shader programs: a standalone (headless) moderngl context and a loader for
the GLSL files in ``gpu_shaders/`` with ``#include`` and ``#define`` support."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from functools import cache
from pathlib import Path

import moderngl
import numpy as np

SHADER_DIR = Path(__file__).resolve().parents[3] / "gpu_shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


GPU_VARIABLE = "VPLGI_GPU"
"""Environment variable naming the EGL device (0, 1, …) to render on, for machines with
several GPUs; ``python -m addon render --gpu N`` sets it, ``python -m addon gpus`` lists them."""
MAX_DEVICES = 16
REMEDY = ("update the graphics driver (Mesa 20.2 or newer gives OpenGL 4.5 without a GPU), "
          f"or choose another device (--gpu N or {GPU_VARIABLE}=N; `python -m addon gpus` "
          "lists them)")


VERSIONS = (430, 410)
"""The OpenGL versions a context is asked for, best first: 4.3 (compute shaders), else 4.1 (as
on macOS). Drivers such as NVIDIA's make 3.3 unless a newer version is asked for."""


class GLUnavailableError(RuntimeError):
    """No OpenGL 4.1 context, or no OpenGL feature a step needs, is available on this machine."""


def requested_device() -> int | None:
    """The EGL device ``VPLGI_GPU`` names, or None where it is unset (the first device)."""
    text = os.environ.get(GPU_VARIABLE, "").strip()
    if not text:
        return None
    if not text.isdigit():
        raise GLUnavailableError(f"{GPU_VARIABLE}={text!r} is not a device number (0, 1, …); "
                                 "`python -m addon gpus` lists the devices")
    return int(text)


def create_context(device: int | None = None) -> moderngl.Context:
    """A new standalone context, current in the calling thread, so Blender's own context is
    never touched: on EGL ``device`` (default: ``requested_device()``, else the first), else
    the platform default; OpenGL 4.3 where there is one, else 4.1 (as on macOS)."""
    device = requested_device() if device is None else device
    backends = [{"backend": "egl"}, {}] if device is None else \
        [{"backend": "egl", "device_index": device}]
    errors = []
    for require in VERSIONS:
        for kwargs in backends:
            try:
                return moderngl.create_standalone_context(require=require, **kwargs)
            except Exception as exc:  # glcontext raises plain Exceptions per backend
                errors.append(str(exc))
    raise GLUnavailableError(explain_failure(errors, device))


def explain_failure(errors: list[str], device: int | None) -> str:
    """What is missing, from the backends' errors, and what to do about it."""
    details = "; ".join(dict.fromkeys(errors))
    for error in errors:
        found = re.search(r"requested device index (\d+), but found (\d+) devices", error)
        if found:
            count = int(found.group(2))
            numbers = "0" if count == 1 else f"0–{count - 1}"
            return (f"GPU {device} does not exist: EGL finds {count} device"
                    f"{'s' if count != 1 else ''} ({numbers}); `python -m addon gpus` lists "
                    "them")
    if any("libEGL" in e and "not loaded" in e for e in errors):
        return ("no OpenGL: libEGL (headless OpenGL) is not installed"
                + (" and there is no X display" if any("XOpenDisplay" in e for e in errors)
                   else "")
                + "; install libegl1 with libegl-mesa0 (Mesa, works without a GPU) or the GPU "
                f"driver's EGL library (details: {details})")
    if any("eglCreateContext failed" in e for e in errors):
        return ("no OpenGL 4.1 core context: the driver offers an older OpenGL; " + REMEDY
                + f" (details: {details})")
    return f"could not create an OpenGL 4.1 context ({details})"


def list_devices() -> list[str]:
    """One line per EGL device: its index, renderer and OpenGL version (or why it cannot
    render). Probed in a thread of its own: a context made current here would replace the
    caller's (Blender's, or a renderer's)."""
    with ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(_probe_devices).result()


def _newest_context(index: int) -> moderngl.Context:
    """A context on EGL device ``index`` as a render makes it (the best of VERSIONS), else of
    the driver's default version, to say which it offers."""
    try:
        return create_context(index)
    except GLUnavailableError:  # the default's error (a missing device, say) is the one kept
        return moderngl.create_standalone_context(backend="egl", device_index=index)


def _probe_devices() -> list[str]:
    lines = []
    for index in range(MAX_DEVICES):
        try:
            ctx = _newest_context(index)
        except Exception as exc:  # glcontext raises plain Exceptions
            if "requested device index" in str(exc):
                break
            if "not loaded" in str(exc):
                raise GLUnavailableError(explain_failure([str(exc)], None)) from None
            lines.append(f"{index}: unusable ({exc})")
            continue
        try:
            major, minor = divmod(ctx.version_code // 10, 10)
            note = "" if ctx.version_code >= 430 else " (VPL GI needs 4.3)"
            lines.append(f"{index}: {ctx.info['GL_RENDERER']}, OpenGL {major}.{minor}{note}")
        finally:
            ctx.release()
    return lines


def make_current(ctx: moderngl.Context) -> None:
    """Make ``ctx`` current in this thread, where other code (Blender 5's GPU compositor) may
    have made its own current since. Entered only: on EGL, leaving ``with ctx`` makes no
    context current, not the one before."""
    ctx.__enter__()


def shared_context(device: int | None = None) -> moderngl.Context:
    """One standalone context per process and device for final renders, made on first use."""
    return _context_of(device)


@cache
def _context_of(device: int | None) -> moderngl.Context:
    return create_context(device)


def require_compute(ctx: moderngl.Context) -> None:
    """Raise GLUnavailableError unless ``ctx`` has OpenGL 4.3 (compute shaders, SSBOs)."""
    if ctx.version_code < 430:
        major, minor = divmod(ctx.version_code // 10, 10)
        raise GLUnavailableError(
            "indirect light and ray-traced shadows need OpenGL 4.3 (compute shaders); "
            f"{ctx.info['GL_RENDERER']} offers {major}.{minor}: " + REMEDY
            + "; or render direct light only (bounces=0, direct_shadows=shadow_maps)")


def load_source(name: str, defines: dict[str, object] | None = None, version: int = 410) -> str:
    """Read ``gpu_shaders/<name>``, expand every ``#include "file"`` (lib files carry include
    guards, so an include inside an inactive ``#ifdef`` does not hide a later one), prepend
    ``#version <version> core`` and the defines."""

    def expand(file_name: str, stack: tuple[str, ...]) -> str:
        if file_name in stack:
            raise ValueError(f"circular #include of {file_name}: {' -> '.join(stack)}")
        text = (SHADER_DIR / file_name).read_text(encoding="utf-8")
        return _INCLUDE.sub(lambda m: expand(m.group(1), (*stack, file_name)), text)

    header = "".join(f"#define {k} {v}\n" for k, v in sorted((defines or {}).items()))
    return f"#version {version} core\n" + header + expand(name, ())


@cache
def included(name: str) -> frozenset[str]:
    """The ``gpu_shaders/`` files ``name`` includes, directly or not."""
    text = (SHADER_DIR / name).read_text(encoding="utf-8")
    direct = set(_INCLUDE.findall(text))
    return frozenset(direct.union(*(included(f) for f in direct)))


RAY_LIB = "raytrace_lib.glsl"


class ProgramCache:
    """Compiled programs keyed by their shader files and defines. ``ray_defines`` (set by
    RayTracer.upload: what its scene needs, e.g. RT_CUTOUTS) are added to the defines of every
    program that includes raytrace_lib.glsl."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._programs: dict[tuple, moderngl.Program | moderngl.ComputeShader] = {}
        self.ray_defines: dict[str, object] = {}

    def _defines(self, files: tuple[str, ...], defines: dict[str, object] | None
                 ) -> dict[str, object]:
        defines = defines or {}
        if self.ray_defines and any(RAY_LIB in included(f) for f in files):
            return {**defines, **self.ray_defines}
        return defines

    def get(self, vertex: str, fragment: str, defines: dict[str, object] | None = None,
            version: int = 410) -> moderngl.Program:
        """The program of two ``gpu_shaders/`` files; ``version=430`` for shaders that include
        raytrace_lib.glsl (storage buffers)."""
        defines = self._defines((vertex, fragment), defines)
        key = (vertex, fragment, tuple(sorted(defines.items())), version)
        if key not in self._programs:
            self._programs[key] = self.ctx.program(
                vertex_shader=load_source(vertex, defines, version),
                fragment_shader=load_source(fragment, defines, version))
        return self._programs[key]

    def __len__(self) -> int:
        """How many programs are compiled."""
        return len(self._programs)

    def compute(self, name: str, defines: dict[str, object] | None = None
                ) -> moderngl.ComputeShader:
        """The compute shader ``gpu_shaders/<name>``, compiled as GLSL 4.30."""
        defines = self._defines((name,), defines)
        key = ("compute", name, tuple(sorted(defines.items())))
        if key not in self._programs:
            self._programs[key] = self.ctx.compute_shader(load_source(name, defines, 430))
        return self._programs[key]

    def release(self) -> None:
        for program in self._programs.values():
            program.release()
        self._programs.clear()


def set_uniforms(program: moderngl.Program, **values: object) -> None:
    """Set the uniforms the compiler kept (unused ones are optimised away)."""
    for name, value in values.items():
        if name in program:
            program[name].value = value


def set_sampler_array(program: moderngl.Program, name: str, first: int, count: int) -> None:
    """Point the sampler array ``name`` at texture units ``first`` .. ``first + count - 1``
    (an array of one takes a plain unit)."""
    program[name].value = list(range(first, first + count)) if count > 1 else first


def copy_into_texture(ctx: moderngl.Context, texture: moderngl.Texture,
                      source: moderngl.Framebuffer) -> None:
    """Copy the first colour attachment of ``source`` into ``texture``, which keeps its
    format. (moderngl's ``copy_framebuffer`` into a texture re-specifies it as unsized RGBA: 8
    bits a channel, clamped to [0, 1], on llvmpipe; framebuffer to framebuffer it is a blit,
    which needs as many attachments on both sides.)"""
    first = ctx.framebuffer(source.color_attachments[:1])
    target = ctx.framebuffer([texture])
    try:
        ctx.copy_framebuffer(target, first)
    finally:
        target.release()
        first.release()


def draw_into_new_textures(ctx: moderngl.Context, vao: moderngl.VertexArray,
                           size: tuple[int, int], count: int) -> list[moderngl.Texture]:
    """Draw ``vao``'s full-screen triangle (fullscreen_vert.glsl), without blending, into
    ``count`` new RGBA32F textures of ``size``, which the caller releases."""
    targets = [ctx.texture(size, 4, dtype="f4") for _ in range(count)]
    fbo = ctx.framebuffer(targets)
    try:
        fbo.use()
        ctx.disable(moderngl.BLEND)
        vao.render(moderngl.TRIANGLES, vertices=3)
    finally:
        fbo.release()
    return targets


def read_textures(textures: Sequence[moderngl.Texture]) -> np.ndarray:
    """RGBA32F textures side by side as one (h, w, 4 × len(textures)) float32 array."""
    w, h = textures[0].size
    return np.concatenate([np.frombuffer(t.read(), dtype=np.float32).reshape(h, w, 4)
                           for t in textures], axis=-1)
