"""Which side of an emissive triangle faces out of its closed object."""

from __future__ import annotations

import numpy as np

from addon.core.scene.closed_surfaces import outward_sides

CUBE_FACES = [(2, 3, 1, 0), (5, 7, 6, 4), (1, 5, 4, 0), (6, 7, 3, 2), (4, 6, 2, 0), (3, 7, 5, 1)]
"""Quads of the unit cube's corners (bit 0: x, bit 1: y, bit 2: z), wound outwards."""


def cube(offset: float = 0.0) -> np.ndarray:
    corners = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], float) + offset
    quads = np.array(CUBE_FACES)
    return corners[np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])]


def test_a_closed_cube_faces_out_and_an_inverted_one_in():
    triangles = cube()
    assert np.all(outward_sides(triangles, np.zeros(12, int)) == 1)
    assert np.all(outward_sides(triangles[:, ::-1], np.zeros(12, int)) == -1)


def test_an_open_box_or_a_mixed_winding_has_no_outside():
    open_box = cube()[2:]  # one face left out
    assert np.all(outward_sides(open_box, np.zeros(10, int)) == 0)
    mixed = cube()
    mixed[0] = mixed[0, ::-1]
    assert np.all(outward_sides(mixed, np.zeros(12, int)) == 0)


def test_groups_are_judged_apart_even_where_they_touch():
    """Two cubes sharing a face's corners (one open): each group on its own."""
    triangles = np.concatenate([cube(), cube(1.0)[2:]])
    group = np.repeat([0, 1], [12, 10])
    sides = outward_sides(triangles, group)
    assert np.all(sides[:12] == 1) and np.all(sides[12:] == 0)
