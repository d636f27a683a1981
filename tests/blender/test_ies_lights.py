"""Lights with an IES profile (an IES Texture's Fac as the Emission's Strength) against Cycles:
a tilted point light with a profile that differs all round, a rotationally symmetric
downlight (one horizontal angle: Cycles 4.x's spline bulges by up to 12.5 % at 180° there,
5.x's does not), a spot, a sphere light, an area light and a sun (its light the profile's
straight down; direct light, 64², 64 samples), and
an uplight whose light reaches the floor only off the ceiling (one bounce: the VPLs' paths
drawn from the profile). Each case also renders the light without its profile (the IES
Texture unlinked), which must miss Cycles by far more. The profile is tests/core/builders.py's
``profile_text``.

Measured (bpy 4.5 and 5.3, llvmpipe): energy within 0.5 % and relRMSE 0.6–1.7 % in direct
light (the downlight with 5.x's rule on 4.5: −6.7 % and 10.6 %), the uplight 0.5 % and
4.3 %; without the profiles relRMSE 99–129 %. Cycles 4.x gives a sun with an IES Strength
1.0 % less light than its profile straight down (whatever its rotation; 5.3: +0.04 %), which
its bounds allow.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import bpy
import numpy as np
import pytest

from addon.blender_compat import ensure_nodes
from addon.export_lights import export_light
from tests.blender.rendering import (
    add_primitive,
    assert_near_cycles,
    configure_cycles,
    lamp_over_floor,
    render_linear,
)
from tests.core.builders import downlight_text, profile_text

SIZE, SAMPLES = 64, 64


@dataclass(frozen=True)
class Case:
    kind: str
    power: float
    location: tuple[float, float, float]
    rotation: tuple[float, float, float]  # degrees
    radius: float = 0.0
    upward: bool = False
    bounces: int = 0
    strength: float = 1.0  # the IES Texture's own Strength
    text: Callable[[bool], str] = profile_text  # the profile (its argument: upward)
    bounds: tuple[float, float] = (0.01, 0.025)


CASES = {
    "point, tilted 25°": Case("POINT", 300.0, (0.5, -0.3, 1.8), (25, 10, 40)),
    "downlight of one horizontal angle, tilted 25°": Case(
        "POINT", 300.0, (0.5, -0.3, 1.8), (25, 10, 40), text=lambda _: downlight_text()),
    "spot of 120°, IES Strength 2": Case("SPOT", 150.0, (0.2, 0.1, 2.2), (10, 0, 70),
                                         strength=2.0),
    "point of radius 0.2 m": Case("POINT", 300.0, (0.5, -0.3, 1.8), (0, 0, 30), radius=0.2),
    "area 0.6 × 0.4 m": Case("AREA", 400.0, (0.3, -0.2, 2.2), (20, 0, 0)),
    "sun, tilted 30°": Case("SUN", 0.05, (0, 0, 3), (30, 0, 50), bounds=(0.015, 0.025)),
    "uplight under a ceiling (one bounce)": Case("POINT", 600.0, (0.6, 0.2, 1.0), (0, 0, 20),
                                                 upward=True, bounces=1,
                                                 bounds=(0.015, 0.07)),
}


def _scene(case: Case) -> bpy.types.Object:
    """``lamp_over_floor`` with the light's IES profile (and a ceiling for the uplight)."""
    light = lamp_over_floor(case.kind, case.power, case.location, case.rotation, SIZE)
    if case.upward:  # a ceiling the camera sees through: its back faces it
        grey = bpy.data.materials["Grey"]
        ceiling = add_primitive("plane", grey, size=8, location=(0, 0, 2.5))
        ceiling.rotation_euler = (math.pi, 0.0, 0.0)
        ceiling.visible_camera = False
    data = light.data
    if case.kind in ("POINT", "SPOT"):
        data.shadow_soft_size = case.radius
    if case.kind == "SPOT":
        data.spot_size = math.radians(120)
    ensure_nodes(data)
    tree = data.node_tree
    text = bpy.data.texts.new("profile.ies")
    text.write(case.text(case.upward))
    ies = tree.nodes.new("ShaderNodeTexIES")
    ies.mode, ies.ies = "INTERNAL", text
    ies.inputs["Strength"].default_value = case.strength
    tree.links.new(ies.outputs["Fac"], tree.nodes["Emission"].inputs["Strength"])
    return light


@pytest.mark.parametrize("name", list(CASES))
def test_ies_light_matches_cycles(blender, tmp_path, name):
    case = CASES[name]
    light = _scene(case)
    scene = bpy.context.scene
    configure_cycles(scene, SAMPLES, bounces=case.bounces)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")[..., :3]
    scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = case.bounces, 4
    scene.vpl_gi.light_samples = SAMPLES
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")[..., :3]
    tree = light.data.node_tree
    for link in list(tree.nodes["Emission"].inputs["Strength"].links):
        tree.links.remove(link)
    without = render_linear(scene, "VPL_GI", tmp_path / "without.exr")[..., :3]
    assert_near_cycles(name, ours, reference, case.bounds, without, "without its profile")


def test_unreadable_ies_file_warns_and_renders_the_plain_light(blender, tmp_path):
    """An IES Texture whose file is missing, or not a profile: the light at its own power,
    with one warning that names the light, the file and why, and what Cycles does (a light
    100 times as bright: measured with 4.5 and 5.3)."""
    light = _scene(CASES["point, tilted 25°"])
    ies = light.data.node_tree.nodes["IES Texture"]
    ies.mode = "EXTERNAL"
    broken = tmp_path / "broken.ies"
    broken.write_text("IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 3 1 3 2 0 0 0\n1 1 120\n0 45 90\n")
    cycles = "Cycles lights it 100 times as bright"
    for path, why in ((tmp_path / "missing.ies",
                       f"cannot be read (No such file or directory: {cycles})"),
                      (broken, f"is not a profile Cycles reads (photometric type 3 (Cycles "
                               f"reads types B and C): {cycles})")):
        ies.filepath = str(path)
        warnings: list[str] = []
        exported = export_light(light, np.eye(4), warnings)
        assert exported.profile is None and exported.power == pytest.approx(300.0)
        assert warnings == [f"light 'Lamp': its IES file '{path}' {why}; rendered without "
                            f"its nodes (only an Emission node of constant or Blackbody "
                            f"colour and constant, IES or Light Falloff strength is read)"]
