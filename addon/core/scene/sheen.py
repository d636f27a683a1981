"""The Principled BSDF's sheen (Cycles' microfiber sheen, Blender 4.0+): the top layer, a
soft reflection that grows towards grazing angles (velvet, cloth), which dims every layer
below it by one minus the largest channel of its albedo, as Cycles layers it.

Its BRDF times the light's cosine is R(μ_v, r) D(ω_l): the albedo R towards a view at
cosine μ_v for roughness r times a linearly transformed cosine D (Zeltner et al. 2022's
form: D(ω) = D_o(M⁻¹ω / |M⁻¹ω|) a² / |M⁻¹ω|³ with M⁻¹ω = (a x + b z, a y, z) in the frame
whose x is the view's projection on the surface, D_o the clamped cosine / π), which
integrates to 1. R, a and b are measured on Cycles at each node of a 17 × 17 grid of r × μ_v
(``tools/measure_sheen.py``: renders of a plane of sheen under a white world, and under a
sun from 31 directions, to which the transformed cosine fits within 0.1 % wherever the
albedo is over 1 %, but for roughness 0.125 and below at grazing views: ``sheen_table.json``).
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .table_lookup import lerp_2d

TABLE = Path(__file__).with_name("sheen_table.json")
SIZE = 17  # roughness × cos(view) nodes, evenly spaced on [0, 1]


class Sheen(NamedTuple):
    """A sheen: its colour (weight × tint, at least 0), roughness in [0, 1], whether it is
    the Principled BSDF's layer, which dims the layers below it and the emission the camera
    sees (a Sheen BSDF mixed or added to other shaders dims nothing), and whether it dims
    the light that emission casts on other surfaces too (Blender 5.x, measured; 4.x not)."""

    color: tuple[float, float, float]
    roughness: float
    layered: bool = True
    dims_cast_light: bool = False


NO_SHEEN = Sheen((0.0, 0.0, 0.0), 0.5)


@lru_cache(maxsize=1)
def table() -> np.ndarray:
    """The measured tables (3 SIZE, SIZE) float64, rows by roughness × columns by the view's
    cosine: the albedo R, then the lobe's a, then its b."""
    measured = json.loads(TABLE.read_text())
    parts = [np.clip(np.asarray(measured["albedo"], np.float64), 0.0, 1.0),
             np.asarray(measured["ltc_a"], np.float64), np.asarray(measured["ltc_b"], np.float64)]
    if any(part.shape != (SIZE, SIZE) for part in parts):
        raise ValueError(f"{TABLE.name}: expected {SIZE}×{SIZE} tables")
    return np.vstack(parts)


def albedo(rough: np.ndarray | float, mu: np.ndarray) -> np.ndarray:
    """R(μ, r) (n,) at cosines ``mu`` (n,), interpolated bilinearly between the table's
    nodes as the shaders do (principled_lib.glsl's sheen_albedo)."""
    rough, mu = np.broadcast_arrays(np.asarray(rough, float), np.asarray(mu, float))
    return lerp_2d(table(), 0, rough, mu, SIZE)


def layer(sheen: Sheen, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What a sheen reflects towards views at cosines ``mu`` (n,) (and, near enough by
    reciprocity, of light arriving at them), its colour × R (n, 3), and what it leaves the
    layers below (n,): one minus its largest channel (Cycles' closure_layering_weight), all
    where it is not ``layered``."""
    color = np.maximum(np.asarray(sheen.color, float), 0.0)
    if not color.any():
        return np.zeros((len(mu), 3)), np.ones(len(mu))
    reflected = albedo(sheen.roughness, np.clip(mu, 0.0, 1.0))[:, None] * color[None]
    if not sheen.layered:
        return reflected, np.ones(len(mu))
    return reflected, np.clip(1.0 - reflected.max(axis=1), 0.0, 1.0)
