"""Blender's Combined pass composed on the GPU and read back at pixel resolution
(gpu_shaders/combined_frag.glsl); the other passes stay in frame/compose.py."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import moderngl
import numpy as np

from .gl import ProgramCache, draw_into_new_textures, read_textures, set_uniforms


def combined_pass(ctx: moderngl.Context, programs: ProgramCache,
                  direct: Sequence[moderngl.Texture], indirect: Sequence[moderngl.Texture],
                  soft: Sequence[moderngl.Texture], gbuffer: Mapping[str, moderngl.Texture],
                  background: np.ndarray | None, factor: int,
                  transmittance: moderngl.Texture | None = None, holdouts: bool = False,
                  catchers: moderngl.Texture | None = None) -> np.ndarray:
    """(h, w, 4) float32 Combined of a tile of ``factor``² supersamples per pixel. ``direct``,
    ``indirect`` and ``soft`` (may be empty): light textures, diffuse then glossy where the
    g-buffer has glossy layers; ``background``: a colour (3,), one per supersample
    (h·factor, w·factor, 3), or None for a transparent film; ``transmittance``: per
    supersample, the light clear surfaces let through to the camera (gpu/clear_view.py);
    ``holdouts``: the scene has holdouts (marked in the g-buffer's geometric.w);
    ``catchers``: a table of the triangles of shadow catchers (1) and others (0), whose
    supersamples are then holes too (the matte, frame/shadow_catcher.py)."""
    glossy = len(direct) > 1
    defines: dict[str, object] = {}
    units: dict[str, moderngl.Texture] = {
        "u_direct": direct[0], "u_indirect": indirect[0], "u_albedo": gbuffer["albedo"],
        "u_emission": gbuffer["emission"], "u_normal": gbuffer["normal"]}
    if holdouts or catchers is not None:
        defines["HOLDOUTS"] = 1
        units["u_geometric"] = gbuffer["geometric"]
    if catchers is not None:
        defines["CATCHERS"] = 1
        units["u_catchers"] = catchers
    if soft:
        defines["SOFT"] = 1
        units["u_soft"] = soft[0]
    if glossy:
        defines["GLOSSY"] = 1
        units.update(u_direct_glossy=direct[1], u_indirect_glossy=indirect[1])
        if soft:
            units["u_soft_glossy"] = soft[1]
    if transmittance is not None:
        defines["TRANSMITTANCE"] = 1
        units["u_transmittance"] = transmittance
    owned: list[moderngl.Texture] = []
    if background is not None and background.ndim == 3:
        defines["BACKGROUND_IMAGE"] = 1
        h, w, _ = background.shape
        image = ctx.texture((w, h), 3, np.ascontiguousarray(background, np.float32), dtype="f4")
        owned.append(image)
        units["u_background"] = image
    elif background is not None:
        defines["BACKGROUND"] = 1
    program = programs.get("fullscreen_vert.glsl", "combined_frag.glsl", defines)
    for unit, (name, texture) in enumerate(units.items()):
        texture.use(unit)
        set_uniforms(program, **{name: unit})
    set_uniforms(program, u_factor=factor)
    if background is not None and background.ndim == 1:
        set_uniforms(program, u_background=tuple(float(c) for c in background[:3]))
    w, h = gbuffer["normal"].size
    vao = ctx.vertex_array(program, [])
    try:
        owned += draw_into_new_textures(ctx, vao, (w // factor, h // factor), 1)
        return read_textures(owned[-1:])
    finally:
        vao.release()
        for texture in owned:
            texture.release()
