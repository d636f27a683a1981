"""A GL context with its compiled programs and the GPU helpers made on first use."""

from __future__ import annotations

from typing import TypeVar

import moderngl

from ..gpu.blur import GeometryAwareBlur
from ..gpu.gl import ProgramCache
from ..gpu.ism import ImperfectShadowMaps
from ..gpu.raytrace import RayTracer

Helper = TypeVar("Helper", RayTracer, ImperfectShadowMaps, GeometryAwareBlur)


class GpuSession:
    """The context frames render with; the ray tracer and imperfect shadow maps raise
    GLUnavailableError on first use without OpenGL 4.3. ``programs``: another session's
    compiled programs on the same context, shared (that session releases them)."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache | None = None) -> None:
        self.ctx = ctx
        self._owns_programs = programs is None
        self.programs = programs if programs is not None else ProgramCache(ctx)
        self.max_texture = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        self.max_storage = int(ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE") or 0) \
            if ctx.version_code >= 430 else 0  # bytes; 0: no storage buffers, no ray tracer
        self._helpers: dict[type, RayTracer | ImperfectShadowMaps | GeometryAwareBlur] = {}

    def _helper(self, cls: type[Helper]) -> Helper:
        if cls not in self._helpers:
            self._helpers[cls] = cls(self.ctx, self.programs)
        return self._helpers[cls]  # type: ignore[return-value]

    @property
    def tracer(self) -> RayTracer:
        return self._helper(RayTracer)

    @property
    def ism(self) -> ImperfectShadowMaps:
        return self._helper(ImperfectShadowMaps)

    @property
    def blur(self) -> GeometryAwareBlur:
        return self._helper(GeometryAwareBlur)

    @property
    def helpers(self) -> tuple[RayTracer | ImperfectShadowMaps | GeometryAwareBlur, ...]:
        """The helpers made so far."""
        return tuple(self._helpers.values())

    @property
    def ism_if_made(self) -> ImperfectShadowMaps | None:
        """The imperfect shadow maps helper if a frame made it (None otherwise)."""
        return self._helpers.get(ImperfectShadowMaps)  # type: ignore[return-value]

    def release(self) -> None:
        """Release the helpers and the programs it compiled (the context stays the caller's)."""
        for helper in self._helpers.values():
            helper.release()
        self._helpers.clear()
        if self._owns_programs:
            self.programs.release()
