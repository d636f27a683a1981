"""The image: in tiles of supersampled pixels, each a g-buffer, the gather of every light
pass (direct light, then indirect light and its bias compensation), the blur of the indirect
light and the composition of Blender's passes."""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from functools import partial

import moderngl
import numpy as np

from ..gpu.clear_view import ClearView
from ..gpu.combined import combined_pass
from ..gpu.gl import read_textures
from ..gpu.scene_buffers import SceneBuffers, table_texture
from ..gpu.upsample import upsample
from ..scene.environment import background
from ..scene.geometry import WorldGeometry
from . import ism_maps
from .ambient_occlusion import AmbientOcclusion
from .compose import COMPOSED_PASSES, compose, downsample
from .denoise import DenoisingData
from .gather import RAY_OFFSET, LightPass, gather, new_accumulator, read_accumulator
from .gbuffer import GBuffer, Tile, render_gbuffer
from .gpu_scope import GpuScope
from .gpu_session import GpuSession
from .id_passes import IdPasses
from .motion import MotionVectors
from .near_field import compensate_from_image
from .result import BACKDROP, MATTE, PASS_FILL, pass_channels
from .reuse import KeptProducts
from .shadow_catcher import catcher_triangles
from .shadow_hints import render_hints, takes_hints
from .shadow_maps import KeptAtlases, ShadowAtlases
from .stages import indirect_per_pixel
from .state import FrameState, RenderError, Stage
from .thin_surfaces import gather_with_mask, thin_surface_mask
from .visibility import FrameMaps, ImperfectVisibility, RayTracedVisibility

MAX_TILE = 2048  # supersampled pixels per image tile edge (later tiles reuse the maps)


@dataclass
class FrameGpu:
    """The frame's GPU data: its triangles (with their image textures), the lights'
    outlines, maps."""

    scene: SceneBuffers | None
    shapes: SceneBuffers | None
    maps: FrameMaps
    clear: ClearView | None = None  # the clear triangles, for the camera's view through them
    catchers: moderngl.Texture | None = None  # shadow catchers' triangles (combined.py)


@dataclass
class TileWork:
    """What the tile stages of one tile hand each other."""

    tile: Tile
    scope: GpuScope  # the tile's GPU objects
    gbuffer: GBuffer | None = None
    pixels: GBuffer | None = None  # one sample per pixel (with antialiasing, where needed)
    indirect_gbuffer: GBuffer | None = None  # the indirect light's samples: gbuffer or pixels
    direct: moderngl.Framebuffer | None = None
    soft: moderngl.Framebuffer | None = None  # interleaved soft direct light, to be blurred
    indirect: moderngl.Framebuffer | None = None
    near: moderngl.Framebuffer | None = None  # bias compensation per supersample, where the
    # indirect light is gathered per pixel
    soft_light: list[moderngl.Texture] = field(default_factory=list)  # after the blur
    indirect_light: list[moderngl.Texture] = field(default_factory=list)
    thin: moderngl.Renderbuffer | None = None  # pixels that gather every VPL (thin_surfaces)
    background: np.ndarray | None = None  # what rays that miss see (None: transparent film)
    transmittance: moderngl.Texture | None = None  # per supersample: what clear surfaces in
    # front let through to the camera (None where the scene has none)


def tiles_of(width: int, height: int, aa: int) -> list[Tile]:
    """The tiles of an image of width × height supersamples, row by row; each tile's edges
    fall on pixel edges (whole aa × aa blocks)."""
    edge = max(aa, MAX_TILE - MAX_TILE % aa)
    return [Tile(x, min(x + edge, width), y, min(y + edge, height), width, height)
            for y in range(0, height, edge) for x in range(0, width, edge)]


