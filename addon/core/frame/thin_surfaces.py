"""VPLs gathered in full on surfaces thinner than the interleaving pattern
(gpu_shaders/thin_surface_frag.glsl). Gathered once per pixel, each pixel of a K×K pattern
takes one K²-th of the VPLs, and the geometry-aware blur averages the pattern away where it
finds the pixel's surface around it. On a sunlit edge one pixel wide it finds a few of the K²
subsets, so a VPL in one of them lights every K-th pixel along the edge at K² times its
weight (Sponza, seed 4: 38.7 % error against 28.5 % per supersample). Those pixels gather
every VPL instead; the others keep their subset."""

from __future__ import annotations

from dataclasses import replace

import moderngl
import numpy as np

from ..gpu.blur import NORMAL_POWER, PLANE_TOLERANCE
from ..gpu.gl import ProgramCache, draw_into_new_textures, set_uniforms
from ..gpu.scene_buffers import SceneBuffers
from .gather import LightPass, gather
from .gbuffer import GBuffer
from .gpu_scope import GpuScope

MAX_PATTERN = 4  # K of the patterns the mask tells apart (K² bits in one float's mantissa)


def thin_surface_mask(ctx: moderngl.Context, programs: ProgramCache,
                      position: moderngl.Texture, normal: moderngl.Texture, interleave: int,
                      radius: int, scope: GpuScope) -> moderngl.Renderbuffer:
    """A depth renderbuffer of the g-buffer's size (``position``, ``normal``): 1 where the
    blur of ``radius`` finds under half of the K × K pattern's VPL subsets on the pixel's
    surface (K = ``interleave``, at most MAX_PATTERN), 0 elsewhere."""
    if not 1 <= interleave <= MAX_PATTERN:
        raise ValueError(f"thin surfaces are found for patterns up to {MAX_PATTERN}, "
                         f"not {interleave}")
    uniforms = {"u_position": 0, "u_normal": 1, "u_radius": radius, "u_interleave": interleave,
                "u_normal_power": NORMAL_POWER, "u_plane_tolerance": PLANE_TOLERANCE}
    position.use(0)
    normal.use(1)
    rows = programs.get("fullscreen_vert.glsl", "thin_surface_frag.glsl", {"ROWS": 1})
    set_uniforms(rows, **uniforms)
    ctx.disable(moderngl.BLEND)
    columns = scope.own(draw_into_new_textures(
        ctx, scope.own(ctx.vertex_array(rows, [])), position.size, 1)[0])
    columns.use(2)
    program = programs.get("fullscreen_vert.glsl", "thin_surface_frag.glsl")
    set_uniforms(program, u_columns=2, **uniforms)
    mask = scope.own(ctx.depth_renderbuffer(position.size))
    scope.own(ctx.framebuffer(depth_attachment=mask)).use()
    ctx.enable(moderngl.DEPTH_TEST)
    ctx.depth_func = "1"  # every fragment writes its depth
    scope.own(ctx.vertex_array(program, [])).render(moderngl.TRIANGLES, vertices=3)
    ctx.depth_func = "<"
    ctx.disable(moderngl.DEPTH_TEST)
    return mask


def gather_with_mask(ctx: moderngl.Context, programs: ProgramCache, light_pass: LightPass,
                     atlas: moderngl.Texture, gbuffer: GBuffer,
                     accumulator: moderngl.Framebuffer, mask: moderngl.Renderbuffer,
                     scene: SceneBuffers | None, centre: np.ndarray, radius: float,
                     bias: float, clear_atlas: moderngl.Texture | None = None) -> None:
    """Add an interleaved pass's light to ``accumulator`` (gather.gather) with its own pattern
    where ``mask`` is 0 and with every VPL where it is 1."""
    with GpuScope() as scope:
        target = scope.own(ctx.framebuffer(accumulator.color_attachments, mask))
        target.depth_mask = False  # tested (the full-screen triangle lies at 0.5), kept
        ctx.enable(moderngl.DEPTH_TEST)
        for depth_func, each in ((">", light_pass), ("<", replace(light_pass, interleave=1))):
            ctx.depth_func = depth_func
            gather(ctx, programs, each, atlas, gbuffer, target, scene, centre, radius, bias,
                   clear_atlas=clear_atlas)
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)
