"""Whether a UV map can hold a bake (addon/uv_unwrap.py): the overlaps and collapsed faces
that would make two surface points share a texel, or a face none."""

from __future__ import annotations

import numpy as np

from addon.uv_unwrap import OVERLAP_GRID, shared_texels, unsuitable

SQUARE = np.array([[0.1, 0.1], [0.4, 0.1], [0.4, 0.4], [0.1, 0.1], [0.4, 0.4], [0.1, 0.4]])
"""Two triangles, a square of a tenth of the unit square's area."""


def test_separate_islands_can_hold_a_bake():
    assert unsuitable(np.concatenate([SQUARE, SQUARE + 0.5])) is None
    assert shared_texels(np.concatenate([SQUARE, SQUARE + 0.5])) == 0


def test_an_island_on_another_is_found_though_their_areas_fit():
    """Mirrored halves or a front and back face on one island: their areas sum to 0.18 of
    the square, which the area test lets through."""
    mirrored = SQUARE[:, ::-1].copy()  # the same square, its triangles wound the other way
    stacked = np.concatenate([SQUARE, mirrored])
    shared = shared_texels(stacked)
    side = round(0.3 * OVERLAP_GRID)  # texel centres across the square
    assert shared == side * side - side  # all but those on the diagonal both triangles share
    assert unsuitable(stacked) == (f"its UV map's triangles overlap ({shared} of a "
                                   f"{OVERLAP_GRID}² grid's texels lie in two or more)")


def test_islands_sharing_an_edge_share_no_texel():
    right = SQUARE + np.array([0.3, 0.0])  # touching along x = 0.4
    assert shared_texels(np.concatenate([SQUARE, right])) == 0


def test_faces_collapsed_in_uv_cannot_hold_a_bake():
    """A text object's front faces: UVs on a line (v = 0), so the bake has no texel for
    them; a sliver under 1 % of the surface is let through."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0]],
                         float)
    line = np.array([[0.1, 0.0], [0.5, 0.0], [0.3, 0.0]])
    uvs = np.concatenate([SQUARE[:3], line])
    assert unsuitable(uvs, positions) == "its UV map collapses 50 % of the surface to lines " \
                                         "or points"
    assert unsuitable(uvs) is None  # without the surface, the test cannot be made
    tiny = positions.copy()
    tiny[3:] *= 0.05  # the collapsed face 0.25 % of the surface
    assert unsuitable(uvs, tiny) is None
