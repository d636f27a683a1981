"""OpenGL context and shader programs: a standalone (headless) moderngl context and a loader for
the GLSL files in ``gpu_shaders/`` with ``#include`` and ``#define`` support."""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import moderngl

SHADER_DIR = Path(__file__).resolve().parents[2] / "gpu_shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)
GLSL_VERSION = "#version 410 core\n"


class GLUnavailableError(RuntimeError):
    """No OpenGL 4.1 context could be created on this machine."""


@cache
def shared_context() -> moderngl.Context:
    """One standalone context per process, created on first use (EGL first, then the platform
    default), so Blender's own context is never touched."""
    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            return moderngl.create_standalone_context(require=410, **kwargs)
        except Exception as exc:  # glcontext raises plain Exceptions per backend
            errors.append(f"{kwargs.get('backend', 'default')}: {exc}")
    raise GLUnavailableError("could not create an OpenGL 4.1 context (" + "; ".join(errors) + ")")


def load_source(name: str, defines: dict[str, object] | None = None) -> str:
    """Read ``gpu_shaders/<name>``, expand ``#include "file"`` once per file, prepend defines."""
    seen: set[str] = set()

    def expand(file_name: str) -> str:
        if file_name in seen:
            return ""
        seen.add(file_name)
        text = (SHADER_DIR / file_name).read_text(encoding="utf-8")
        return _INCLUDE.sub(lambda m: expand(m.group(1)), text)

    header = "".join(f"#define {k} {v}\n" for k, v in sorted((defines or {}).items()))
    return GLSL_VERSION + header + expand(name)


class ProgramCache:
    """Compiled programs keyed by their shader files and defines."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._programs: dict[tuple, moderngl.Program] = {}

    def get(self, vertex: str, fragment: str, defines: dict[str, object] | None = None
            ) -> moderngl.Program:
        key = (vertex, fragment, tuple(sorted((defines or {}).items())))
        if key not in self._programs:
            self._programs[key] = self.ctx.program(
                vertex_shader=load_source(vertex, defines),
                fragment_shader=load_source(fragment, defines))
        return self._programs[key]

    def release(self) -> None:
        for program in self._programs.values():
            program.release()
        self._programs.clear()
