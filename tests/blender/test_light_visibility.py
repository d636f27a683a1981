"""Ray visibility of light objects: a light hidden from diffuse rays lights no diffuse surface
in Cycles (measured with 4.5: the light_point scene renders black at 0 and 2 bounces), nor in
VPL GI; in a scene with other lights it is as if it were not there. A light's Max Bounces
limits how often its light bounces, in both."""

from __future__ import annotations

import numpy as np
import pytest

from addon.export import export_scene
from tests.blender.rendering import (
    against,
    configure_cycles,
    cycles_and_ours,
    open_scene,
    render_linear,
)


def test_light_hidden_from_diffuse_rays_lights_nothing(blender, tmp_path):
    scene = open_scene("light_point", 32)
    light = next(o for o in scene.objects if o.type == "LIGHT")
    light.visible_diffuse = False
    configure_cycles(scene, 16, bounces=2)
    cycles = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    scene.vpl_gi.bounces = 2
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")
    assert cycles[..., :3].max() == 0.0
    assert ours[..., :3].max() == 0.0


def test_hidden_light_is_left_out_of_direct_and_indirect_light(blender, tmp_path):
    scene = open_scene("multi_light", 32)
    scene.vpl_gi.bounces, scene.vpl_gi.vpl_count = 2, 256
    lights = [o for o in scene.objects if o.type == "LIGHT"]
    hidden = lights[0]
    hidden.visible_diffuse = False
    exported = export_scene(blender.context.evaluated_depsgraph_get())
    assert [light.name for light in exported.surface_lights] == [o.name for o in lights[1:]]
    assert not exported.warnings
    with_hidden = render_linear(scene, "VPL_GI", tmp_path / "hidden.exr")
    blender.data.objects.remove(hidden)
    without = render_linear(scene, "VPL_GI", tmp_path / "without.exr")
    np.testing.assert_allclose(with_hidden, without, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("limit", [0, 1])
def test_a_lights_max_bounces_limits_its_light_as_in_cycles(blender, tmp_path, limit):
    """The Cornell box, three bounces (Cycles 64 samples), its light's Max Bounces (Cycles'
    light setting) 0 — direct light only — or 1. Measured (bpy 4.5 and 5.3, llvmpipe, 48²):
    energy −0.2 / +0.2 %, relRMSE 7.9 / 11.4 %; every bounce rendered (before stop 67):
    +72.5 / +18.9 %, 95 / 27 %."""
    scene = open_scene("cornell_box", 48)
    blender.data.objects["Light.Area"].data.cycles.max_bounces = limit
    reference, ours = cycles_and_ours(scene, tmp_path, 64, 3)
    energy, error = against(ours[..., :3], reference[..., :3])
    print(f"light Max Bounces {limit} vs Cycles: energy {energy:+.4f} relRMSE {error:.4f}")
    assert abs(energy) < 0.03
    assert error < 0.2
