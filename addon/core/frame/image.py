"""The image: in tiles of supersampled pixels, each a g-buffer, the gather of every light
pass (direct light, then indirect light and its bias compensation), the blur of the indirect
light and the composition of Blender's passes."""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from ..gpu.scene_buffers import SceneBuffers
from ..gpu.texture_array import upload as upload_textures
from ..scene.environment import background
from ..scene.geometry import WorldGeometry
from .compose import compose
from .denoise import DenoisingData
from .gather import RAY_OFFSET, gather, new_accumulator, read_accumulator
from .gbuffer import GBuffer, Tile, render_gbuffer
from .gpu_scope import GpuScope
from .gpu_session import GpuSession
from .near_field import compensate_from_image
from .result import PASS_CHANNELS
from .reuse import KeptProducts
from .shadow_maps import KeptAtlases, ShadowAtlases
from .state import FrameState, RenderError, Stage
from .visibility import FrameMaps

MAX_TILE = 2048  # supersampled pixels per image tile edge (each tile renders its own maps)


@dataclass
class FrameGpu:
    """The frame's GPU data: its triangles, the lights' outlines, image textures, maps."""

    scene: SceneBuffers | None
    shapes: SceneBuffers | None
    textures: tuple[moderngl.TextureArray, moderngl.Texture] | None
    maps: FrameMaps


@dataclass
class TileWork:
    """What the tile stages of one tile hand each other."""

    tile: Tile
    scope: GpuScope  # the tile's GPU objects
    gbuffer: GBuffer | None = None
    direct: moderngl.Framebuffer | None = None
    soft: moderngl.Framebuffer | None = None  # interleaved soft direct light, to be blurred
    indirect: moderngl.Framebuffer | None = None
    soft_light: np.ndarray | None = None  # after the blur
    indirect_light: np.ndarray | None = None
    background: np.ndarray | None = None  # what rays that miss see (None: transparent film)


def tiles_of(width: int, height: int, aa: int) -> list[Tile]:
    """The tiles of an image of width × height supersamples, row by row; each tile's edges
    fall on pixel edges (whole aa × aa blocks)."""
    edge = max(aa, MAX_TILE - MAX_TILE % aa)
    return [Tile(x, min(x + edge, width), y, min(y + edge, height), width, height)
            for y in range(0, height, edge) for x in range(0, width, edge)]


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
        with frame.stats.timed(self.name):
            work.gbuffer = render_gbuffer(self.gpu.ctx, self.gpu.programs, data.scene,
                                          data.shapes, data.textures, frame.camera, work.tile,
                                          work.scope)
        glossy = work.gbuffer.glossy
        work.direct = new_accumulator(self.gpu.ctx, work.tile.size, work.scope, glossy)
        work.indirect = new_accumulator(self.gpu.ctx, work.tile.size, work.scope, glossy)
        if any(p.blurred for p in frame.light_passes):
            work.soft = new_accumulator(self.gpu.ctx, work.tile.size, work.scope, glossy)


class GatherStage(TileStage):
    """Each light pass's maps, then its light gathered into the direct or indirect
    accumulator (and the bias compensation of indirect light)."""

    name = "gather"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        ctx, stats, passes = self.gpu.ctx, frame.stats, frame.light_passes
        centre, radius, bias = frame.centre, frame.radius, frame.settings.shadow_bias
        for light_pass in passes:
            frame.check_cancelled()
            with stats.timed(f"{light_pass.name} maps"):
                atlas = light_pass.visibility.maps(light_pass.batch, data.maps)
                ctx.finish()
            with stats.timed(light_pass.name):
                target = work.indirect if light_pass.indirect else \
                    work.soft if light_pass.blurred else work.direct
                gather(ctx, self.gpu.programs, light_pass, atlas, work.gbuffer, target,
                       data.scene, centre, radius, bias)
                ctx.finish()
            if frame.compensation is not None:
                with stats.timed("bias compensation"):
                    gather(ctx, self.gpu.programs, light_pass, atlas, work.gbuffer,
                           work.indirect, data.scene, centre, radius, bias, frame.compensation)
                    ctx.finish()
            frame.steps_done += 1
            frame.report(frame.steps_done / frame.steps,
                         f"{light_pass.name} {frame.steps_done}/{frame.steps}")


