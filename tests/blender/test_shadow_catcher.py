"""Shadow catchers against Cycles: a grey floor marked Shadow Catcher under a red box lit by
a sun and a blue sky, its Combined pass with the film opaque and transparent, with and
without the Shadow Catcher pass asked for (which turns Combined into the matte), and the
Shadow Catcher pass itself."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from tests.blender.rendering import (
    add_camera,
    add_primitive,
    add_sun,
    assert_near_where,
    configure_cycles,
    plain_world,
    render_linear,
    shader_material,
)
from tests.blender.versions import compositor_output

SAMPLES = 256


def catcher_scene() -> bpy.types.Scene:
    """The floor (the catcher), the box, the sun and the sky; one diffuse bounce more than
    the box's light needs, 48² pixels."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    configure_cycles(scene, SAMPLES, bounces=2)
    scene.vpl_gi.bounces = 2
    add_camera(scene, 48, (0, -6, 4), (0.98, 0, 0))
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.5, 0.5, 0.5, 1))
    add_primitive("plane", grey, size=10).is_shadow_catcher = True
    red = shader_material("Red", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.1, 0.1, 1))
    add_primitive("cube", red, size=1, location=(0, 0, 0.5))
    add_sun(scene, (40, 0, 30), 3.0)
    plain_world(scene, (0.2, 0.3, 0.5))
    return scene


def differences(ours: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """Mean absolute differences of RGB and of alpha."""
    error = np.abs(ours - reference)
    return float(error[..., :3].mean()), float(error[..., 3].mean())


@pytest.mark.parametrize("with_pass", [False, True])
@pytest.mark.parametrize("transparent", [False, True])
def test_combined_with_a_shadow_catcher_is_cycles(blender, tmp_path, transparent, with_pass):
    """The box over the floor's shadow (alpha the shadow, film transparent; the sky dimmed by
    it, opaque), or over a hole where the Shadow Catcher pass is asked for; the floor as an
    ordinary surface is off by ten times as much or more."""
    scene = catcher_scene()
    scene.render.film_transparent = transparent
    scene.view_layers[0].cycles.use_pass_shadow_catcher = with_pass
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")
    bpy.data.objects["Plane"].is_shadow_catcher = False
    ordinary = render_linear(scene, "VPL_GI", tmp_path / "ordinary.exr")
    rgb, alpha = differences(ours, reference)
    plain_rgb, plain_alpha = differences(ordinary, reference)
    print(f"film transparent {transparent}, Shadow Catcher pass {with_pass}: mean abs RGB "
          f"{rgb:.4f} alpha {alpha:.4f}; as an ordinary surface RGB {plain_rgb:.4f} alpha "
          f"{plain_alpha:.4f}")
    assert np.isfinite(ours).all()
    assert rgb < 0.004 and alpha < 0.006
    assert plain_rgb + plain_alpha > 10 * (rgb + alpha)


def test_the_shadow_catcher_pass_is_cycles(blender, tmp_path):
    """The floor's light with the box over its light without it: the shadow, and the box's
    red bounce above 1 in red."""
    scene = catcher_scene()
    scene.view_layers[0].cycles.use_pass_shadow_catcher = True
    scene.render.engine = "CYCLES"  # the Render Layers node shows the engine's passes
    tree, output = compositor_output(scene)
    layers = tree.nodes.new("CompositorNodeRLayers")
    tree.links.new(layers.outputs["Shadow Catcher"], output)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")[..., :3]
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")[..., :3]
    caught = (np.abs(reference - 1.0) > 0.05).any(axis=-1)  # shadow and bounce
    assert_near_where("Shadow Catcher pass", ours, reference, np.ones_like(ours), caught,
                      (0.01, 0.04), "1 (no shadow)", share=0.03)
    print(f"red bounce: ours {ours[..., 0].max():.3f}, Cycles {reference[..., 0].max():.3f}")
    assert ours[..., 0].max() > 1.03 and reference[..., 0].max() > 1.03
