"""Cutouts (a Principled BSDF's Alpha, a Transparent BSDF mixed in: leaves, fences): surfaces
that are there in part. Rays and rasterised samples keep them with probability their coverage,
shadow rays pass dimmed by it, as in Cycles. And the Holdout shader, a surface the camera sees
as a hole."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.gpu.raytrace import Cutouts
from addon.core.scene.model import (
    COVERAGE_INVERTED,
    COVERAGE_LUMINANCE,
    Instance,
    LightKind,
    Material,
    Texture,
)
from addon.core.scene.surface_points import area_cdf
from addon.core.scene.textures import mean_coverage, sample_coverage
from addon.core.settings import Settings
from tests.core.builders import floor_scene, light, pixel_centres, quad, translation

HALF = 1.5  # the panel's half size: it covers [-1.5, 1.5]² at z = 1


def checker() -> Texture:
    """2×2 texels, Closest: alpha 1 in the lower-left and upper-right quadrants, 0 elsewhere."""
    pixels = np.ones((2, 2, 4), np.float32)
    pixels[0, 1, 3] = pixels[1, 0, 3] = 0.0
    return Texture("checker", pixels, interpolation="Closest")


def panel(material: Material, seen: bool = False) -> Instance:
    mesh = quad(HALF, HALF)
    mesh.uvs = ((mesh.positions[:, :2] / HALF + 1) / 2).astype(np.float32)
    # off the pixel grid's diagonal: a ray through the shared edge crosses both triangles
    return Instance(mesh, translation(0.013, 0.007, 1), [material], visible_to_camera=seen)


def sun_scene(material: Material, seen: bool = False):
    sun = light(LightKind.SUN, np.eye(4), power=3.0)  # straight down
    return floor_scene([sun], extra=[panel(material, seen)])


def quadrant_means(image: np.ndarray, margin: float = 0.35) -> np.ndarray:
    """The mean of each quadrant under the panel (lower-left, lower-right, upper-left,
    upper-right), ``margin`` metres from its edges and the texel boundaries."""
    x, y = pixel_centres()
    means = []
    for sy in (-1, 1):
        for sx in (-1, 1):
            inside = (np.abs(x - sx * HALF / 2) < HALF / 2 - margin) \
                & (np.abs(y - sy * HALF / 2) < HALF / 2 - margin)
            means.append(image[inside].mean())
    return np.array(means)


@pytest.mark.parametrize("shadows", ["ray_traced", "shadow_maps", "hybrid"])
def test_a_masked_panel_shadows_the_floor_where_its_texture_is_opaque(renderer, shadows):
    """The sun through a checker mask: dark under its opaque texels, lit under the others
    (ray traced, shadow-mapped, and the default)."""
    settings = Settings(bounces=0, antialiasing=1, direct_shadows=shadows)
    material = Material("leaf", (0.5, 0.5, 0.5), coverage_texture=checker())
    frame, _ = renderer.render(sun_scene(material), settings)
    light_on_floor = 3.0 / np.pi  # DiffDir: irradiance / π
    np.testing.assert_allclose(quadrant_means(frame.passes["DiffDir"][..., 0]),
                               [0.0, light_on_floor, light_on_floor, 0.0], atol=0.01)


def test_a_constant_alpha_lets_its_share_of_the_light_through(renderer):
    """Alpha 0.3: the floor under the panel gets 0.7 of the sun. Shadow rays are dimmed by it
    exactly; shadow maps keep the panel in 30 % of their texels (each pixel 0 to 1: their
    mean over the 576 pixels under the panel, within 2.3 standard deviations)."""
    share = {}
    for shadows in ("ray_traced", "shadow_maps"):
        settings = Settings(bounces=0, antialiasing=1, direct_shadows=shadows)
        frame, _ = renderer.render(sun_scene(Material("veil", alpha=0.3)), settings)
        share[shadows] = frame.passes["DiffDir"][..., 0] / (3.0 / np.pi)
    np.testing.assert_allclose(quadrant_means(share["ray_traced"]), 0.7, atol=1e-4)
    under = share["shadow_maps"][20:44, 20:44]  # pixels 20 to 43: |x|, |y| < 1.1 m
    assert abs(under.mean() - 0.7) < 0.03
    assert under.std() > 0.1  # texels keep the panel or not


def test_the_camera_sees_a_constant_alpha_in_part(renderer):
    """A black panel of alpha 0.3 seen from above, over the floor it shades to 0.7: each
    pixel averages its supersamples, 70 % of which see the floor (0.7 × 0.7 of the open
    floor's light)."""
    settings = Settings(bounces=0, antialiasing=4, direct_shadows="ray_traced")
    material = Material("veil", (0.0, 0.0, 0.0), alpha=0.3)
    frame, _ = renderer.render(sun_scene(material, seen=True), settings)
    open_floor = 3.0 / np.pi * 0.8
    share = quadrant_means(frame.passes["Combined"][..., 0]) / open_floor
    np.testing.assert_allclose(share, 0.49, atol=0.02)


def cutout_panel(tracer, alpha: float = 1.0, texture: Texture | None = None, mode: int = 0):
    """Upload one panel (two triangles at z = 1 over [-1.5, 1.5]²) as a cutout."""
    mesh = quad(HALF, HALF, z=1.0)
    uv = ((mesh.positions[:, :2] / HALF + 1) / 2).astype(np.float32).reshape(2, 3, 2)
    texel = np.array([[1.0 if texture else 0.0, 1.0 - alpha, float(mode), 0.0]] * 2, np.float32)
    tracer.upload(mesh.positions.reshape(2, 3, 3),
                  cutouts=Cutouts(np.arange(2), uv, texel, [texture] if texture else []))


def test_rays_hit_a_cutout_with_probability_its_coverage(tracer):
    """Closest-hit and any-hit rays from 20 000 origins stop at a panel of alpha 0.3 three
    times in ten (within 3 standard deviations), a shadow ray's transmittance is 0.7."""
    cutout_panel(tracer, alpha=0.3)
    rng = np.random.default_rng(1)
    origins = np.column_stack([rng.uniform(-1, 1, (20000, 2)), np.full(20000, 2.0)])
    down = np.tile([0.0, 0.0, -1.0], (20000, 1))
    bound = 3 * np.sqrt(0.3 * 0.7 / 20000)
    hits = tracer.intersect(origins, down)
    assert abs((hits.triangle >= 0).mean() - 0.3) < bound
    assert abs(tracer.occluded(origins, down, t_max=5.0).mean() - 0.3) < bound
    tracer.upload(np.zeros((0, 3, 3), np.float32))


def test_rays_pass_a_mask_where_it_is_clear(tracer):
    """A checker mask (Closest): rays hit the opaque texels and pass the others, every time;
    inverted (a Transparent BSDF in a Mix Shader's second slot), the other way round."""
    centres = np.array([[-0.75, -0.75, 2], [0.75, -0.75, 2], [-0.75, 0.75, 2], [0.75, 0.75, 2]])
    down = np.tile([0.0, 0.0, -1.0], (4, 1))
    cutout_panel(tracer, texture=checker())
    np.testing.assert_array_equal(tracer.intersect(centres, down).triangle >= 0,
                                  [True, False, False, True])
    cutout_panel(tracer, texture=checker(), mode=COVERAGE_INVERTED)
    np.testing.assert_array_equal(tracer.occluded(centres, down, t_max=5.0),
                                  [False, True, True, False])
    tracer.upload(np.zeros((0, 3, 3), np.float32))


def test_coverage_from_a_colour_is_its_luminance():
    """An Image Texture's Color output as the coverage: Rec. 709 luminance of the decoded
    colour (white 1, pure green 0.7152 in linear values); the mean is over the texels."""
    pixels = np.array([[[1, 1, 1, 1], [0, 1, 0, 1]]], np.float32)
    texture = Texture("mask", pixels, interpolation="Closest")
    values = sample_coverage(texture, COVERAGE_LUMINANCE, np.array([[0.25, 0.5], [0.75, 0.5]]))
    np.testing.assert_allclose(values, [1.0, 0.7152])
    assert mean_coverage(texture, COVERAGE_LUMINANCE) == pytest.approx((1 + 0.7152) / 2)
    assert mean_coverage(texture, COVERAGE_LUMINANCE | COVERAGE_INVERTED) == \
        pytest.approx((0 + 0.2848) / 2)


def test_imperfect_shadow_maps_put_fewer_points_on_cutouts():
    """The ISM points' area table weighs each triangle by its mean coverage."""
    triangles = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]] * 2, np.float32)
    np.testing.assert_allclose(area_cdf(triangles, np.array([1.0, 0.25])), [0.8, 1.0])


