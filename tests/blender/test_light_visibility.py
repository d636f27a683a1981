"""Ray visibility of light objects: a light hidden from diffuse rays lights no diffuse surface
in Cycles (measured with 4.5: the light_point scene renders black at 0 and 2 bounces), nor in
VPL GI; in a scene with other lights it is as if it were not there."""

from __future__ import annotations

import numpy as np

from addon.export import export_scene
from tests.blender.rendering import configure_cycles, open_scene, render_linear


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
