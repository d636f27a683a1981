"""IES profiles (scene/ies.py, transport/light_profiles.py): files read as Cycles reads them,
the profile on the GPU against its exact interpolation, and light paths drawn from it. The
renders against Cycles are in tests/blender/test_ies_lights.py."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from addon.core.scene.ies import IesError, catmull_rom, parse_ies
from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings
from addon.core.transport.light_profiles import ProfileSampler
from tests.core.builders import (
    floor_scene,
    light,
    pixel_centres,
    profile_text,
    quad,
    traced_vpls,
    translation,
)

HEADER = "IESNA:LM-63-2002\n[TEST] t\nTILT=NONE\n"


def _file(v: list[float], h: list[float], rows: list[list[float]], kind: int = 1) -> str:
    values = "\n".join(" ".join(map(str, row)) for row in rows)
    return (f"{HEADER}1 -1 2 {len(v)} {len(h)} {kind} 2 0 0 0\n1 1 100\n"
            f"{' '.join(map(str, v))}\n{' '.join(map(str, h))}\n{values}\n")


def test_a_quadrant_is_mirrored_to_the_whole_circle():
    """Type C with horizontal angles 0-90°: mirrored to 0-360° (as Cycles does), so the
    profile at h and at 180° - h, 180° + h and 360° - h is the same (away from 0° and 360°,
    where Cycles' splines end: test_cycles_4_and_5_differ_only_at_the_tables_edges); the
    candela multiplier
    (2) and Cycles' candela-to-watt factor scale every value."""
    profile = parse_ies(_file([0, 30, 60, 90], [0, 45, 90],
                              [[100, 80, 40, 0], [120, 90, 50, 0], [90, 70, 30, 0]]))
    np.testing.assert_allclose(np.degrees(profile.h_angles), [0, 45, 90, 135, 180, 225, 270,
                                                              315, 360], atol=1e-4)
    np.testing.assert_allclose(profile.intensity[1, 1], 90 * 2 * 0.0706650768394, rtol=1e-6)
    h = np.radians(np.linspace(46, 89, 23))
    v = np.radians(40.0)
    for mirrored in (np.pi - h, np.pi + h, 2 * np.pi - h):
        np.testing.assert_allclose(profile.at_angles(mirrored, v), profile.at_angles(h, v),
                                   rtol=1e-6)


def test_the_spline_passes_through_the_table_and_ends_at_the_last_angle():
    """At the file's own angles the profile is the table's value; at or past its last
    vertical angle it is 0 (Cycles: a downlight gives no light upwards)."""
    profile = parse_ies(profile_text())
    h, v = np.meshgrid(profile.h_angles[1:-1], profile.v_angles[:-1], indexing="ij")
    np.testing.assert_allclose(profile.at_angles(h, v), profile.intensity[1:-1, :-1],
                               rtol=1e-9, atol=1e-9)
    short = parse_ies(_file([0, 45, 90], [0], [[100, 60, 20]]))
    assert short.at_angles(1.0, short.v_angles[-1]) == 0
    assert short.at_angles(1.0, np.radians(120.0)) == 0
    assert short.at_angles(1.0, np.radians(89.0)) > 0


def test_cycles_4_and_5_differ_only_at_the_tables_edges():
    """Cycles 4.x reads 0 where a spline's outer point lies past the table, 5.x the nearest
    value: the two agree away from 0°/360° of horizontal angle and the last vertical angle,
    and differ next to them."""
    zero = parse_ies(profile_text())
    repeat = dataclasses.replace(zero, edge="repeat")
    v = np.radians(60.0)
    inner = np.radians([60.0, 100.0, 170.0, 200.0, 250.0, 300.0])
    np.testing.assert_allclose(zero.at_angles(inner, v), repeat.at_angles(inner, v))
    near_zero = np.radians([10.0, 350.0])
    assert np.all(np.abs(zero.at_angles(near_zero, v) / repeat.at_angles(near_zero, v) - 1)
                  > 0.01)


def test_catmull_rom_is_cycles_cubic():
    """Cycles' cubic_interp: b at 0, c at 1, and exact on a cubic's samples."""
    x = np.linspace(0, 1, 7)
    a, b, c, d = (t**3 - 2 * t for t in (-1.0, 0.0, 1.0, 2.0))
    np.testing.assert_allclose(catmull_rom(a, b, c, d, x)[[0, -1]], [b, c])
    np.testing.assert_allclose(catmull_rom(0.0, 1.0, 2.0, 3.0, x), 1 + x)


@pytest.mark.parametrize(("text", "why"), [
    ("IESNA\n1 2 3", "no TILT= line"),
    (_file([0, 90], [0], [[1, 2]], kind=3), "photometric type 3 (Cycles reads types B and C)"),
    (_file([0, 90], [0], [[1, 2]])[:-6], "it ends before its data does"),
    (_file([0, 90], [0], [[1, "x"]]), "'x' is not a number"),
    (_file([0, 90], [10, 20], [[1, 2], [3, 4]]), "its horizontal angles do not start at 0°"),
    (_file([0, 90], [0, 100], [[1, 2], [3, 4]]), "its horizontal angles end short of 360°"),
])
def test_files_cycles_would_not_read_are_refused_with_the_reason(text, why):
    with pytest.raises(IesError, match=re.escape(why)):
        parse_ies(text)


def test_direct_light_follows_the_profile(renderer):
    """A tilted, turned point light over a floor with and without the profile: per pixel,
    their ratio is the profile towards the pixel (the shaders' bilinear grid of 1° × 2°
    against the exact spline, within 0.5 %)."""
    settings = Settings(bounces=0, antialiasing=1)
    matrix = translation(0.3, -0.2, 1.5)
    turn, tilt = np.radians(40.0), np.radians(20.0)
    rz = np.array([[np.cos(turn), -np.sin(turn), 0], [np.sin(turn), np.cos(turn), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    matrix[:3, :3] = rz @ rx
    profile = parse_ies(profile_text())
    images = [renderer.render(floor_scene([light(LightKind.POINT, matrix, power=100.0,
                                                 profile=p)]), settings)[0]
              .passes["DiffDir"][..., 0] for p in (profile, None)]
    x, y = pixel_centres()
    direction = np.stack([x - 0.3, y + 0.2, np.full_like(x, -1.5)], -1)
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    expected = profile.towards(direction @ matrix[:3, :3])
    lit = images[1] > 0
    np.testing.assert_allclose(images[0][lit] / images[1][lit], expected[lit], rtol=5e-3,
                               atol=1e-3 * expected.max())


def test_light_paths_are_drawn_from_the_profile():
    """ProfileSampler: its paths' weights average to the profile's mean (unbiased); a
    profile with sideways light that differs all round, and a downlight, whose paths leave
    downwards but for the 1 % of the mean every cell is drawn with."""
    for profile, down in ((parse_ies(profile_text(upward=True)), 0.0),
                          (parse_ies(_file([0, 45, 90], [0], [[100, 60, 20]])), 0.98)):
        _assert_drawn_from(profile, down)


def _assert_drawn_from(profile, down: float) -> None:
    u = (np.arange(1 << 16)[:, None] + np.random.default_rng(1).random((1 << 16, 3))) \
        / (1 << 16)
    u[:, 1:] = np.random.default_rng(2).random((1 << 16, 2))
    local, weight = ProfileSampler(profile).sample(u)
    np.testing.assert_allclose(weight.mean(), profile.mean, rtol=0.01)
    assert (local[:, 2] < 0).mean() >= down
    np.testing.assert_allclose(np.linalg.norm(local, axis=1), 1.0, atol=1e-9)


@pytest.mark.parametrize("incremental", [False, True])
def test_an_uplights_vpls_carry_its_light_to_the_ceiling(renderer, incremental):
    """An uplight 1 m under a 40 m ceiling of albedo 0.5: its first-bounce VPLs there (light
    paths, or Incremental Instant Radiosity's anchors) carry the light's power × the
    profile's share of the sphere the ceiling covers × 0.5 (the profile integrated over 2^18
    directions), within 3 % (measured 0.9973 and 0.9989 of it)."""
    profile = parse_ies(profile_text(upward=True))
    ceiling = Instance(quad(20.0, 20.0, 2.0, flip=True), np.eye(4),
                       [Material("ceiling", (0.5,) * 3)])
    scene = floor_scene([light(LightKind.POINT, translation(0, 0, 1.0), power=100.0,
                               profile=profile)], extra=[ceiling])
    renderer.forget_frames()  # the tracer is given other triangles than the frames' here
    vpls = traced_vpls(renderer, scene,
                       Settings(bounces=1, vpl_count=1024, seed=2, incremental=incremental))
    renderer.forget_frames()
    on_ceiling = (vpls.generation == 1) & (np.abs(vpls.position[:, 2] - 2.0) < 1e-3)
    assert on_ceiling.sum() > 300
    flux = np.pi * vpls.intensity[on_ceiling].sum(axis=0)  # a diffuse VPL's flux is π I
    n = 1 << 18
    z = 1 - 2 * (np.arange(n) + 0.5) / n
    phi = np.pi * (1 + 5**0.5) * np.arange(n)
    r = np.sqrt(1 - z * z)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    reaches = (z > 0) & np.all(np.abs(d[:, :2]) < 20.0 * np.maximum(z, 1e-9)[:, None], 1)
    share = (profile.towards(d) * reaches).mean()
    print(f"{on_ceiling.sum()} VPLs on the ceiling: {flux[0] / (50.0 * share):.4f} of its light")
    np.testing.assert_allclose(flux, 100.0 * share * 0.5, rtol=0.03)


def test_reflective_shadow_maps_carry_the_profile(renderer):
    """An uplight under a ceiling the camera does not see: the floor's indirect light with
    VPLs from reflective shadow maps (``vpl_source = rsm``) is the light paths' within 3 %
    (measured 0.9 %), and 10 % or more off the same light without its profile."""
    def indirect(source: str, profile) -> float:
        ceiling = Instance(quad(5.0, 5.0, 2.0, flip=True), np.eye(4),
                           [Material("ceiling", (0.5,) * 3)], visible_to_camera=False)
        scene = floor_scene([light(LightKind.POINT, translation(0.5, 0, 1.0), power=100.0,
                                   profile=profile)], extra=[ceiling])
        image = renderer.render(scene, Settings(bounces=1, vpl_source=source,
                                                vpl_count=1024))[0]
        return float(image.passes["DiffInd"][..., :3].mean())

    profile = parse_ies(profile_text(upward=True))
    from_maps, from_paths = indirect("rsm", profile), indirect("paths", profile)
    print(f"indirect light: maps {from_maps:.4f}, paths {from_paths:.4f}")
    assert from_maps == pytest.approx(from_paths, rel=0.03)
    assert abs(indirect("rsm", None) / from_maps - 1) > 0.1
