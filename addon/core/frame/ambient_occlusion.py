"""The Ambient Occlusion pass (gpu_shaders/ao_frag.glsl): at each supersample, the share of
cosine-distributed rays as long as the world's AO distance that leave its surface
unoccluded, averaged over the pixel's supersamples (and a render's passes), as Cycles writes
it from one such ray per sample."""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl

from ..gpu.gl import read_textures, set_uniforms
from .compose import downsample
from .gather import RAY_OFFSET
from .gpu_scope import GpuScope

if TYPE_CHECKING:  # image.py runs AmbientOcclusion among its tile stages
    from .gpu_session import GpuSession
    from .image import FrameGpu, TileWork
    from .state import FrameState

AO_RAYS_PER_PIXEL = 16  # and pass, spread over its supersamples (2 each at antialiasing 3)
NEEDS_RAYS = "the Ambient Occlusion pass needs OpenGL 4.3 (ray tracing): it is left black"


def needs_ambient_occlusion(frame: FrameState, version_code: int) -> bool:
    """Whether the frame traces AO rays (the pass asked for, surfaces to trace, a GPU that
    traces); where the GPU cannot, a warning says so."""
    if "AO" not in frame.plan.passes or frame.geometry.vertex_count == 0:
        return False
    if version_code < 430:
        if NEEDS_RAYS not in frame.stats.warnings:
            frame.stats.warnings.append(NEEDS_RAYS)
        return False
    return True


def rays_per_sample(aa: int) -> int:
    """AO rays per supersample: AO_RAYS_PER_PIXEL spread over a pixel's aa × aa, one at
    least."""
    return max(1, -(-AO_RAYS_PER_PIXEL // (aa * aa)))


class AmbientOcclusion:
    """A tile stage (image.py's TileStage interface): the AO pass of one tile. The frame's
    triangles must be in the ray tracer (``FrameState.traces_rays``)."""

    name = "ambient occlusion"

    def __init__(self, gpu: GpuSession) -> None:
        self.gpu = gpu

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        if not needs_ambient_occlusion(frame, self.gpu.ctx.version_code):
            return
        frame.check_cancelled()
        ctx, aa, tile = self.gpu.ctx, frame.settings.antialiasing, work.tile
        with frame.stats.timed(self.name), GpuScope() as scope:
            textures = work.gbuffer.textures
            target = scope.own(ctx.framebuffer([scope.own(
                ctx.texture(textures["position"].size, 4, dtype="f4"))]))
            program = self.gpu.programs.get("fullscreen_vert.glsl", "ao_frag.glsl",
                                            version=430)
            for unit, name in enumerate(("position", "normal", "geometric")):
                textures[name].use(unit)
            self.gpu.tracer.bind()
            set_uniforms(program, u_position=0, u_normal=1, u_geometric=2,
                         u_distance=frame.scene.ao_distance, u_rays=rays_per_sample(aa),
                         u_ray_offset=RAY_OFFSET * frame.radius,
                         u_seed=frame.settings.seed & 0xFFFFFFFF)
            target.use()
            scope.own(ctx.vertex_array(program, [])).render(moderngl.TRIANGLES, vertices=3)
            open_share = read_textures(target.color_attachments)[..., :3]
        h, w = open_share.shape[0] // aa, open_share.shape[1] // aa
        x0, y0 = tile.x0 // aa, tile.y0 // aa
        frame.output["AO"][y0:y0 + h, x0:x0 + w] = downsample(open_share, aa)
