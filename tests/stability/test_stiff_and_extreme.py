"""Numerical stability on stiff and extreme cases with known answers (issue: stability suite).

Stiff: inside a closed sphere (albedo ρ, point light at the centre) every bounce multiplies the
irradiance by ρ, so DiffInd / DiffDir = ρ(1 + ρ + … + ρ^(D−1)) — up to D = 64 bounces and
ρ = 0.999, where fractional absorption keeps almost every path for all 64 bounces.
Extreme: scale (10^-4 … 10^4, light power scaled with area), albedo at and above 1, a light a
hair's breadth from a surface, a single triangle.
"""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene import Camera, Instance, LightKind, Material, Mesh, Scene, World
from addon.core.settings import Settings
from tests.core.builders import light, rotation_x, translation
from tests.core.test_instant_radiosity import sphere_scene
from tests.core.test_interleaved_gather import smooth_scene

EXACT = {"antialiasing": 1, "clamp_distance": 0.0, "visibility": "exact", "interleave": 1}


def bounce_ratio(renderer, albedo: float, bounces: int, paths: int = 32):
    frame, stats = renderer.render(sphere_scene(albedo),
                                   Settings(bounces=bounces, vpl_count=paths, **EXACT))
    p = frame.passes
    assert all(np.isfinite(image).all() for image in p.values())
    return float(p["DiffInd"][..., 0].mean() / p["DiffDir"][..., 0].mean()), stats


@pytest.mark.parametrize("albedo", [0.5, 0.9, 0.99, 0.999])
@pytest.mark.parametrize("bounces", [1, 8, 64])
def test_closed_sphere_stiff_bounce_sums(renderer, record, albedo, bounces):
    ratio, stats = bounce_ratio(renderer, albedo, bounces)
    expected = albedo * sum(albedo**k for k in range(bounces))
    error = ratio / expected - 1
    record(f"closed sphere ρ={albedo}, D={bounces}", "DiffInd/DiffDir = ρΣρ^k", "±3 %",
           f"{error * 100:+.2f} %")
    assert abs(error) < 0.03
    assert stats.counts["vpls"] <= 32 * bounces  # bounded work: at most one VPL a bounce a path


def test_albedo_above_one_is_capped_with_a_warning(renderer, record):
    at_one, _ = bounce_ratio(renderer, 1.0, 16)
    above, stats = bounce_ratio(renderer, 1.5, 16)
    record("closed sphere ρ=1 and ρ=1.5, D=16", "capped at 1: ratio = D", "±3 %",
           f"{(at_one / 16 - 1) * 100:+.2f} %, {(above / 16 - 1) * 100:+.2f} %")
    assert at_one == pytest.approx(16, rel=0.03)
    assert above == pytest.approx(at_one, rel=1e-6)
    assert any("capped" in w for w in stats.warnings)


def scaled_scene(scale: float) -> Scene:
    """smooth_scene (floor, red wall, point light) with every length × scale, power × scale²."""
    scene = smooth_scene()
    for inst in scene.instances:
        inst.matrix = np.diag([scale, scale, scale, 1.0]) @ inst.matrix
    for lamp in scene.lights:
        lamp.matrix = np.diag([scale, scale, scale, 1.0]) @ lamp.matrix
        lamp.power *= scale**2
    extent, height = 6.0 * scale, 5.0 * scale
    near, far = 0.01 * scale, 100.0 * scale
    view = translation(0, 0, -height)
    projection = np.array([[2 / extent, 0, 0, 0], [0, 2 / extent, 0, 0],
                           [0, 0, -2 / (far - near), -(far + near) / (far - near)], [0, 0, 0, 1]])
    scene.camera = Camera(view, projection, 48, 48, is_orthographic=True)
    return scene


@pytest.mark.parametrize("scale", [1e-4, 1e4])
def test_scale_does_not_change_the_image(renderer, record, scale):
    settings = Settings(antialiasing=1, vpl_count=256, bounces=2)
    reference, _ = renderer.render(scaled_scene(1.0), settings)
    frame, _ = renderer.render(scaled_scene(scale), settings)
    a, b = reference.passes["Combined"][..., :3], frame.passes["Combined"][..., :3]
    error = float(np.sqrt(np.mean((a - b) ** 2)) / a.mean())
    record(f"floor and wall scaled by {scale:g}", "Combined equals the unscaled image",
           "relRMSE < 2 %", f"{error * 100:.3f} %")
    assert np.isfinite(b).all()
    assert error < 0.02


