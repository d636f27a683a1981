"""The Principled BSDF's reflection layers as Cycles 4.x/5.x builds them (svm/closure.h):

- a dielectric GGX lobe (alpha = roughness²) whose Fresnel is the real dielectric Fresnel of
  ``eta`` remapped from [F0(eta), 1] to [F0 × Specular Tint, 1] (generalized Schlick with a
  negative exponent), where Specular IOR Level scales F0 (level 0.5 keeps the IOR's F0);
- a metallic GGX lobe of weight ``metallic`` with Schlick's Fresnel from the base colour;
- both with multiple-scattering energy compensation (Kulla & Conty: the lobe scaled by
  (1 + Fms (1 − E)/E) for the single-scattering albedo E and the Fresnel's cosine average);
- a diffuse base of weight (1 − metallic)(1 − max over channels of the dielectric lobe's
  albedo), the energy-conserving layering;
- over them a clear coat: a dielectric GGX lobe of weight ``coat`` with its own
  roughness and IOR (real Fresnel, no energy compensation, as Cycles' plain GGX), which
  dims every layer below by (1 − coat × its albedo at the view);
- over all of them a sheen (core/scene/sheen.py: Cycles' microfiber sheen, measured), which
  dims the rest by (1 − the largest channel of its albedo at the view).

The albedos come from tables of the GGX lobe, computed here by stratified sampling of visible
normals (Heitz 2018), as Cycles precomputes its own (``ggx_E``, ``ggx_Eavg``,
``ggx_gen_schlick_ior_s``, ``ggx_gen_schlick_s``). The shaders read the same tables
(gpu_shaders/principled_lib.glsl) and interpolate them as ``lookup`` does.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

from . import oren_nayar
from . import sheen as sheens
from .sheen import NO_SHEEN, Sheen
from .table_lookup import lerp_2d, lerp_row, node

E_SIZE = 32  # roughness × cos(view) nodes of the single-scattering albedo E
S_SIZE = 16  # roughness × cos(view) × IOR nodes of the Fresnel factors s
SAMPLES = 32  # stratified visible-normal samples per axis and table entry
MIN_ROUGHNESS = 0.2
"""Glossy lobes narrower than this (Principled Roughness) are rendered at this roughness: light
samples and VPLs are points, and a narrower lobe turns each into a visible speck."""


class Coat(NamedTuple):
    """A clear coat: its weight, roughness (clamped to MIN_ROUGHNESS in a specular row), IOR
    and tint (the colour light below it keeps at normal incidence, through it and back)."""

    weight: float
    roughness: float
    ior: float
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0)


NO_COAT = Coat(0.0, MIN_ROUGHNESS, 1.5)

# Rows of the table texture (width E_SIZE): E by roughness, then E_avg, then s_ior by
# (IOR, roughness), then s for Schlick's exponent 5 by roughness, then the sheen's albedo and
# its lobe's a and b by roughness (sheen.table(), sheen.SIZE wide).
ROW_E, ROW_EAVG = 0, E_SIZE
ROW_S_IOR = ROW_EAVG + 1
ROW_S5 = ROW_S_IOR + S_SIZE * S_SIZE
ROW_SHEEN = ROW_S5 + S_SIZE
TABLE_ROWS = ROW_SHEEN + 3 * sheens.SIZE


def f0_from_ior(eta: np.ndarray | float) -> np.ndarray:
    """Reflectance at normal incidence of a dielectric interface."""
    return ((np.asarray(eta) - 1.0) / (np.asarray(eta) + 1.0)) ** 2


def ior_from_f0(f0: float) -> float:
    """The IOR whose normal-incidence reflectance is ``f0`` (< 1)."""
    root = np.sqrt(np.clip(f0, 0.0, 1.0 - 1e-7))
    return float((1.0 + root) / (1.0 - root))


def fresnel_dielectric(cos_i: np.ndarray, eta: np.ndarray | float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of light arriving at cosine ``cos_i`` (eta = n2/n1)."""
    c = np.abs(cos_i)
    g2 = np.asarray(eta) ** 2 - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (g - c) / (g + c)
        b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
        f = 0.5 * a * a * (1.0 + b * b)
    return np.where(g2 > 0, np.nan_to_num(f, nan=1.0), 1.0)


