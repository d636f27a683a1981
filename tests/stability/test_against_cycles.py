"""Stiff and singular cases against Cycles and closed forms (needs bpy; small frames, few samples).

The scenes are built in Blender; Cycles renders them through bpy and VPL GI renders the same
exported scene (``addon.export.export_scene``, as the engine does) with the core renderer, so
every pass is at hand. Cycles is set up as in tests/blender: CPU, no denoiser, a one-pixel box
filter, Principled BSDF with roughness 1 and Specular IOR Level 0 (purely diffuse).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from addon.core.scene.geometry import bounding_sphere, flatten_instances
from addon.core.settings import Settings

bpy = pytest.importorskip("bpy")

from addon.export import export_scene  # noqa: E402  (needs bpy)
from tests.blender.rendering import configure_cycles, render_linear  # noqa: E402
from tests.blender.test_cycles_indirect import closed_sphere  # noqa: E402
from tests.stability.test_stiff_and_extreme import (  # noqa: E402
    parallel_plate_clamp_loss,
    wedge_pixel_gap,
)

POINT_POWER = 100.0  # W (closed sphere, hair's breadth)


# -- building scenes in Blender ---------------------------------------------------------------

def empty_scene(size: int) -> bpy.types.Scene:
    """Factory settings, no world (black), size × size pixels."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.world = None
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    return scene


