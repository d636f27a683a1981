"""Light samples cut into batches whose shadow maps fit one atlas texture."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gpu.ism import atlas_grid
from ..transport.lights import LightSamples

ATLAS_TEXELS = 1 << 25  # texels per shadow atlas batch (128 MiB of float32)
MAX_BATCH = 8192  # samples or tiles per batch (rows of a table texture)


@dataclass
class Batch:
    """Light samples gathered in one pass, with their atlas layout: the tile of each
    sample's first map, and the atlas's columns and rows of tiles of ``resolution``²."""

    samples: LightSamples
    resolution: int
    first_tile: np.ndarray
    columns: int
    rows: int


def shadow_map_batches(samples: LightSamples, max_texture: int) -> list[Batch]:
    """Group samples by shadow resolution and cut the groups so each atlas fits the budget."""
    batches: list[Batch] = []
    tiles = samples.tiles_per_sample
    shadowless = np.flatnonzero(tiles == 0)
    for start in range(0, len(shadowless), MAX_BATCH):
        chunk = shadowless[start:start + MAX_BATCH]
        batches.append(Batch(samples.subset(chunk), 1, np.zeros(len(chunk), int), 1, 1))
    for resolution in np.unique(samples.resolution[tiles > 0]):
        res = int(resolution)
        index = np.flatnonzero((tiles > 0) & (samples.resolution == res))
        per_edge = max(1, max_texture // res)
        capacity = min(per_edge * per_edge, max(6, ATLAS_TEXELS // (res * res)), MAX_BATCH)
        start = 0
        while start < len(index):
            used, stop = 0, start
            while stop < len(index) and used + tiles[index[stop]] <= capacity:
                used += tiles[index[stop]]
                stop += 1
            chunk = index[start:stop]
            first = np.concatenate([[0], np.cumsum(tiles[chunk])[:-1]])
            columns = min(used, per_edge)
            batches.append(Batch(samples.subset(chunk), res, first, columns,
                                 -(-used // columns)))
            start = stop
    return batches


def unmapped_batches(samples: LightSamples) -> list[Batch]:
    """Samples in batches that need no maps (ray-traced visibility): tile 0 marks a sample
    that casts shadows, as the light table's tile -1 marks one that does not."""
    return [Batch(samples.subset(np.arange(start, min(start + MAX_BATCH, len(samples)))), 1,
                  np.zeros(min(MAX_BATCH, len(samples) - start), int), 1, 1)
            for start in range(0, len(samples), MAX_BATCH)]


def ism_tiles_per_atlas(resolution: int) -> int:
    """Imperfect shadow maps of ``resolution``² that one atlas holds."""
    return max(1, min(MAX_BATCH, ATLAS_TEXELS // (resolution * resolution)))


def ism_batches(samples: LightSamples, resolution: int) -> list[Batch]:
    """Samples in groups whose imperfect shadow maps fit one atlas (tile k = sample k)."""
    size = ism_tiles_per_atlas(resolution)
    batches = []
    for start in range(0, len(samples), size):
        index = np.arange(start, min(start + size, len(samples)))
        columns, rows = atlas_grid(len(index))
        batch_samples = samples.subset(index)
        batch_samples.resolution = np.full(len(index), resolution)
        batches.append(Batch(batch_samples, resolution, np.arange(len(index)), columns, rows))
    return batches