class NearFieldStage(TileStage):
    """Bias compensation from the image: the near surfaces' light, read from what the gather
    put in the direct and indirect accumulators, added to the indirect light before its
    blur."""

    name = "bias compensation"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        if frame.near_field is None:
            return
        frame.check_cancelled()
        with frame.stats.timed(self.name):
            self.gpu.tracer.bind()
            compensate_from_image(self.gpu.ctx, self.gpu.programs, frame.near_field,
                                  work.gbuffer, (work.direct, work.soft), work.indirect,
                                  RAY_OFFSET * frame.radius)
            self.gpu.ctx.finish()


class BlurStage(TileStage):
    """The geometry-aware blur that removes the interleaving pattern of indirect light and of
    soft direct light."""

    name = "blur"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        accumulators = [work.indirect] + ([work.soft] if work.soft is not None else [])
        lights = self._blurred(frame, work, accumulators)
        work.indirect_light = lights[0]
        if work.soft is not None:
            work.soft_light = lights[1]

    def _blurred(self, frame: FrameState, work: TileWork,
                 accumulators: list[moderngl.Framebuffer]) -> list[np.ndarray]:
        """Each accumulator's light (diffuse, then glossy, side by side), blurred in one
        draw per axis."""
        if not frame.blur_radius:
            return [read_accumulator(a) for a in accumulators]
        with frame.stats.timed(self.name):
            textures = work.gbuffer.textures
            targets = [t for a in accumulators for t in a.color_attachments]
            results = [work.scope.own(t) for t in self.gpu.blur.apply(
                targets, textures["position"], textures["normal"], frame.blur_radius)]
            w, h = results[0].size
            images = iter(np.frombuffer(r.read(), dtype=np.float32).reshape(h, w, 4)
                          for r in results)
            return [np.concatenate([next(images) for _ in a.color_attachments], axis=-1)
                    for a in accumulators]


class ComposeStage(TileStage):
    name = "compose"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        with frame.stats.timed(self.name):
            direct = read_accumulator(work.direct)
            if work.soft_light is not None:
                direct += work.soft_light
            aa, tile, scene = frame.settings.antialiasing, work.tile, frame.scene
            if not scene.film_transparent:  # through this pass's camera (sub-sample offset)
                work.background = background(scene.world, frame.camera, aa, tile.x0, tile.y0,
                                             *tile.size)
            compose(frame.output, work.gbuffer.images, direct, work.indirect_light,
                    work.background, aa, tile.x0, tile.y0, frame.plan.passes)


class RenderImage(Stage):
    """Every tile through the tile stages, with the frame's GPU data in one scope."""

    name = "image"
    needs = ("camera", "geometry", "shapes", "centre", "plan", "light_passes")
    makes = ("output",)

    def __init__(self, gpu: GpuSession, kept: KeptProducts) -> None:
        self.gpu, self.kept = gpu, kept
        self.tile_stages = [GBufferStage(gpu), GatherStage(gpu), NearFieldStage(gpu),
                            BlurStage(gpu), ComposeStage(gpu), DenoisingData()]

    def run(self, frame: FrameState) -> None:
        camera, settings, ctx = frame.camera, frame.settings, self.gpu.ctx
        aa = settings.antialiasing
        tiles = tiles_of(camera.width * aa, camera.height * aa, aa)
        frame.output = {name: np.zeros((camera.height, camera.width, c), np.float32)
                        for name, c in PASS_CHANNELS.items()}
        kept = KeptAtlases(self.kept.shadow_atlases, self.kept.versions.shape) \
            if len(tiles) == 1 else None
        frame.steps, frame.steps_done = len(tiles) * max(1, len(frame.light_passes)), 0
        with GpuScope() as scope:
            geometry = frame.geometry
            scene = _buffers(ctx, geometry, scope)
            shapes = _buffers(ctx, frame.shapes, scope)
            textures = tuple(scope.own(t) for t in upload_textures(ctx, geometry.textures)) \
                if geometry.has_textures else None
            atlases = ShadowAtlases(ctx, self.gpu.programs, scene, kept)
            maps = FrameMaps(atlases, frame.ism_maps, frame.centre, frame.radius,
                             reuse_atlas=len(frame.light_passes) == 1)
            data = FrameGpu(scene, shapes, textures, maps)
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
                self.kept.keep_shadow_atlases(kept.used if kept is not None else {})
        if kept is not None and kept.hits:
            frame.stats.skipped["shadow maps"] = (f"{kept.hits} atlas(es) of unchanged "
                                                  f"lights and triangles kept from the last "
                                                  f"frame")
