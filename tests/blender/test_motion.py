"""The Vector pass against Cycles': a box moving diagonally across the view over a backdrop,
then the camera moving and turning past still boxes (the sky's vectors from its turn alone),
read through the compositor's Render Layers node. Keyframes are linear, so the motion to the
previous and the next frame are alike. Cycles: 16 samples, a one-pixel box filter; its
Vector pass averages a pixel's samples, VPL GI's is the pixel centre's, so they differ at
edges only."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from tests.blender.rendering import (
    add_camera,
    add_primitive,
    add_sun,
    against,
    assert_near_cycles,
    configure_cycles,
    cycles_and_ours,
    plain_world,
    render_linear,
    shader_material,
)
from tests.blender.versions import compositor_output

SIZE = 48


def keyframed(obj: bpy.types.Object, path: str, values: list[tuple[float, float, float]],
              frames: list[int]) -> None:
    """Linear keyframes of ``obj``'s ``path`` at ``frames``."""
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for value, frame in zip(values, frames, strict=True):
        setattr(obj, path, value)
        obj.keyframe_insert(path, frame=frame)


def motion_scene(camera_moves: bool) -> bpy.types.Scene:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    add_primitive("plane", grey, size=8, location=(0, 6, 0), rotation=(math.radians(90), 0, 0))
    box = add_primitive("cube", grey, size=1.0)
    still = add_primitive("cube", grey, size=0.8, location=(1.6, 2.0, -0.8))
    still.rotation_euler = (0.3, 0.2, 0.4)
    add_sun(scene, (40, 0, 30))
    plain_world(scene, (0.2, 0.3, 0.5))
    camera = add_camera(scene, SIZE, location=(0, -4, 0), rotation=(math.radians(90), 0, 0))
    if camera_moves:
        box.location = (-1.0, 1.0, 0.5)
        keyframed(camera, "location", [(-0.4, -4.2, 0.1), (0.4, -3.8, -0.1)], [1, 3])
        keyframed(camera, "rotation_euler", [(math.radians(88), 0, math.radians(-4)),
                                             (math.radians(92), 0, math.radians(4))], [1, 3])
    else:
        keyframed(box, "location", [(-1.2, 1.0, -0.6), (0.6, 1.0, 0.3)], [1, 3])
        keyframed(box, "rotation_euler", [(0, 0, -0.3), (0, 0, 0.3)], [1, 3])
    scene.frame_set(2)
    scene.view_layers[0].use_pass_vector = True
    configure_cycles(scene, 16)
    return scene


def vector_pass(scene: bpy.types.Scene, engine: str, path) -> np.ndarray:
    tree, output = compositor_output(scene)
    layers = tree.nodes.new("CompositorNodeRLayers")
    tree.links.new(layers.outputs["Vector"], output)
    return render_linear(scene, engine, path)


def test_the_vector_pass_is_cycles(blender, tmp_path):
    for camera_moves in (False, True):
        scene = motion_scene(camera_moves)
        reference = vector_pass(scene, "CYCLES", tmp_path / "cycles.exr")
        ours = vector_pass(scene, "VPL_GI", tmp_path / "ours.exr")
        error = np.abs(ours - reference).max(axis=2)
        label = "camera moving" if camera_moves else "a box moving"
        print(f"vector pass, {label}: vectors up to {np.abs(reference).max():.1f} px, "
              f"mean error {error.mean():.4f} px, pixels over 0.5 px: "
              f"{(error > 0.5).mean():.3f}")
        assert np.abs(reference).max() > 3.0  # pixels of motion to see
        assert np.median(error) < 0.01
        assert (error > 0.5).mean() < 0.04  # edges only


