"""The atlas-tile layout shared by shadow maps and reflective shadow maps: one tile per cube face
of a point sample or per directional sample, drawn in one instanced call (tiles_lib.glsl)."""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from ..transport.lights import KIND_DIRECTIONAL, LightSamples

GL_CLIP_DISTANCE0 = 0x3000


def near_far(samples: LightSamples, centre: np.ndarray, radius: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """Clip distances of each sample's cube maps, relative to the scene's size."""
    far = np.linalg.norm(samples.position - centre, axis=1) + radius * 1.01
    near = np.maximum(far * 1e-5, radius * 1e-6)
    return near, far


@dataclass
class TileTable:
    """Per tile: the row tiles_lib.glsl reads, its sample and its cube face (-1: directional)."""

    rows: np.ndarray  # (tiles, 2, 4) float32: (origin or axis, face), (near, far, col, row)
    sample: np.ndarray  # (tiles,) int index into the samples
    face: np.ndarray  # (tiles,) int

    def texture(self, ctx: moderngl.Context) -> moderngl.Texture:
        return ctx.texture((2, len(self.rows)), 4, self.rows.tobytes(), dtype="f4")


def tile_table(samples: LightSamples, first_tile: np.ndarray, columns: int,
               centre: np.ndarray, radius: float) -> TileTable:
    """The tiles of the shadow-casting samples: six cube faces from ``first_tile`` for point
    samples, one orthographic tile for directional ones."""
    near, far = near_far(samples, centre, radius)
    shadowed = np.flatnonzero(samples.casts_shadow)
    directional = samples.kind[shadowed] == KIND_DIRECTIONAL
    faces = np.where(directional, 1, 6)
    sample = np.repeat(shadowed, faces)
    face = np.concatenate([[-1] if d else range(6) for d in directional] or [[]]).astype(int)
    tile = np.repeat(first_tile[shadowed], faces) + np.maximum(face, 0)
    rows = np.zeros((len(sample), 2, 4), np.float32)
    rows[:, 0, :3] = np.where(directional.repeat(faces)[:, None], samples.axis[sample],
                              samples.position[sample])
    rows[:, 0, 3] = face
    rows[:, 1, 0], rows[:, 1, 1] = near[sample], far[sample]
    rows[:, 1, 2], rows[:, 1, 3] = tile % columns, tile // columns
    return TileTable(rows, sample, face)


def draw_tiles(ctx: moderngl.Context, vao: moderngl.VertexArray, vertices: int,
               tiles: int, blended: bool = False) -> None:
    """Draw the scene once per tile (instanced), depth-tested, cut to each tile by the four
    clip distances tiles_lib.glsl sets; ``blended``: with the context's blending (enabled and
    set by the caller), else without."""
    ctx.enable(moderngl.DEPTH_TEST)
    ctx.disable(moderngl.CULL_FACE)
    if not blended:
        ctx.disable(moderngl.BLEND)
    for plane in range(4):
        ctx.enable_direct(GL_CLIP_DISTANCE0 + plane)
    vao.render(moderngl.TRIANGLES, vertices=vertices, instances=tiles)
    for plane in range(4):
        ctx.disable_direct(GL_CLIP_DISTANCE0 + plane)
    ctx.disable(moderngl.DEPTH_TEST)
