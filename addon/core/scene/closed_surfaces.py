"""Which side of a triangle faces out of the closed surface it belongs to: an emissive object
that is closed (a lamp's bulb, a glowing cube) sends the light of its inner side nowhere
that an outside point sees, so light paths leave it outwards only."""

from __future__ import annotations

import numpy as np


def outward_sides(triangles: np.ndarray, group: np.ndarray) -> np.ndarray:
    """Per triangle of ``triangles`` (n, 3, 3) in groups ``group`` (n,) (an object's
    triangles each): +1 where its winding's normal points out of its group's closed,
    consistently wound surface, -1 where it points in (a surface wound inside out), 0 where
    the group is not closed (an edge without exactly one twin running the other way).
    Vertices are joined where their positions are equal."""
    sides = np.zeros(len(triangles), np.int8)
    for g in np.unique(group):
        rows = np.flatnonzero(group == g)
        sides[rows] = _side_of_closed(triangles[rows])
    return sides


def _side_of_closed(triangles: np.ndarray) -> int:
    """+1 or -1 for a closed, consistently wound surface by its signed volume's sign; 0 for
    any other."""
    _, vertex = np.unique(triangles.reshape(-1, 3), axis=0, return_inverse=True)
    vertex = vertex.reshape(-1, 3)
    directed = np.concatenate([vertex[:, [0, 1]], vertex[:, [1, 2]], vertex[:, [2, 0]]])
    if np.any(directed[:, 0] == directed[:, 1]):  # a collapsed edge
        return 0
    count = int(vertex.max()) + 1
    forward = directed[:, 0].astype(np.int64) * count + directed[:, 1]
    backward = directed[:, 1].astype(np.int64) * count + directed[:, 0]
    if len(np.unique(forward)) != len(forward) \
            or not np.array_equal(np.sort(forward), np.sort(backward)):
        return 0
    t = triangles.astype(np.float64)
    t = t - t.reshape(-1, 3).mean(axis=0)
    volume = float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum())
    return int(np.sign(volume))
