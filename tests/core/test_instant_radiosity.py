"""Instant Radiosity against the closed sphere's exact answer, and its sampling invariants.

Inside a closed sphere of radius R with albedo ρ and a point light of intensity I at the centre,
direct irradiance E0 = I/R² is uniform and every bounce multiplies it by ρ, so with D diffuse
bounces DiffDir + DiffInd = (E0/π)(1 + ρ + … + ρ^D). The sphere is tessellated: its faces sit
slightly inside R, so the direct term is compared with our own DiffDir and the indirect sum with
ρ(1 + … + ρ^(D-1)) times the mean direct term.

On a sphere the geometry term between two wall points is the constant 1/(4R²) (both cosines are
d/2R), so every VPL lights the whole wall evenly: the check needs few VPLs and no noise margin,
and clamping distances below c removes exactly the share c²/(8R²) of the first bounce (the wall
within chord d of a point has area πd²).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from addon.core.scene.model import NO_BOUNCE_LIMIT, Instance, LightKind, Material, Scene, World
from addon.core.settings import Settings
from tests.core.builders import icosphere, inside_sphere_camera, light, rotation_x, translation

RADIUS, POWER = 2.0, 100.0


def sphere_scene(albedo: float) -> Scene:
    sphere = Instance(icosphere(RADIUS, 3), np.eye(4), [Material("wall", (albedo,) * 3)])
    return Scene([sphere], [light(LightKind.POINT, translation(0, 0, 0), power=POWER)],
                 World(), inside_sphere_camera())


def indirect_ratio(renderer, albedo: float, **settings) -> float:
    frame, _ = renderer.render(sphere_scene(albedo), Settings(antialiasing=1, **settings))
    return float(frame.passes["DiffInd"][..., 0].mean() / frame.passes["DiffDir"][..., 0].mean())


@pytest.mark.parametrize("bounces", [1, 2, 4])
@pytest.mark.parametrize("visibility", ["classic", "exact"])
def test_closed_sphere_bounce_sum(renderer, bounces, visibility):
    rho = 0.5
    ratio = indirect_ratio(renderer, rho, bounces=bounces, vpl_count=128, clamp_distance=0.0,
                           visibility=visibility, vpl_shadow_resolution=32)
    expected = rho * sum(rho**k for k in range(bounces))
    assert ratio == pytest.approx(expected, rel=0.03)


@pytest.mark.parametrize("termination", ["fractional", "roulette"])
def test_both_path_terminations_are_unbiased(renderer, termination):
    rho = 0.8
    ratio = indirect_ratio(renderer, rho, bounces=6, vpl_count=512, clamp_distance=0.0,
                           termination=termination, visibility="exact")
    assert ratio == pytest.approx(rho * sum(rho**k for k in range(6)), rel=0.03)


@pytest.mark.parametrize("limit", [0, 1, 2])
@pytest.mark.parametrize("incremental", [False, True])
def test_a_lights_max_bounces_ends_its_paths(renderer, limit, incremental):
    """Cycles' Max Bounces of a light: with 4 bounces its light bounces at most ``limit``
    times (0: direct light only), in final renders and in the viewport's incremental mode."""
    rho = 0.5
    scene = sphere_scene(rho)
    scene.lights[0].max_bounces = limit
    settings = Settings(antialiasing=1, bounces=4, vpl_count=128, clamp_distance=0.0,
                        visibility="exact", incremental=incremental)
    frame, stats = renderer.render(scene, settings)
    renderer.forget_frames()
    ratio = frame.passes["DiffInd"][..., 0].mean() / frame.passes["DiffDir"][..., 0].mean()
    assert ratio == pytest.approx(rho * sum(rho**k for k in range(limit)), rel=0.03, abs=1e-9)
    assert limit or stats.counts["vpls"] == 0


def test_the_worlds_max_bounces_zero_leaves_its_light_direct(renderer):
    """A ball on a floor under a white world: its light bounces between them, unless the
    world's Max Bounces is 0."""
    from tests.core.builders import floor_scene

    ball = Instance(icosphere(0.5, 2), translation(0, 0, 0.5), [Material("ball", (0.8,) * 3)])
    for limit in (NO_BOUNCE_LIMIT, 0):
        scene = floor_scene([], extra=[ball], world=World(color=(1.0, 1.0, 1.0),
                                                             max_bounces=limit))
        frame, _ = renderer.render(scene, Settings(antialiasing=1, bounces=2))
        assert (frame.passes["DiffInd"].max() > 0.01) == (limit > 0)
        assert frame.passes["DiffDir"].max() > 0.1