def diffuse(name: str, albedo: float) -> bpy.types.Material:
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (albedo, albedo, albedo, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    return material


def quad(name: str, corners: list[tuple[float, float, float]], albedo: float = 0.8) -> None:
    """A one-face mesh through four corners (counter-clockwise seen from its front)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(diffuse(name, albedo))
    bpy.context.scene.collection.objects.link(bpy.data.objects.new(name, mesh))


def point_light(location: tuple[float, float, float], power: float, radius: float = 0.0) -> None:
    """A point light (a sphere light with radius > 0; Cycles' soft falloff off: VPL GI does
    not model it)."""
    lamp = bpy.data.lights.new("Point", "POINT")
    lamp.energy, lamp.shadow_soft_size = power, radius
    lamp.use_soft_falloff = False
    obj = bpy.data.objects.new("Point", lamp)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)


def ortho_camera(location: tuple[float, float, float], tilt: float, scale: float,
                 clip: tuple[float, float] = (1e-3, 100.0)) -> None:
    """An orthographic camera looking down -Z, tilted by ``tilt`` about the x axis."""
    data = bpy.data.cameras.new("Camera")
    data.type, data.ortho_scale = "ORTHO", scale
    data.clip_start, data.clip_end = clip
    obj = bpy.data.objects.new("Camera", data)
    obj.location, obj.rotation_euler = location, (tilt, 0.0, 0.0)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.scene.camera = obj


def cycles(scene: bpy.types.Scene, tmp_path: Path, samples: int, bounces: int) -> np.ndarray:
    """Cycles' linear RGB (rows bottom-up)."""
    configure_cycles(scene, samples, bounces=bounces)
    return render_linear(scene, "CYCLES", tmp_path / f"cycles_{bounces}.exr")[..., :3]


def vpl_gi(renderer, **settings) -> dict[str, np.ndarray]:
    """VPL GI's passes of the current Blender scene (exported as the engine exports it)."""
    frame, _ = renderer.render(export_scene(bpy.context.evaluated_depsgraph_get()),
                               Settings(**settings))
    assert all(np.isfinite(image).all() for image in frame.passes.values())
    return frame.passes


def clamp_distance() -> float:
    """The default VPL clamp distance of the current scene (a share of its bounding radius)."""
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    _, radius = bounding_sphere(flatten_instances(scene, []).positions)
    return Settings().clamp_distance * radius


def energy_error(image: np.ndarray, reference: np.ndarray) -> float:
    return float(image.mean() / reference.mean() - 1)


# -- the closed sphere: absolute radiance ----------------------------------------------------

def tessellated_direct_irradiance(scene: bpy.types.Scene, size: int, power: float,
                                  supersampling: int = 4) -> tuple[np.ndarray, float]:
    """Direct irradiance E0 (W/m²) of the wall each pixel sees, averaged over the pixel, for a
    point light at the camera's position at the centre of the convex tessellated sphere; and
    the mesh's area. A ray from inside a convex polyhedron leaves it through the face plane it
    meets first, so t = min over faces facing the ray of (n·v0)/(n·d), and E0 = I cos/t²."""
    mesh = next(o for o in scene.objects if o.type == "MESH").data
    mesh.calc_loop_triangles()
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    corner = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", corner)
    tri = co.reshape(-1, 3)[corner.reshape(-1, 3)]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * float(np.linalg.norm(normal, axis=1).sum())
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    offset = np.einsum("ij,ij->i", normal, tri[:, 0])  # > 0: the centre is inside
    frame = np.array([tuple(v) for v in scene.camera.data.view_frame(scene=scene)])
    n = size * supersampling
    u = (np.arange(n) + 0.5) / n
    x = frame[:, 0].min() + u * np.ptp(frame[:, 0])
    y = frame[:, 1].min() + u * np.ptp(frame[:, 1])
    gx, gy = np.meshgrid(x, y)  # row 0 at the bottom, as the rendered images
    rays = np.stack([gx, gy, np.full_like(gx, frame[0, 2])], axis=-1).reshape(-1, 3)
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    rays = (np.asarray(scene.camera.matrix_world)[:3, :3] @ rays.T).T
    facing = rays @ normal.T
    t = np.where(facing > 0, offset / np.maximum(facing, 1e-12), np.inf)
    hit = t.argmin(axis=1)
    rows = np.arange(len(rays))
    irradiance = power / (4 * np.pi) * facing[rows, hit] / t[rows, hit] ** 2
    pixels = irradiance.reshape(size, supersampling, size, supersampling).mean(axis=(1, 3))
    return pixels, area


@pytest.mark.sweep("albedo, bounces", [(0.9, 4)],
                   full=[(0.5, 1), (0.9, 4), (0.9, 8), (0.99, 16)])
def test_closed_sphere_absolute_radiance_cycles_and_vpl_gi(renderer, record, tmp_path, albedo,
                                                           bounces):
    """Inside Blender's closed UV sphere (radius 2, 64 × 32, flat faces) with a 100 W point
    light at the centre, the wall's radiance is (ρ/π)(E0 + Σ_{k=1..D} ρ^k Ē), with E0 the
    pixel's own direct irradiance on the flat face it sees (1 to 3 ‰ above I/R²: the faces are
    inside the sphere) and Ē = P / mesh area the mean irradiance every further bounce spreads
    (a closed surface receives all of P). Cycles (64 samples) must match this in absolute
    units, which validates the reference itself; VPL GI too (its ratio test is in
    test_stiff_and_extreme.py, the ratio-only Blender test in tests/blender)."""
    size = 24
    closed_sphere(bpy, albedo)
    scene = bpy.context.scene
    direct, area = tessellated_direct_irradiance(scene, size, POINT_POWER)
    spread = sum(albedo**k for k in range(1, bounces + 1)) * POINT_POWER / area
    expected = albedo / np.pi * (direct + spread)
    uniform = albedo / np.pi * POINT_POWER / (4 * np.pi * 4.0) * sum(
        albedo**k for k in range(bounces + 1))
    reference = cycles(scene, tmp_path, 64, bounces)[..., 0]
    ours = vpl_gi(renderer, bounces=bounces, vpl_count=256)["Combined"][..., 0]
    cycles_error, ours_error = energy_error(reference, expected), energy_error(ours, expected)
    record(f"closed UV sphere ρ={albedo}, D={bounces}: Cycles and VPL GI",
           "absolute radiance (ρ/π)(E0 + Σρ^k P/A), tessellation included",
           "Cycles ±0.5 %, VPL GI ±2 %",
           f"Cycles {cycles_error * 100:+.2f} %, VPL GI {ours_error * 100:+.2f} % "
           f"(smooth-sphere formula off by {(expected.mean() / uniform - 1) * 100:+.2f} %)")
    assert abs(cycles_error) < 0.005
    assert abs(ours_error) < 0.02


# -- a light a hair's breadth from a wall ----------------------------------------------------

HAIR = 1e-4  # m: the light's distance from the wall
LIGHT_HEIGHT = 0.05  # m above the floor: below the clamp distance (0.075 m here)


def hairs_breadth_scene(size: int, radius: float = 0.0, gap: float = HAIR,
                        height: float = LIGHT_HEIGHT) -> bpy.types.Scene:
    """A 2 m floor and a 1 m high wall along its far edge (y = 1); a 100 W point light
    ``gap`` from the wall's face, ``height`` above the floor; an orthographic camera looks
    straight down at the floor (the wall is edge-on, out of the image)."""
    scene = empty_scene(size)
    quad("floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    quad("wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 1), (-1, 1, 1)])
    point_light((0.0, 1.0 - gap - radius, height), POINT_POWER, radius)
    ortho_camera((0.0, 0.0, 5.0), 0.0, 2.0)
    return scene


def rectangle_solid_angle(distance: float, widths: tuple[float, float],
                          heights: tuple[float, float]) -> float:
    """Solid angle of a rectangle seen from a point ``distance`` in front of it, split at the
    foot of the perpendicular into four rectangles with a corner there."""
    d = distance
    return float(sum(np.arctan(a * b / (d * np.sqrt(d * d + a * a + b * b)))
                     for a in widths for b in heights))


