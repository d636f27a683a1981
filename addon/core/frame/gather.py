"""Gathering light at every g-buffer sample from a batch of light samples (direct light) or
VPLs (indirect light), with the batch's visibility, into an accumulator."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import moderngl
import numpy as np

from ..gpu.gl import ProgramCache, read_textures, set_uniforms
from ..gpu.ism import ISM_BIAS_TEXELS
from ..gpu.scene_buffers import SceneBuffers
from ..gpu.shadow_atlas import near_far
from ..transport.light_profiles import H_SAMPLES, LightProfiles
from ..transport.lights import AreaShapes
from .batches import Batch
from .gbuffer import GLOSSY_LAYERS, GBuffer
from .gpu_scope import GpuScope

if TYPE_CHECKING:
    from .visibility import Visibility

SURFACE_VERTICES_BINDING = 4  # the position stream as surface_lib.glsl's storage buffer
LOBE_UNITS = 9, 10, 11  # the g-buffer's glossy lobe layers (units 6-8: the scene's tables)
HINTS_UNIT = 12  # the shadow hints
AREA_SHAPES_UNIT = 13  # the area lights' outlines (transport/lights.py AreaShapes)
CLEAR_ATLAS_UNIT = 14  # a shadow atlas's clear layer (frame/shadow_maps.py)
PROFILE_UNITS = 5, 15  # IES-profiled lights' frames and profiles (transport/light_profiles.py)
AREA_SHAPES_WIDTH = 1024  # texels per row of their texture (a power of two)
RAY_OFFSET = 1e-4  # rays from a pixel start this fraction of the scene's radius off its surface


@dataclass
class LightPass:
    """One batch of light samples to gather, with its distance clamp and visibility."""

    name: str  # "direct light" or "indirect light": the stage's name in the stats
    batch: Batch
    min_distance: float
    visibility: Visibility
    interleave: int = 1
    blurred: bool = False  # direct light: into the accumulator the blur smooths (world light)
    spread: bool = False  # a sun's angle samples: edge rays take several of them (lights_lib)

    @property
    def indirect(self) -> bool:
        return self.name == "indirect light"


@dataclass
class Compensation:
    """Parameters of the bias-compensation pass (Kollig & Keller 2004)."""

    clamp_distance: float
    samples: int
    seed: int
    max_generation: int


def light_table_texture(ctx: moderngl.Context, batch: Batch, centre: np.ndarray,
                        radius: float) -> moderngl.Texture:
    """The batch's light samples as the float texture lights_lib.glsl reads (the caller
    releases it)."""
    s = batch.samples
    near, far = near_far(s, centre, radius)
    table = s.table(batch.first_tile, near, far)
    return ctx.texture((table.shape[1], len(s)), 4, table.tobytes(), dtype="f4")


def bind_light_profiles(ctx: moderngl.Context, profiles: LightProfiles,
                        scope: GpuScope) -> tuple[dict[str, object], dict[str, object]]:
    """Bind the IES profiles' textures (PROFILE_UNITS, released with ``scope``); the
    shaders' defines and uniforms for them."""
    frames = profiles.frames
    scope.own(ctx.texture((3, len(frames)), 4, frames.tobytes(), dtype="f4")).use(
        PROFILE_UNITS[0])
    grid = scope.own(ctx.texture(profiles.grid.shape[::-1], 1, profiles.grid.tobytes(),
                                 dtype="f4"))
    grid.repeat_x = grid.repeat_y = False
    grid.use(PROFILE_UNITS[1])
    return ({"LIGHT_PROFILES": 1, "PROFILE_ROWS": H_SAMPLES},
            {"u_profile_frames": PROFILE_UNITS[0], "u_profile_grid": PROFILE_UNITS[1]})


