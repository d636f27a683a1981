"""The Principled BSDF's specular layers against Cycles (same scene, seeded, small images).

- the Cornell box with Blender's default Principled material (Roughness 0.5, IOR 1.5, Specular
  IOR Level 0.5) on every surface, direct light (the direct-light test's bounds) and with
  indirect light (Cycles: as many glossy as diffuse bounces, Filter Glossy 0);
- a glossy floor (roughness 0.3 and 0.5) under an area light, next to a coloured wall;
- a metallic sphere under a point light (a Principled BSDF, and a Glossy BSDF).

Each case is also rendered with the specular layer removed from VPL GI's material table
(``without_specular``): that image must fail the bounds the real one passes, so a test cannot
pass with the glossy lobe or the diffuse attenuation missing. The measured numbers are in
docs/measurements.md (the command there prints them).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import bpy
import numpy as np
import pytest

from tests.blender.rendering import (
    add_camera,
    configure_cycles,
    open_scene,
    render_linear,
    shader_material,
)
from tests.blender.test_cycles_direct import errors
from tests.blender.versions import ensure_nodes

SIZE = 64
CYCLES_SAMPLES = 256


def set_principled(material, roughness: float = 0.5, metallic: float = 0.0,
                   level: float = 0.5, ior: float = 1.5) -> None:
    """The material's Principled BSDF with Blender's defaults for its specular inputs."""
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Specular IOR Level"].default_value = level
    bsdf.inputs["IOR"].default_value = ior


def principled_material(name: str, color: tuple[float, float, float], roughness: float,
                        **specular: float) -> bpy.types.Material:
    """A new Principled material of base ``color`` with ``set_principled``'s inputs."""
    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*color, 1.0)
    set_principled(material, roughness, **specular)
    return material


@pytest.fixture
def without_specular(monkeypatch):
    """Calling it makes VPL GI render every material without its specular layer."""
    from addon.core.scene import principled

    def remove() -> None:
        monkeypatch.setattr(principled, "specular_row",
                            lambda *args: np.zeros(principled.SPECULAR_COLUMNS, np.float32))
    return remove


def specular_rows_from(monkeypatch, kept: int) -> Callable[[], None]:
    """A function that makes VPL GI build every specular row from ``principled.specular_row``'s
    first ``kept`` arguments (the layers past them left out)."""
    from addon.core.scene import principled

    specular_row = principled.specular_row

    def remove() -> None:
        monkeypatch.setattr(principled, "specular_row", lambda *args: specular_row(*args[:kept]))
    return remove


def compare(scene, tmp_path, without_specular, bounds, label: str,
            left_out: str = "the specular layer") -> None:
    """Render with both engines, check the bounds, and check that leaving ``left_out`` out
    (``without_specular`` does) breaks at least one of them."""
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    ours = render_linear(scene, "VPL_GI", tmp_path / "vpl_gi.exr")
    assert np.isfinite(ours).all()
    measured = errors(ours, reference)
    without_specular()
    lambert = errors(render_linear(scene, "VPL_GI", tmp_path / "without.exr"), reference)
    print(f"{label}: energy {measured[0]:+.4f} interior relRMSE {measured[1]:.4f} overall "
          f"relRMSE {measured[2]:.4f}; without {left_out}: energy {lambert[0]:+.4f} "
          f"interior {lambert[1]:.4f} overall {lambert[2]:.4f}")
    energy_bound, interior_bound, overall_bound = bounds
    assert abs(measured[0]) < energy_bound
    assert measured[1] < interior_bound
    assert measured[2] < overall_bound
    assert abs(lambert[0]) >= energy_bound or lambert[1] >= interior_bound \
        or lambert[2] >= overall_bound


def default_principled_cornell(size: int):
    scene = open_scene("cornell_box", size)
    for material in {s.material for o in scene.objects for s in o.material_slots
                     if s.material}:
        set_principled(material)
    return scene


