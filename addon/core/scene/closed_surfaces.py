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
    Vertices of a group are joined where their positions are equal."""
    n = len(triangles)
    if n == 0:
        return np.zeros(0, np.int8)
    _, groups = np.unique(group, return_inverse=True)
    positions = np.ascontiguousarray(triangles.reshape(-1, 3), np.float32) + np.float32(0.0)
    bits = positions.view(np.uint32)  # + 0: -0 and 0 alike
    corners = np.column_stack([np.repeat(groups, 3).astype(np.uint32), bits])
    _, vertex = np.unique(np.ascontiguousarray(corners).view("V16").ravel(),
                          return_inverse=True)  # one 16-byte key per corner: a sort of bytes
    vertex = vertex.reshape(-1, 3).astype(np.int64)
    tail = vertex.ravel()
    head = vertex[:, [1, 2, 0]].ravel()
    owner = np.repeat(groups, 3)
    count = int(vertex.max()) + 1
    forward, backward = tail * count + head, head * count + tail
    keys, counts = np.unique(forward, return_counts=True)
    open_edge = (tail == head) | ~np.isin(backward, forward) \
        | (counts[np.searchsorted(keys, forward)] > 1)
    closed = np.bincount(owner[open_edge], minlength=groups.max() + 1) == 0
    t = triangles.astype(np.float64)
    centre = np.stack([np.bincount(groups, t[..., k].mean(axis=1)) for k in range(3)], axis=1)
    t = t - (centre / np.bincount(groups)[:, None])[groups][:, None, :]
    volume = np.bincount(groups, np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])))
    return (np.sign(volume) * closed).astype(np.int8)[groups]
