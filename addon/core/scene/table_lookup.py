"""Lookups in tables of nodes evenly spaced on [0, 1], interpolated linearly as the shaders'
table_row and table_2d (principled_lib.glsl) do: the GGX lobe's tables and the sheen's."""

from __future__ import annotations

import numpy as np


def node(x: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """The node below ``x`` (clipped to [0, 1]) among ``size`` nodes, and the weight of the
    one above it."""
    f = np.clip(x, 0.0, 1.0) * (size - 1)
    i = np.minimum(np.floor(f).astype(int), size - 2)
    return i, f - i


def lerp_row(table: np.ndarray, row: np.ndarray, x: np.ndarray, size: int) -> np.ndarray:
    """Row ``row`` of ``table`` (per element) at ``x``, between its first ``size`` nodes."""
    i, t = node(x, size)
    return (1 - t) * table[row, i] + t * table[row, i + 1]


def lerp_2d(table: np.ndarray, first: int, y: np.ndarray, x: np.ndarray, size: int
            ) -> np.ndarray:
    """The ``size`` × ``size`` block of ``table`` from row ``first`` at (``y`` along its
    rows, ``x`` along its columns), bilinearly."""
    i, t = node(y, size)
    return (1 - t) * lerp_row(table, first + i, x, size) \
        + t * lerp_row(table, first + i + 1, x, size)
