"""Triangle shadow maps of a batch of light samples, rendered into one atlas; atlases are kept
for the frame's later tiles and for the next frame while their samples and triangles repeat."""

from __future__ import annotations

import moderngl
import numpy as np

from ..gpu.clear_view import ClearView
from ..gpu.gl import ProgramCache, set_uniforms
from ..gpu.scene_buffers import SceneBuffers, table_texture
from ..gpu.shadow_atlas import TileTable, draw_tiles, tile_table
from .batches import ATLAS_TEXELS, Batch
from .gather import mask_words
from .gpu_scope import GpuScope

FAR_DEPTH = 3.0e38  # an atlas texel no triangle covers
TILE_BLOCKERS_UNIT = 5  # the tiles' blocker sets (shadow_vert.glsl; 6-10: the scene's)


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
                s.casts_shadow.tobytes(), batch.first_tile.tobytes(), tuple(centre), radius,
                None if s.blockers is None else s.blockers.tobytes())

    def room_for(self, batch: Batch) -> bool:
        texels = batch.columns * batch.rows * batch.resolution**2
        return self.texels + texels <= 2 * ATLAS_TEXELS

    def keep(self, key: tuple, objects: list, batch: Batch) -> None:
        self.used[key] = objects
        self.texels += batch.columns * batch.rows * batch.resolution**2


