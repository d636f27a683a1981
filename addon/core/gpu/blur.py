"""The geometry-aware blur that removes the interleaved-sampling pattern (gpu_shaders/
interleave_lib.glsl) from the indirect light without blurring across depth or normal edges."""

from __future__ import annotations

import moderngl

from .gl import ProgramCache

AXES = ((1, 0), (0, 1))


class GeometryAwareBlur:
    """A separable cross-bilateral filter over an RGBA32F light texture, steered by the g-buffer's
    position (xyz world, w view depth) and normal (xyz, w 1 on surfaces) textures."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache) -> None:
        self.ctx = ctx
        self.program = programs.get("fullscreen_vert.glsl", "blur_frag.glsl")
        self._vao = ctx.vertex_array(self.program, [])

    def apply(self, source: moderngl.Texture, position: moderngl.Texture,
              normal: moderngl.Texture, radius: int, normal_power: float = 32.0,
              plane_tolerance: float = 0.01) -> moderngl.Texture:
        """A new RGBA32F texture (the caller releases it) of ``source`` blurred over 2·radius
        pixels per axis; with interleave size K dividing 2·radius the K×K pattern cancels on
        flat surfaces. ``normal_power`` sharpens the normal weight, ``plane_tolerance`` is the
        tangent-plane distance, relative to view depth, at which a tap's weight drops to 1/e.
        Leaves blending disabled and texture units 0-2 bound."""
        if radius < 0:
            raise ValueError(f"blur radius must be ≥ 0, not {radius}")
        if not source.size == position.size == normal.size:
            raise ValueError("light, position and normal textures differ in size")
        position.use(1)
        normal.use(2)
        self.program["u_source"].value = 0
        self.program["u_position"].value = 1
        self.program["u_normal"].value = 2
        self.program["u_radius"].value = radius
        self.program["u_normal_power"].value = normal_power
        self.program["u_plane_tolerance"].value = plane_tolerance
        self.ctx.disable(moderngl.BLEND)
        across = self._pass(source, AXES[0])
        try:
            return self._pass(across, AXES[1])
        finally:
            across.release()

    def _pass(self, source: moderngl.Texture, axis: tuple[int, int]) -> moderngl.Texture:
        """Blur ``source`` along one axis into a new texture."""
        target = self.ctx.texture(source.size, 4, dtype="f4")
        fbo = self.ctx.framebuffer([target])
        try:
            fbo.use()
            source.use(0)
            self.program["u_axis"].value = axis
            self._vao.render(moderngl.TRIANGLES, vertices=3)
        finally:
            fbo.release()
        return target

    def release(self) -> None:
        """Free the vertex array (the program belongs to the ProgramCache)."""
        self._vao.release()