def test_cornell_default_principled_direct(blender, tmp_path, without_specular):
    scene = default_principled_cornell(SIZE)
    configure_cycles(scene, CYCLES_SAMPLES, bounces=0)
    settings = scene.vpl_gi
    settings.bounces, settings.antialiasing, settings.light_samples = 0, 4, 64
    # the direct-light test's bounds for the Cornell box, the energy's tightened to 1 %
    compare(scene, tmp_path, without_specular, (0.01, 0.025, 0.08), "cornell direct")


def test_cornell_default_principled_indirect(blender, tmp_path, without_specular):
    scene = default_principled_cornell(48)
    configure_cycles(scene, CYCLES_SAMPLES, bounces=4)
    scene.cycles.glossy_bounces = 4
    # Filter Glossy (default 1) roughens glossy lobes after diffuse bounces, a bias of Cycles'
    # own: with it the reference measured 2 % darker than with 0 (docs/measurements.md)
    scene.cycles.blur_glossy = 0.0
    settings = scene.vpl_gi
    settings.antialiasing, settings.light_samples, settings.interleave = 2, 64, "4"
    settings.visibility, settings.clamp_distance, settings.vpl_count = "exact", 0.0, 2048
    settings.bounces = 4
    # VPLs reflect glossily too (glossy point emitters); measured in docs/measurements.md
    compare(scene, tmp_path, without_specular, (0.01, 0.07, 0.11), "cornell indirect")