def hot_spot_flux() -> float:
    """Flux the wall reflects: ρ I Ω, Ω the solid angle of the wall seen from the light."""
    intensity = POINT_POWER / (4 * np.pi)
    return 0.8 * intensity * rectangle_solid_angle(HAIR, (1.0, 1.0),
                                                   (LIGHT_HEIGHT, 1.0 - LIGHT_HEIGHT))


def hot_spot_floor_radiance(size: int, clamp: float, supersampling: int = 8) -> np.ndarray:
    """One bounce off the wall, seen on the floor, with the VPL clamp ``clamp`` (0 = none).

    Half of the light lands within ~2·10⁻⁴ m of the foot F = (0, 1, H) on the wall (99 %
    within 1 cm): to the floor, 0.3 m and more away, the lit wall is a Lambertian point emitter
    at F facing −y with flux Φ = ρ I Ω_wall, so E(p) = (Φ/π) cosθ_wall cosθ_floor / d², and
    with the clamp (Φ/π) cos cos / max(d², c²)."""
    flux = hot_spot_flux()
    n = size * supersampling
    u = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(u, u)  # row 0 at the bottom (y = −1)
    along = 1 - y  # distance from the wall
    d2 = x * x + along * along + LIGHT_HEIGHT**2
    irradiance = flux / np.pi * along * LIGHT_HEIGHT / (d2 * np.maximum(d2, clamp * clamp))
    return (0.8 / np.pi * irradiance).reshape(size, supersampling, size,
                                              supersampling).mean(axis=(1, 3))


def test_light_a_hairs_breadth_from_a_wall(renderer, record, tmp_path):
    """A point light 0.1 mm from a wall, 5 cm above the floor. Direct light on the floor must
    match Cycles (shadow-map depth range and bias next to the wall). The wall's hot spot
    (radius ~0.2 mm) then lights the floor; Cycles cannot find so small a spot by BSDF sampling
    (two seeds of 256 samples differ by 5 % and give a tenth of the light), so one bounce is
    checked against the point-emitter limit, in which the clamp's loss has a closed form."""
    size = 48
    hairs_breadth_scene(size)
    reference = cycles(bpy.context.scene, tmp_path, 64, 0)[..., 0]
    clamp = clamp_distance()
    exact = {"antialiasing": 4, "bounces": 1, "visibility": "exact", "interleave": 1,
             "vpl_count": 256}
    clamped = vpl_gi(renderer, **exact)
    unclamped = vpl_gi(renderer, **exact, clamp_distance=0.0)
    default = vpl_gi(renderer, bounces=1, vpl_count=256)
    albedo = clamped["DiffCol"][..., 0]
    direct = clamped["DiffDir"][..., 0] * albedo
    model_unclamped = hot_spot_floor_radiance(size, 0.0)
    model_clamped = hot_spot_floor_radiance(size, clamp)
    direct_error = energy_error(direct, reference)
    indirect_error = energy_error(unclamped["DiffInd"][..., 0] * albedo, model_unclamped)
    predicted_loss = 1 - model_clamped.mean() / model_unclamped.mean()
    loss = 1 - clamped["DiffInd"][..., 0].mean() / unclamped["DiffInd"][..., 0].mean()
    full_reference = reference + model_unclamped
    default_error = energy_error(default["Combined"][..., 0], full_reference)
    predicted_error = -predicted_loss * model_unclamped.mean() / full_reference.mean()
    ceiling = hot_spot_flux() / np.pi / clamp**2  # irradiance: VPLs give at most Φ/(π c²)
    brightest = float(clamped["DiffInd"].max()) * np.pi / ceiling  # DiffInd = irradiance / π
    record("point light 0.1 mm from a wall, 5 cm above the floor, 1 bounce",
           "direct vs Cycles; indirect vs point-emitter limit; clamp loss vs closed form; "
           "energy with default settings vs Cycles direct + limit; brightest indirect "
           "irradiance / (Φ/(π c²))",
           "±1 %; ±3 %; ±2 points; ±3 points of the prediction; ≤ 1",
           f"direct {direct_error * 100:+.2f} %; indirect (no clamp) "
           f"{indirect_error * 100:+.2f} %; clamp removes {loss * 100:.1f} % of the indirect "
           f"(predicted {predicted_loss * 100:.1f} %); default settings "
           f"{default_error * 100:+.1f} % (predicted {predicted_error * 100:+.1f} %); "
           f"{brightest:.2f}")
    assert abs(direct_error) < 0.01
    assert abs(indirect_error) < 0.03
    assert abs(loss - predicted_loss) < 0.02
    assert abs(default_error - predicted_error) < 0.03
    assert brightest <= 1.0  # no firefly above the clamp


@pytest.mark.xfail(strict=True, reason="sphere lights are not occluders in VPL GI: light "
                   "reflected by the wall right behind a sphere light passes through the light's "
                   "body (Cycles blocks it); +10 % energy with a 5 cm sphere 0.1 mm from a wall")
