"""The colour of a black body at a temperature, as Blender gives it (a light's Temperature, the
Blackbody shader node): linear Rec.709, luminance 1, temperatures clamped to 800–12 000 K."""

from __future__ import annotations

import numpy as np

MIN_KELVIN, MAX_KELVIN = 800.0, 12000.0
"""Blender's range: a light's Temperature stops at 800 K, and colours above 12 000 K are the
colour at 12 000 K (measured with bpy 4.5's ``Light.temperature_color``)."""

_WAVELENGTHS = np.arange(360.0, 831.0, 1.0)  # nm, the CIE tables' range

# CIE 1931 2° colour matching functions as sums of piecewise Gaussians (weight, mean nm,
# sigma below the mean, sigma above): Wyman, Sloan & Shirley 2013, "Simple Analytic
# Approximations to the CIE XYZ Color Matching Functions", multi-lobe fit.
_LOBES = (
    ((1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)),
    ((0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)),
    ((1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)),
)

_XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                           [-0.9692660, 1.8760108, 0.0415560],
                           [0.0556434, -0.2040259, 1.0572252]])


def _matching(lobes: tuple[tuple[float, float, float, float], ...]) -> np.ndarray:
    total = np.zeros_like(_WAVELENGTHS)
    for weight, mean, below, above in lobes:
        sigma = np.where(mean > _WAVELENGTHS, below, above)
        total += weight * np.exp(-0.5 * ((_WAVELENGTHS - mean) / sigma) ** 2)
    return total


_CMF = np.stack([_matching(lobes) for lobes in _LOBES])  # (3, wavelengths)


def blackbody_rgb(kelvin: float) -> tuple[float, float, float]:
    """Linear Rec.709 colour of a black body at ``kelvin`` (clamped to Blender's range; NaN
    reads as 6500 K), scaled to luminance 1, negative channels set to 0."""
    kelvin = float(np.clip(np.nan_to_num(kelvin, nan=6500.0), MIN_KELVIN, MAX_KELVIN))
    metres = _WAVELENGTHS * 1e-9
    # Planck's law up to a constant factor (the colour is normalised below).
    radiance = 1.0 / (metres ** 5 * np.expm1(1.438776877e-2 / (metres * kelvin)))
    xyz = _CMF @ radiance
    rgb = _XYZ_TO_REC709 @ (xyz / xyz[1])
    r, g, b = np.maximum(rgb, 0.0).tolist()
    return r, g, b
