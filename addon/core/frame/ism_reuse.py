"""Imperfect shadow maps kept from frame to frame: the maps of VPLs that survive (Incremental
Instant Radiosity gives each VPL a ``key`` it keeps while it holds still) stay in their atlas
tiles, and only new VPLs get a map, rendered into free tiles by a partial update. A frame whose
VPLs and geometry are unchanged (a camera-only edit) renders no map at all."""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from ..gpu.ism import ImperfectShadowMaps, atlas_grid
from ..transport.lights import KIND_DIRECTIONAL, LightSamples

SPARE_TILES = 0.25  # extra tiles a keyed atlas reserves for VPL counts that grow a little


@dataclass
class AtlasUse:
    """Where the maps of a batch's samples are: the atlas, each sample's tile and the grid."""

    texture: moderngl.Texture
    tiles: np.ndarray
    columns: int
    rows: int
    rendered: int  # maps rendered this frame


def _assign_tiles(keys: np.ndarray, previous: dict[int, int], capacity: int
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """Tiles for ``keys``: a key seen before keeps its tile, new keys take free tiles (lowest
    first). Returns (tiles, new mask), or None when the free tiles do not suffice."""
    tiles = np.array([previous.get(int(k), -1) for k in keys], dtype=np.int64)
    new = tiles < 0
    free = np.setdiff1d(np.arange(capacity), tiles[~new])
    if new.sum() > len(free):
        return None
    tiles[new] = free[: int(new.sum())]
    return tiles, new


class ReusedISMAtlas:
    """The atlas of the last single-batch ISM render, and what it holds."""

    def __init__(self) -> None:
        self._exact: tuple | None = None  # inputs of the last render, for an exact repeat
        self._layout: tuple | None = None  # (geometry, settings, capacity) of the atlas
        self._tiles: dict[int, int] = {}
        self._last: AtlasUse | None = None

    def forget(self) -> None:
        self._exact, self._layout, self._last = None, None, None
        self._tiles = {}

    def render(self, ism: ImperfectShadowMaps, triangles: np.ndarray, samples: LightSamples,
               keys: np.ndarray | None, settings_key: tuple, resolution: int, levels: int,
               sphere: tuple[np.ndarray, float], max_tiles: int) -> AtlasUse:
        """The maps of ``samples`` (VPLs identified by ``keys``, or None), rendering only what
        the atlas does not hold yet. ``settings_key`` names everything else the maps depend on
        (geometry version, points, resolution, levels, seed)."""
        exact = (settings_key, samples.position.tobytes(), samples.axis.tobytes())
        if exact == self._exact and self._last is not None:
            return AtlasUse(self._last.texture, self._last.tiles.copy(), self._last.columns,
                            self._last.rows, 0)
        n = len(samples)
        assigned = None
        if keys is not None and self._layout is not None and self._layout[0] == settings_key:
            assigned = _assign_tiles(keys, self._tiles, self._layout[1])
        if assigned is None:
            capacity = n if keys is None else min(max_tiles, n + int(np.ceil(SPARE_TILES * n)))
            tiles, new = np.arange(n), np.ones(n, bool)
        else:
            capacity = self._layout[1]
            tiles, new = assigned
        directional = samples.kind == KIND_DIRECTIONAL
        if new.any() or ism.atlas is None:
            texture = ism.render(triangles, samples.position[new], samples.axis[new],
                                 resolution, levels, directional[new], sphere,
                                 tiles=tiles[new], tile_count=capacity)
        else:
            texture = ism.atlas
        columns, rows = atlas_grid(capacity)
        self._last = AtlasUse(texture, tiles, columns, rows, int(new.sum()))
        self._exact = exact
        self._layout = (settings_key, capacity)
        self._tiles = {} if keys is None else dict(zip(keys.tolist(), tiles.tolist(),
                                                       strict=True))
        return AtlasUse(texture, tiles.copy(), columns, rows, int(new.sum()))
