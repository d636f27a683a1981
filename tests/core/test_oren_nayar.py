"""Rough diffuse reflection (core/scene/oren_nayar.py): the single-scattering albedo's closed
form against a numerical integral of Fujii's lobe, the multiple-scattering term's furnace,
and the material row's code."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene import oren_nayar, principled


def integrated_albedo(sigma: float, mu_v: float, n: int = 400) -> float:
    """∫ (A + B t) cos θ_l dω_l over the hemisphere, by the midpoint rule."""
    a, b = oren_nayar.coefficients(sigma)
    theta = (np.arange(n) + 0.5) / n * np.pi / 2
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    theta, phi = np.meshgrid(theta, phi, indexing="ij")
    mu_l, sin_l = np.cos(theta), np.sin(theta)
    t = np.sqrt(1 - mu_v**2) * sin_l * np.cos(phi)  # l·v − μ_l μ_v
    t = np.where(t > 0, t / np.maximum(mu_l, mu_v), t)
    cell = (np.pi / 2 / n) * (2 * np.pi / (2 * n))
    return float(((a + b * t) * mu_l * sin_l).sum() * cell)


@pytest.mark.parametrize("sigma", [0.3, 1.0])
def test_the_single_scattering_albedo_is_the_lobe_integrated(sigma):
    for mu in (0.1, 0.5, 0.9, 1.0):
        assert oren_nayar.single_albedo(sigma, np.array([mu]))[0] == pytest.approx(
            integrated_albedo(sigma, mu), abs=2e-4)
    mu = (np.arange(4000) + 0.5) / 4000
    assert oren_nayar.average_albedo(sigma) == pytest.approx(
        (oren_nayar.single_albedo(sigma, mu) * 2 * mu).mean(), rel=1e-4)
    assert oren_nayar.single_albedo(0.0, mu) == pytest.approx(1.0)  # Lambert


def test_the_multiple_scattering_term_closes_the_furnace():
    """A white rough surface reflects everything with the term (both modes), E without; a
    grey one less than white, the colour-scaled mode (Blender 4.3–4.5) least."""
    mu = np.linspace(0.05, 1.0, 9)
    white, grey = np.ones((9, 3)), np.full((9, 3), 0.5)
    for mode in (oren_nayar.COLOUR_SCALED, oren_nayar.OPENPBR):
        assert oren_nayar.albedo_factor(white, 1.0, mu, mode) == pytest.approx(1.0)
    single = oren_nayar.albedo_factor(white, 1.0, mu, oren_nayar.NO_MULTISCATTER)
    assert single[:, 0] == pytest.approx(oren_nayar.single_albedo(1.0, mu))
    scaled = oren_nayar.albedo_factor(grey, 1.0, mu, oren_nayar.COLOUR_SCALED)
    openpbr = oren_nayar.albedo_factor(grey, 1.0, mu, oren_nayar.OPENPBR)
    assert np.all(single < scaled) and np.all(scaled < openpbr) and np.all(openpbr < 1.0)


def test_the_row_codes_roughness_and_mode():
    for sigma in (0.001, 0.5, 1.0):
        for mode in (0, 1, 2):
            row = principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1),
                                          diffuse_roughness=sigma, diffuse_multiscatter=mode)
            decoded = principled.diffuse_roughness_of(row)
            assert decoded[0] == pytest.approx(sigma, abs=1e-6) and decoded[1] == mode
            assert row[7] == 0.0  # no glossy flag: the gather reads it from the table
    assert not principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1),
                                       diffuse_roughness=np.nan).any()
    smooth = principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1), diffuse_roughness=0.0)
    assert principled.diffuse_roughness_of(smooth) == (0.0, 0)


def test_light_paths_keep_the_rough_albedo():
    row = principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1), diffuse_roughness=1.0,
                                  diffuse_multiscatter=oren_nayar.NO_MULTISCATTER)
    kept = principled.path_albedo(np.full((1, 3), 0.8), row)[0]
    assert kept == pytest.approx(0.8 * oren_nayar.average_albedo(1.0), rel=2e-3)


def vpl_excess(u: np.ndarray, v: np.ndarray, towards_light: np.ndarray,
               out: np.ndarray) -> np.ndarray:
    """lights_lib.glsl's oren_nayar_vpl_excess about the normal +z, towards directions
    ``out`` (k, 3): (k, 3)."""
    a, b = oren_nayar.coefficients(u[3])
    mu_l, mu_o = towards_light[2], np.clip(out[:, 2], 0.0, 1.0)
    t = out @ towards_light - mu_l * mu_o
    t = np.where(t > 0, t / np.maximum(np.maximum(mu_l, mu_o), 1e-6), t)
    e_l = oren_nayar.single_albedo(u[3], np.array([mu_l]))[0]
    e_o = oren_nayar.single_albedo(u[3], mu_o)
    return u[None, :3] * (a + b * t - e_l / np.pi)[:, None] \
        + v[None, :3] * (oren_nayar.average_albedo(u[3]) - e_o)[:, None]


@pytest.mark.parametrize("mode", [oren_nayar.NO_MULTISCATTER, oren_nayar.COLOUR_SCALED,
                                  oren_nayar.OPENPBR])
@pytest.mark.parametrize("mu", [0.2, 0.7, 1.0])
def test_a_rough_vpl_emits_its_lobe_with_its_lambertian_power(mode, mu):
    """A VPL at a rough diffuse surface (its Lambertian intensity, Φ × the path's diffuse
    reflectance / π, plus what rough_lobes' texels add in the gather) emits Φ ρ f(ω_l, ω) cos
    towards every ω (f the lobe of the documented BRDF), and so exactly its Lambertian
    power."""
    from addon.core.scene.geometry import CUTOUT, SPECULAR, WorldGeometry
    colour, sigma = np.array([0.8, 0.5, 0.3]), 1.0
    corners = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    geometry = WorldGeometry.from_triangles(corners, np.tile([0.0, 0.0, 1.0], (3, 1)),
                                            colour[None], np.zeros((1, 3)))
    geometry.materials[0, SPECULAR:CUTOUT] = principled.specular_row(
        0.5, 0.0, 1.5, 0.0, (1, 1, 1), diffuse_roughness=sigma, diffuse_multiscatter=mode)
    triangle, base, mus = np.zeros(1, int), colour[None], np.array([mu])
    diffuse = geometry.reflectance_split(triangle, base, mus)[0][0]
    u, v = geometry.rough_lobes(triangle, base, mus)[0]
    towards_light = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    n = 400
    theta = (np.arange(n) + 0.5) / n * np.pi / 2
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    th, ph = (x.ravel() for x in np.meshgrid(theta, phi, indexing="ij"))
    out = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    emitted = diffuse / np.pi + vpl_excess(u, v[:3], towards_light, out)  # per cos, Φ = 1
    a, b = oren_nayar.coefficients(sigma)
    t = out @ towards_light - mu * out[:, 2]
    t = np.where(t > 0, t / np.maximum(mu, out[:, 2]), t)
    e = oren_nayar.single_albedo(sigma, np.array([mu, *out[:, 2]]))
    e_avg = oren_nayar.average_albedo(sigma)  # m = ρ_ms ρ^k / ρ / (π (1 − Ē)), k by mode
    m = colour * e_avg / (1 - colour * (1 - e_avg)) / (np.pi * (1 - e_avg))
    m = {oren_nayar.NO_MULTISCATTER: 0 * m, oren_nayar.COLOUR_SCALED: m * colour}.get(mode, m)
    lobe = colour * ((a + b * t)[:, None] + m * ((1 - e[0]) * (1 - e[1:]))[:, None])
    np.testing.assert_allclose(emitted, lobe, rtol=1e-6, atol=1e-9)
    cell = (np.pi / 2 / n) * (np.pi / n)
    power = (emitted * (out[:, 2] * np.sin(th))[:, None]).sum(0) * cell
    assert power == pytest.approx(diffuse, rel=2e-4)
