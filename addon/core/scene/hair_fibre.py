"""The colour of a mass of hair from its fibres' absorption, as the Principled Hair BSDF
parametrises it (Chiang et al. 2016, "A Practical and Controllable Hair and Fur Model for
Production Path Tracing"): its Direct Coloring is the colour whose absorption makes a mass
of hair look that colour, so the inverse mapping turns melanin or an absorption coefficient
into the colour VPL GI renders the hair with (a diffuse surface)."""

from __future__ import annotations

import numpy as np

EUMELANIN = np.array([0.506, 0.841, 1.653])
"""Absorption of one unit of eumelanin (brown-black), per channel, as Cycles' Principled Hair
BSDF has it (the paper: 0.419, 0.697, 1.37)."""
PHEOMELANIN = np.array([0.343, 0.733, 1.924])
"""Absorption of one unit of pheomelanin (red-yellow), as Cycles has it."""


def _roughness_term(radial_roughness: float) -> float:
    b = float(np.clip(radial_roughness, 0.0, 1.0))
    return 5.969 - 0.215 * b + 2.532 * b ** 2 - 10.73 * b ** 3 + 5.574 * b ** 4 \
        + 0.245 * b ** 5


def absorption_from_colour(colour, radial_roughness: float) -> np.ndarray:
    """The absorption coefficient that makes hair of ``radial_roughness`` look ``colour``."""
    colour = np.clip(np.asarray(colour, np.float64), 1e-4, 1.0)
    return (np.log(colour) / _roughness_term(radial_roughness)) ** 2


def colour_from_absorption(absorption, radial_roughness: float) -> tuple[float, ...]:
    """The colour a mass of hair with fibres of ``absorption`` looks (the inverse)."""
    sigma = np.maximum(np.nan_to_num(np.asarray(absorption, np.float64), nan=0.0), 0.0)
    return tuple(float(c) for c in np.exp(-np.sqrt(sigma) * _roughness_term(radial_roughness)))


def melanin_absorption(melanin: float, redness: float, tint, radial_roughness: float
                       ) -> np.ndarray:
    """The absorption of fibres of ``melanin`` (0..1, perceptually even), ``redness`` (the
    share of pheomelanin) and a dye ``tint``, as the node's Melanin Concentration reads
    them."""
    amount = -np.log(max(1.0 - float(np.clip(melanin, 0.0, 1.0)), 1e-4))
    share = float(np.clip(redness, 0.0, 1.0))
    return amount * ((1.0 - share) * EUMELANIN + share * PHEOMELANIN) \
        + absorption_from_colour(tint, radial_roughness)