def blurred_scene(position: str) -> bpy.types.Scene:
    """A red box crossing the view fast (about 20 pixels over the shutter) and turning, in
    front of a lit backdrop, with motion blur on (shutter 0.5 at ``position``)."""
    scene = motion_scene(False)
    box = bpy.data.objects["Cube"]
    box.active_material = shader_material("Red", "ShaderNodeBsdfDiffuse",
                                          Color=(0.8, 0.1, 0.1, 1))
    keyframed(box, "location", [(-2.0, 1.0, -0.4), (1.6, 1.0, 0.4)], [1, 3])
    scene.frame_set(2)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.5
    scene.render.motion_blur_position = position
    scene.view_layers[0].use_pass_vector = False
    return scene


def blur_renders(scene: bpy.types.Scene, tmp_path) -> tuple[np.ndarray, ...]:
    """The motion-blurred scene by Cycles (64 samples), by VPL GI with 8 passes and with
    one, and by VPL GI without motion blur."""
    scene.vpl_gi.passes = 8
    reference, eight = cycles_and_ours(scene, tmp_path, 64, 0)
    scene.vpl_gi.passes = 1
    one_pass = render_linear(scene, "VPL_GI", tmp_path / "one.exr")
    scene.render.use_motion_blur = False
    return reference, eight, one_pass, render_linear(scene, "VPL_GI", tmp_path / "sharp.exr")


@pytest.mark.parametrize("position", ["CENTER", "START"])
def test_motion_blur_is_cycles(blender, tmp_path, position):
    """Eight passes each see an eighth of the shutter, blurred over it; one pass blurs the
    whole shutter from the frame at its middle (a moving object then hides what its trail
    passes over: measured 7.3–8.2 % against 1.6 % for eight passes)."""
    reference, ours, one_pass, sharp = blur_renders(blurred_scene(position), tmp_path)
    assert_near_cycles(f"motion blur ({position.lower()}), 8 passes", ours, reference,
                       (0.01, 0.025), sharp, "without it", factor=4.0)
    assert_near_cycles(f"motion blur ({position.lower()}), 1 pass", one_pass, reference,
                       (0.02, 0.09), sharp, "without it", factor=1.3)


def test_degenerate_motion_renders_finite_passes(blender, tmp_path):
    """A box scaled to nothing at the previous frame and one flying to a huge distance at the
    next, with motion blur on and the Vector pass asked for: finite passes, no warning
    about non-finite pixels."""
    scene = motion_scene(False)
    box = bpy.data.objects["Cube"]
    keyframed(box, "scale", [(0.0, 0.0, 0.0), (1.0, 1.0, 1.0)], [1, 2])
    far = add_primitive("cube", bpy.data.materials["Grey"], size=0.5, location=(0, 2, 0))
    keyframed(far, "location", [(0.0, 2.0, 0.0), (1e30, 2.0, 0.0)], [2, 3])
    scene.frame_set(2)
    scene.render.use_motion_blur = True
    scene.vpl_gi.passes = 2
    from addon.engine import monitor

    for blurred in (True, False):
        scene.render.use_motion_blur = blurred
        image = vector_pass(scene, "VPL_GI", tmp_path / f"{blurred}.exr")
        assert np.isfinite(image).all() and monitor.last_error is None
        assert not any("non-finite" in w for w in monitor.last_warnings), monitor.last_warnings
    assert np.abs(image).max() > 1.0  # the Vector pass, motion blur off


def deforming_scene() -> bpy.types.Scene:
    """motion_scene's box held still, and in front of it a red flag (a grid facing the
    camera) that a shape key shears sideways over frames 1 to 3: its top moves right and its
    bottom left, about 4 pixels a frame at its edges, while the object stays put."""
    scene = motion_scene(False)
    bpy.data.objects["Cube"].animation_data_clear()
    red = shader_material("Red", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.1, 0.1, 1))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=8, y_subdivisions=8, size=2.0,
                                    location=(0.0, -0.2, 0.0), rotation=(math.radians(90), 0, 0))
    flag = bpy.context.object
    flag.name = "Flag"
    flag.data.materials.append(red)
    flag.shape_key_add(name="Basis")
    shear = flag.shape_key_add(name="Shear")
    for point in shear.data:
        point.co.x += 1.5 * point.co.y
    bpy.context.preferences.edit.keyframe_new_interpolation_type = "LINEAR"
    for value, frame in ((0.0, 1), (1.0, 3)):
        shear.value = value
        shear.keyframe_insert("value", frame=frame)
    scene.frame_set(2)
    return scene


