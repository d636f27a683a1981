"""The Mist, Position and Depth passes against Cycles': a floor, a box and a sphere from 2 to 12 m
away (the world's mist from 3 m over 6 m, each falloff), through the compositor as a user
would read them; Cycles: 16 samples, a one-pixel box filter. Mist is the samples' mean, so
it differs only at edges; Position and Depth are one sample's, at the pixel's centre
(measured: Position as the mean over the pixel put 5.5 % of pixels more than 5 cm off, as the
nearest supersample 35 %; Depth as the nearest supersample, VPL GI's before, 44 %)."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from devtools import metrics
from tests.blender.rendering import (
    add_camera,
    add_primitive,
    add_sun,
    configure_cycles,
    plain_world,
    render_linear,
    shader_material,
)
from tests.blender.versions import compositor_output

SIZE = 48


def passes_scene() -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    add_primitive("plane", grey, size=30)
    add_primitive("cube", grey, size=1.0, location=(0.8, 3.0, 0.5))
    add_primitive("uv_sphere", grey, radius=1.0, location=(-1.5, 9.0, 1.0))
    add_sun(scene, (40, 0, 30))
    plain_world(scene, (0.2, 0.3, 0.5))
    add_camera(scene, SIZE, location=(0, -1.0, 1.5), rotation=(math.radians(80), 0, 0))
    return scene


def rendered_pass(scene: bpy.types.Scene, engine: str, name: str, path) -> np.ndarray:
    """The view layer's ``name`` pass (the Render Layers node's socket) as rendered by
    ``engine``, routed to the compositor's output."""
    layer = scene.view_layers[0]
    layer.use_pass_mist = layer.use_pass_position = True
    scene.render.engine = engine
    tree, output = compositor_output(scene)
    node = tree.nodes.new("CompositorNodeRLayers")
    tree.links.new(node.outputs[name], output)
    return render_linear(scene, engine, path)[..., :3]


@pytest.mark.parametrize("falloff", ["QUADRATIC", "LINEAR", "INVERSE_QUADRATIC"])
def test_the_mist_pass_is_cycles(blender, tmp_path, falloff):
    scene = passes_scene()
    mist = scene.world.mist_settings
    mist.start, mist.depth, mist.falloff = 3.0, 6.0, falloff
    configure_cycles(scene, 16)
    reference = rendered_pass(scene, "CYCLES", "Mist", tmp_path / "cycles.exr")
    ours = rendered_pass(scene, "VPL_GI", "Mist", tmp_path / "ours.exr")
    error = np.abs(ours - reference)
    print(f"mist ({falloff.lower()}) vs Cycles: mean abs {error.mean():.4f}, "
          f"pixels over 0.02: {(error.max(axis=2) > 0.02).mean():.3f}")
    assert reference.min() < 0.5 and reference.max() == pytest.approx(1.0)  # a range of mist
    assert error.mean() < 0.004
    assert (error.max(axis=2) > 0.02).mean() < 0.03  # edges only


@pytest.mark.parametrize("name", ["Position", "Depth"])
def test_the_position_and_depth_passes_are_cycles(blender, tmp_path, name):
    scene = passes_scene()
    scene.view_layers[0].use_pass_z = True
    configure_cycles(scene, 16)
    reference = rendered_pass(scene, "CYCLES", name, tmp_path / "cycles.exr")
    ours = rendered_pass(scene, "VPL_GI", name, tmp_path / "ours.exr")
    error = np.linalg.norm(ours - reference, axis=2)
    print(f"{name.lower()} vs Cycles: mean {error.mean():.4f} m, pixels over 5 cm: "
          f"{(error > 0.05).mean():.3f}")
    assert error.mean() < 0.005
    assert (error > 0.05).mean() < 0.01


def test_the_ambient_occlusion_pass_is_cycles(blender, tmp_path):
    """AO with the world's distance at 1 m (the box's and sphere's contact with the floor,
    the floor under them): VPL GI's 18 rays a pixel against Cycles' one a sample (256). Where
    Cycles' AO is below 0.95, the mean error against what no occlusion (1) would be off."""
    from addon.blender_compat import pass_name

    scene = passes_scene()
    scene.world.light_settings.distance = 1.0
    scene.view_layers[0].use_pass_ambient_occlusion = True
    configure_cycles(scene, 256)
    reference = rendered_pass(scene, "CYCLES", pass_name("AO"), tmp_path / "cycles.exr")
    ours = rendered_pass(scene, "VPL_GI", pass_name("AO"), tmp_path / "ours.exr")
    occluded = (reference[..., 0] > 0) & (reference[..., 0] < 0.95)
    error = np.abs(ours - reference)[occluded].mean()
    unoccluded = np.abs(1.0 - reference)[occluded].mean()
    shift = ours[occluded].mean() - reference[occluded].mean()
    print(f"AO pass: mean {ours.mean():.4f} (Cycles {reference.mean():.4f}); where occluded "
          f"({occluded.mean():.3f} of pixels) mean {shift:+.4f} off, mean abs error "
          f"{error:.4f} (no occlusion: {unoccluded:.4f}); relRMSE "
          f"{metrics.relative_rmse(ours, reference):.4f}")
    assert occluded.mean() > 0.05  # occlusion to see
    assert abs(ours.mean() / reference.mean() - 1.0) < 0.02
    assert abs(shift) < 0.1 * unoccluded  # no bias: the rays' noise averages out
    assert error < 0.4 * unoccluded  # per pixel, within the rays' noise


@pytest.mark.parametrize("transparent", [False, True])
def test_the_environment_pass_is_cycles(blender, tmp_path, transparent):
    """The world where the camera sees it (a colour, and an environment map's sky), with the
    film transparent or not."""
    from addon.blender_compat import pass_name

    scene = passes_scene()
    scene.render.film_transparent = transparent
    scene.view_layers[0].use_pass_environment = True
    configure_cycles(scene, 16)
    reference = rendered_pass(scene, "CYCLES", pass_name("Env"), tmp_path / "cycles.exr")
    ours = rendered_pass(scene, "VPL_GI", pass_name("Env"), tmp_path / "ours.exr")
    error = np.abs(ours - reference).max(axis=2)
    print(f"Environment pass (transparent film: {transparent}): sky {reference.max():.3f}, "
          f"pixels off by over 0.01: {(error > 0.01).mean():.4f}")
    assert reference.max() > 0.1 and (reference.max(axis=2) == 0).mean() > 0.3
    assert np.median(error) < 1e-4 and (error > 0.01).mean() < 0.03  # the horizon's pixels