class ShadowAtlases:
    """Renders batches' shadow atlases for one frame; the current atlas lives until the next
    one is rendered or ``release`` (kept atlases belong to KeptAtlases). With ``clear``
    surfaces each atlas has a clear layer (``clear_atlas``); with ``shadowless`` triangles
    (objects that cast no shadow) the atlases of lights leave them out, those of VPLs keep
    them (their light comes along diffuse paths, which such objects block); with
    ``diffuse_hidden`` ones (Diffuse visibility off) the other way round."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache,
                 scene: SceneBuffers | None, kept: KeptAtlases,
                 clear: ClearView | None = None, shadowless: bool = False,
                 diffuse_hidden: bool = False) -> None:
        self.ctx = ctx
        self.programs = programs
        self.scene = scene
        self.kept = kept
        self.clear = clear
        self.shadowless = shadowless
        self.diffuse_hidden = diffuse_hidden
        self._current = GpuScope()
        self._last: tuple[moderngl.Texture, Batch] | None = None
        self._placeholder: moderngl.Texture | None = None
        self._clear_layers: dict[int, moderngl.Texture] = {}  # by their atlas's glo
        self._current_atlas: int | None = None  # the glo of the atlas _current owns

    def clear_atlas(self, atlas: moderngl.Texture) -> moderngl.Texture | None:
        """The clear layer of an atlas ``atlas`` returned (None without clear surfaces)."""
        return self._clear_layers.get(atlas.glo)

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
            return self._layers(kept.used[key])
        if key in kept.previous:
            objects = kept.previous[key]
            kept.keep(key, objects, batch)
            kept.hits += 1
            return self._layers(objects)
        self._release_current()
        keeping = kept.room_for(batch)
        objects: list = []
        own = objects.append if keeping else self._current.own
        res = batch.resolution
        size = (batch.columns * res, batch.rows * res)
        texture = self.ctx.texture(size, 1, dtype="f4")
        layer = self.ctx.texture(size, 4, dtype="f4") if self.clear is not None else None
        depth = self.ctx.depth_renderbuffer(size)
        fbo = self.ctx.framebuffer([texture], depth)
        for obj in (texture, layer, depth, fbo):
            if obj is not None:
                own(obj)
        if keeping:
            kept.keep(key, objects, batch)
        fbo.use()
        fbo.clear(FAR_DEPTH, 0.0, 0.0, 0.0, depth=1.0)
        self._last = (texture, batch)
        if layer is not None:
            self._clear_layers[texture.glo] = layer
        if not keeping:
            self._current_atlas = texture.glo
        s = batch.samples
        table = None
        if s.casts_shadow.any() and (self.scene is not None or layer is not None):
            table = tile_table(s, batch.first_tile, batch.columns, centre, radius)
            tiles = table.texture(self.ctx)
            own(tiles)
            tiles.use(0)
        if table is not None and self.scene is not None:
            streams, defines = self.scene.cutout_streams()
            if self.shadowless and not s.generation.any():  # lights' samples
                defines["SHADOWLESS"] = 1
            if self.diffuse_hidden and s.generation.all():  # VPLs
                defines["DIFFUSE_HIDDEN"] = 1
            if s.shadow_linked:  # each tile's sample's blockers (shadow linking)
                defines["SHADOW_LINKING"] = 1
                words = np.array([mask_words(int(m)) for m in s.blockers], np.uint32)
                blockers = table_texture(self.ctx, words[table.sample], 2, "u4")
                own(blockers)
                blockers.use(TILE_BLOCKERS_UNIT)
            program = self.programs.get("shadow_vert.glsl", "shadow_frag.glsl", defines)
            vao = self.ctx.vertex_array(program, streams)
            own(vao)
            if set(defines) - {"SHADOW_LINKING"}:
                self.scene.bind_cutouts(program)
            elif defines:  # the triangles' blocker sets alone
                self.scene.bind_triangle_rows(program)
            set_uniforms(program, u_tiles=0, u_atlas_tiles=(batch.columns, batch.rows),
                         u_scene_centre=tuple(centre), u_scene_radius=radius)
            if "SHADOW_LINKING" in defines:
                set_uniforms(program, u_tile_blockers=TILE_BLOCKERS_UNIT)
            draw_tiles(self.ctx, vao, self.scene.vertex_count, len(table.rows))
        if layer is not None:
            self._draw_clear(layer, depth, table, batch, centre, radius)
        return texture

    def _layers(self, objects: list) -> moderngl.Texture:
        """A kept atlas (its objects: the atlas first, then its clear layer if any)."""
        if self.clear is not None:
            self._clear_layers[objects[0].glo] = objects[1]
        return objects[0]

    def _draw_clear(self, layer: moderngl.Texture, depth: moderngl.Renderbuffer,
                    table: TileTable | None, batch: Batch, centre: np.ndarray,
                    radius: float) -> None:
        """The atlas's clear layer: cleared to (1, 1, 1, far), then the clear triangles in
        front of the opaque ones multiply rgb and keep the nearest distance in a."""
        fbo = self.ctx.framebuffer([layer], depth)
        try:
            fbo.depth_mask = False  # the opaque layer's depth is tested, not written
            fbo.use()
            fbo.clear(1.0, 1.0, 1.0, FAR_DEPTH)
            if table is None:
                return
            program = self.programs.get("shadow_vert.glsl", "shadow_clear_frag.glsl",
                                        {"CLEAR": 1})
            vao = self.clear.vertex_array(program)
            if vao is None:
                return
            set_uniforms(program, u_tiles=0, u_atlas_tiles=(batch.columns, batch.rows),
                         u_scene_centre=tuple(centre), u_scene_radius=radius)
            self.ctx.enable(moderngl.BLEND)
            self.ctx.blend_equation = moderngl.FUNC_ADD, moderngl.MIN
            self.ctx.blend_func = moderngl.ZERO, moderngl.SRC_COLOR, moderngl.ONE, moderngl.ONE
            try:
                draw_tiles(self.ctx, vao, self.clear.vertex_count, len(table.rows), True)
            finally:
                self.ctx.blend_equation = moderngl.FUNC_ADD
                self.ctx.blend_func = moderngl.DEFAULT_BLENDING
                self.ctx.disable(moderngl.BLEND)
                vao.release()
        finally:
            fbo.release()

    def placeholder(self) -> moderngl.Texture:
        """A 1×1 atlas for passes that read no maps (the gather binds an atlas regardless)."""
        if self._placeholder is None:
            self._placeholder = self.ctx.texture((1, 1), 1, dtype="f4")
        return self._placeholder

    def _release_current(self) -> None:
        """Release the atlas no KeptAtlases holds (its name may then be reused)."""
        self._current.release()
        self._clear_layers.pop(self._current_atlas, None)
        self._current_atlas = None

    def release(self) -> None:
        self._release_current()
        self._last = None
        self._clear_layers.clear()
        if self._placeholder is not None:
            self._placeholder.release()
            self._placeholder = None