def _lambda(alpha2: np.ndarray, cos: np.ndarray) -> np.ndarray:
    tan2 = np.maximum(1.0 / np.maximum(cos * cos, 1e-12) - 1.0, 0.0)
    return 0.5 * (np.sqrt(1.0 + alpha2 * tan2) - 1.0)


def _visible_normal_samples(rough: np.ndarray, mu: np.ndarray, n: int = SAMPLES
                            ) -> tuple[np.ndarray, np.ndarray]:
    """cos(view, half vector) and the estimator weight G2/G1 (0 below the horizon) of n×n
    stratified visible-normal samples, for every (rough, mu) pair: arrays (..., n*n). The mean
    of the weight is the lobe's albedo without Fresnel."""
    alpha = np.maximum(np.asarray(rough, float) ** 2, 1e-4)
    mu = np.clip(np.asarray(mu, float), 1e-3, 1.0)
    alpha, mu = np.broadcast_arrays(alpha, mu)
    u = (np.arange(n) + 0.5) / n
    u1, u2 = (x.ravel() for x in np.meshgrid(u, u))
    sin = np.sqrt(1.0 - mu * mu)
    # the view (sin, 0, mu) stretched by alpha; T1 = y, T2 = stretched × y (Heitz 2018)
    length = np.sqrt((alpha * sin) ** 2 + mu * mu)
    sx, sz = (alpha * sin / length)[..., None], (mu / length)[..., None]
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    t1, t2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + sz)
    t2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - t1 * t1, 0.0)) + s * t2
    t3 = np.sqrt(np.maximum(1.0 - t1 * t1 - t2 * t2, 0.0))
    # T2 = (sx, 0, sz) × (0, 1, 0) = (-sz, 0, sx)
    a = alpha[..., None]
    hx, hy, hz = a * (-t2 * sz + t3 * sx), a * t1, np.maximum(t2 * sx + t3 * sz, 0.0)
    norm = np.maximum(np.sqrt(hx * hx + hy * hy + hz * hz), 1e-30)
    hx, hz = hx / norm, hz / norm
    cos_vh = sin[..., None] * hx + mu[..., None] * hz
    cos_l = 2.0 * cos_vh * hz - mu[..., None]
    a2 = a * a
    lv = _lambda(a2, mu[..., None])
    weight = np.where(cos_l > 0, (1.0 + lv) / (1.0 + lv + _lambda(a2, np.maximum(cos_l, 1e-6))),
                      0.0)
    return np.clip(cos_vh, 0.0, 1.0), weight


def _nodes(size: int) -> np.ndarray:
    return np.linspace(0.0, 1.0, size)


def eta_of_z(z: np.ndarray) -> np.ndarray:
    """The table's IOR parameter: z = sqrt((eta − 1)/(eta + 1)), so z⁴ = F0 (as in Cycles)."""
    z2 = np.minimum(np.asarray(z, float) ** 2, 0.999)
    return (1.0 + z2) / (1.0 - z2)