def test_bounces_zero_leaves_indirect_black(renderer):
    frame, stats = renderer.render(sphere_scene(0.5), Settings(antialiasing=1, bounces=0))
    assert stats.counts["vpls"] == 0
    assert np.all(frame.passes["DiffInd"] == 0)


@pytest.mark.parametrize("visibility", ["classic", "exact"])
def test_clamp_removes_the_predicted_share_and_compensation_restores_it(renderer, visibility):
    rho, clamp = 0.5, 0.8  # the clamp distance is clamp × the scene radius (= RADIUS here)
    common = {"bounces": 1, "vpl_count": 128, "visibility": visibility,
              "vpl_shadow_resolution": 32}
    unclamped = indirect_ratio(renderer, rho, clamp_distance=0.0, **common)
    clamped = indirect_ratio(renderer, rho, clamp_distance=clamp, bias_compensation="off",
                             **common)
    compensated = indirect_ratio(renderer, rho, clamp_distance=clamp, bias_compensation="full",
                                 bias_samples=64, **common)
    assert clamped / unclamped == pytest.approx(1 - clamp**2 / 8, rel=0.01)
    assert compensated / unclamped == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize(("bounces", "antialiasing", "resolution"),
                         [(1, 1, "supersample"), (3, 1, "supersample"), (3, 2, "pixel")])
