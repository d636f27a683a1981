"""Bias compensation from the frame's own image (gpu_shaders/near_field_frag.glsl): the light
the VPL clamp removes, brought back by short rays whose hits take their radiance from the
direct and indirect light already gathered. One ray per supersample and pass costs about what
one hard light's shadow rays do; the blur that follows averages the rays of neighbours."""

from __future__ import annotations

from dataclasses import dataclass

import moderngl

from ..gpu.gl import ProgramCache, set_uniforms
from .gbuffer import GBuffer
from .gpu_scope import GpuScope

MATCH_FRACTION = 0.1  # a hit matches the surface seen at its pixel within this × the clamp
RAYS_PER_DRAW = 16  # llvmpipe ends a shader invocation's loops after 65535 iterations


@dataclass(frozen=True)
class NearField:
    """Parameters of the image-based bias compensation."""

    clamp_distance: float
    samples: int
    seed: int
    indirect_at_hits: bool  # the hits' indirect light may bounce once more (bounces > 1)


def compensate_from_image(ctx: moderngl.Context, programs: ProgramCache, near: NearField,
                          gbuffer: GBuffer,
                          direct: tuple[moderngl.Framebuffer, moderngl.Framebuffer | None],
                          indirect: moderngl.Framebuffer, ray_offset: float) -> None:
    """Add the near-field light to ``indirect`` (additive blending). ``direct``: the direct
    light's accumulators, hard and (when soft lights are interleaved) soft. The ray tracer's
    scene must be bound."""
    with GpuScope() as scope:
        size = indirect.size
        clamped = scope.own(ctx.texture(size, 4, dtype="f4"))  # the indirect light read back
        ctx.copy_framebuffer(clamped, indirect)
        textures = gbuffer.textures
        units = {"u_position": textures["position"], "u_normal": textures["normal"],
                 "u_geometric": textures["geometric"], "u_albedo": textures["albedo"],
                 "u_direct": direct[0].color_attachments[0], "u_indirect": clamped}
        defines = {"GLOSSY": 1} if len(indirect.color_attachments) > 1 else {}
        if near.indirect_at_hits:
            defines["INDIRECT_AT_HITS"] = 1
        if direct[1] is not None:
            units["u_soft_direct"] = direct[1].color_attachments[0]
            defines["SOFT_DIRECT"] = 1
        for unit, texture in enumerate(units.values()):
            texture.use(unit)
        program = programs.get("fullscreen_vert.glsl", "near_field_frag.glsl", defines,
                               version=430)
        set_uniforms(program, **{name: unit for unit, name in enumerate(units)},
                     u_view_projection=gbuffer.view_projection,
                     u_clamp_distance=near.clamp_distance, u_ray_offset=ray_offset,
                     u_match_distance=MATCH_FRACTION * near.clamp_distance,
                     u_samples=near.samples, u_seed=near.seed)
        indirect.use()
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        vao = scope.own(ctx.vertex_array(program, []))
        for first in range(0, near.samples, RAYS_PER_DRAW):
            set_uniforms(program, u_first=first, u_count=min(RAYS_PER_DRAW, near.samples - first))
            vao.render(moderngl.TRIANGLES, vertices=3)
        ctx.disable(moderngl.BLEND)