def test_bad_coverage_values_render_finite(renderer):
    """NaN, infinite and negative alphas in a cutout's texture, and a NaN constant alpha:
    NaN reads as 0 (as the export reads NaN texels), the rest is clamped to [0, 1]; every
    ray-traced and mapped pixel stays finite."""
    pixels = np.ones((2, 2, 4), np.float32)
    pixels[..., 3] = [[np.nan, np.inf], [-3.0, 0.5]]
    texture = Texture("bad", pixels, interpolation="Closest")
    for material in (Material("bad", coverage_texture=texture),
                     Material("nan", alpha=float("nan"))):
        for shadows in ("ray_traced", "shadow_maps"):
            settings = Settings(bounces=1, antialiasing=1, direct_shadows=shadows,
                                vpl_count=64)
            frame, _ = renderer.render(sun_scene(material, seen=True), settings)
            assert all(np.isfinite(p).all() for p in frame.passes.values())
    assert mean_coverage(texture, 0) == pytest.approx((0 + 1 + 0 + 0.5) / 4)


def test_passes_average_a_partial_alpha(renderer):
    """One supersample per pixel: a pass sees the veil of alpha 0.3 or the floor in each
    pixel; each pass draws its own pattern, so 16 passes average it (the pixels' spread under
    the panel falls by about 4, their mean stays 0.49 of the open floor)."""
    material = Material("veil", (0.0, 0.0, 0.0), alpha=0.3)
    spread, mean = [], []
    for passes in (1, 16):
        settings = Settings(bounces=0, antialiasing=1, direct_shadows="ray_traced",
                            passes=passes)
        frame, _ = renderer.render_progressive(sun_scene(material, seen=True), settings)
        share = frame.passes["Combined"][20:44, 20:44, 0] / (3.0 / np.pi * 0.8)
        spread.append(share.std())
        mean.append(share.mean())
    assert spread[1] < 0.4 * spread[0], spread
    np.testing.assert_allclose(mean, 0.49, atol=0.03)


