"""OpenGL context and shader programs: a standalone (headless) moderngl context and a loader for
the GLSL files in ``gpu_shaders/`` with ``#include`` and ``#define`` support."""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import moderngl

SHADER_DIR = Path(__file__).resolve().parents[3] / "gpu_shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


class GLUnavailableError(RuntimeError):
    """No OpenGL 4.1 context, or no OpenGL feature a step needs, is available on this machine."""


def create_context() -> moderngl.Context:
    """A new standalone context, current in the calling thread (EGL first, then the platform
    default; OpenGL 4.3 where there is one, else 4.1, as on macOS), so Blender's own context is
    never touched."""
    errors = []
    for require in (430, 410):
        for kwargs in ({"backend": "egl"}, {}):
            try:
                return moderngl.create_standalone_context(require=require, **kwargs)
            except Exception as exc:  # glcontext raises plain Exceptions per backend
                errors.append(f"{kwargs.get('backend', 'default')} {require}: {exc}")
    raise GLUnavailableError("could not create an OpenGL 4.1 context (" + "; ".join(errors) + ")")


@cache
def shared_context() -> moderngl.Context:
    """One standalone context per process for final renders, created on first use."""
    return create_context()


def require_compute(ctx: moderngl.Context) -> None:
    """Raise GLUnavailableError unless ``ctx`` has OpenGL 4.3 (compute shaders, SSBOs)."""
    if ctx.version_code < 430:
        major, minor = divmod(ctx.version_code // 10, 10)
        raise GLUnavailableError("ray tracing needs OpenGL 4.3 compute shaders; this context has "
                                 f"{major}.{minor}")


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


class ProgramCache:
    """Compiled programs keyed by their shader files and defines."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._programs: dict[tuple, moderngl.Program | moderngl.ComputeShader] = {}

    def get(self, vertex: str, fragment: str, defines: dict[str, object] | None = None,
            version: int = 410) -> moderngl.Program:
        """The program of two ``gpu_shaders/`` files; ``version=430`` for shaders that include
        raytrace_lib.glsl (storage buffers)."""
        key = (vertex, fragment, tuple(sorted((defines or {}).items())), version)
        if key not in self._programs:
            self._programs[key] = self.ctx.program(
                vertex_shader=load_source(vertex, defines, version),
                fragment_shader=load_source(fragment, defines, version))
        return self._programs[key]

    def compute(self, name: str, defines: dict[str, object] | None = None
                ) -> moderngl.ComputeShader:
        """The compute shader ``gpu_shaders/<name>``, compiled as GLSL 4.30."""
        key = ("compute", name, tuple(sorted((defines or {}).items())))
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
