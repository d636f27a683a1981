"""Light gathered once per pixel, brought to every supersample along the g-buffer's geometry
(gpu_shaders/upsample_frag.glsl), optionally plus light gathered per supersample."""

from __future__ import annotations

from collections.abc import Sequence

import moderngl

from .blur import MAX_SOURCES, NORMAL_POWER, PLANE_TOLERANCE
from .gl import ProgramCache, draw_into_new_textures, set_sampler_array, set_uniforms


def upsample(ctx: moderngl.Context, programs: ProgramCache, sources: Sequence[moderngl.Texture],
             pixels: tuple[moderngl.Texture, moderngl.Texture],
             supersamples: tuple[moderngl.Texture, moderngl.Texture], factor: int,
             added: Sequence[moderngl.Texture] | None = None,
             normal_power: float = NORMAL_POWER, plane_tolerance: float = PLANE_TOLERANCE
             ) -> list[moderngl.Texture]:
    """New RGBA32F textures (the caller releases them) of the supersamples' size, one per
    source, each plus its ``added`` texture (supersample light) where given. ``pixels`` and
    ``supersamples``: the (position, normal) g-buffer layers of the sources' samples and of
    the supersamples, ``factor`` supersamples per pixel edge; the weights are the blur's
    (GeometryAwareBlur.apply). Leaves texture units 0.. bound."""
    if not 1 <= len(sources) <= MAX_SOURCES:
        raise ValueError(f"upsampling takes 1 to {MAX_SOURCES} light textures, "
                         f"not {len(sources)}")
    if any(t.size != pixels[0].size for t in sources):
        raise ValueError("light and pixel g-buffer textures differ in size")
    size = supersamples[0].size
    if (pixels[0].size[0] * factor, pixels[0].size[1] * factor) != size:
        raise ValueError(f"{size} supersamples are not {factor}× the pixels {pixels[0].size}")
    added = list(added or [])
    if added and (len(added) != len(sources) or any(t.size != size for t in added)):
        raise ValueError("added light needs one supersample texture per source")
    program = programs.get("fullscreen_vert.glsl", "upsample_frag.glsl",
                           {"SOURCES": len(sources), **({"ADDED": 1} if added else {})})
    for unit, texture in enumerate((*pixels, *supersamples, *sources, *added)):
        texture.use(unit)
    set_uniforms(program, u_pixel_position=0, u_pixel_normal=1, u_position=2, u_normal=3,
                 u_factor=factor, u_normal_power=normal_power,
                 u_plane_tolerance=plane_tolerance)
    set_sampler_array(program, "u_source", 4, len(sources))
    if added:
        set_sampler_array(program, "u_added", 4 + len(sources), len(added))
    vao = ctx.vertex_array(program, [])
    try:
        return draw_into_new_textures(ctx, vao, size, len(sources))
    finally:
        vao.release()
