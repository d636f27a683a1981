"""Bias compensation from the frame's own image (gpu_shaders/near_field_frag.glsl): the light
the VPL clamp removes, brought back by short rays whose hits take their radiance from the
direct and indirect light already gathered. One ray per supersample and pass costs about what
one hard light's shadow rays do; the blur that follows averages the rays of neighbours. Hits
the camera does not see (off screen, hidden, seen from behind: a window's sill beside the
image's edge, a ceiling above it) become surface samples whose light is gathered there
instead (direct light, and with more than one bounce the VPLs' light)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import moderngl

from ..gpu.gl import ProgramCache, copy_into_texture, set_uniforms
from ..gpu.scene_buffers import GGX_TABLES_UNIT, MATERIAL_UNITS, SceneBuffers
from .gather import SURFACE_VERTICES_BINDING
from .gbuffer import GBuffer
from .gpu_scope import GpuScope

MATCH_FRACTION = 0.1  # a hit matches the surface seen at its pixel within this × the clamp
TEXTURE_UNITS = [u for u in range(16) if u not in (*MATERIAL_UNITS, GGX_TABLES_UNIT)]

GatherAt = Callable[[GBuffer, moderngl.Framebuffer], None]
"""Adds the light at a g-buffer's surface samples to an accumulator."""


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
                          indirect: moderngl.Framebuffer, target: moderngl.Framebuffer,
                          ray_offset: float, scene: SceneBuffers, gather_at: GatherAt) -> None:
    """Add the near-field light to ``target`` (additive blending), with rays from the
    supersamples of ``gbuffer``, one ray per draw. ``direct``: the direct light's accumulators
    (``gbuffer``'s size), hard and (when soft lights are interleaved) soft; ``indirect``: the
    indirect light (per pixel or per supersample), which may be ``target`` itself. Hits the
    camera does not see get their light from ``gather_at``. The ray tracer's scene
    (``scene``'s triangles) must be bound."""
    with GpuScope() as scope:
        size = target.size
        clamped = scope.own(ctx.texture(indirect.size, 4, dtype="f4"))  # read back
        copy_into_texture(ctx, clamped, indirect)
        textures = gbuffer.textures
        units = {"u_position": textures["position"], "u_normal": textures["normal"],
                 "u_geometric": textures["geometric"], "u_albedo": textures["albedo"],
                 "u_direct": direct[0].color_attachments[0], "u_indirect": clamped}
        defines: dict[str, object] = {"GLOSSY": 1} if len(target.color_attachments) > 1 \
            else {}
        if near.indirect_at_hits:
            defines["INDIRECT_AT_HITS"] = 1
        if direct[1] is not None:
            units["u_soft_direct"] = direct[1].color_attachments[0]
            defines["SOFT_DIRECT"] = 1
        first_hit = len(target.color_attachments)
        defines.update(HIT_POSITION_LOCATION=first_hit, HIT_NORMAL_LOCATION=first_hit + 1,
                       HIT_FACTOR_LOCATION=first_hit + 2,
                       SURFACE_VERTICES_BINDING=SURFACE_VERTICES_BINDING)
        hits = [scope.own(ctx.texture(size, 4, dtype="f4")) for _ in range(3)]
        unseen = scope.own(ctx.depth_renderbuffer(size))  # 1 at unseen hits, 0 elsewhere
        draw = scope.own(ctx.framebuffer([*target.color_attachments, *hits], unseen))
        hit_targets = scope.own(ctx.framebuffer(hits))
        program = programs.get("fullscreen_vert.glsl", "near_field_frag.glsl", defines,
                               version=430)
        vao = scope.own(ctx.vertex_array(program, []))
        for ray in range(near.samples):
            for unit, texture in zip(TEXTURE_UNITS, units.values(), strict=False):
                texture.use(unit)
            set_uniforms(program, **dict(zip(units, TEXTURE_UNITS, strict=False)),
                         u_view_projection=gbuffer.view_projection,
                         u_clamp_distance=near.clamp_distance, u_ray_offset=ray_offset,
                         u_match_distance=MATCH_FRACTION * near.clamp_distance,
                         u_samples=near.samples, u_seed=near.seed, u_ray=ray)
            scene.bind_materials(program)
            scene.positions.bind_to_storage_buffer(SURFACE_VERTICES_BINDING)
            hit_targets.clear(0.0, 0.0, 0.0, 0.0)
            draw.use()
            ctx.enable(moderngl.BLEND | moderngl.DEPTH_TEST)
            ctx.depth_func = "1"  # every fragment writes its depth
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            vao.render(moderngl.TRIANGLES, vertices=3)
            ctx.depth_func = "<"
            ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
            _add_offscreen(ctx, programs, hits, unseen, target, gather_at, gbuffer)


def _add_offscreen(ctx: moderngl.Context, programs: ProgramCache, hits: list[moderngl.Texture],
                   unseen: moderngl.Renderbuffer, indirect: moderngl.Framebuffer,
                   gather_at: GatherAt, like: GBuffer) -> None:
    """Gather the light at the unseen hits (position, normal, factor) and add it,
    times each hit's factor, to the indirect light's diffuse target. The depth test against
    ``unseen`` (1 at those hits, 0 elsewhere; the full-screen draw is at 0.5) keeps the
    gather from running anywhere else: most samples' rays hit what the camera sees, or
    nothing."""
    with GpuScope() as scope:
        position, normal, factor = hits
        samples = GBuffer({"position": position, "normal": normal, "geometric": normal}, {},
                          like.view_projection)
        light = scope.own(ctx.framebuffer([scope.own(ctx.texture(position.size, 4,
                                                                 dtype="f4"))], unseen))
        light.depth_mask = False  # tested, not written: clear() keeps it too
        light.clear(0.0, 0.0, 0.0, 0.0)
        ctx.enable(moderngl.DEPTH_TEST)
        gather_at(samples, light)
        ctx.disable(moderngl.DEPTH_TEST)
        light.color_attachments[0].use(0)
        factor.use(1)
        program = programs.get("fullscreen_vert.glsl", "modulate_frag.glsl")
        set_uniforms(program, u_light=0, u_factor=1)
        scope.own(ctx.framebuffer([indirect.color_attachments[0]])).use()
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        scope.own(ctx.vertex_array(program, [])).render(moderngl.TRIANGLES, vertices=3)
        ctx.disable(moderngl.BLEND)