def test_light_a_hairs_breadth_from_a_surface(renderer, record):
    scene = smooth_scene()
    scene.lights = [light(LightKind.POINT, translation(0.3, 0.2, 1e-6), power=100.0)]
    frame, _ = renderer.render(scene, Settings(antialiasing=1, vpl_count=256, bounces=2))
    combined = frame.passes["Combined"]
    record("point light 1e-6 above the floor", "finite image", "no NaN/Inf",
           f"max {combined[..., :3].max():.3g}")
    assert np.isfinite(combined).all()


def test_light_in_a_surfaces_plane_and_single_triangle(renderer, record):
    triangle = Mesh("triangle", np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32),
                    np.tile(np.float32([0, 0, 1]), (3, 1)), np.zeros(1, np.int32))
    scene = Scene([Instance(triangle, np.eye(4), [Material("m")])],
                  [light(LightKind.SUN, rotation_x(np.pi / 2), power=3.0),
                   light(LightKind.POINT, translation(2, 0, 0), power=10.0)],
                  World(), scaled_scene(1.0).camera)
    frame, _ = renderer.render(scene, Settings(antialiasing=1, bounces=4))
    record("single triangle; sun and point light in its plane", "finite, unlit (cos = 0)",
           "no NaN/Inf", f"max DiffDir {frame.passes['DiffDir'].max():.3g}")
    assert all(np.isfinite(image).all() for image in frame.passes.values())
    assert frame.passes["DiffDir"].max() < 1e-3


def test_absurd_resolution_is_refused_up_front(renderer, record):
    from addon.core.pipeline import MAX_FRAME_SAMPLES, RenderError

    scene = scaled_scene(1.0)
    scene.camera.width = scene.camera.height = 40000
    with pytest.raises(RenderError, match="limit is"):
        renderer.render(scene, Settings(antialiasing=8))
    record("40000×40000 pixels at antialiasing 8", "refused before any work",
           f"≤ {MAX_FRAME_SAMPLES:,} samples", "refused with the limit named")


@pytest.mark.parametrize("power", [1e-8, 1e12])
def test_power_scales_linearly_through_indirect_light(renderer, record, power):
    settings = Settings(antialiasing=1, vpl_count=128, bounces=2)
    reference, _ = renderer.render(scaled_scene(1.0), settings)
    scene = scaled_scene(1.0)
    scene.lights[0].power = power
    frame, _ = renderer.render(scene, settings)
    expected = reference.passes["Combined"][..., :3] * power / 300.0
    error = float(np.abs(frame.passes["Combined"][..., :3] - expected).max() / expected.max())
    record(f"point light of {power:g} W", "image ∝ power (direct + 2 bounces)", "max error < 1e-4",
           f"{error:.1e}")
    assert np.isfinite(frame.passes["Combined"]).all()
    assert error < 1e-4


def wedge_scene(angle_degrees: float) -> Scene:
    """Two 4 m planes meeting at the floor's x axis with the given opening angle, a point light
    inside the wedge; camera from above."""
    floor = Mesh("floor", np.array([[-2, 0, 0], [2, 0, 0], [2, 4, 0], [-2, 0, 0], [2, 4, 0],
                                    [-2, 4, 0]], np.float32),
                 np.tile(np.float32([0, 0, 1]), (6, 1)), np.zeros(2, np.int32))
    lid = Mesh(floor.name, floor.positions.copy(), floor.normals.copy(), floor.material_slots)
    tilt = rotation_x(np.radians(angle_degrees))
    inside = translation(0, 3.0, 3.0 * np.tan(np.radians(angle_degrees)) / 2)
    return Scene([Instance(floor, np.eye(4), [Material("a")]),
                  Instance(lid, tilt, [Material("b")])],
                 [light(LightKind.POINT, inside, power=50.0)], World(), scaled_scene(1.0).camera)


@pytest.mark.parametrize("angle", [1.0, 10.0])
def test_narrow_wedge_stays_finite_and_clamped(renderer, record, angle):
    frame, stats = renderer.render(wedge_scene(angle), Settings(antialiasing=1, bounces=4,
                                                               vpl_count=256))
    indirect = frame.passes["DiffInd"]
    record(f"{angle:g}° wedge between two planes", "finite, bounded indirect light",
           "no NaN/Inf", f"max DiffInd {indirect.max():.3g}, {stats.counts['vpls']} VPLs")
    assert all(np.isfinite(image).all() for image in frame.passes.values())


