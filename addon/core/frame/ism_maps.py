"""Imperfect shadow maps of one frame's batches: the area CDF their surface points are drawn
from (on the GPU) uploaded once per geometry version, the atlas kept between frames when the
frame has a single ISM batch, and each batch's atlas kept for the frame when it has several
(within KEPT_ATLAS_BYTES)."""

from __future__ import annotations

import time

import moderngl
import numpy as np

from ..gpu.ism import ImperfectShadowMaps
from ..scene.geometry import WorldGeometry
from ..settings import Settings
from ..transport.lights import KIND_DIRECTIONAL
from .batches import Batch, ism_tiles_per_atlas
from .result import Stats
from .reuse import KeptProducts, settings_key
from .state import RenderError

ATLAS_FIELDS = ("ism_points", "ism_resolution", "pull_push_levels", "seed")
"""Settings the kept ISM atlas depends on (with the triangle positions' version)."""
KEPT_ATLAS_BYTES = 1 << 30
"""GPU memory a frame with several ISM atlases may keep them in (each up to 128 MiB,
batches.ATLAS_TEXELS), so that the image's tiles and the bias compensation's unseen hits read
them without rendering them again: 8 atlases, 16384 VPLs of 128² maps."""


def prepare_points(ism: ImperfectShadowMaps, kept: KeptProducts, geometry: WorldGeometry,
                   settings: Settings, point_seed: int, stats: Stats) -> None:
    """Have ``ism`` draw the frame's points (``ism_points`` per map from ``point_seed``),
    uploading the triangles' area table unless the geometry's version is the one uploaded."""
    start = time.perf_counter()
    try:
        uploaded = ism.prepare(geometry.positions.reshape(-1, 3, 3), settings.ism_points,
                               point_seed, kept.versions.shape,
                               geometry.coverage if geometry.cutout.any() else None,
                               geometry.diffuse_hidden if geometry.diffuse_hidden.any()
                               else None)
    except ValueError as exc:  # the area table exceeds the GPU's storage-buffer limit
        raise RenderError(f"imperfect shadow maps: {exc}") from None
    if uploaded:
        stats.timings["ism points"] = time.perf_counter() - start
    else:
        stats.skipped["ism points"] = "triangle positions unchanged (area table kept)"


def pull_push_levels(settings: Settings) -> int:
    """The pull-push levels the maps get (capped at log2 of their resolution)."""
    return min(settings.pull_push_levels, int(np.log2(settings.ism_resolution)))


class ImperfectShadowMapFrame:
    """Renders the imperfect shadow maps of a frame's batches. With a single batch its atlas
    is kept between frames: ``keys`` identify the VPLs of ``keyed_batch``, and only maps of
    VPLs with new keys are rendered; with several, each batch's atlas is kept until
    :meth:`release` where they fit KEPT_ATLAS_BYTES (``keeps_all``), else rendered whenever it
    is asked for. The points come from ``point_seed`` (the same in every pass of a
    progressive render)."""

    def __init__(self, ism: ImperfectShadowMaps, kept: KeptProducts, geometry: WorldGeometry,
                 settings: Settings, batches: list[Batch], sphere: tuple[np.ndarray, float],
                 stats: Stats, keyed_batch: Batch | None, keys: np.ndarray | None,
                 point_seed: int) -> None:
        self.ism, self.kept, self.settings, self.batches = ism, kept, settings, batches
        self.sphere, self.stats, self.keyed_batch, self.keys = sphere, stats, keyed_batch, keys
        self.triangles = geometry.positions.reshape(-1, 3, 3)
        self.empty = geometry.vertex_count == 0
        prepare_points(ism, kept, geometry, settings, point_seed, stats)
        self.levels = pull_push_levels(settings)
        stats.counts["isms"] = sum(len(b.samples) for b in batches)
        self.atlas_key = (kept.versions.shape, *settings_key(settings, ATLAS_FIELDS))
        self.atlas_bytes = 4 * sum(b.columns * b.rows * b.resolution**2 for b in batches)
        """GPU memory of every batch's atlas."""
        self.keeps_all = len(batches) == 1 or self.atlas_bytes <= KEPT_ATLAS_BYTES
        """Whether every batch's atlas, once rendered, is kept for the frame."""
        self._rendered: dict[int, moderngl.Texture] = {}
        self._taken: list[moderngl.Texture] = []  # the several batches' atlases this owns

    def atlas(self, batch: Batch) -> moderngl.Texture:
        """The batch's atlas of maps (tile k for sample k, or as the kept atlas assigns)."""
        ism, settings, stats = self.ism, self.settings, self.stats
        if self.empty:
            return ism.render(self.triangles, np.zeros((0, 3)), np.zeros((0, 3)),
                              settings.ism_resolution, self.levels)
        if id(batch) in self._rendered:
            return self._rendered[id(batch)]
        s = batch.samples
        if len(self.batches) > 1:  # several atlases per frame: nothing is kept between frames
            self.kept.ism_atlas.forget()
            texture = ism.render(self.triangles, s.position, s.axis, settings.ism_resolution,
                                 self.levels, s.kind == KIND_DIRECTIONAL, self.sphere)
            rendered = len(s)
            if self.keeps_all:
                texture = ism.take_atlas()
                self._taken.append(texture)
                self._rendered[id(batch)] = texture
        else:
            use = self.kept.ism_atlas.render(
                ism, self.triangles, s, self.keys if batch is self.keyed_batch else None,
                self.atlas_key, settings.ism_resolution, self.levels, self.sphere,
                ism_tiles_per_atlas(settings.ism_resolution))
            texture, rendered = use.texture, use.rendered
            batch.first_tile, batch.columns, batch.rows = use.tiles, use.columns, use.rows
            self._rendered[id(batch)] = texture
        stats.counts["isms_rendered"] = stats.counts.get("isms_rendered", 0) + rendered
        if rendered == 0:
            stats.skipped["ism"] = "VPLs and geometry unchanged since the last frame"
            return texture
        for stage, seconds in ism.timings.items():
            stats.timings[f"ism {stage}"] = stats.timings.get(f"ism {stage}", 0) + seconds
        return texture

    def release(self) -> None:
        """Release the several batches' atlases kept for the frame."""
        for texture in self._taken:
            texture.release()
        self._taken.clear()
        self._rendered.clear()