def test_sphere_light_a_hairs_breadth_from_a_wall_matches_cycles(renderer, record, tmp_path):
    """A 5 cm sphere light whose surface is 0.1 mm from the wall: its hot spot is ~5 cm wide,
    which Cycles samples well. A point light at the sphere's centre gives the same image in
    both engines (+0.07 % measured), so a difference here is the sphere's own body, which
    hides the brightest part of the wall from the floor in Cycles and not in VPL GI."""
    size = 32
    hairs_breadth_scene(size, radius=0.05, height=0.3)
    reference = cycles(bpy.context.scene, tmp_path, 256, 1)[..., 0]
    ours = vpl_gi(renderer, bounces=1, visibility="exact", interleave=1,
                  clamp_distance=0.0)["Combined"][..., 0]
    error = energy_error(ours, reference)
    record("5 cm sphere light 0.1 mm from a wall, 1 bounce (known bug)",
           "energy vs Cycles", "±3 % (fails)", f"{error * 100:+.1f} %")
    assert abs(error) < 0.03


# -- narrow wedges ---------------------------------------------------------------------------

def wedge_in_blender(angle_degrees: float, size: int) -> bpy.types.Scene:
    """test_stiff_and_extreme.wedge_scene built in Blender: floor and lid 4 × 4 m hinged on the
    x axis, a 50 W point light on the bisector at y = 3, an orthographic camera in the
    bisector plane looking at the floor's inner face over y = 2 … 3.5."""
    scene = empty_scene(size)
    a = np.radians(angle_degrees)
    quad("floor", [(-2, 0, 0), (2, 0, 0), (2, 4, 0), (-2, 4, 0)])
    lid = [(x, y * np.cos(a), y * np.sin(a)) for x, y in ((-2, 0), (2, 0), (2, 4), (-2, 4))]
    quad("lid", lid)
    point_light((0.0, 3.0, 3.0 * np.tan(a / 2)), 50.0)
    ortho_camera((0.0, 2.75, 2.75 * np.tan(a / 2)), a / 2, 1.5, clip=(1e-5, 2.0))
    return scene


@pytest.mark.sweep("angle", [1.0], full=[0.5, 1.0, 5.0, 10.0, 30.0])
def test_narrow_wedge_energy_against_cycles(renderer, record, tmp_path, angle):
    """Four bounces in a wedge. Direct light must match Cycles; without the clamp (exact
    visibility) so must the total; with the default settings but no bias compensation the
    clamp removes the share of the indirect light the parallel-plate estimate predicts
    (test_stiff_and_extreme.py), and the default compensation brings part of it back."""
    size = 32
    scene = wedge_in_blender(angle, size)
    direct_reference = cycles(scene, tmp_path, 256, 0)[..., 0]
    reference = cycles(scene, tmp_path, 256, 4)[..., 0]
    # 4 × 4 samples a pixel: at 0.5° the direct spot under the light (1.3 cm high) is smaller
    # than a pixel (4.7 cm), and 2 × 2 fixed samples miss 4 % of it (Cycles jitters its samples)
    default = vpl_gi(renderer, bounces=4, vpl_count=256, antialiasing=4,
                     bias_compensation="off")
    compensated = vpl_gi(renderer, bounces=4, vpl_count=256, antialiasing=4)
    unclamped = vpl_gi(renderer, bounces=4, vpl_count=256, antialiasing=4, visibility="exact",
                       interleave=1, clamp_distance=0.0)["Combined"][..., 0]
    direct = default["DiffDir"][..., 0] * default["DiffCol"][..., 0]
    indirect = np.clip(reference - direct_reference, 0, None)
    share = parallel_plate_clamp_loss(wedge_pixel_gap(angle, size), clamp_distance())
    predicted = -float((share[:, None] * indirect).sum() / reference.sum())
    direct_error = energy_error(direct, direct_reference)
    unclamped_error = energy_error(unclamped, reference)
    default_error = energy_error(default["Combined"][..., 0], reference)
    compensated_error = energy_error(compensated["Combined"][..., 0], reference)
    record(f"{angle:g}° wedge, 4 bounces, vs Cycles (256 samples)",
           "direct; total without clamp; energy lost with the default clamp, uncompensated, vs "
           "estimate; compensated", "±1 %; ±4 %; ±5 points; less",
           f"direct {direct_error * 100:+.2f} %, no clamp {unclamped_error * 100:+.2f} %, "
           f"clamped {default_error * 100:+.1f} % (estimate {predicted * 100:+.1f} %), "
           f"compensated {compensated_error * 100:+.1f} %")
    assert abs(direct_error) < 0.01
    assert abs(unclamped_error) < 0.04
    assert abs(default_error - predicted) < 0.05
    assert abs(compensated_error) < abs(default_error) - 0.05
