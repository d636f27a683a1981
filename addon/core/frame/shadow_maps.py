"""Triangle shadow maps of a batch of light samples, rendered into one atlas; atlases are kept
for the frame's later tiles and for the next frame while their samples and triangles repeat."""

from __future__ import annotations

import moderngl
import numpy as np

from ..gpu.gl import ProgramCache, set_uniforms
from ..gpu.scene_buffers import SceneBuffers
from ..gpu.shadow_atlas import draw_tiles, tile_table
from .batches import ATLAS_TEXELS, Batch
from .gpu_scope import GpuScope

FAR_DEPTH = 3.0e38  # an atlas texel no triangle covers


class KeptAtlases:
    """The atlases a frame takes from the last one and keeps for its later tiles and the next
    frame, within a budget of twice one batch's texels."""

    def __init__(self, previous: dict[tuple, list], shape_version: int) -> None:
        self.previous = previous
        self.shape_version = shape_version
        self.used: dict[tuple, list] = {}
        self.texels = 0
        self.hits = 0  # atlases taken from the last frame
        self.tile_hits = 0  # atlases a later tile of this frame took from an earlier one

    def key(self, batch: Batch, centre: np.ndarray, radius: float) -> tuple:
        s = batch.samples
        return (self.shape_version, batch.resolution, batch.columns, batch.rows,
                s.position.tobytes(), s.axis.tobytes(), s.kind.tobytes(),
                s.casts_shadow.tobytes(), batch.first_tile.tobytes(), tuple(centre), radius)

    def room_for(self, batch: Batch) -> bool:
        texels = batch.columns * batch.rows * batch.resolution**2
        return self.texels + texels <= 2 * ATLAS_TEXELS

    def keep(self, key: tuple, objects: list, batch: Batch) -> None:
        self.used[key] = objects
        self.texels += batch.columns * batch.rows * batch.resolution**2


class ShadowAtlases:
    """Renders batches' shadow atlases for one frame; the current atlas lives until the next
    one is rendered or ``release`` (kept atlases belong to KeptAtlases)."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache,
                 scene: SceneBuffers | None, kept: KeptAtlases) -> None:
        self.ctx = ctx
        self.programs = programs
        self.scene = scene
        self.kept = kept
        self._current = GpuScope()
        self._last: tuple[moderngl.Texture, Batch] | None = None
        self._placeholder: moderngl.Texture | None = None

    def atlas(self, batch: Batch, centre: np.ndarray, radius: float, again: bool
               ) -> moderngl.Texture:
        """The batch's atlas of tiles (cube faces or directional); with ``again``, the atlas
        of the last call if it was for this batch."""
        if again and self._last is not None and self._last[1] is batch:
            return self._last[0]
        kept = self.kept
        key = kept.key(batch, centre, radius)
        if key in kept.used:
            kept.tile_hits += 1
            return kept.used[key][0]
        if key in kept.previous:
            objects = kept.previous[key]
            kept.keep(key, objects, batch)
            kept.hits += 1
            return objects[0]
        self._current.release()
        keeping = kept.room_for(batch)
        objects: list = []
        own = objects.append if keeping else self._current.own
        res = batch.resolution
        size = (batch.columns * res, batch.rows * res)
        texture = self.ctx.texture(size, 1, dtype="f4")
        depth = self.ctx.depth_renderbuffer(size)
        fbo = self.ctx.framebuffer([texture], depth)
        for obj in (texture, depth, fbo):
            own(obj)
        if keeping:
            kept.keep(key, objects, batch)
        fbo.use()
        fbo.clear(FAR_DEPTH, 0.0, 0.0, 0.0, depth=1.0)
        self._last = (texture, batch)
        s = batch.samples
        if self.scene is None or not s.casts_shadow.any():
            return texture
        table = tile_table(s, batch.first_tile, batch.columns, centre, radius)
        tiles = table.texture(self.ctx)
        own(tiles)
        tiles.use(0)
        program = self.programs.get("shadow_vert.glsl", "shadow_frag.glsl")
        vao = self.ctx.vertex_array(program, self.scene.streams(normals=False))
        own(vao)
        set_uniforms(program, u_tiles=0, u_atlas_tiles=(batch.columns, batch.rows),
                     u_scene_centre=tuple(centre), u_scene_radius=radius)
        draw_tiles(self.ctx, vao, self.scene.vertex_count, len(table.rows))
        return texture

    def placeholder(self) -> moderngl.Texture:
        """A 1×1 atlas for passes that read no maps (the gather binds an atlas regardless)."""
        if self._placeholder is None:
            self._placeholder = self.ctx.texture((1, 1), 1, dtype="f4")
        return self._placeholder

    def release(self) -> None:
        self._current.release()
        self._last = None
        if self._placeholder is not None:
            self._placeholder.release()
            self._placeholder = None