def floor_scene(bpy, roughness: float):
    """A grey glossy floor and a red diffuse wall under a tilted area light, seen at a grazing
    angle so the light's reflection lies in the image."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=8.0)
    bpy.context.object.data.materials.append(
        principled_material("Floor", (0.5, 0.5, 0.5), roughness))
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 2.0, 2.0),
                                     rotation=(math.pi / 2, 0.0, 0.0))
    bpy.context.object.data.materials.append(
        principled_material("Wall", (0.6, 0.1, 0.1), 1.0, level=0.0))
    lamp = bpy.data.lights.new("Area", "AREA")
    lamp.energy, lamp.size = 300.0, 0.5
    light = bpy.data.objects.new("Area", lamp)
    light.location = (0.0, 1.0, 2.5)
    light.rotation_euler = (math.radians(-20), 0.0, 0.0)
    scene.collection.objects.link(light)
    add_camera(scene, SIZE, (0.0, -4.0, 1.5), (math.radians(72), 0.0, 0.0))
    return scene


@pytest.mark.parametrize("roughness", [0.3, 0.5])
def test_glossy_floor_under_area_light(blender, tmp_path, without_specular, roughness):
    scene = floor_scene(blender, roughness)
    configure_cycles(scene, 256, bounces=0)
    settings = scene.vpl_gi
    settings.bounces, settings.antialiasing, settings.light_samples = 0, 2, 64
    compare(scene, tmp_path, without_specular, (0.01, 0.02, 0.04), f"floor {roughness}")


def glossy_bsdf(name: str, color: tuple[float, float, float], roughness: float
                ) -> bpy.types.Material:
    """A Glossy BSDF material (Blender's default distribution, Multiscatter GGX)."""
    return shader_material(name, "ShaderNodeBsdfGlossy", Color=(*color, 1.0),
                           Roughness=roughness)


def floor_with_two_bounces(scene) -> None:
    """The floor scene set up for two bounces: Cycles with as many glossy bounces and Filter
    Glossy 0, VPL GI with 4096 VPLs, exact visibility and no clamp."""
    configure_cycles(scene, 256, bounces=2)
    scene.cycles.glossy_bounces = 2
    scene.cycles.blur_glossy = 0.0
    settings = scene.vpl_gi
    settings.bounces, settings.antialiasing, settings.light_samples = 2, 2, 64
    settings.visibility, settings.clamp_distance, settings.vpl_count = "exact", 0.0, 4096


def sphere_scene(bpy, material: Callable[[], bpy.types.Material]):
    """A smooth sphere of the ``material`` it makes (in a new, empty file) under a point
    light, a black world, direct light only (Cycles 256 samples; VPL GI antialiasing 4, 64
    light samples)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=64, ring_count=32)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(material())
    lamp = bpy.data.lights.new("Point", "POINT")
    lamp.energy, lamp.shadow_soft_size = 500.0, 0.0
    light = bpy.data.objects.new("Point", lamp)
    light.location = (2.0, -3.0, 3.0)
    scene.collection.objects.link(light)
    add_camera(scene, SIZE, (0.0, -4.0, 0.0), (math.pi / 2, 0.0, 0.0))
    configure_cycles(scene, 256, bounces=0)
    settings = scene.vpl_gi
    settings.bounces, settings.antialiasing, settings.light_samples = 0, 4, 64
    return scene


@pytest.mark.parametrize("material", ["principled", "glossy_bsdf"])
def test_metallic_sphere(blender, tmp_path, without_specular, material):
    """A Principled BSDF of Metallic 1, and a Glossy BSDF (rendered as one)."""
    scene = sphere_scene(blender, lambda: principled_material(
        "Metal", (0.9, 0.6, 0.3), 0.4, metallic=1.0) if material == "principled"
        else glossy_bsdf("Metal", (0.9, 0.6, 0.3), 0.4))
    # a black world: outside the highlight the image is black, so the overall error counts
    compare(scene, tmp_path, without_specular, (0.01, 0.03, 0.03),
            f"metallic sphere, {material}")


def fresnel_mix(fac: str) -> bpy.types.Material:
    """A blue Diffuse BSDF and a white Glossy BSDF (roughness 0.4) in a Mix Shader whose Fac
    is a Fresnel node's (IOR 1.45) or a Layer Weight's Fresnel output (Blend 0.3)."""
    material = bpy.data.materials.new("Plastic")
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.1, 0.25, 0.8, 1.0)
    glossy = nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.4
    mix = nodes.new("ShaderNodeMixShader")
    if fac == "fresnel":
        weight = nodes.new("ShaderNodeFresnel")
        weight.inputs["IOR"].default_value = 1.45
    else:
        weight = nodes.new("ShaderNodeLayerWeight")
        weight.inputs["Blend"].default_value = 0.3
    links.new(weight.outputs["Fac" if fac == "fresnel" else "Fresnel"], mix.inputs["Fac"])
    links.new(diffuse.outputs[0], mix.inputs[1])
    links.new(glossy.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], nodes["Material Output"].inputs["Surface"])
    return material


@pytest.mark.parametrize("fac", ["fresnel", "layer_weight"])
def test_diffuse_and_glossy_mixed_by_their_fresnel(blender, tmp_path, without_specular, fac):
    """Plastic as materials made before the Principled BSDF build it, rendered as a Principled
    BSDF of that IOR (before stop 67: the viewport colour, with a warning). Measured (bpy 4.5):
    energy +1.2 %, relRMSE 2.2 % inside, 11 % overall (the lit silhouette's pixels); without
    the specular layer 15–16 % inside."""
    scene = sphere_scene(blender, lambda: fresnel_mix(fac))
    compare(scene, tmp_path, without_specular, (0.02, 0.05, 0.15), f"fresnel mix, {fac}")


@pytest.mark.parametrize("roughness, inside", [(0.1, False), (0.2, True)])
def test_minimum_roughness(blender, tmp_path, monkeypatch, roughness, inside):
    """principled.MIN_ROUGHNESS is where the glossy floor with one bounce (light samples and
    VPLs are points) stays within the Cornell box direct test's overall bound, 8 %: rendered
    unclamped, roughness 0.2 does (measured 6.6 %), 0.1 does not (14.0 %)."""
    from addon.core.scene import principled
    assert principled.MIN_ROUGHNESS == 0.2
    monkeypatch.setattr(principled, "MIN_ROUGHNESS", 0.0)
    scene = floor_scene(blender, roughness)
    configure_cycles(scene, 256, bounces=1)
    scene.cycles.glossy_bounces = 1
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    settings = scene.vpl_gi
    settings.bounces, settings.antialiasing, settings.light_samples = 1, 2, 64
    energy, interior, overall = errors(render_linear(scene, "VPL_GI", tmp_path / "v.exr"),
                                       reference)
    print(f"roughness {roughness} unclamped, 1 bounce: energy {energy:+.4f} interior relRMSE "
          f"{interior:.4f} overall relRMSE {overall:.4f}")
    assert (overall < 0.08) == inside