@lru_cache(maxsize=1)
def tables() -> np.ndarray:
    """The lobe tables, (TABLE_ROWS, E_SIZE) float32 (layout: the ROW_* constants; entries of
    the S_SIZE-wide rows past S_SIZE are 0). Computed once per process (about 1 s)."""
    out = np.zeros((TABLE_ROWS, E_SIZE), np.float32)
    rough, mu = np.meshgrid(_nodes(E_SIZE), _nodes(E_SIZE), indexing="ij")
    out[ROW_E:ROW_E + E_SIZE] = _visible_normal_samples(rough, mu)[1].mean(-1)
    gauss_mu, gauss_w = np.polynomial.legendre.leggauss(16)
    gauss_mu, gauss_w = 0.5 * (gauss_mu + 1.0), 0.5 * gauss_w
    r, m = np.meshgrid(_nodes(E_SIZE), gauss_mu, indexing="ij")
    e = _visible_normal_samples(r, m)[1].mean(-1)
    out[ROW_EAVG] = 2.0 * (e * gauss_mu * gauss_w).sum(-1)
    rough, mu = np.meshgrid(_nodes(S_SIZE), _nodes(S_SIZE), indexing="ij")
    cos_vh, weight = _visible_normal_samples(rough, mu)
    albedo = np.maximum(weight.mean(-1), 1e-12)
    for k, eta in enumerate(eta_of_z(_nodes(S_SIZE))):
        f0 = f0_from_ior(eta)
        s = (fresnel_dielectric(cos_vh, eta) - f0) / (1.0 - f0)
        rows = slice(ROW_S_IOR + k * S_SIZE, ROW_S_IOR + (k + 1) * S_SIZE)
        out[rows, :S_SIZE] = (weight * s).mean(-1) / albedo
    out[ROW_S5:ROW_S5 + S_SIZE, :S_SIZE] = (weight * (1.0 - cos_vh) ** 5).mean(-1) / albedo
    out[ROW_SHEEN:, :sheens.SIZE] = sheens.table()
    return out


@lru_cache(maxsize=1)
def _tables64() -> np.ndarray:
    """``tables()`` as float64, for the CPU's lookups (made once, not per call)."""
    return tables().astype(np.float64)


