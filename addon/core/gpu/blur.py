"""The geometry-aware blur that removes the interleaved-sampling pattern (gpu_shaders/
interleave_lib.glsl) from the indirect light without blurring across depth or normal edges."""

from __future__ import annotations

from collections.abc import Sequence

import moderngl

from .gl import ProgramCache, draw_into_new_textures, set_sampler_array, set_uniforms

AXES = ((1, 0), (0, 1))
MAX_SOURCES = 4  # light textures per draw (every OpenGL 3.3 context has 8 draw buffers)
NORMAL_POWER = 32.0  # the normal weight: pow(n_p · n_q, NORMAL_POWER)
PLANE_TOLERANCE = 0.01  # tangent-plane distance, relative to view depth, of weight 1/e


class GeometryAwareBlur:
    """A separable cross-bilateral filter over RGBA32F light textures, steered by the g-buffer's
    position (xyz world, w view depth) and normal (xyz, w 1 on surfaces) textures. Several light
    textures of one g-buffer are blurred in one draw per axis (the weights computed once)."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache) -> None:
        self.ctx = ctx
        self.programs = programs
        self._vao: dict[int, moderngl.VertexArray] = {}

    def apply(self, sources: Sequence[moderngl.Texture], position: moderngl.Texture,
              normal: moderngl.Texture, radius: int, normal_power: float = NORMAL_POWER,
              plane_tolerance: float = PLANE_TOLERANCE) -> list[moderngl.Texture]:
        """New RGBA32F textures (the caller releases them), one per source, each blurred over
        2·radius pixels per axis; with interleave size K dividing 2·radius the K×K pattern
        cancels on flat surfaces. ``normal_power`` sharpens the normal weight,
        ``plane_tolerance`` is the tangent-plane distance, relative to view depth, at which a
        tap's weight drops to 1/e. Leaves blending disabled and texture units 0.. bound."""
        if radius < 0:
            raise ValueError(f"blur radius must be ≥ 0, not {radius}")
        if not 1 <= len(sources) <= MAX_SOURCES:
            raise ValueError(f"blur takes 1 to {MAX_SOURCES} light textures, not {len(sources)}")
        if any(t.size != position.size for t in sources) or normal.size != position.size:
            raise ValueError("light, position and normal textures differ in size")
        count = len(sources)
        program = self.programs.get("fullscreen_vert.glsl", "blur_frag.glsl",
                                    {"SOURCES": count})
        if count not in self._vao:
            self._vao[count] = self.ctx.vertex_array(program, [])
        position.use(0)
        normal.use(1)
        set_uniforms(program, u_position=0, u_normal=1, u_radius=radius,
                     u_normal_power=normal_power, u_plane_tolerance=plane_tolerance)
        set_sampler_array(program, "u_source", 2, count)
        self.ctx.disable(moderngl.BLEND)
        across = self._pass(self._vao[count], program, sources, AXES[0])
        try:
            return self._pass(self._vao[count], program, across, AXES[1])
        finally:
            for texture in across:
                texture.release()

    def _pass(self, vao: moderngl.VertexArray, program: moderngl.Program,
              sources: Sequence[moderngl.Texture], axis: tuple[int, int]
              ) -> list[moderngl.Texture]:
        """Blur ``sources`` along one axis into new textures."""
        for unit, texture in enumerate(sources, start=2):
            texture.use(unit)
        program["u_axis"].value = axis
        return draw_into_new_textures(self.ctx, vao, sources[0].size, len(sources))

    def release(self) -> None:
        """Free the vertex arrays (the programs belong to the ProgramCache)."""
        for vao in self._vao.values():
            vao.release()
        self._vao.clear()
