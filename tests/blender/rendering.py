"""Rendering helpers shared by the Blender tests: open a sample scene, render it with an engine,
get the linear image back as numpy."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import bpy
import numpy as np

from addon.blender_compat import ensure_nodes
from devtools import metrics

SAMPLE_SCENES = Path(__file__).resolve().parents[2] / "sample_scenes"


def open_scene(name: str, size: int) -> bpy.types.Scene:
    """Load sample_scenes/<name>.blend at size × size pixels."""
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLE_SCENES / f"{name}.blend"), load_ui=False)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    return scene


def add_camera(scene: bpy.types.Scene, size: int, location=(0.0, 0.0, 0.0),
               rotation=(0.0, 0.0, 0.0)) -> bpy.types.Object:
    """A perspective camera at ``location`` turned by Euler ``rotation``, made the scene's
    camera, with a size × size image."""
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location, camera.rotation_euler = location, rotation
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.resolution_x = scene.render.resolution_y = size
    return camera


def configure_cycles(scene: bpy.types.Scene, samples: int, bounces: int = 0, seed: int = 0
                     ) -> None:
    """Cycles set up for a like-for-like diffuse reference: CPU, no denoiser, no clamping,
    a one-pixel box filter (the same pixel footprint as VPL GI's supersampling)."""
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = c.diffuse_bounces = bounces
    c.glossy_bounces = c.transmission_bounces = c.volume_bounces = 0
    c.transparent_max_bounces = 0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.seed = seed


def render_linear(scene: bpy.types.Scene, engine: str, path: Path) -> np.ndarray:
    """Render with ``engine`` to a 32-bit EXR at ``path`` and return it (rows bottom-up)."""
    scene.render.engine = engine
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    try:
        width, height = image.size
        pixels = np.empty(width * height * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        return pixels.reshape(height, width, 4)
    finally:
        bpy.data.images.remove(image)


def cycles_and_ours(scene: bpy.types.Scene, tmp_path: Path, samples: int, bounces: int,
                    transparent: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The scene rendered by Cycles (``configure_cycles``; with ``transparent``, 8 transparent
    bounces) and by VPL GI with the same bounces and antialiasing 4: (reference, ours)."""
    configure_cycles(scene, samples, bounces=bounces)
    if transparent:
        scene.cycles.transparent_max_bounces = 8
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = bounces, 4
    return reference, render_linear(scene, "VPL_GI", tmp_path / "ours.exr")


def against(image: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """``image``'s mean relative energy and relative RMSE against ``reference``."""
    return (metrics.mean_relative_energy(image, reference),
            metrics.relative_rmse(image, reference))


def assert_near_cycles(label: str, ours: np.ndarray, reference: np.ndarray,
                       bounds: tuple[float, float], without: np.ndarray,
                       without_label: str, factor: float = 3.0) -> None:
    """Print and check ``ours`` against Cycles' ``reference``: finite, energy and relRMSE
    within ``bounds``; and the render ``without`` the feature under test (``without_label``)
    off by ``factor`` times the relRMSE or more, so that the test fails without it."""
    assert np.isfinite(ours).all()
    energy, error = against(ours, reference)
    without_error = against(without, reference)[1]
    print(f"{label} vs Cycles: energy {energy:+.4f} relRMSE {error:.4f}; {without_label}: "
          f"relRMSE {without_error:.4f}")
    assert abs(energy) < bounds[0]
    assert error < bounds[1]
    assert without_error > factor * error


def assert_near_where(label: str, ours: np.ndarray, reference: np.ndarray,
                      without: np.ndarray, region: np.ndarray, bounds: tuple[float, float],
                      without_label: str, share: float = 0.02) -> None:
    """Print and check ``ours`` against Cycles' ``reference`` (RGB): finite, energy and
    relRMSE within ``bounds``; and where the feature under test changes the image
    (``region``, over ``share`` of the pixels) ``ours`` off on average by a third or less of
    what the render ``without`` it (``without_label``) is, relative to the reference's mean."""
    rgb = reference[..., :3]
    energy, error = against(ours[..., :3], rgb)
    off, ignored = (float(np.abs(image[..., :3] - rgb)[region].mean() / rgb.mean())
                    for image in (ours, without))
    print(f"{label} vs Cycles: energy {energy:+.4f} relRMSE {error:.4f}; where it changes the "
          f"image ({region.mean():.3f} of pixels) {off:.4f} of the mean off, {without_label} "
          f"{ignored:.4f} (relRMSE {against(without[..., :3], rgb)[1]:.4f})")
    assert np.isfinite(ours).all()
    assert abs(energy) < bounds[0] and error < bounds[1]
    assert region.mean() > share and ignored > 3 * off


def plain_world(scene: bpy.types.Scene, colour: tuple[float, float, float]) -> None:
    """A new world of one colour, through its Background node (no deprecated use_nodes)."""
    scene.world = bpy.data.worlds.new("Plain")
    ensure_nodes(scene.world)
    background = scene.world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*colour, 1.0)
    background.inputs["Strength"].default_value = 1.0


def shader_material(name: str, kind: str, **inputs) -> bpy.types.Material:
    """A material whose surface is one new node of ``kind`` with ``inputs`` set."""
    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    node = tree.nodes.new(kind)
    for label, value in inputs.items():
        node.inputs[label.replace("_", " ")].default_value = value
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def add_primitive(kind: str, material: bpy.types.Material, **options) -> bpy.types.Object:
    """A new mesh from ``bpy.ops.mesh.primitive_<kind>_add(**options)`` with ``material``."""
    getattr(bpy.ops.mesh, f"primitive_{kind}_add")(**options)
    obj = bpy.context.object
    obj.data.materials.append(material)
    return obj


def add_sun(scene: bpy.types.Scene, rotation: tuple[float, float, float],
            energy: float = 3.0) -> bpy.types.Object:
    """A sun of angle 0 turned by Euler ``rotation`` (degrees), ``energy`` W/m²."""
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = energy, 0.0
    sun.rotation_euler = tuple(math.radians(a) for a in rotation)
    scene.collection.objects.link(sun)
    return sun


def sunlit_box(roof: Callable[[], bpy.types.Material]) -> bpy.types.Scene:
    """A new scene: a grey box (1.5 m) on a grey floor under a sun of angle 0 (3 W/m², 25° from
    the zenith) and a black world, with a 6 m roof of the material ``roof()`` makes 3 m above
    the floor; no camera yet."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    add_primitive("plane", grey, size=40)
    add_primitive("cube", grey, size=1.5, location=(0, 0, 0.75))
    add_primitive("plane", roof(), size=6, location=(0, 0, 3.0))
    add_sun(scene, (25, 0, 30))
    scene.world = bpy.data.worlds.new("Black")
    return scene


def lamp_over_floor(kind: str, power: float, location: tuple, rotation: tuple,
                    size: int) -> bpy.types.Object:
    """A new scene: a grey floor (8 m) and box (0.8 m) under one light of ``kind`` and
    ``power`` at ``location``, turned by Euler ``rotation`` (degrees; an area light is a
    0.6 × 0.4 m rectangle), a black world and a camera 5 m above the floor looking down
    (size × size pixels). Returns the light."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    add_primitive("plane", grey, size=8)
    add_primitive("cube", grey, size=0.8, location=(-0.4, 0.2, 0.4))
    plain_world(scene, (0.0, 0.0, 0.0))
    add_camera(scene, size, location=(0, 0, 5))
    data = bpy.data.lights.new("Lamp", kind)
    data.energy = power
    if kind == "AREA":
        data.shape, data.size, data.size_y = "RECTANGLE", 0.6, 0.4
    light = bpy.data.objects.new("Lamp", data)
    light.location, light.rotation_euler = location, tuple(math.radians(a) for a in rotation)
    scene.collection.objects.link(light)
    return light