def test_a_deforming_mesh_moves_and_blurs_as_in_cycles(blender, tmp_path):
    """The flag's own vertices move (its object does not): its Vector pass against Cycles',
    where reading the object's motion alone gives none; then motion blur of one pass and of
    eight against Cycles' (deformation blur on, its default). Measured (bpy 4.5): vectors up
    to 12.4 px, mean error 0.36 px where they exceed 1 px; 8 passes 1.7 % relRMSE, one pass
    5.9 %, the sharp frame 7.1 %."""
    scene = deforming_scene()
    reference = vector_pass(scene, "CYCLES", tmp_path / "cycles_vectors.exr")
    ours = vector_pass(scene, "VPL_GI", tmp_path / "ours_vectors.exr")
    moving = np.abs(reference[..., :2]).max(axis=2) > 1.0
    error = np.abs(ours - reference).max(axis=2)
    print(f"vector pass, a deforming mesh: {moving.mean():.3f} of pixels move over 1 px (up "
          f"to {np.abs(reference).max():.1f} px), mean error there {error[moving].mean():.3f}"
          f" px (vectors' mean size {np.abs(reference[moving]).max(axis=1).mean():.2f} px)")
    assert moving.mean() > 0.05 and np.abs(reference).max() > 3.0
    assert np.median(error[moving]) < 0.1
    assert error[moving].mean() < 0.2 * np.abs(reference[moving]).max(axis=1).mean()
    scene = deforming_scene()  # without the compositor's Vector output
    scene.render.use_motion_blur = True
    scene.view_layers[0].use_pass_vector = False
    reference, eight, one_pass, sharp = blur_renders(scene, tmp_path)
    assert_near_cycles("deformation blur, 8 passes", eight, reference, (0.01, 0.025), sharp,
                       "without it", factor=3.0)
    # one pass smears each pixel along its own motion: without the vertices' (the object
    # holds still) it is the sharp frame, 7.1 %; the same flag moved whole instead measures
    # 9.4 % against its sharp 12.5 % (one pass's blur keeps a moving surface too opaque)
    assert_near_cycles("deformation blur, 1 pass", one_pass, reference, (0.01, 0.065), sharp,
                       "without it", factor=1.15)


def test_objects_whose_motion_blur_is_off_stay_sharp(blender, tmp_path):
    """Object Properties › Motion Blur off on the moving box or the moving camera, or
    Deformation off on the sheared flag: rendered as without motion blur (Cycles: the same
    to the bit), also where passes see the scene at other times of the shutter, while
    leaving them on blurs them (the camera by under a pixel at 48²: passes, not one pass's
    smear)."""
    for name, make, toggle, passes in (
            ("Cube", lambda: blurred_scene("CENTER"), "use_motion_blur", 1),
            ("Cube", lambda: blurred_scene("START"), "use_motion_blur", 4),
            ("Camera", lambda: motion_scene(True), "use_motion_blur", 4),
            ("Flag", deforming_scene, "use_deform_motion", 4)):
        scene = make()
        scene.render.use_motion_blur = True
        scene.vpl_gi.passes = passes
        blurred = render_linear(scene, "VPL_GI", tmp_path / "blurred.exr")
        setattr(bpy.data.objects[name].cycles, toggle, False)
        off = render_linear(scene, "VPL_GI", tmp_path / "off.exr")
        scene.render.use_motion_blur = False
        sharp = render_linear(scene, "VPL_GI", tmp_path / "sharp.exr")
        error, blur = against(off, sharp)[1], against(blurred, sharp)[1]
        print(f"{name} with {toggle} off, {passes} pass(es): relRMSE {error:.5f} against "
              f"the sharp frame, blurred {blur:.4f}")
        assert error < 1e-3 and blur > 0.008