def test_coincident_and_flipped_faces_light_like_single_faces(renderer, record):
    """A floor duplicated on top of itself with reversed winding renders like the floor alone
    (surfaces are two-sided, as in Cycles)."""
    settings = Settings(antialiasing=1, vpl_count=128, bounces=1)
    single = scaled_scene(1.0)
    reference, _ = renderer.render(single, settings)
    doubled = scaled_scene(1.0)
    floor = doubled.instances[0]
    flipped = Mesh("flipped", floor.mesh.positions[[0, 2, 1, 3, 5, 4]].copy(),
                   -floor.mesh.normals, floor.mesh.material_slots)
    doubled.instances.append(Instance(flipped, floor.matrix, floor.materials))
    frame, _ = renderer.render(doubled, settings)
    a, b = reference.passes["Combined"][..., :3], frame.passes["Combined"][..., :3]
    error = float(np.sqrt(np.mean((a - b) ** 2)) / a.mean())
    record("floor duplicated with flipped winding", "same image as one floor", "relRMSE < 2 %",
           f"{error * 100:.2f} %")
    assert error < 0.02


def test_random_scenes_always_finish_finite(renderer, record):
    """Seeded random scenes and settings: random triangles (degenerate ones too), lights of
    every type with random sizes, powers and transforms."""
    rng = np.random.default_rng(7)
    for _ in range(6):
        count = int(rng.integers(1, 60))
        tri = rng.normal(0, 1, (count, 3, 3)).astype(np.float32)
        degenerate = rng.uniform(size=count) < 0.2  # zero-area triangles too
        tri[degenerate, 1] = tri[degenerate, 0]
        mesh = Mesh("soup", tri.reshape(-1, 3), np.tile(np.float32([0, 0, 1]), (count * 3, 1)),
                    np.zeros(count, np.int32))
        lights = [light(kind, translation(*rng.normal(0, 2, 3)) @ rotation_x(rng.uniform(0, 6)),
                        power=float(10 ** rng.uniform(-3, 4)), size_x=float(rng.uniform(0, 2)),
                        radius=float(rng.uniform(0, 0.5)), spot_size=float(rng.uniform(0.1, 3)))
                  for kind in (list(LightKind)[i] for i in rng.integers(0, 4, rng.integers(0, 4)))]
        scene = Scene([Instance(mesh, np.eye(4), [Material("m", tuple(rng.uniform(0, 1.2, 3)))])],
                      lights, World(tuple(rng.uniform(0, 0.3, 3))), scaled_scene(1.0).camera)
        settings = Settings(antialiasing=int(rng.integers(1, 3)), bounces=int(rng.integers(0, 5)),
                            vpl_count=int(rng.integers(1, 200)),
                            visibility=str(rng.choice(["ism", "classic", "exact"])),
                            interleave=int(rng.choice([1, 2, 4])), seed=int(rng.integers(0, 99)))
        frame, _ = renderer.render(scene, settings)
        assert all(np.isfinite(image).all() for image in frame.passes.values())
    record("6 seeded random scenes and settings", "finished, finite", "no NaN/Inf", "all finite")


def test_thin_wall_light_leak_of_imperfect_shadow_maps(renderer, record):
    """A zero-thickness wall splits the floor; the light is on one side. The indirect light on
    the dark side with ISM visibility minus that with exact visibility is the ISM's leak."""
    from tests.core.builders import floor_scene, quad

    wall = Instance(quad(5, 2.5), translation(0, 0, 2.5) @ rotation_x(np.pi / 2),
                    [Material("wall", (0.8, 0.8, 0.8))])
    scene = floor_scene([light(LightKind.POINT, translation(0, -1.5, 0.7), power=200.0)],
                        extra=[wall], size=48)
    common = {"antialiasing": 1, "vpl_count": 512, "bounces": 1, "interleave": 1}
    exact, _ = renderer.render(scene, Settings(visibility="exact", **common))
    ism, _ = renderer.render(scene, Settings(visibility="ism", **common))
    rows = slice(30, 48)  # y > 0.75 m: the dark side, away from the wall's own pixels
    lit = exact.passes["DiffInd"][:18].mean()
    leak = float((ism.passes["DiffInd"][rows].mean() - exact.passes["DiffInd"][rows].mean())
                 / lit)
    record("zero-thickness wall, light on one side", "ISM minus exact indirect on the dark side",
           "< 10 % of the lit side", f"{leak * 100:+.2f} %")
    assert leak < 0.10
