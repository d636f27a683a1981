"""Shadow hints (gpu_shaders/shadow_hints_frag.glsl): the shadow rays of a ray-traced light
pass traced once per pixel first, so that the gather at every supersample traces its own rays
only where the 3×3 pixels around it disagree: shadow edges, penumbrae and silhouettes keep
every supersample's ray, lit and shadowed areas take the pixels' answer."""

from __future__ import annotations

import moderngl
import numpy as np

from ..gpu.gl import ProgramCache, set_uniforms
from .gather import RAY_OFFSET, LightPass, light_table_texture, mask_words
from .gbuffer import GBuffer
from .gpu_scope import GpuScope

MAX_HINTED_SAMPLES = 31  # bits of the hint texture (bit 31 marks pixels with hints)


def takes_hints(light_pass: LightPass) -> bool:
    """Whether a pass's gather can use shadow hints: direct light with ray-traced shadows, at
    most MAX_HINTED_SAMPLES in all, each hinted by its own rays at the pixels around, or a
    sun's angle samples interleaved one per supersample. Those are hinted by the neighbours'
    other samples, which only samples of nearly one direction can stand for: the world's or
    an area light's, interleaved, would take their neighbours' answer for other directions
    (through a window, mostly shadowed: a room's sky light 7 % dark). Shadow-linked samples
    take them where the pass's samples share their blockers (one hint draw traces all)."""
    blockers = light_pass.batch.samples.blockers
    if light_pass.indirect or light_pass.visibility.rays_per_sample == 0 \
            or (blockers is not None and len(np.unique(blockers)) > 1):
        return False
    if light_pass.interleave > 1:
        return light_pass.spread
    return len(light_pass.batch.samples) <= MAX_HINTED_SAMPLES


def render_hints(ctx: moderngl.Context, programs: ProgramCache, light_pass: LightPass,
                 pixels: GBuffer, factor: int, centre: np.ndarray, radius: float,
                 scope: GpuScope) -> moderngl.Texture:
    """The pass's shadow hints over the pixels' g-buffer (``factor`` supersamples per pixel
    edge), as a one-channel uint texture that ``scope`` owns. The ray tracer's scene must be
    bound."""
    size = pixels.textures["position"].size
    hints = scope.own(ctx.texture(size, 1, dtype="u4"))
    with GpuScope() as local:
        table = local.own(light_table_texture(ctx, light_pass.batch, centre, radius))
        for unit, name in enumerate(("position", "normal", "geometric")):
            pixels.textures[name].use(unit)
        table.use(3)
        samples = light_pass.batch.samples
        defines = {**light_pass.visibility.defines, "SHADOW_HINTS": 1}
        if samples.shadow_linked:  # one blocker mask for all (takes_hints)
            defines["RT_SHADOW_LINKING"] = 1
        program = programs.get("fullscreen_vert.glsl", "shadow_hints_frag.glsl", defines,
                               version=430)
        set_uniforms(program, u_position=0, u_normal=1, u_geometric=2, u_light_table=3,
                     u_count=len(samples), u_hint_factor=factor,
                     u_interleave=light_pass.interleave, u_ray_offset=RAY_OFFSET * radius)
        if samples.shadow_linked:
            set_uniforms(program, u_blockers=mask_words(int(samples.blockers[0])))
        fbo = local.own(ctx.framebuffer([hints]))
        fbo.use()
        ctx.disable(moderngl.BLEND)
        local.own(ctx.vertex_array(program, [])).render(moderngl.TRIANGLES, vertices=3)
    return hints
