"""Bad input (issue 19), bpy-free: far outliers do not move the scene's bounds, and random
scenes with outliers render within a stated bound of the same scenes without them."""

from __future__ import annotations

import hypothesis
import numpy as np
import pytest
from hypothesis import strategies as st

from addon.core.scene.bounds import OUTLIER_FACTOR, robust_bounds
from addon.core.scene.geometry import bounding_sphere, flatten_instances
from addon.core.scene.model import Instance, LightKind, Material, Mesh, Scene
from addon.core.settings import Settings
from tests.core.builders import floor_scene, icosphere, light, quad, rotation_x, translation

EXACT = Settings(visibility="exact", antialiasing=1, vpl_count=64)
ISM = Settings(antialiasing=1, vpl_count=64, ism_points=1024, ism_resolution=64)
OUTLIER_BOUND = 0.01
"""Relative change of the mean Combined and DiffInd a far outlier may make (measured: 0.26 %
at most, with ISM; before robust bounds the frame went black or lost its indirect light)."""


def room(extra: list[Instance] | None = None, size: int = 32) -> Scene:
    """A floor and a red wall lit by a point light, seen from above: direct and indirect
    light in a 10 m scene."""
    wall = Instance(quad(2, 1), translation(0, 1, 1) @ rotation_x(np.pi / 2),
                    [Material("wall", (0.8, 0.2, 0.2))])
    return floor_scene([light(LightKind.POINT, translation(0, -0.5, 1.5), power=100.0)],
                       extra=[wall, *(extra or [])], size=size)


def ball(name: str, x: float) -> Instance:
    """A 1 m ball at (x, 0, 0)."""
    mesh = icosphere(0.5, 1)
    return Instance(Mesh(name, mesh.positions, mesh.normals, mesh.material_slots),
                    translation(x, 0, 0), [Material(name, (0.8, 0.8, 0.8))])


def with_far_triangle(distance: float) -> Instance:
    """A small tile on the floor whose mesh has one more triangle, ``distance`` away."""
    tile = quad(0.5, 0.5)
    far = np.array([[distance, 0, 0], [distance, 1, 0], [distance, 0, 1]], np.float32)
    mesh = Mesh("tile", np.vstack([tile.positions, far]),
                np.vstack([tile.normals, np.tile([0, 0, 1], (3, 1))]).astype(np.float32),
                np.zeros(3, np.int32))
    return Instance(mesh, translation(-2, -2, 0.01), [Material("tile", (0.5, 0.5, 0.5))])


def tile() -> Instance:
    return Instance(quad(0.5, 0.5), translation(-2, -2, 0.01), [Material("tile", (0.5,) * 3)])


def relative_change(renderer, with_outlier: Scene, without: Scene, settings: Settings
                    ) -> tuple[float, float, list[str]]:
    """Relative change of the mean Combined and DiffInd the outlier makes, and the warnings."""
    (a, stats), (b, _) = (renderer.render(s, settings) for s in (with_outlier, without))
    assert all(np.isfinite(image).all() for image in a.passes.values())
    change = [abs(float(a.passes[p].mean()) / float(b.passes[p].mean()) - 1)
              for p in ("Combined", "DiffInd")]
    return change[0], change[1], stats.warnings


@pytest.mark.parametrize("case, settings", [
    ("object at x = 1e30", EXACT), ("ball 1e4 m away", EXACT), ("ball 1e8 m away", EXACT),
    ("mesh with a triangle at 1e30", EXACT), ("ball 1e4 m away", ISM),
])
def test_far_outliers_leave_the_image_within_a_bound_and_are_named(renderer, record, case,
                                                                    settings):
    """Before: the bounding sphere reached the outlier, so the clamp distance, shadow-map
    depth ranges and ray offsets grew with it: black frames at 1e8 and beyond, no indirect
    light at 1e4."""
    distance = float(case.split()[-3] if case.startswith("ball") else 1e30)
    if case.startswith("mesh"):
        extra, base, name = [with_far_triangle(distance)], [tile()], "tile"
    else:
        extra, base, name = [ball("far", distance)], [], "far"
    combined, indirect, warnings = relative_change(renderer, room(extra), room(base), settings)
    record(f"far outlier: {case} ({settings.visibility})", "mean Combined and DiffInd "
           "against the scene without it", f"< {OUTLIER_BOUND:.1%}",
           f"{combined:.3%}, {indirect:.3%}")
    assert combined < OUTLIER_BOUND and indirect < OUTLIER_BOUND
    assert [w for w in warnings if w.startswith("far outliers")] == [
        f"far outliers '{name}': over {OUTLIER_FACTOR:g} times the size of the camera's view "
        f"away from it; rendered, but left out of the scene's bounds (which the clamp "
        f"distance, shadow-map depths and ray offsets scale with)"]