def test_compensation_from_the_image_restores_what_the_camera_sees(renderer, bounces,
                                                                   antialiasing, resolution):
    """Image-based compensation reads the near surfaces' light from the image: at the centre of
    a 90° view every surface within the clamp distance (a 35° cone here) is on screen, so the
    clamped share comes back there; without it the clamp's share is missing. Also with the
    indirect light per pixel: rays from the pixels, hits looked up among the supersamples."""
    rho, clamp, size = 0.5, 0.6, 64
    scene = sphere_scene(rho)
    scene.camera = inside_sphere_camera(size)
    centre = slice(size // 2 - 2, size // 2 + 2)

    def indirect(**settings) -> float:
        frame, _ = renderer.render(scene, Settings(
            antialiasing=antialiasing, bounces=bounces, vpl_count=256, visibility="exact",
            interleave=1, indirect_resolution=resolution, **settings))
        return float(frame.passes["DiffInd"][centre, centre, 0].mean())

    unclamped = indirect(clamp_distance=0.0)
    clamped = indirect(clamp_distance=clamp, bias_compensation="off")
    compensated = indirect(clamp_distance=clamp, bias_compensation="image", bias_samples=256)
    assert clamped / unclamped == pytest.approx(1 - clamp**2 / 8, abs=0.01)  # every bounce's
    assert compensated / unclamped == pytest.approx(1.0, abs=0.01)


def narrow_view(albedo: float, size: int = 32) -> tuple[Scene, slice]:
    """The sphere seen through a 20° view, and the rows (and columns) of the image's centre."""
    scene = sphere_scene(albedo)
    camera = inside_sphere_camera(size)
    focal = 1.0 / np.tan(np.radians(10.0))
    camera.projection_matrix[0, 0] = camera.projection_matrix[1, 1] = focal
    scene.camera = camera
    return scene, slice(size // 2 - 2, size // 2 + 2)


@pytest.mark.parametrize(("bounces", "visibility"), [(1, "exact"), (3, "ism")])
def test_compensation_gathers_light_where_the_camera_does_not_see(renderer, bounces,
                                                                  visibility):
    """A 20° view of the sphere's wall: most surfaces within the clamp distance of its centre
    (a 35° cone) are off screen. Their hits take the light gathered there instead of the
    image's, so the clamped share still comes back: with one bounce their direct light, with
    more also their VPLs' light (with imperfect shadow maps). Measured (compensated /
    unclamped): 1.006 with one bounce; with 3, 1.008, where the hits' direct light alone gave
    0.991 (the clamped share of bounces 2 and 3 was missing)."""
    clamp = 0.6
    scene, centre = narrow_view(0.5)

    def indirect(**settings) -> float:
        frame, _ = renderer.render(scene, Settings(
            antialiasing=1, bounces=bounces, vpl_count=256, visibility=visibility,
            interleave=1, **settings))
        return float(frame.passes["DiffInd"][centre, centre, 0].mean())

    unclamped = indirect(clamp_distance=0.0)
    compensated = indirect(clamp_distance=clamp, bias_compensation="image", bias_samples=256)
    assert compensated / unclamped == pytest.approx(1.005, abs=0.007)


def test_unseen_hits_take_the_vpls_light_from_several_atlases(renderer, monkeypatch):
    """The same 20° view with the VPLs' imperfect shadow maps in atlases of 64 maps: every
    atlas is kept for the frame, so the unseen hits still take the VPLs' light (before, a frame
    of several atlases left it out: 0.991, and the Cornell box's back wall below the
    off-screen ceiling was 33 % dark at 4096 light paths). Where the atlases exceed what a
    frame keeps, the hits take their direct light alone, and the stats say so."""
    from addon.core.frame import batches, ism_maps

    monkeypatch.setattr(batches, "ATLAS_TEXELS", 64 * 128 * 128)
    clamp = 0.6
    scene, centre = narrow_view(0.5)

    def indirect(**settings) -> tuple[float, list[str]]:
        frame, stats = renderer.render(scene, Settings(
            antialiasing=1, bounces=3, vpl_count=256, visibility="ism", interleave=1,
            ism_resolution=128, **settings))
        assert stats.counts["isms"] > 2 * 64  # three atlases or more
        return float(frame.passes["DiffInd"][centre, centre, 0].mean()), stats.notes

    unclamped, _ = indirect(clamp_distance=0.0)
    compensated, notes = indirect(clamp_distance=clamp, bias_compensation="image",
                                  bias_samples=256)
    assert compensated / unclamped == pytest.approx(1.005, abs=0.007)
    assert not any("does not see" in note for note in notes)
    monkeypatch.setattr(ism_maps, "KEPT_ATLAS_BYTES", 0)
    direct_only, notes = indirect(clamp_distance=clamp, bias_compensation="image",
                                  bias_samples=256)
    assert direct_only / unclamped == pytest.approx(0.991, abs=0.007)
    assert any("does not see" in note for note in notes)


def test_scrambled_halton_is_stratified_and_seeded():
    from addon.core.transport.sequences import scrambled_halton

    points = scrambled_halton(256, 4, seed=1)
    assert points.shape == (256, 4) and points.min() >= 0 and points.max() < 1
    for k, cells in enumerate((256, 243, 125, 49)):  # the first b^m points: one per cell
        counts = np.bincount((points[:cells, k] * cells).astype(int), minlength=cells)
        assert counts.min() == counts.max() == 1
    assert not np.allclose(points, scrambled_halton(256, 4, seed=2))
    # a range from index 100 continues the same sequence (the passes of a render)
    np.testing.assert_array_equal(scrambled_halton(156, 4, seed=1, first=100), points[100:])


def test_a_continued_path_sequence_traces_the_longer_sequences_paths(renderer):
    """Two halves of 2N light paths (the second from path N) leave the first-bounce VPLs of
    the 2N paths, at twice their intensity each (each half is N paths, not 2N)."""
    from addon.core.scene.geometry import bounding_sphere, flatten_instances
    from addon.core.transport.vpl import PathSequence, VPLs, generate_vpls

    scene = sphere_scene(0.5)
    geometry = flatten_instances(scene, [])
    centre, radius = bounding_sphere(geometry.positions)
    renderer.forget_frames()  # the tracer is given other triangles than the frames' here
    tracer = renderer.tracer
    tracer.upload(geometry.positions.reshape(-1, 3, 3))
    settings = Settings(bounces=1, vpl_count=64, seed=5)
    whole = generate_vpls(scene, geometry, replace(settings, vpl_count=128), tracer, centre,
                          radius)
    halves = [generate_vpls(scene, geometry, settings, tracer, centre, radius,
                            PathSequence(5, first)) for first in (0, 64)]
    renderer.forget_frames()
    joined = VPLs.concatenate(halves)
    np.testing.assert_allclose(joined.position, whole.position, atol=1e-6)
    np.testing.assert_allclose(joined.intensity, 2 * whole.intensity, rtol=1e-6)


@pytest.mark.parametrize("kind", [LightKind.POINT, LightKind.SPOT, LightKind.SUN, LightKind.AREA])
def test_reflective_shadow_map_vpls_match_light_path_vpls(renderer, kind):
    """One bounce: VPLs importance-sampled from the lights' reflective shadow maps carry the same
    indirect light as traced light paths (floor and red wall, exact visibility, no clamp)."""
    from tests.core.test_interleaved_gather import smooth_scene

    scene = smooth_scene()
    matrix = translation(0, 1.5, 2.5) if kind is not LightKind.SUN else rotation_x(0.6)
    scene.lights = [light(kind, matrix, power=300.0 if kind is not LightKind.SUN else 3.0,
                          spot_size=np.radians(120), size_x=0.5)]
    common = {"antialiasing": 1, "bounces": 1, "vpl_count": 4096, "clamp_distance": 0.0,
              "visibility": "exact", "interleave": 1}
    paths, _ = renderer.render(scene, Settings(vpl_source="paths", **common))
    rsm, stats = renderer.render(scene, Settings(vpl_source="rsm", **common))
    assert "vpl generation (rsm)" in stats.timings
    ratio = rsm.passes["DiffInd"].sum() / paths.passes["DiffInd"].sum()
    assert ratio == pytest.approx(1.0, abs=0.03)


@pytest.mark.parametrize("bounces", [1, 3])
def test_reflective_shadow_map_paths_continue_for_more_bounces(renderer, bounces):
    """First hits from the point light's reflective shadow map, later bounces traced: the closed
    sphere's bounce sum again."""
    rho = 0.5
    ratio = indirect_ratio(renderer, rho, bounces=bounces, vpl_count=512, clamp_distance=0.0,
                           visibility="exact", vpl_source="rsm")
    assert ratio == pytest.approx(rho * sum(rho**k for k in range(bounces)), rel=0.03)


def test_imperfect_shadow_maps_beyond_the_point_sets(renderer):
    """1536 VPLs > 512 point sets (later VPLs get shifted sets): still the sphere's bounce."""
    ratio = indirect_ratio(renderer, 0.5, bounces=1, vpl_count=1536, clamp_distance=0.0,
                           visibility="ism", interleave=1)
    assert ratio == pytest.approx(0.5, rel=0.01)


def test_glossy_vpls_widen_the_light_table_only_when_present():
    """Diffuse-only VPLs keep the 5-texel table (the shaders' Lambert path); glossy ones get
    texels 5-9 and a flag, kept through subsets, scaling and concatenation (which scales the
    flux texels, not the directions, alphas and IORs); rough diffuse ones texels 10-11 too."""
    from addon.core.transport.vpl import GLOSSY_TEXELS, VPLs
    n = 3
    diffuse = VPLs(np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.ones((n, 3)),
                   np.ones(n, int), np.arange(n))
    assert diffuse.as_light_samples(8).table(np.zeros(n), np.ones(n), np.ones(n)).shape == \
        (n, 5, 4)
    lobe = np.zeros((n, GLOSSY_TEXELS, 4))
    lobe[1, 0] = [0.1, 0.2, 0.3, 0.25]
    lobe[1, 3] = [0.0, 0.0, 1.0, 1.5]
    lobe[1, 4] = [0.5, 0.5, 0.5, 0.04]
    glossy = VPLs(diffuse.position, diffuse.normal, np.zeros((n, 3)), diffuse.generation,
                  diffuse.rank, glossy=lobe)
    table = glossy.as_light_samples(8).table(np.zeros(n), np.ones(n), np.ones(n))
    assert table.shape == (n, 10, 4)
    assert list(table[:, 4, 3]) == [0, 1, 0] and np.allclose(table[1, 5:], lobe[1, :5])
    both = VPLs.concatenate([diffuse, glossy.scaled(slice(None), 2.0)])
    assert both.glossy.shape == (2 * n, GLOSSY_TEXELS, 4) and not both.glossy[:n].any()
    assert np.allclose(both.glossy[n + 1, 0], [0.2, 0.4, 0.6, 0.25])
    assert np.allclose(both.glossy[n + 1, 3], [0.0, 0.0, 1.0, 1.5])
    assert np.allclose(both.glossy[n + 1, 4], [1.0, 1.0, 1.0, 0.04])
    kept = both.as_light_samples(8).subset(np.array([0, n + 1]))
    assert kept.glossy.shape == (2, GLOSSY_TEXELS, 4) and kept.glossy[1, 0, 3] == 0.25
    lobe[2, 3] = [0.0, 0.6, 0.8, 0.0]  # a rough diffuse VPL: no glossy lobe, its sigma
    lobe[2, 5], lobe[2, 6] = [0.4, 0.3, 0.2, 0.7], [0.1, 0.1, 0.1, 0.0]
    table = glossy.as_light_samples(8).table(np.zeros(n), np.ones(n), np.ones(n))
    assert table.shape == (n, 12, 4) and list(table[:, 4, 3]) == [0, 1, 1]
    rough = glossy.scaled(slice(None), 2.0).glossy[2]
    assert np.allclose(rough[5], [0.8, 0.6, 0.4, 0.7]) and np.allclose(rough[6, :3], 0.2)
    assert np.allclose(rough[3], lobe[2, 3])
