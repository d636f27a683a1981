"""Rough diffuse reflection as Cycles renders a Diffuse BSDF's Roughness and the Principled
BSDF's Diffuse Roughness σ: Fujii's improved Oren–Nayar lobe with, from Blender 4.3 on, a
multiple-scattering term (measured on Cycles by ``tools/measure_oren_nayar.py``: a plane
of each under a white world reads these albedos within 0.0001, one mode per version).

Per unit colour ρ the BRDF is A + B t + m (1 − E(μ_l)) (1 − E(μ_v)): A = 1 / (π + σ (π/2 −
2/3)), B = σ A, t = l·v − μ_l μ_v (divided by max(μ_l, μ_v) where positive), E the
single-scattering albedo πA + B G(μ) and m = ρ_ms / (π (1 − Ē)) × ρ^k / ρ, ρ_ms = ρ² Ē /
(1 − ρ (1 − Ē)) with Ē its cosine-weighted average (OpenPBR's EON: k = 0, Blender 5.x; 4.3–4.5
scale the term by the colour once more: k = 1; 4.2's Diffuse BSDF has none). The shaders
evaluate it per light sample (oren_nayar_lib.glsl); here are its albedos, for light paths."""

from __future__ import annotations

import numpy as np

NO_MULTISCATTER, COLOUR_SCALED, OPENPBR = 0, 1, 2  # the multiple-scattering term's modes


def coefficients(sigma: float) -> tuple[float, float]:
    """(A, B) of roughness ``sigma``."""
    a = 1.0 / (np.pi + sigma * (np.pi / 2.0 - 2.0 / 3.0))
    return a, sigma * a


def _g(mu: np.ndarray) -> np.ndarray:
    mu = np.clip(np.asarray(mu, float), 0.0, 1.0)
    small = mu < 1e-6  # tan θ's limit: the Taylor expansion
    safe = np.where(small, 1.0, mu)
    sin = np.sqrt(1.0 - safe * safe)
    theta = np.arccos(safe)
    g = sin * (theta - 2.0 / 3.0 - sin * safe) + 2.0 / 3.0 * (sin / safe) * (1.0 - sin**3)
    return np.where(small, np.pi / 2.0 - 2.0 / 3.0 - mu, g)


def single_albedo(sigma: float, mu: np.ndarray) -> np.ndarray:
    """E(μ): what the single-scattering lobe of ρ = 1 reflects of light arriving at (or seen
    from) cosines ``mu``."""
    a, b = coefficients(sigma)
    return np.pi * a + b * _g(mu)


def average_albedo(sigma: float) -> float:
    """Ē: E's cosine-weighted average."""
    a, b = coefficients(sigma)
    return float(np.pi * a + (2.0 * np.pi - 5.6) / 3.0 * b)


def _per_colour(color: np.ndarray, sigma: float, mode: int) -> np.ndarray:
    """ρ_ms ρ^k / ρ (n, 3) of colours ``color`` (n, 3) by the multiple-scattering ``mode``."""
    e_avg = average_albedo(sigma)
    rho = np.clip(np.asarray(color, float), 0.0, 1.0)
    per_colour = rho * e_avg / (1.0 - rho * (1.0 - e_avg))
    return per_colour * rho if mode == COLOUR_SCALED else per_colour


def albedo_factor(color: np.ndarray, sigma: float, mu: np.ndarray, mode: int) -> np.ndarray:
    """What a rough diffuse surface of colours ``color`` (n, 3) reflects of light arriving at
    cosines ``mu`` (n,), over what a Lambertian one of the same colours does (n, 3):
    E + ρ_ms ρ^k / ρ (1 − E) by the multiple-scattering ``mode``, E alone without it."""
    e = single_albedo(sigma, mu)[:, None]
    if mode == NO_MULTISCATTER:
        return np.repeat(e, 3, axis=1)
    return e + _per_colour(color, sigma, mode) * (1.0 - e)


def multiscatter_at(color: np.ndarray, sigma: float, mu: np.ndarray, mode: int) -> np.ndarray:
    """m (1 − E(μ)) (n, 3): the multiple-scattering term's factor of the cosines ``mu`` (n,)
    on one side of the lobe (the BRDF's term is it times 1 − E at the other side's cosine);
    zero without the term."""
    if mode == NO_MULTISCATTER:
        return np.zeros((len(mu), 3))
    e = single_albedo(sigma, mu)[:, None]
    m = _per_colour(color, sigma, mode) / (np.pi * (1.0 - average_albedo(sigma)))
    return m * (1.0 - e)
