"""Clear surfaces (Material.is_clear) on the GPU: their triangles, and the camera's view
through them, the light the clear triangles in front of each supersample's surface (or of the
background) let through to the camera, rasterised against the g-buffer's depth
(gpu_shaders/clear_view_*.glsl). Shadow atlases draw them too (frame/shadow_maps.py)."""

from __future__ import annotations

import moderngl
import numpy as np

from ..scene.model import Camera
from .gl import ProgramCache, set_uniforms


def clear_vertices(triangles: np.ndarray, transmission: np.ndarray) -> np.ndarray:
    """(3C, 10) float32 vertex rows of clear triangles (C, 3, 3) with their transmission rows
    (C, 4): position, the triangle's unit normal, colour and Fresnel IOR. Triangles without
    an area are left out."""
    triangles = np.asarray(triangles, np.float32).reshape(-1, 3, 3)
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(normal, axis=1)
    keep = np.isfinite(length) & (length > 0)
    rows = np.empty((int(keep.sum()), 3, 10), np.float32)
    rows[:, :, :3] = triangles[keep]
    rows[:, :, 3:6] = (normal[keep] / length[keep, None])[:, None]
    rows[:, :, 6:] = np.asarray(transmission, np.float32).reshape(-1, 4)[keep][:, None]
    return rows.reshape(-1, 10)


class ClearView:
    """The clear triangles of a frame on the GPU, drawn once per image tile."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache, triangles: np.ndarray,
                 transmission: np.ndarray) -> None:
        vertices = clear_vertices(triangles, transmission)
        self.ctx = ctx
        self.vertex_count = len(vertices)
        self._buffer = ctx.buffer(vertices.tobytes()) if len(vertices) else None
        self._program = programs.get("clear_view_vert.glsl", "clear_view_frag.glsl")
        self._vao = self.vertex_array(self._program)

    def vertex_array(self, program: moderngl.Program) -> moderngl.VertexArray | None:
        """A new vertex array of the clear triangles for ``program`` (in_position, in_normal,
        in_transmission), which the caller releases; None where there are none."""
        if self._buffer is None:
            return None
        return self.ctx.vertex_array(program, [(self._buffer, "3f 3f 4f", "in_position",
                                                "in_normal", "in_transmission")])

    def transmittance(self, depth: moderngl.Renderbuffer, view_projection: tuple[float, ...],
                      camera: Camera) -> moderngl.Texture:
        """A new RGBA32F texture the size of ``depth`` (a g-buffer's depth, drawn with
        ``view_projection``), which the caller releases: per supersample, the product over the
        clear surfaces nearer than its surface of the light each lets through (1 where none)."""
        target = self.ctx.texture(depth.size, 4, dtype="f4")
        fbo = self.ctx.framebuffer([target], depth)
        try:
            fbo.depth_mask = False  # the g-buffer's depth is tested, never written or cleared
            fbo.use()
            fbo.clear(1.0, 1.0, 1.0, 1.0)
            if self._vao is None:
                return target
            set_uniforms(self._program, u_view_projection=view_projection,
                         **camera.view_uniforms)
            self.ctx.enable(moderngl.DEPTH_TEST | moderngl.BLEND)
            self.ctx.disable(moderngl.CULL_FACE)
            self.ctx.blend_func = moderngl.ZERO, moderngl.SRC_COLOR  # destination × fragment
            self._vao.render(moderngl.TRIANGLES, vertices=self.vertex_count)
        finally:
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            self.ctx.blend_func = moderngl.DEFAULT_BLENDING
            fbo.release()
        return target

    def release(self) -> None:
        for obj in (self._vao, self._buffer):
            if obj is not None:
                obj.release()
        self._vao = self._buffer = None