def test_a_vertex_at_1e30_of_a_connected_face_keeps_the_frame_lit(renderer):
    """The tile's far corner makes two slivers that cross the view (real geometry, drawn),
    but the bounds stay the room's: the frame keeps its direct and indirect light."""
    moved = tile()
    positions = moved.mesh.positions.copy()
    positions[[2, 4]] = [1e30, 1e30, 0.5]
    moved.mesh = Mesh("moved", positions, moved.mesh.normals, moved.mesh.material_slots)
    frame, stats = renderer.render(room([moved]), EXACT)
    reference, _ = renderer.render(room([tile()]), EXACT)
    for name in ("Combined", "DiffInd"):
        assert np.isfinite(frame.passes[name]).all()
        assert frame.passes[name].mean() > 0.5 * reference.passes[name].mean()
    assert any(w.startswith("far outliers 'moved'") for w in stats.warnings)


def test_scenes_without_outliers_keep_their_bounding_sphere():
    """Bit-identical images of every scene without outliers: the same sphere as before."""
    scene = room([ball("near", 3.0)])
    positions = flatten_instances(scene, []).positions
    centre, radius, warning = robust_bounds(positions, scene.camera, scene.instances)
    expected = bounding_sphere(positions)
    assert warning is None and radius == expected[1]
    np.testing.assert_array_equal(centre, expected[0])


FLOATS = {"allow_nan": False, "allow_infinity": False, "allow_subnormal": False}


@st.composite
def scenes_with_outliers(draw: st.DrawFn) -> tuple[Scene, Scene, Settings, list[str]]:
    """The room with 1–3 far outliers (balls or a mesh's far triangle, 1e4 … 1e30 m away in
    any direction), the same room without them, random settings and the outliers' names."""
    outliers, base, names = [], [], []
    for i in range(draw(st.integers(1, 3))):
        exponent = draw(st.floats(4, 30, **FLOATS))
        direction = np.array([draw(st.floats(-1, 1, **FLOATS)) for _ in range(3)])
        direction = direction / max(np.linalg.norm(direction), 1e-9) if \
            np.linalg.norm(direction) > 0.1 else np.array([1.0, 0.0, 0.0])
        if draw(st.booleans()):
            outlier = ball(f"far{i}", 0.0)
            outlier.matrix = translation(*(direction * 10.0**exponent))
        else:
            outlier = with_far_triangle(10.0**exponent)
            outlier.mesh.name = f"far{i}"
            base.append(tile())
        outliers.append(outlier)
        names.append(f"far{i}")
    settings = Settings(antialiasing=1, vpl_count=draw(st.sampled_from([16, 64])),
                        visibility=draw(st.sampled_from(["exact", "classic"])),
                        bounces=draw(st.integers(1, 3)), seed=draw(st.integers(0, 1000)),
                        clamp_distance=draw(st.sampled_from([0.0, 0.1, 0.5])),
                        vpl_shadow_resolution=16)
    return room(outliers + base, 16), room(base, 16), settings, names


def test_random_far_outliers_render_within_the_bound(renderer, record):
    """Property (hypothesis, derandomised, 8 examples): finite frames, the outliers named in
    one warning, and mean Combined and DiffInd within OUTLIER_BOUND of the scene without."""
    worst: list[float] = []

    @hypothesis.settings(max_examples=8, derandomize=True, database=None, deadline=None,
                         suppress_health_check=list(hypothesis.HealthCheck))
    @hypothesis.given(scenes_with_outliers())
    def check(case: tuple[Scene, Scene, Settings, list[str]]) -> None:
        with_outliers, without, settings, names = case
        combined, indirect, warnings = relative_change(renderer, with_outliers, without,
                                                       settings)
        assert combined < OUTLIER_BOUND and indirect < OUTLIER_BOUND
        named = [w for w in warnings if w.startswith("far outliers")]
        assert len(named) == 1 and all(f"'{name}'" in named[0] for name in names[:3])
        worst.append(max(combined, indirect))

    check()
    record("random far outliers (hypothesis, 8 scenes)", "mean Combined and DiffInd against "
           "the scene without them", f"< {OUTLIER_BOUND:.1%}", f"worst {max(worst):.3%}")


def rotation_y(angle: float) -> np.ndarray:
    m = np.eye(4)
    c, s = np.cos(angle), np.sin(angle)
    m[0, 0], m[0, 2], m[2, 0], m[2, 2] = c, s, -s, c
    return m