def pixel_tile(tile: Tile, aa: int) -> Tile:
    """The pixels of a tile of supersamples (whose edges fall on pixel edges)."""
    return Tile(tile.x0 // aa, tile.x1 // aa, tile.y0 // aa, tile.y1 // aa, tile.width // aa,
                tile.height // aa)


def _buffers(ctx: moderngl.Context, geometry: WorldGeometry, scope: GpuScope
             ) -> SceneBuffers | None:
    if geometry.vertex_count == 0:
        return None
    try:
        return scope.own(SceneBuffers(ctx, geometry))
    except ValueError as exc:  # more triangles or materials than the GPU's textures hold
        raise RenderError(f"the scene is too large for this GPU: {exc}") from None


class TileStage:
    """One step of a tile (the base of the stages below)."""

    name: str

    def __init__(self, gpu: GpuSession) -> None:
        self.gpu = gpu

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        raise NotImplementedError


class GBufferStage(TileStage):
    name = "g-buffer"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        aa, settings = frame.settings.antialiasing, frame.settings
        per_pixel = indirect_per_pixel(settings, frame.geometry.has_specular) \
            and any(p.indirect for p in frame.light_passes)
        hinted = settings.adaptive_shadows and any(map(takes_hints, frame.light_passes))
        with frame.stats.timed(self.name):
            work.gbuffer = self._render(data, frame, work, work.tile)
            if aa > 1 and (per_pixel or hinted):
                work.pixels = self._render(data, frame, work, pixel_tile(work.tile, aa))
            self.gpu.ctx.finish()  # its GPU work timed here, not in the next stage
        if data.clear is not None:
            with frame.stats.timed("view through clear surfaces"):
                work.transmittance = work.scope.own(data.clear.transmittance(
                    work.gbuffer.depth, work.gbuffer.view_projection, frame.camera))
                self.gpu.ctx.finish()
        work.indirect_gbuffer = work.pixels if per_pixel else work.gbuffer
        glossy = work.gbuffer.glossy
        work.direct = new_accumulator(self.gpu.ctx, work.tile.size, work.scope, glossy)
        work.indirect = new_accumulator(self.gpu.ctx, work.indirect_gbuffer.textures[
            "position"].size, work.scope, glossy)
        if any(p.blurred for p in frame.light_passes):
            work.soft = new_accumulator(self.gpu.ctx, work.tile.size, work.scope, glossy)
        if per_pixel and frame.near_field is not None:
            work.near = new_accumulator(self.gpu.ctx, work.tile.size, work.scope, glossy)

    def _render(self, data: FrameGpu, frame: FrameState, work: TileWork, tile: Tile
                ) -> GBuffer:
        return render_gbuffer(self.gpu.ctx, self.gpu.programs, data.scene, data.shapes,
                              frame.camera, tile, work.scope, frame.pass_index)


class GatherStage(TileStage):
    """Each light pass's maps, then its light gathered into the direct or indirect
    accumulator (and the bias compensation of indirect light)."""

    name = "gather"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        ctx, stats, passes = self.gpu.ctx, frame.stats, frame.light_passes
        centre, radius, bias = frame.centre, frame.radius, frame.settings.shadow_bias
        for light_pass in passes:
            frame.check_cancelled()
            traced = light_pass.visibility.rays_per_sample > 0  # no maps: a placeholder
            with nullcontext() if traced else stats.timed(f"{light_pass.name} maps"):
                atlas = light_pass.visibility.maps(light_pass.batch, data.maps)
                clear = data.maps.shadow_atlases.clear_atlas(atlas)
                ctx.finish()
            hints = self._hints(frame, work, light_pass)
            thin = self._thin(frame, work, light_pass)
            with stats.timed(light_pass.name):
                target = work.indirect if light_pass.indirect else \
                    work.soft if light_pass.blurred else work.direct
                gbuffer = work.indirect_gbuffer if light_pass.indirect else work.gbuffer
                if thin is None:
                    gather(ctx, self.gpu.programs, light_pass, atlas, gbuffer, target,
                           data.scene, centre, radius, bias, hints=hints, clear_atlas=clear)
                else:
                    gather_with_mask(ctx, self.gpu.programs, light_pass, atlas, gbuffer,
                                     target, thin, data.scene, centre, radius, bias, clear)
                ctx.finish()
            if frame.compensation is not None:
                with stats.timed("bias compensation"):
                    gather(ctx, self.gpu.programs, light_pass, atlas, work.indirect_gbuffer,
                           work.indirect, data.scene, centre, radius, bias, frame.compensation,
                           clear_atlas=clear)
                    ctx.finish()
            frame.steps_done += 1
            frame.report(frame.steps_done / frame.steps,
                         f"{light_pass.name} {frame.steps_done}/{frame.steps}")

    def _thin(self, frame: FrameState, work: TileWork, light_pass: LightPass
              ) -> moderngl.Renderbuffer | None:
        """Where VPLs gathered once per pixel are gathered in full (thin_surfaces.py): the
        tile's mask, made at its first interleaved indirect pass; None per supersample."""
        if not light_pass.indirect or light_pass.interleave == 1 or not frame.blur_radius \
                or work.indirect_gbuffer is work.gbuffer:
            return None
        if work.thin is None:
            with frame.stats.timed("thin surfaces"):
                textures = work.indirect_gbuffer.textures
                work.thin = thin_surface_mask(self.gpu.ctx, self.gpu.programs,
                                              textures["position"], textures["normal"],
                                              light_pass.interleave, frame.blur_radius,
                                              work.scope)
                self.gpu.ctx.finish()
        return work.thin

    def _hints(self, frame: FrameState, work: TileWork, light_pass: LightPass
               ) -> tuple[moderngl.Texture, int] | None:
        """The pass's shadow hints where it takes them (adaptive shadow rays)."""
        if work.pixels is None or not frame.settings.adaptive_shadows \
                or not takes_hints(light_pass):
            return None
        aa = frame.settings.antialiasing
        with frame.stats.timed("shadow hints"):
            hints = render_hints(self.gpu.ctx, self.gpu.programs, light_pass, work.pixels, aa,
                                 frame.centre, frame.radius, work.scope)
            self.gpu.ctx.finish()
        return hints, aa


def vpls_at_unseen_hits(frame: FrameState) -> bool:
    """Whether the bias compensation's unseen hits can take the VPLs' light: every indirect
    pass has imperfect shadow maps that the frame keeps from the gather (one atlas, or several
    within ism_maps.KEPT_ATLAS_BYTES). Triangle maps would be made again, and ray-traced
    visibility would trace a ray per VPL at every hit of every compensation ray."""
    indirect = [p for p in frame.light_passes if p.indirect]
    return bool(indirect) and frame.ism_maps is not None and frame.ism_maps.keeps_all \
        and all(type(p.visibility) is ImperfectVisibility for p in indirect)


class NearFieldStage(TileStage):
    """Bias compensation from the image: the near surfaces' light, read from what the gather
    put in the direct and indirect accumulators, added to the indirect light before its
    blur; at every supersample even where the VPLs' light is gathered per pixel (its detail
    next to contacts and sunlit patches is finer than the VPLs')."""

    name = "bias compensation"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        if frame.near_field is None or data.scene is None:
            return
        frame.check_cancelled()
        if frame.near_field.indirect_at_hits and frame.ism_maps is not None \
                and not frame.ism_maps.keeps_all:
            note = (f"bias compensation without the VPLs' light at hits the camera does not "
                    f"see: the {len(frame.ism_maps.batches)} ISM atlases "
                    f"({frame.ism_maps.atlas_bytes >> 20} MiB) exceed what a frame keeps "
                    f"({ism_maps.KEPT_ATLAS_BYTES >> 20} MiB; fewer light paths a pass "
                    f"keep them)")
            if note not in frame.stats.notes:
                frame.stats.notes.append(note)
        target = work.indirect if work.near is None else work.near
        with frame.stats.timed(self.name):
            self.gpu.tracer.bind()
            compensate_from_image(self.gpu.ctx, self.gpu.programs, frame.near_field,
                                  work.gbuffer, (work.direct, work.soft), work.indirect,
                                  target, RAY_OFFSET * frame.radius, data.scene,
                                  partial(self._light_at, frame, data))
            self.gpu.ctx.finish()

    def _light_at(self, frame: FrameState, data: FrameGpu, samples: GBuffer,
                  target: moderngl.Framebuffer) -> None:
        """Every direct light pass's light at the surface samples, shadowed by rays, and
        where the hits' light may bounce once more (bounces > 1) the VPLs' light: an
        off-screen ceiling lit only by VPLs gives the wall below it its near light (without
        it, the Cornell box's back wall below the off-screen ceiling was 33 % dark). Only where
        :func:`vpls_at_unseen_hits` says so."""
        traced = RayTracedVisibility()
        with_vpls = frame.near_field.indirect_at_hits and vpls_at_unseen_hits(frame)
        for light_pass in frame.light_passes:
            if not light_pass.indirect:
                gather(self.gpu.ctx, self.gpu.programs, replace(light_pass, visibility=traced),
                       data.maps.shadow_atlases.placeholder(), samples, target, data.scene,
                       frame.centre, frame.radius, frame.settings.shadow_bias)
            elif with_vpls:  # the hits are supersamples: the supersamples' pattern
                atlas = light_pass.visibility.maps(light_pass.batch, data.maps)
                gather(self.gpu.ctx, self.gpu.programs,
                       replace(light_pass, interleave=frame.settings.interleave), atlas,
                       samples, target, data.scene, frame.centre, frame.radius,
                       frame.settings.shadow_bias)


SUPERSAMPLE_BLUR = "supersample blur"
"""The stage of the blur of soft direct light and bias compensation at every supersample, where
indirect light is gathered per pixel (its own blur is "blur")."""


class BlurStage(TileStage):
    """The geometry-aware blur that removes the interleaving pattern of indirect light and of
    soft direct light; indirect light gathered per pixel is then brought to every
    supersample."""

    name = "blur"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        per_pixel = work.indirect_gbuffer is not work.gbuffer
        soft = [work.soft] if work.soft is not None else []
        if per_pixel:
            near = [work.near] if work.near is not None else []
            lights = self._blurred(frame, work, work.indirect_gbuffer, [work.indirect])
            if soft or near:  # at every supersample, whatever the VPLs: timed apart
                lights += self._blurred(frame, work, work.gbuffer, soft + near,
                                        SUPERSAMPLE_BLUR)
            added = lights.pop() if near else None
            lights[0] = self._upsampled(frame, work, lights[0], added)
        else:
            lights = self._blurred(frame, work, work.gbuffer, [work.indirect, *soft])
        work.indirect_light = lights[0]
        work.soft_light = lights[1] if soft else []

    def _upsampled(self, frame: FrameState, work: TileWork, textures: list[moderngl.Texture],
                   added: list[moderngl.Texture] | None) -> list[moderngl.Texture]:
        """Light textures of the pixels' g-buffer brought to every supersample, plus
        ``added`` (supersample light textures, one per texture) where given."""
        with frame.stats.timed("upsample"):
            pixels, supersamples = work.pixels.textures, work.gbuffer.textures
            result = [work.scope.own(t) for t in upsample(
                self.gpu.ctx, self.gpu.programs, textures,
                (pixels["position"], pixels["normal"]),
                (supersamples["position"], supersamples["normal"]),
                frame.settings.antialiasing, added)]
            self.gpu.ctx.finish()
        return result

    def _blurred(self, frame: FrameState, work: TileWork, gbuffer: GBuffer,
                 accumulators: list[moderngl.Framebuffer], stage: str | None = None
                 ) -> list[list[moderngl.Texture]]:
        """Each accumulator's light textures (diffuse, then glossy), blurred in one draw per
        axis, timed as ``stage`` (default: this stage's name)."""
        if not frame.blur_radius:
            return [list(a.color_attachments) for a in accumulators]
        with frame.stats.timed(stage or self.name):
            textures = gbuffer.textures
            targets = [t for a in accumulators for t in a.color_attachments]
            results = iter([work.scope.own(t) for t in self.gpu.blur.apply(
                targets, textures["position"], textures["normal"], frame.blur_radius)])
            self.gpu.ctx.finish()
            return [[next(results) for _ in a.color_attachments] for a in accumulators]


class ComposeStage(TileStage):
    name = "compose"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        """Combined on the GPU, read back per pixel; the other passes Blender asks for from
        the supersamples read back."""
        with frame.stats.timed(self.name):
            aa, tile, scene = frame.settings.antialiasing, work.tile, frame.scene
            if not scene.film_transparent:  # through this pass's camera (sub-sample offset)
                work.background = background(scene.world, frame.camera, aa, tile.x0, tile.y0,
                                             *tile.size)
            holdouts = bool(frame.geometry.holdout.any())
            light = (work.direct.color_attachments, work.indirect_light, work.soft_light,
                     work.gbuffer.textures, work.background, aa, work.transmittance, holdouts)
            combined = combined_pass(self.gpu.ctx, self.gpu.programs, *light)
            h, w = combined.shape[:2]
            x0, y0 = tile.x0 // aa, tile.y0 // aa
            region = slice(y0, y0 + h), slice(x0, x0 + w)
            frame.output["Combined"][region] = combined
            if MATTE in frame.output:  # shadow_catcher.py
                frame.output[MATTE][region] = combined if data.catchers is None else \
                    combined_pass(self.gpu.ctx, self.gpu.programs, *light,
                                  catchers=data.catchers)
            if BACKDROP in frame.output:
                backdrop = work.background
                frame.output[BACKDROP][region] = backdrop[:3] if backdrop.ndim == 1 \
                    else downsample(backdrop, aa)
            others = frame.plan.passes - {"Combined"}
            if others & COMPOSED_PASSES:
                through = None if work.transmittance is None else \
                    partial(read_textures, [work.transmittance])
                compose(frame.output, work.gbuffer.images, partial(read_light, work), aa,
                        tile.x0, tile.y0, others, through, holdouts,
                        (frame.camera, frame.scene.mist), partial(_background, frame, work))


def _background(frame: FrameState, work: TileWork) -> np.ndarray:
    """What the tile's supersamples see where no surface is: the composed background, or
    with a transparent film the world all the same (the Environment pass)."""
    if work.background is not None:
        return work.background
    tile = work.tile
    return background(frame.scene.world, frame.camera, frame.settings.antialiasing, tile.x0,
                      tile.y0, *tile.size)


def read_light(work: TileWork) -> tuple[np.ndarray, np.ndarray]:
    """The tile's direct light (soft light added) and indirect light, read back."""
    direct = read_accumulator(work.direct)
    if work.soft_light:
        direct += read_textures(work.soft_light)
    return direct, read_textures(work.indirect_light)


class RenderImage(Stage):
    """Every tile through the tile stages, with the frame's GPU data in one scope."""

    name = "image"
    needs = ("camera", "geometry", "shapes", "centre", "plan", "light_passes")
    makes = ("output",)

    def __init__(self, gpu: GpuSession, kept: KeptProducts) -> None:
        self.gpu, self.kept = gpu, kept
        self.tile_stages = [GBufferStage(gpu), GatherStage(gpu), NearFieldStage(gpu),
                            BlurStage(gpu), ComposeStage(gpu), AmbientOcclusion(gpu),
                            DenoisingData(), IdPasses(), MotionVectors()]

    def run(self, frame: FrameState) -> None:
        camera, settings, ctx = frame.camera, frame.settings, self.gpu.ctx
        aa = settings.antialiasing
        tiles = tiles_of(camera.width * aa, camera.height * aa, aa)
        frame.output = {name: np.full((camera.height, camera.width, pass_channels(name)),
                                      PASS_FILL.get(name, 0.0), np.float32)
                        for name in sorted(frame.plan.passes)}
        kept = KeptAtlases(self.kept.shadow_atlases, self.kept.versions.shape)
        frame.steps, frame.steps_done = len(tiles) * max(1, len(frame.light_passes)), 0
        with GpuScope() as scope:
            geometry = frame.geometry
            scene = _buffers(ctx, geometry, scope)
            shapes = _buffers(ctx, frame.shapes, scope)
            clear = scope.own(ClearView(ctx, self.gpu.programs, geometry.clear_triangles,
                                        geometry.clear_transmission)) \
                if len(geometry.clear_triangles) else None
            atlases = ShadowAtlases(ctx, self.gpu.programs, scene, kept, clear,
                                    bool(geometry.shadowless.any()),
                                    bool(geometry.diffuse_hidden.any()))
            maps = FrameMaps(atlases, frame.ism_maps, frame.centre, frame.radius,
                             reuse_atlas=len(frame.light_passes) == 1)
            catchers = catcher_triangles(frame.scene, geometry)
            data = FrameGpu(scene, shapes, maps, clear, None if catchers is None or scene is None
                            else scope.own(table_texture(ctx, catchers.astype(np.int32)[:, None],
                                                         1, "i4")))
            if frame.traces_rays:
                self.gpu.tracer.bind()
            try:
                for tile in tiles:
                    with GpuScope() as tile_scope:
                        work = TileWork(tile, tile_scope)
                        for stage in self.tile_stages:
                            stage.run(frame, data, work)
            finally:
                atlases.release()
                if frame.ism_maps is not None:
                    frame.ism_maps.release()
                self.kept.keep_shadow_atlases(kept.used)
        reused = [f"{kept.hits} atlas(es) of unchanged lights and triangles kept from the "
                  f"last frame"] if kept.hits else []
        if kept.tile_hits:
            reused.append(f"{kept.tile_hits} atlas(es) rendered for an earlier tile")
        if reused:
            frame.stats.skipped["shadow maps"] = "; ".join(reused)