def area_shapes_texture(ctx: moderngl.Context, shapes: AreaShapes) -> moderngl.Texture:
    """The area lights' outline texels as the float texture lights_lib.glsl reads, in rows
    of at most AREA_SHAPES_WIDTH (the caller releases it)."""
    texels = shapes.texels
    rows = -(-len(texels) // AREA_SHAPES_WIDTH)
    padded = np.zeros((rows * AREA_SHAPES_WIDTH, 4), np.float32)
    padded[:len(texels)] = texels
    return ctx.texture((AREA_SHAPES_WIDTH, rows), 4, padded.tobytes(), dtype="f4")


def mask_words(mask: int) -> tuple[int, int]:
    """A draw's receiver or blocker sets (LightSamples.receivers, .blockers) as the uvec2
    light_linking_lib.glsl and raytrace_lib.glsl read: bits 0-31, 32-63."""
    return mask & 0xFFFFFFFF, mask >> 32


def samples_per_draw(rays_per_sample: int, compensation: Compensation | None) -> int:
    """Light samples one full-screen draw may loop over. Software OpenGL (Mesa llvmpipe) stops
    a shader invocation's loops after 65535 iterations in all; a ray's BVH traversal takes a
    few hundred, so ray-traced passes are split into draws of few samples."""
    if compensation is not None:
        rays_per_sample = compensation.samples * (1 + rays_per_sample)
    return 4096 if rays_per_sample == 0 else max(1, 48 // rays_per_sample)


def new_accumulator(ctx: moderngl.Context, size: tuple[int, int], scope: GpuScope,
                    glossy: bool = False) -> moderngl.Framebuffer:
    """A cleared float32 RGBA target of ``size`` that light is added to; with ``glossy`` a
    second one for glossy radiance."""
    targets = [scope.own(ctx.texture(size, 4, dtype="f4")) for _ in range(1 + glossy)]
    fbo = scope.own(ctx.framebuffer(targets))
    fbo.clear(0.0, 0.0, 0.0, 0.0)
    return fbo


def read_accumulator(accumulator: moderngl.Framebuffer) -> np.ndarray:
    """The accumulator as (h, w, 4) float32, or (h, w, 8) with its glossy target after."""
    return read_textures(accumulator.color_attachments)


def inverse_mat4(uniform: tuple[float, ...]) -> tuple[float, ...]:
    """The inverse of a mat4 uniform (column-major floats), as one."""
    matrix = np.array(uniform, np.float64).reshape(4, 4)  # the transpose; inverting commutes
    return tuple(np.linalg.inv(matrix).astype("f4").ravel())


def gather(ctx: moderngl.Context, programs: ProgramCache, light_pass: LightPass,
           atlas: moderngl.Texture, gbuffer: GBuffer, accumulator: moderngl.Framebuffer,
           scene: SceneBuffers | None, centre: np.ndarray, radius: float, bias: float,
           compensation: Compensation | None = None,
           hints: tuple[moderngl.Texture, int] | None = None,
           clear_atlas: moderngl.Texture | None = None) -> None:
    """Add one batch's light to the accumulator (additive blending); with
    ``compensation``, add the light its distance clamp removed instead. ``hints``: the batch's
    shadow hints (shadow_hints.py) and the supersamples per pixel edge; ``clear_atlas``: the
    shadow atlas's clear layer, which dims the light clear surfaces let through."""
    batch = light_pass.batch
    s = batch.samples
    with GpuScope() as scope:
        light_table = scope.own(light_table_texture(ctx, batch, centre, radius))
        for unit, name in enumerate(("position", "normal", "geometric")):
            gbuffer.textures[name].use(unit)
        light_table.use(3)
        atlas.use(4)
        visibility = light_pass.visibility
        defines: dict[str, object] = dict(visibility.defines)
        uniforms: dict[str, object] = dict(gbuffer.view)  # view-dependent reflection
        if light_table.width > 5:  # some VPLs reflect directionally (LightSamples.table)
            defines.update(VPL_GLOSSY=1)
        if light_table.width > 10:  # some VPLs are at rough diffuse surfaces
            defines.update(VPL_ROUGH=1)
        if s.shapes is not None and s.shape is not None and bool(np.any(s.shape >= 0)):
            defines.update(AREA_SHAPES=1, AREA_SHAPES_WIDTH=AREA_SHAPES_WIDTH)
            scope.own(area_shapes_texture(ctx, s.shapes)).use(AREA_SHAPES_UNIT)
            uniforms.update(u_area_shapes=AREA_SHAPES_UNIT)
        if s.has_profiles:
            profile_defines, profile_uniforms = bind_light_profiles(ctx, s.profiles, scope)
            defines.update(profile_defines)
            uniforms.update(profile_uniforms)
        if s.linked and scene is not None:  # light linking: draws of one emitter's receivers
            defines.update(LIGHT_LINKING=1)
        if s.shadow_linked and ("EXACT_VISIBILITY" in defines or compensation is not None):
            defines.update(RT_SHADOW_LINKING=1)  # shadow linking: draws of one's blockers
        if clear_atlas is not None:
            defines.update(CLEAR_SHADOWS=1)
            clear_atlas.use(CLEAR_ATLAS_UNIT)
            uniforms.update(u_clear_atlas=CLEAR_ATLAS_UNIT)
        if hints is not None:
            defines.update(SHADOW_HINTS=1)
            if light_pass.spread and light_pass.interleave > 1:
                defines.update(SPREAD_EDGE_RAYS=1)
            hints[0].use(HINTS_UNIT)
            uniforms.update(u_shadow_hints=HINTS_UNIT, u_hint_factor=hints[1],
                            u_inverse_view_projection=inverse_mat4(gbuffer.view_projection),
                            u_tile_size=gbuffer.textures["position"].size)
        if scene is not None and scene.has_rough_diffuse:
            defines.update(ROUGH_DIFFUSE=1)
        if scene is not None and scene.has_translucency:
            defines.update(TRANSLUCENT=1)
        if gbuffer.glossy:
            defines.update(GLOSSY=1)
            for unit, name in zip(LOBE_UNITS, GLOSSY_LAYERS, strict=True):
                gbuffer.textures[name].use(unit)
                uniforms[f"u_{name}"] = unit
            if scene is not None and scene.has_coat:
                defines.update(COAT=1)
            if scene is not None and scene.has_sheen:
                defines.update(SHEEN=1)
        if compensation is not None:
            defines.update(BIAS_COMPENSATION=1, SURFACE_VERTICES_BINDING=SURFACE_VERTICES_BINDING)
            uniforms.update(u_clamp_distance=compensation.clamp_distance,
                            u_bias_samples=compensation.samples, u_seed=compensation.seed,
                            u_max_generation=compensation.max_generation)
        needs_430 = visibility.rays_per_sample > 0 or compensation is not None
        program = programs.get("fullscreen_vert.glsl", "gather_frag.glsl", defines,
                               version=430 if needs_430 else 410)
        hinted = _HintedDraws(ctx, programs, defines, accumulator, scope) if hints else None
        shaders = [program] if hinted is None else [program, hinted.hints_only]
        for shader in shaders:
            set_uniforms(shader, u_position=0, u_normal=1, u_geometric=2, u_light_table=3,
                         u_shadow_atlas=4, u_atlas_columns=batch.columns,
                         u_interleave=light_pass.interleave, u_ism_bias=ISM_BIAS_TEXELS,
                         u_scene_centre=tuple(centre), u_scene_radius=radius,
                         u_shadow_bias=bias, u_min_distance2=light_pass.min_distance**2,
                         u_ray_offset=RAY_OFFSET * radius, **uniforms)
        if compensation is not None:  # the surfaces rays reach: positions and materials
            scene.positions.bind_to_storage_buffer(SURFACE_VERTICES_BINDING)
            scene.bind_materials(program)
        elif {"COAT", "SHEEN", "ROUGH_DIFFUSE", "TRANSLUCENT"} & defines.keys():  # pixel layers
            for shader in shaders:
                scene.bind_materials(shader)
        elif "LIGHT_LINKING" in defines:
            for shader in shaders:
                scene.bind_triangle_rows(shader)
        if "SHEEN" in defines:  # the sheen's albedo table
            for shader in shaders:
                scene.bind_specular(shader)
        accumulator.use()
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        vao = scope.own(ctx.vertex_array(program, []))
        chunk = samples_per_draw(visibility.rays_per_sample, compensation)
        shape = s.shape if "AREA_SHAPES" in defines else None
        receivers = s.receivers if "LIGHT_LINKING" in defines else None
        blockers = s.blockers if "RT_SHADOW_LINKING" in defines else None
        for first, count in draws(len(s), chunk, shape, receivers, blockers):
            for shader in shaders:
                set_uniforms(shader, u_first=first, u_count=count)
                if receivers is not None:
                    set_uniforms(shader, u_receivers=mask_words(int(receivers[first])))
                if blockers is not None:
                    set_uniforms(shader, u_blockers=mask_words(int(blockers[first])))
            if hinted is None:
                vao.render(moderngl.TRIANGLES, vertices=3)
            else:
                hinted.render(vao)
        ctx.disable(moderngl.BLEND)


class _HintedDraws:
    """A hinted gather in two draws per chunk of samples: one without ray code, which adds
    the light where the pixels' hints settle every sample and writes depth 0 where a
    supersample needs rays (1 elsewhere; the background keeps the cleared 1), then the full
    shader, which the depth test runs only there. On llvmpipe the ray code alone, compiled in
    but run by few fragments, made the interior's sun pass 0.69 s instead of 0.15 s at
    640×360."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache,
                 defines: dict[str, object], accumulator: moderngl.Framebuffer,
                 scope: GpuScope) -> None:
        self.ctx = ctx
        self.hints_only = programs.get("fullscreen_vert.glsl", "gather_frag.glsl",
                                       {**defines, "HINTS_ONLY": 1}, version=430)
        self.vao = scope.own(ctx.vertex_array(self.hints_only, []))
        depth = scope.own(ctx.depth_renderbuffer(accumulator.size))
        self.target = scope.own(ctx.framebuffer(accumulator.color_attachments, depth))
        masks, off = self.target.color_mask, (False,) * 4
        count = len(accumulator.color_attachments)
        self.target.color_mask = off if count == 1 else [off] * count
        self.target.clear(depth=1.0)  # the depth alone: 1 where no fragment writes it
        self.target.color_mask = masks

    def render(self, vao: moderngl.VertexArray) -> None:
        """One chunk, both programs' uniforms set: the hints-only draw, then ``vao`` (the full
        shader's)."""
        ctx, target = self.ctx, self.target
        target.use()
        target.depth_mask = True
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "1"  # every fragment writes its depth
        self.vao.render(moderngl.TRIANGLES, vertices=3)
        target.depth_mask = False
        ctx.depth_func = ">"  # the full-screen triangle's 0.5 passes only where 0 was written
        vao.render(moderngl.TRIANGLES, vertices=3)
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)


def draws(count: int, chunk: int, *runs_of: np.ndarray | None) -> list[tuple[int, int]]:
    """(first, count) of the draws of ``count`` samples: at most ``chunk`` each, and each of
    one value of every array of ``runs_of`` given (per sample: its area light, -1 for none;
    the receiver sets it lights; the blocker sets that cast its shadows)."""
    changes = [np.flatnonzero(np.diff(values)) + 1 for values in runs_of if values is not None]
    bounds = np.unique(np.concatenate([np.zeros(0, int), *changes]))
    runs = zip(np.r_[0, bounds], np.r_[bounds, count], strict=True)
    return [(first, min(chunk, int(stop) - first)) for start, stop in runs
            for first in range(int(start), int(stop), chunk)]