def closed_cube_scene(open_faces: tuple[int, ...] = ()) -> Scene:
    """A closed 2 m cube of zero-thickness walls on stilts over a 16 m ground, lit from above
    by a point light outside; the camera inside looks at the +X wall. ``open_faces``: faces
    left out (0 bottom, 1 top, 2 -X, 3 +X, 4 -Y, 5 +Y)."""
    from tests.core.builders import inside_sphere_camera

    faces = [translation(0, 0, -1), translation(0, 0, 1) @ rotation_x(np.pi),
             translation(-1, 0, 0) @ rotation_y(np.pi / 2),
             translation(1, 0, 0) @ rotation_y(-np.pi / 2),
             translation(0, -1, 0) @ rotation_x(-np.pi / 2),
             translation(0, 1, 0) @ rotation_x(np.pi / 2)]
    walls = [Instance(quad(1, 1), m, [Material("box", (0.8, 0.8, 0.8))])
             for k, m in enumerate(faces) if k not in open_faces]
    ground = Instance(quad(8, 8), translation(0, 0, -2), [Material("ground", (0.8,) * 3)])
    camera = inside_sphere_camera(32)
    camera.view_matrix = np.linalg.inv(rotation_y(-np.pi / 2))
    return Scene([*walls, ground], [light(LightKind.POINT, translation(0, 0, 4), power=1e3)],
                 camera=camera)


LEAK_BOUND = 0.16
"""ISM minus exact indirect light inside the closed cube, as a share of the indirect light on
the same wall with the bottom and -X faces open, averaged over seeds 0 and 1 (measured: 19.1 %
before splats of a farther surface in the gaps of a nearer one counted as holes, 9.6 % after,
most of it along the wall joints, within the lookup's bias; 13.3 % and 14.3 % once the bias
compensation's off-screen hits gathered the VPLs' light, since those hits lie near the joints,
where ISMs leak; 14.5 % and 15.9 % with the clamp distance 0.1, whose longer compensation rays
reach more of them, 9.3 % of it without compensation; exact visibility: 0)."""


def test_closed_cube_lit_from_outside_does_not_leak_with_ism_defaults(renderer, record):
    """The issue's case: light got in through closed zero-thickness walls with the default
    ISM visibility, because the receiver's own wall, splatted into gaps between the nearer
    wall's points, was never replaced by pull-push (exact visibility: 0)."""
    closed = closed_cube_scene()
    ism = np.mean([renderer.render(closed, Settings(antialiasing=1, seed=seed))[0]
                   .passes["DiffInd"].mean() for seed in (0, 1)])
    exact, _ = renderer.render(closed, Settings(antialiasing=1, visibility="exact"))
    lit, _ = renderer.render(closed_cube_scene((0, 2)), Settings(antialiasing=1,
                                                                 visibility="exact"))
    leak = float(ism - exact.passes["DiffInd"].mean()) / float(lit.passes["DiffInd"].mean())
    record("closed cube lit from outside (ISM defaults)", "ISM minus exact indirect inside",
           f"< {LEAK_BOUND:.0%} of the wall's light when open", f"{leak:+.1%}")
    assert float(exact.passes["DiffInd"].max()) < 1e-6
    assert leak < LEAK_BOUND


SHADOW_MAP_LEAK_BOUND = 0.02
"""Direct light inside the closed cube from an area light outside it, low and to one side,
with shadow maps, as a share of the light inside with the wall between them open (measured:
0.79 %; the receiver's offset all along its normal 0.40 %; towards the light by 1 + tan of the
incidence angle, which kept grazing shadow edges in place best, 10 %)."""


def test_closed_cube_lit_from_outside_does_not_leak_through_shadow_maps(renderer, record):
    """Shadow-map offsets towards the light cross zero-thickness walls next to their joints:
    the receivers' offset keeps most of its length along the normal. Planner off, so that the
    light's samples, which no ray from the view reaches, are shadow-mapped all the same."""
    area = light(LightKind.AREA, translation(3.0, 0, 0.5) @ rotation_y(np.pi / 2), power=500.0,
                 size_x=1.0)
    settings = Settings(bounces=0, antialiasing=2, planner=False)
    inside = []
    for open_faces in ((), (3,)):
        scene = closed_cube_scene(open_faces)
        scene.lights = [area]
        scene.camera.view_matrix = np.linalg.inv(rotation_y(-np.pi / 2) @ rotation_x(-0.6))
        frame, _ = renderer.render(scene, settings)
        inside.append(float(frame.passes["DiffDir"][..., :3].mean()))
    leak = inside[0] / inside[1]
    record("closed cube lit from outside (area light, shadow maps)", "direct light inside",
           f"< {SHADOW_MAP_LEAK_BOUND:.0%} of it with the wall open", f"{leak:.2%}")
    assert inside[1] > 0.1 and leak < SHADOW_MAP_LEAK_BOUND