def _cosine_quadrature(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes μ on [0, 1] and weights of ∫ f(μ) 2μ dμ (cosine-weighted)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    return 0.5 * (x + 1.0), 0.5 * w * (x + 1.0)


COSINE_MU, COSINE_WEIGHT = _cosine_quadrature(8)


def lookup(rough: np.ndarray, mu: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, ...]:
    """E, E_avg, s_ior and s5 at (roughness, cos view, IOR parameter), interpolated linearly
    between table nodes (as the shader does)."""
    t = _tables64()
    rough, mu, z = np.broadcast_arrays(*(np.asarray(a, float) for a in (rough, mu, z)))
    e = lerp_2d(t, ROW_E, rough, mu, E_SIZE)
    e_avg = lerp_row(t, np.full(rough.shape, ROW_EAVG), rough, E_SIZE)
    k, w = node(z, S_SIZE)
    s_ior = (1 - w) * lerp_2d(t, ROW_S_IOR + k * S_SIZE, rough, mu, S_SIZE) \
        + w * lerp_2d(t, ROW_S_IOR + (k + 1) * S_SIZE, rough, mu, S_SIZE)
    s5 = lerp_2d(t, ROW_S5, rough, mu, S_SIZE)
    return e, e_avg, s_ior, s5


def fresnel_cosine_average(eta: float) -> float:
    """2 ∫ F(μ) μ dμ of the dielectric Fresnel (Cycles' ``fresnel_dielectric_Fss``)."""
    x, w = np.polynomial.legendre.leggauss(64)
    mu = 0.5 * (x + 1.0)
    return float((fresnel_dielectric(mu, eta) * mu * w).sum())


def coat_albedo(coat: Coat, mu: np.ndarray) -> np.ndarray:
    """What a clear coat reflects (n,) of light arriving at cosines ``mu`` (n,): its weight
    times its lobe's albedo, E (F0 + (1 − F0) s_ior) (0 without a coat)."""
    weight, rough, eta = coat.weight, coat.roughness, coat.ior
    if weight <= 0:
        return np.zeros(len(mu))
    z = np.sqrt(np.abs((eta - 1.0) / (eta + 1.0)))
    e, _, s_ior, _ = lookup(np.full(len(mu), rough), mu, np.full(len(mu), z))
    f0 = float(f0_from_ior(eta))
    return weight * e * (f0 + (1.0 - f0) * s_ior)


def below_coat(coat: Coat, mu: np.ndarray, reflected: np.ndarray) -> np.ndarray:
    """What of the layers below a clear coat is seen at cosines ``mu`` (n,), (n, 3): one minus
    what the coat reflects there (``reflected``, its ``coat_albedo``), times its tint over
    the path through it (Cycles: the tint to the power 1 / cos of the refracted view, mixed
    in by the weight)."""
    below = np.repeat(np.clip(1.0 - reflected, 0.0, 1.0)[:, None], 3, axis=1)
    tint = np.maximum(np.asarray(coat.tint, float), 0.0)
    if coat.weight > 0 and np.any(tint != 1.0):
        cos_refracted = np.sqrt(np.maximum(1.0 - (1.0 - np.square(mu)) / coat.ior**2, 1e-12))
        tinted = np.power(tint[None], 1.0 / cos_refracted[:, None])
        below *= 1.0 + coat.weight * (tinted - 1.0)
    return below


def layer_weights(base: np.ndarray, rough: float, metallic: float, eta: float,
                  f0: np.ndarray, s_avg: float, coat: Coat, sheen: Sheen, mu: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The diffuse weight (n, 3) and the glossy albedo (Cycles' GlossCol, the coat's included)
    (n, 3) of base colours (n, 3) seen at cosines ``mu`` (n,), for a material's specular
    parameters (see ``specular_row``), both dimmed by the sheen above them (whose own albedo,
    ``sheen.layer``, is in neither). The shader computes the same per pixel."""
    z = np.sqrt(np.abs((eta - 1.0) / (eta + 1.0)))
    e, e_avg, s_ior, s5 = (x[:, None] for x in lookup(np.full(len(mu), rough), mu,
                                                      np.full(len(mu), z)))
    diffuse, gloss = np.full(len(mu), 1.0 - metallic), np.zeros((len(mu), 3))
    if eta != 1.0:
        darkening = _darkening(np.broadcast_to(f0, (len(mu), 3)), s_avg, e, e_avg)
        albedo = darkening * (f0 + (1.0 - f0) * s_ior)
        diffuse = diffuse * np.clip(1.0 - albedo.max(axis=1), 0.0, 1.0)
        gloss += (1.0 - metallic) * albedo
    if metallic > 0:
        metal_f0 = np.clip(base, 0.0, 1.0)
        darkening = _darkening(metal_f0, 1.0 / 21.0, e, e_avg)
        gloss += metallic * darkening * (metal_f0 + (1.0 - metal_f0) * s5)
    diffuse = np.repeat(diffuse[:, None], 3, axis=1)
    if coat.weight > 0:
        reflected = coat_albedo(coat, mu)
        below = below_coat(coat, mu, reflected)
        diffuse, gloss = diffuse * below, gloss * below + reflected[:, None]
    _, keep = sheens.layer(sheen, mu)
    return diffuse * keep[:, None], gloss * keep[:, None]


def _darkening(f0: np.ndarray, s_avg: float, e: np.ndarray, e_avg: np.ndarray) -> np.ndarray:
    """E (1 + Fms (1 − E)/E): the energy-compensated lobe's albedo factor (Kulla & Conty)."""
    fss = f0 + (1.0 - f0) * s_avg
    fms = fss * e_avg / (1.0 - fss * (1.0 - e_avg))
    return e + fms * (1.0 - e)


def path_albedo(base: np.ndarray, row: np.ndarray) -> np.ndarray:
    """Reflectance of light arriving from a cosine-weighted direction (what a light path keeps
    at a bounce, the glossy part re-emitted diffusely): ∫ (diffuse weight × base × the rough
    diffuse lobe's albedo factor + GlossCol + the sheen's albedo) 2μ dμ, for base colours
    (n, 3) of one material's specular row."""
    mu, weight = COSINE_MU, COSINE_WEIGHT
    n = len(base)
    repeated, tiled = np.repeat(base, len(mu), axis=0), np.tile(mu, n)
    diffuse, other = repeated.copy(), np.zeros_like(repeated)
    if row[7] > 0:
        params = specular_parameters(row)
        weights, gloss = layer_weights(repeated, *params, tiled)
        diffuse *= weights
        other = gloss + sheens.layer(params[-1], tiled)[0]
    sigma, multiscatter = diffuse_roughness_of(row)
    if sigma > 0:
        diffuse *= oren_nayar.albedo_factor(repeated, sigma, tiled, multiscatter)
    per = diffuse + other
    return (per.reshape(n, len(mu), 3) * weight[None, :, None]).sum(axis=1)


SPECULAR_COLUMNS = 20  # five RGBA texels: (roughness, metallic, eta, s_avg),
# (tint F0 rgb, flag), (coat weight, coat roughness, coat eta, diffuse roughness), (coat
# tint rgb, sheen layering: 0 none, 1 layered, 2 dimming cast light too), (sheen colour rgb,
# sheen roughness)
DIFFUSE_ROUGHNESS_COLUMN = 11
SHEEN_LAYERED_COLUMN = 15
SHEEN_COLUMN = 16


def specular_row(roughness: float, metallic: float, ior: float, level: float,
                 tint: tuple[float, float, float], coat: Coat = NO_COAT,
                 sheen: Sheen = NO_SHEEN, diffuse_roughness: float = 0.0,
                 diffuse_multiscatter: int = oren_nayar.OPENPBR) -> np.ndarray:
    """A material's specular texels: clamped roughness, metallic, the Fresnel's IOR (level
    applied, as Cycles does), its remapped cosine average, F0 × tint (saturated), a flag
    (1 when there is any glossy lobe or sheen; 0 keeps the pure-Lambert path), the clear
    coat's weight (in [0, 1]), clamped roughness, IOR (at least 1, as Cycles takes it) and
    tint (at least 0), the sheen's colour (at least 0), roughness (in [0, 1], as Cycles
    saturates it) and whether it dims the layers below (1; 2 where it dims the light its
    emission casts too) or not (0), and the diffuse
    layer's roughness σ (core/scene/oren_nayar.py; in [0, 1]) as σ + 2 × its
    multiple-scattering mode (0 where σ is 0). The diffuse roughness alone keeps the flag 0:
    the shaders read it from the material table."""
    row = np.zeros(SPECULAR_COLUMNS, np.float32)
    sigma = float(np.clip(np.nan_to_num(diffuse_roughness), 0.0, 1.0))
    if sigma > 0:
        row[DIFFUSE_ROUGHNESS_COLUMN] = sigma + 2 * int(diffuse_multiscatter)
    color = np.maximum(np.nan_to_num(np.asarray(sheen.color, float)), 0.0)
    if color.any():
        row[SHEEN_COLUMN:SHEEN_COLUMN + 3] = color
        row[SHEEN_COLUMN + 3] = np.clip(sheen.roughness, 0.0, 1.0)
        row[SHEEN_LAYERED_COLUMN] = (2.0 if sheen.dims_cast_light else 1.0) \
            if sheen.layered else 0.0
    coat_weight = float(np.clip(coat.weight, 0.0, 1.0))
    coat_ior = max(float(coat.ior), 1.0)
    if coat_weight > 0 and coat_ior > 1.0:
        row[8:11] = (coat_weight,
                     max(float(np.clip(coat.roughness, 0.0, 1.0)), MIN_ROUGHNESS), coat_ior)
        row[12:15] = np.maximum(np.asarray(coat.tint, float), 0.0)
    ior = max(float(ior), 1e-5)
    level = max(float(level), 0.0)
    metallic = float(np.clip(metallic, 0.0, 1.0))
    eta, f0 = ior, float(f0_from_ior(ior))
    if level != 0.5:
        f0 *= 2.0 * level
        eta = ior_from_f0(f0) if f0 < 1.0 else 1e5
        if ior < 1.0:
            eta = 1.0 / eta
    eta = 1.0 / eta if eta < 1.0 else eta  # reflection from outside sees the same F0
    if f0 <= 0.0:
        eta = 1.0
    dielectric = eta != 1.0 and metallic < 1.0
    rough = max(float(np.clip(roughness, 0.0, 1.0)), MIN_ROUGHNESS)
    if not dielectric and metallic <= 0.0:
        if row[8] > 0 or color.any():  # a coat or sheen alone over a diffuse base
            row[:4] = rough, metallic, 1.0, 0.0
            row[7] = 1.0
        return row
    real_f0 = float(f0_from_ior(eta))
    s_avg = float(np.clip((fresnel_cosine_average(eta) - real_f0) / max(1.0 - real_f0, 1e-12),
                          0.0, 1.0)) if dielectric else 0.0
    row[:4] = rough, metallic, eta if dielectric else 1.0, s_avg
    row[4:7] = np.clip(f0 * np.maximum(np.asarray(tint, float), 0.0), 0.0, 1.0)
    row[7] = 1.0
    return row


def specular_parameters(row: np.ndarray
                        ) -> tuple[float, float, float, np.ndarray, float, Coat, Sheen]:
    """(roughness, metallic, eta, F0 × tint, s_avg, coat, sheen) of a specular row, for
    ``layer_weights``."""
    return float(row[0]), float(row[1]), float(row[2]), np.asarray(row[4:7], float), \
        float(row[3]), coat_of(row), sheen_of(row)


def coat_of(row: np.ndarray) -> Coat:
    """The clear coat of a specular row."""
    return Coat(float(row[8]), float(row[9]), float(row[10]),
                (float(row[12]), float(row[13]), float(row[14])))


def diffuse_roughness_of(row: np.ndarray) -> tuple[float, int]:
    """The diffuse layer's roughness of a specular row and its multiple-scattering mode."""
    value = float(row[DIFFUSE_ROUGHNESS_COLUMN])
    mode = min(int(value // 2), oren_nayar.OPENPBR) if value > 1.0 else 0
    return value - 2 * mode, mode


def sheen_of(row: np.ndarray) -> Sheen:
    """The sheen of a specular row."""
    color = row[SHEEN_COLUMN:SHEEN_COLUMN + 3]
    layering = float(row[SHEEN_LAYERED_COLUMN])
    return Sheen((float(color[0]), float(color[1]), float(color[2])),
                 float(row[SHEEN_COLUMN + 3]), layering > 0.5, layering > 1.5)


def sample_reflection(normal: np.ndarray, incoming: np.ndarray, rough: np.ndarray,
                      u: np.ndarray) -> np.ndarray:
    """Directions (m, 3) a glossy lobe of roughness ``rough`` (m,) reflects light arriving
    along ``incoming`` (m, 3, direction of travel) into, sampled from its visible normals
    (Heitz 2018) with unit-square samples ``u`` (m, 2); those below the surface are mirrored
    above it."""
    alpha = np.maximum(np.asarray(rough, float) ** 2, 1e-4)[:, None]
    view = -incoming
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(helper, normal)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(normal, t)
    local = np.stack([(view * t).sum(1), (view * b).sum(1),
                      np.maximum((view * normal).sum(1), 1e-6)], axis=1)
    stretched = local * np.hstack([alpha, alpha, np.ones_like(alpha)])
    stretched /= np.linalg.norm(stretched, axis=1, keepdims=True)
    lensq = stretched[:, 0] ** 2 + stretched[:, 1] ** 2
    t1 = np.where(lensq[:, None] > 1e-7,
                  np.stack([-stretched[:, 1], stretched[:, 0], 0 * lensq], 1)
                  / np.sqrt(np.maximum(lensq, 1e-30))[:, None], [[1.0, 0.0, 0.0]])
    t2 = np.cross(stretched, t1)
    r, phi = np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + stretched[:, 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - p1 * p1, 0.0)) + s * p2
    p3 = np.sqrt(np.maximum(1.0 - p1 * p1 - p2 * p2, 0.0))
    h = p1[:, None] * t1 + p2[:, None] * t2 + p3[:, None] * stretched
    h = h * np.hstack([alpha, alpha, np.ones_like(alpha)])
    h[:, 2] = np.maximum(h[:, 2], 0.0)
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-30)
    out_local = 2.0 * (local * h).sum(1, keepdims=True) * h - local
    out_local[:, 2] = np.abs(out_local[:, 2])
    out = out_local[:, :1] * t + out_local[:, 1:2] * b + out_local[:, 2:] * normal
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-30)


def diffuse_average(row: np.ndarray) -> np.ndarray:
    """The diffuse weight (3,) averaged over outgoing cosine-weighted directions (what a
    diffuse VPL of this material emits per unit base colour, below its sheen):
    ∫ weight(μ) 2μ dμ."""
    mu, weight = COSINE_MU, COSINE_WEIGHT
    diffuse, _ = layer_weights(np.zeros((len(mu), 3)), *specular_parameters(row), mu)
    return (diffuse * weight[:, None]).sum(axis=0)


def emission_below_layers(coat: Coat, sheen: Sheen) -> np.ndarray:
    """What of a surface's emission leaves through its clear coat and sheen as the light it
    casts on other surfaces (3,), averaged over cosine-weighted directions: Cycles dims
    emission under the coat as it dims the layers below (``below_coat`` at the direction it
    leaves in), so this keeps the emitted power exact, and under a sheen where the sheen
    ``dims_cast_light`` (Blender 5.x; measured: 4.x dims only what the camera sees); the
    camera's view is dimmed at its own angle (principled_layers)."""
    mu, weight = COSINE_MU, COSINE_WEIGHT
    below = np.ones((len(mu), 3))
    if coat.weight > 0:
        below = below_coat(coat, mu, coat_albedo(coat, mu))
    if sheen.dims_cast_light:
        below = below * sheens.layer(sheen, mu)[1][:, None]
    return (below * weight[:, None]).sum(axis=0)


LOBE_TEXELS = 3  # (A rgb, alpha), (B rgb, eta), (C rgb, 0): principled_lib.glsl's lobe_a/b/c


def lobe_texels(base: np.ndarray, row: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """The glossy lobe's texels (n, 3, 4) of base colours (n, 3) at cosines ``mu`` (n,), as
    principled_layers in principled_lib.glsl computes them for a pixel (glossy_brdf reads
    them), dimmed by the coat and sheen above it (whose own lobes are not in them); all zero
    for a row without a glossy lobe."""
    rough, metallic, eta, f0, s_avg, coat, sheen = specular_parameters(row)
    out = np.zeros((len(mu), LOBE_TEXELS, 4))
    if row[7] <= 0:
        return out
    z = np.sqrt(np.abs((eta - 1.0) / (eta + 1.0)))
    e, e_avg, _, _ = (x[:, None] for x in lookup(np.full(len(mu), rough),
                                                  np.clip(mu, 1e-3, 1.0), np.full(len(mu), z)))
    e = np.maximum(e, 1e-4)
    if eta != 1.0:
        k_d = (1.0 - metallic) * _darkening(np.broadcast_to(f0, (len(mu), 3)), s_avg, e,
                                             e_avg) / e
        out[:, 0, :3] += k_d * f0
        out[:, 1, :3] = k_d * (1.0 - f0)
    if metallic > 0:
        metal_f0 = np.clip(base, 0.0, 1.0)
        k_m = metallic * _darkening(metal_f0, 1.0 / 21.0, e, e_avg) / e
        out[:, 0, :3] += k_m * metal_f0
        out[:, 2, :3] = k_m * (1.0 - metal_f0)
    mu = np.clip(mu, 1e-3, 1.0)
    if coat.weight > 0:
        out[:, :, :3] *= below_coat(coat, mu, coat_albedo(coat, mu))[:, None, :]
    out[:, :, :3] *= sheens.layer(sheen, mu)[1][:, None, None]
    out[:, 0, 3], out[:, 1, 3] = rough * rough, eta
    return out