def test_an_emissive_cutout_lights_with_the_part_that_is_there(renderer):
    """A glowing panel of alpha 0.4 (hidden from the camera) over the floor: the floor gets
    0.4 of the light the opaque panel gives it."""
    settings = Settings(bounces=0, antialiasing=1, emission_samples=256,
                        direct_shadows="ray_traced")
    light_on_floor = []
    for alpha in (1.0, 0.4):
        glow = Material("glow", (0.0, 0.0, 0.0), emission=(2.0, 2.0, 2.0), alpha=alpha)
        scene = floor_scene([], extra=[panel(glow)])
        frame, _ = renderer.render(scene, settings)
        light_on_floor.append(frame.passes["DiffDir"][20:44, 20:44, 0].mean())
    assert light_on_floor[0] > 0.1
    assert light_on_floor[1] / light_on_floor[0] == pytest.approx(0.4, rel=0.02)


def test_a_holdout_shader_is_a_hole_for_the_camera_and_black_to_light(renderer):
    """A panel whose material is a Holdout shader, seen from above over a sunlit floor: black
    with alpha 0 where the camera sees it, and it still shades the floor (camera-hidden,
    the floor under it is dark)."""
    settings = Settings(bounces=1, antialiasing=1, direct_shadows="ray_traced", vpl_count=64)
    hole = Material("hole", (0.0, 0.0, 0.0), holdout=True)
    seen, _ = renderer.render(sun_scene(hole, seen=True), settings)
    under = (slice(20, 44), slice(20, 44))
    np.testing.assert_array_equal(seen.passes["Combined"][under], 0.0)
    assert seen.passes["Combined"][2:8, 2:8, 3].min() == 1.0  # the open floor is opaque
    hidden, _ = renderer.render(sun_scene(hole), settings)
    assert hidden.passes["DiffDir"][under].max() < 1e-6
