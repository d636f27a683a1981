"""The Principled BSDF's lobe tables (core/scene/principled.py) against direct quadrature of the
GGX lobe, between table nodes (what the shaders interpolate)."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene import principled

# (roughness, cos view) between the table nodes, grazing to normal, smooth to rough
POINTS = [(0.22, 0.97), (0.35, 0.6), (0.5, 0.31), (0.63, 0.83), (0.8, 0.15), (0.95, 0.5)]


def quadrature(rough: float, mu: float, fresnel, n: int = 600) -> float:
    """∫ F(h·v) D G2 / (4 cos_v) dω over the hemisphere, on a θ × φ grid."""
    alpha2 = rough**4
    theta = (np.arange(n) + 0.5) / n * np.pi / 2
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    light = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    view = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    h = light + view
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    d = alpha2 / (np.pi * (1 + (alpha2 - 1) * h[..., 2] ** 2) ** 2)

    def lam(c):
        return 0.5 * (np.sqrt(1 + alpha2 * (1 / c**2 - 1)) - 1)
    g2 = 1 / (1 + lam(mu) + lam(light[..., 2]))
    f = fresnel(np.clip((h * view).sum(-1), 0, 1))
    integrand = f * d * g2 / (4 * mu) * np.sin(t)
    return float(integrand.sum() * (np.pi / 2 / n) * (np.pi / n))


@pytest.mark.parametrize("rough, mu", POINTS)
def test_tables_match_quadrature(rough, mu):
    eta = 1.5
    z = np.sqrt((eta - 1) / (eta + 1))
    e, _, s_ior, s5 = (float(x) for x in principled.lookup(rough, mu, z))
    e_ref = quadrature(rough, mu, lambda c: np.ones_like(c))
    f0 = principled.f0_from_ior(eta)
    s_ref = quadrature(rough, mu, lambda c: (principled.fresnel_dielectric(c, eta) - f0)
                       / (1 - f0)) / e_ref
    s5_ref = quadrature(rough, mu, lambda c: (1 - c) ** 5) / e_ref
    print(f"rough {rough} mu {mu}: E {e:.4f} vs {e_ref:.4f}, s_ior {s_ior:.4f} vs "
          f"{s_ref:.4f}, s5 {s5:.4f} vs {s5_ref:.4f}")
    assert e == pytest.approx(e_ref, abs=0.01)
    assert s_ior == pytest.approx(s_ref, abs=0.003)
    assert s5 == pytest.approx(s5_ref, abs=0.003)


def test_white_metal_reflects_everything_and_default_dielectric_conserves_energy():
    """Energy compensation: a white metal's glossy albedo is 1 at every angle; Blender's
    default material reflects at most what arrives (diffuse weight × base + glossy ≤ 1)."""
    mu = np.linspace(0.05, 1.0, 12)
    white = principled.specular_row(0.6, 1.0, 1.5, 0.5, (1, 1, 1))
    diffuse, gloss = principled.layer_weights(np.ones((12, 3)),
                                              *principled.specular_parameters(white), mu)
    assert np.allclose(diffuse, 0) and np.allclose(gloss, 1, atol=1e-6)
    default = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1))
    diffuse, gloss = principled.layer_weights(np.ones((12, 3)),
                                              *principled.specular_parameters(default), mu)
    total = diffuse + gloss
    assert (total <= 1 + 1e-6).all() and (gloss > 0.03).all()


def test_pure_lambert_materials_have_no_specular_row():
    """Specular IOR Level 0 and metallic 0 keep the Lambert path (flag 0)."""
    assert not principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1)).any()
    row = principled.specular_row(0.05, 0.0, 1.5, 0.5, (1, 1, 1))
    assert row[0] == pytest.approx(principled.MIN_ROUGHNESS) and row[7] == 1


def test_path_albedo_leaves_the_material_table_alone():
    """A glossy material's light-path reflectance (diffuse and glossy, cosine-averaged) is
    below its base colour's plus the lobe's, and computing it keeps the table's base colour
    (one row: a slice of it would be a view)."""
    from addon.core.scene.geometry import CUTOUT, SPECULAR, WorldGeometry
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64)
    geometry = WorldGeometry.from_triangles(corners, np.tile([0.0, 0.0, 1.0], (3, 1)),
                                            np.array([[0.9, 0.6, 0.3]]), np.zeros((1, 3)))
    geometry.materials[0, SPECULAR:CUTOUT] = principled.specular_row(0.4, 1.0, 1.5, 0.5, (1, 1, 1))
    path = geometry.albedo[0]
    assert geometry.materials[0, 0:3] == pytest.approx([0.9, 0.6, 0.3])
    assert (path > 0.3).all() and (path <= 1.0).all()


def glossy_brdf(texels: np.ndarray, normal: np.ndarray, view: np.ndarray,
                light: np.ndarray) -> np.ndarray:
    """principled_lib.glsl's glossy_brdf for one lobe's texels (3, 4), views (k, 3), one light
    direction: F D G2 / (4 cos_v cos_l), (k, 3)."""
    cos_v, cos_l = view @ normal, float(light @ normal)
    h = view + light
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    cos_vh, cos_nh = np.clip(h @ light, 0, 1), np.clip(h @ normal, 0, 1)
    alpha2 = texels[0, 3] ** 2
    d = alpha2 / (np.pi * (1 + (alpha2 - 1) * cos_nh**2) ** 2)

    def lam(c):
        return 0.5 * (np.sqrt(1 + alpha2 * np.maximum(1 / np.maximum(c * c, 1e-12) - 1, 0)) - 1)
    g2 = 1 / (1 + lam(cos_v) + lam(cos_l))
    eta = texels[1, 3]
    f0 = principled.f0_from_ior(eta)
    s_eta = (principled.fresnel_dielectric(cos_vh, eta) - f0) / (1 - f0) if eta != 1 else 0 * d
    f = texels[0, :3] + texels[1, :3] * s_eta[:, None] \
        + texels[2, :3] * ((1 - cos_vh) ** 5)[:, None]
    return np.where((cos_v > 0)[:, None], f * (d * g2 / (4 * np.maximum(cos_v, 1e-12)
                                                           * cos_l))[:, None], 0.0)


def coat_texels(weight: float, rough: float, ior: float) -> np.ndarray:
    """A clear coat's lobe in lobe_texels' layout, as principled_lib.glsl's coat_lobe makes
    it (weight × the real Fresnel)."""
    f0 = float(principled.f0_from_ior(ior))
    texels = np.zeros((3, 4))
    texels[0] = weight * f0, weight * f0, weight * f0, rough * rough
    texels[1] = weight * (1 - f0), weight * (1 - f0), weight * (1 - f0), ior
    return texels


def reflected_over_the_hemisphere(lobes: list[np.ndarray], mu: float) -> np.ndarray:
    """∫ f_glossy cos over every outgoing direction of the ``lobes`` (each (3, 4) texels) for
    light arriving at cosine ``mu``, by a midpoint rule (3,)."""
    n = 800
    theta = (np.arange(n) + 0.5) / n * np.pi / 2
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    t, p = (x.ravel() for x in np.meshgrid(theta, phi, indexing="ij"))
    out = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    light = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    f = sum(glossy_brdf(texels, np.array([0.0, 0.0, 1.0]), out, light) for texels in lobes)
    return (f * (np.cos(t) * np.sin(t))[:, None]).sum(0) * (np.pi / 2 / n) * (np.pi / n)


@pytest.mark.parametrize("rough, metallic, mu, coat", [
    (0.5, 0.0, 0.8, 0.0), (0.3, 0.0, 0.4, 0.0), (0.4, 1.0, 0.6, 0.0), (0.7, 0.5, 0.25, 0.0),
    (0.5, 0.0, 0.8, 1.0), (0.4, 1.0, 0.3, 0.6)])
def test_vpl_glossy_emission_carries_the_glossy_albedo(rough, metallic, mu, coat):
    """A VPL's glossy emission (lobe_texels at the incoming cosine, and a clear coat's lobe as
    lights_lib.glsl adds it, reflected towards every outgoing direction: f_glossy cos)
    integrates to the glossy albedo its path continuation carries (layer_weights' GlossCol at
    the same cosine, the coat's included), so light reflected glossily at a VPL is counted
    once, with the right power."""
    base = np.array([[0.9, 0.6, 0.3]])
    row = principled.specular_row(rough, metallic, 1.5, 0.5, (1, 1, 1),
                                  principled.Coat(coat, 0.3, 1.5, (0.9, 0.7, 0.5)))
    lobes = [principled.lobe_texels(base, row, np.array([mu]))[0]]
    if coat:
        lobes.append(coat_texels(coat, 0.3, 1.5))
    _, gloss = principled.layer_weights(base, *principled.specular_parameters(row),
                                        np.array([mu]))
    emitted = reflected_over_the_hemisphere(lobes, mu)
    print(f"rough {rough} metallic {metallic} mu {mu} coat {coat}: emitted {emitted}, "
          f"GlossCol {gloss[0]}")
    assert emitted == pytest.approx(gloss[0], rel=0.01)


def test_lambert_rows_have_no_glossy_lobe():
    lambert = principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1))
    assert not principled.lobe_texels(np.ones((3, 3)), lambert, np.full(3, 0.5)).any()


@pytest.mark.parametrize("rough, mu", [(0.25, 0.9), (0.25, 0.3), (0.5, 0.6)])
def test_a_clear_coat_reflects_what_it_takes_from_the_layers_below(rough, mu):
    """A coat's lobe (principled_lib.glsl's coat_lobe: weight × the real Fresnel) integrates
    to the albedo by which it dims every layer below (Cycles' layering), so a white material
    under a coat still reflects at most what arrives, and more at grazing angles."""
    weight, ior = 0.8, 1.5
    row = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1),
                                  principled.Coat(weight, rough, ior))
    reflected = reflected_over_the_hemisphere([coat_texels(weight, rough, ior)], mu)
    albedo = principled.coat_albedo(principled.coat_of(row), np.array([mu]))[0]
    assert reflected[0] == pytest.approx(albedo, rel=0.01)
    uncoated = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1))
    white = np.ones((1, 3))
    diffuse, gloss = principled.layer_weights(white, *principled.specular_parameters(row),
                                              np.array([mu]))
    bare_diffuse, bare_gloss = principled.layer_weights(
        white, *principled.specular_parameters(uncoated), np.array([mu]))
    assert diffuse[0] == pytest.approx(bare_diffuse[0] * (1 - albedo))
    assert gloss[0] == pytest.approx(bare_gloss[0] * (1 - albedo) + albedo)
    assert (diffuse[0] + gloss[0] <= 1 + 1e-6).all()


def test_a_coats_tint_colours_the_layers_below_more_at_grazing_angles():
    """Cycles' coat tint: the layers below keep tint^(1 / cos of the view refracted into the
    coat), mixed in by the weight; the coat's own reflection stays white."""
    weight, tint = 0.5, (1.0, 0.5, 0.25)
    plain = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1),
                                    principled.Coat(weight, 0.3, 1.5))
    tinted = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1),
                                     principled.Coat(weight, 0.3, 1.5, tint))
    mu = np.array([1.0, 0.2])
    white = np.ones((2, 3))
    diffuse, gloss = principled.layer_weights(white, *principled.specular_parameters(tinted), mu)
    plain_diffuse, plain_gloss = principled.layer_weights(
        white, *principled.specular_parameters(plain), mu)
    cos_refracted = np.sqrt(1 - (1 - mu**2) / 1.5**2)
    expected = 1 + weight * (np.power(np.array(tint)[None], 1 / cos_refracted[:, None]) - 1)
    assert diffuse == pytest.approx(plain_diffuse * expected)
    coat = principled.coat_albedo(principled.coat_of(tinted), mu)[:, None]
    assert gloss == pytest.approx((plain_gloss - coat) * expected + coat)
    assert expected[1, 2] < expected[0, 2] < 1  # a longer path through the coat at grazing


