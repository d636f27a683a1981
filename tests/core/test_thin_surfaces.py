"""Where VPLs gathered once per pixel are gathered in full (frame/thin_surfaces.py): pixels whose
blur window holds under half of the interleaving pattern's subsets on their own surface."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.frame.gpu_scope import GpuScope
from addon.core.frame.thin_surfaces import thin_surface_mask
from tests.core.test_shading import surface

SIZE = 64
K = 4  # the pattern at antialiasing 3 (pixel_interleave(8, 3))
RADIUS = 4  # the blur radius at interleave 8


def ledge_gbuffer(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """A wall facing the camera with a ledge ``rows`` pixels tall across it, facing up (its
    normal is perpendicular to the wall's, so the blur never mixes the two), and background
    in the last 8 columns."""
    normal = np.broadcast_to([0.0, 0.0, 1.0], (SIZE, SIZE, 3)).copy()
    normal[30:30 + rows] = [0.0, 1.0, 0.0]
    covered = np.ones((SIZE, SIZE))
    covered[:, -8:] = 0.0
    return surface(np.zeros((SIZE, SIZE)), normal, covered)


def mask_of(programs, position: np.ndarray, normal: np.ndarray) -> np.ndarray:
    ctx = programs.ctx
    with GpuScope() as scope:
        textures = [scope.own(ctx.texture((SIZE, SIZE), 4, np.ascontiguousarray(
            a, np.float32).tobytes(), dtype="f4")) for a in (position, normal)]
        mask = thin_surface_mask(ctx, programs, *textures, K, RADIUS, scope)
        target = scope.own(ctx.framebuffer(depth_attachment=mask))
        depth = np.frombuffer(target.read(components=1, attachment=-1, dtype="f4"), np.float32)
        return depth.reshape(SIZE, SIZE)


@pytest.mark.parametrize("rows", [1, 2, 3])
def test_a_ledge_thinner_than_the_pattern_gathers_every_vpl(programs, rows):
    """A ledge of 1 (K of K² subsets in its window), 2 (2K, exactly half: kept) or 3 rows."""
    mask = mask_of(programs, *ledge_gbuffer(rows))
    ledge = mask[30:30 + rows, RADIUS:-8 - RADIUS]
    assert np.all(ledge == (1.0 if rows < 2 else 0.0))
    assert np.all(mask[:24, :-8] == 0.0)  # the wall, away from the ledge
    assert np.all(mask[:, -8:] == 0.0)  # the background


def test_a_wide_ledge_and_the_wall_s_edges_keep_the_pattern(programs):
    """Eight rows hold every subset; so does the wall next to the image's border and the
    background, where the window is cut in half."""
    mask = mask_of(programs, *ledge_gbuffer(8))
    assert not mask.any()