def test_a_coat_alone_makes_a_diffuse_row_glossy():
    """A coat over a diffuse base (Specular IOR Level 0) still needs the glossy path."""
    row = principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1),
                                  principled.Coat(1.0, 0.03, 1.5))
    assert row[7] == 1 and row[2] == 1.0
    coat = principled.coat_of(row)
    assert coat[:3] == pytest.approx((1.0, principled.MIN_ROUGHNESS, 1.5))
    assert coat.tint == (1.0, 1.0, 1.0)
    assert not principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1),
                                       principled.Coat(1.0, 0.3, 1.0)).any()


def test_emission_leaves_a_coat_as_the_layers_below_do_on_average():
    """The emitted power through a coat: below_coat averaged over cosine-weighted
    directions (a fine midpoint rule here), none taken without a coat, the tint's colour
    kept."""
    no_sheen = principled.NO_SHEEN
    assert principled.emission_below_layers(principled.NO_COAT, no_sheen) == pytest.approx(
        np.ones(3))
    coat = principled.Coat(1.0, 0.3, 1.5, (0.9, 0.6, 0.2))
    mu = (np.arange(4000) + 0.5) / 4000
    below = principled.below_coat(coat, mu, principled.coat_albedo(coat, mu))
    expected = (below * 2 * mu[:, None]).mean(axis=0)
    through = principled.emission_below_layers(coat, no_sheen)
    assert through == pytest.approx(expected, rel=2e-3)
    assert 0.0 < through[2] < through[1] < through[0] < 0.9  # dimmed, amber
