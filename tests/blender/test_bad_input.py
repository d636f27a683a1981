"""Bad scene input through the engine (F12's path): one clear error, or a warning and a
finished, finite frame (issue 19). The command line's rows are in test_cli.py."""

from __future__ import annotations

import numpy as np
import pytest

import addon.engine
from tests.blender.rendering import render_linear
from tests.blender.test_export import add_light, add_plane, new_scene
from tests.blender.test_textures import textured_material, with_uvs


def lit_plane_scene(bpy):
    """A 3 m plane under a sun, seen from above, one bounce with exact visibility."""
    scene = new_scene(bpy, 16)
    scene.vpl_gi.bounces, scene.vpl_gi.vpl_count, scene.vpl_gi.visibility = 1, 16, "exact"
    plane = add_plane(bpy, "Plane", 3.0)
    add_light(bpy, "SUN", 2.0)
    return scene, plane


def render(scene, tmp_path) -> tuple[np.ndarray, list[str]]:
    """The finished frame and its warnings; fails on an error."""
    image = render_linear(scene, "VPL_GI", tmp_path / "frame.exr")
    assert addon.engine.monitor.last_error is None, addon.engine.monitor.last_error
    assert np.isfinite(image).all()
    return image, list(addon.engine.monitor.last_warnings)


def render_error(scene, tmp_path) -> str:
    """The engine's error message (Blender raises it from the render operator)."""
    with pytest.raises(RuntimeError):
        render_linear(scene, "VPL_GI", tmp_path / "frame.exr")
    message = addon.engine.monitor.last_error
    assert message and "internal error" not in message
    return message


def test_float_texture_with_nan_and_inf_texels_is_read_as_0_with_one_warning(blender,
                                                                             tmp_path):
    bpy = blender
    scene, plane = lit_plane_scene(bpy)
    image = bpy.data.images.new("Broken", 4, 4, float_buffer=True)
    texels = np.full((4, 4, 4), 0.5, np.float32)
    texels[0, 0, 0], texels[1, 1, 1], texels[2, 2, 2] = np.nan, np.inf, -np.inf
    image.pixels.foreach_set(texels.ravel())
    image.pack()
    with_uvs(plane)
    plane.data.materials.append(textured_material(bpy, "Textured", image,
                                                  **{"Specular IOR Level": 0.0}))
    frame, warnings = render(scene, tmp_path)
    assert warnings == ["image 'Broken': 3 NaN/Inf values read as 0 (as if black there)"]
    assert frame[..., :3].mean() > 0.1


@pytest.mark.parametrize("change, message", [
    ("scale 0", "camera 'Camera' has a transform without an inverse (a scale of 0"),
    ("empty", "the scene camera 'Empty' is not a camera but an object of type Empty"),
    ("clipping", "camera 'Camera' clips everything: its Clip Start (10 m) is not below its "
                 "Clip End (0.5 m)"),
])
def test_camera_that_cannot_be_rendered_from_is_one_clear_error(blender, tmp_path, change,
                                                                message):
    bpy = blender
    scene, _ = lit_plane_scene(bpy)
    if change == "scale 0":
        scene.camera.scale = (0.0, 0.0, 0.0)
    elif change == "clipping":  # Cycles renders it black
        scene.camera.data.clip_start, scene.camera.data.clip_end = 10.0, 0.5
    else:
        empty = bpy.data.objects.new("Empty", None)
        empty.location = (0, 0, 5)
        scene.collection.objects.link(empty)
        scene.camera = empty
    assert render_error(scene, tmp_path).startswith(message)


def test_a_panorama_type_not_rendered_renders_as_perspective_with_a_warning(blender,
                                                                           tmp_path):
    bpy = blender
    scene, _ = lit_plane_scene(bpy)
    scene.camera.data.type = "PANO"
    scene.camera.data.panorama_type = "FISHEYE_LENS_POLYNOMIAL"
    _, warnings = render(scene, tmp_path)
    assert warnings == ["camera 'Camera': its panorama type Fisheye Lens Polynomial is not "
                        "rendered: rendered as a perspective camera of the same lens"]


@pytest.mark.parametrize("focus, fstop, expected", [
    (0.0, 2.8, ["depth of field is not rendered: its focus distance is 0"]),
    (4.0, 0.001, []),  # a lens wider than the scene: capped, with a note, not a warning
])
def test_depth_of_field_of_absurd_lenses_renders_a_finite_frame(blender, tmp_path, focus, fstop,
                                                                expected):
    bpy = blender
    scene, _ = lit_plane_scene(bpy)
    dof = scene.camera.data.dof
    dof.use_dof, dof.focus_distance, dof.aperture_fstop = True, focus, fstop
    frame, warnings = render(scene, tmp_path)
    assert warnings == expected
    assert frame[..., :3].mean() > 0.01


@pytest.mark.parametrize("energy, warning", [
    (-5.0, "light 'PointLight' has negative power (-5 W): rendered as 0 W"),
    (float("inf"), "light 'PointLight' has NaN/Inf settings or transform and was left out"),
])
def test_negative_or_infinite_light_power_is_left_out_with_a_warning(blender, tmp_path, energy,
                                                                     warning, recwarn):
    bpy = blender
    scene, _ = lit_plane_scene(bpy)
    add_light(bpy, "POINT", energy, location=(0, 0, 1))
    bpy.data.objects.remove(bpy.data.objects["SunLight"])
    add_light(bpy, "SUN", 2.0)
    frame, warnings = render(scene, tmp_path)
    assert warnings == [warning]
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    scene.collection.objects.unlink(bpy.data.objects["PointLight"])
    without, _ = render(scene, tmp_path)
    np.testing.assert_array_equal(frame, without)


def test_negative_or_huge_emission_strength_is_rendered_0_or_capped_with_a_warning(blender,
                                                                                 tmp_path):
    bpy = blender
    scene, plane = lit_plane_scene(bpy)
    material = bpy.data.materials.new("Dark")
    material.use_nodes = True
    node = material.node_tree.nodes["Principled BSDF"]
    node.inputs["Emission Color"].default_value = (1, 1, 1, 1)
    node.inputs["Emission Strength"].default_value = -3.0
    plane.data.materials.append(material)
    _, warnings = render(scene, tmp_path)
    assert "material 'Dark': emission (-3.0, -3.0, -3.0) is negative or not finite: rendered as " \
           "0 there" in warnings
    node.inputs["Emission Strength"].default_value = 1e38  # its light overflowed to Inf
    _, warnings = render(scene, tmp_path)
    assert [w for w in warnings if "Dark" in w] == [
        "material 'Dark': emission (9.999999680285692e+37, 9.999999680285692e+37, "
        "9.999999680285692e+37) capped to 1e+30 (its light would overflow 32-bit floats)"]


def test_a_nan_base_colour_or_world_is_black_there_with_a_warning(blender, tmp_path):
    """A NaN in a material's base colour, or in the world's strength, blackens that alone
    (before stop 66: the colour silently, the world every pixel, the frame black)."""
    bpy = blender
    scene, plane = lit_plane_scene(bpy)
    material = bpy.data.materials.new("Broken")
    material.use_nodes = True
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = \
        (float("nan"), 0.5, 0.5, 1.0)
    plane.data.materials.append(material)
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = float("nan")
    scene.world = world
    frame, warnings = render(scene, tmp_path)
    assert warnings == [
        "world 'Sky': its colour × strength (nan, nan, nan) is negative or not finite: "
        "rendered black",
        "material 'Broken': base colour (nan, 0.5, 0.5) is not finite: rendered as 0 there"]
    red, green = frame[..., 0].mean(), frame[..., 1].mean()  # the sun on (0, 0.5, 0.5): red
    assert green > 0.05 and red < 0.5 * green  # only from the Principled BSDF's specular


# -- random command lines on random bad scenes (hypothesis) -------------------------------------

# Good values repeat, so that most examples pass the checks and render; hypothesis starts
# from the first of each (a perspective camera, an outlier at 1e4 m, an EXR: a render whose
# energy is compared).
CAMERAS = ["perspective", "orthographic", "perspective", "panoramic", "scale 0", "empty"]
OUTLIERS = [1e4, 1e30, None]
ENERGIES = [100.0, 100.0, -5.0, float("inf")]
OUTPUTS = [".exr", ".exr", ".exr", ".png", ".jpg", ".gif", "folder"]
RESOLUTIONS = [None, None, None, "16x12", "1x1", "12xbig"]
PERCENTAGES = [None, None, None, 100, 1]
SETTINGS = [None, None, "visibility=exact", "visibility=ism", "ism_resolution=7",
            "bounces=-1", "clamp_distance=0.5"]
ENERGY_BOUND = 0.01  # mean of an image with a far outlier against the one without


def build_scene(bpy, camera: str, outlier: float | None, energy: float):
    """A lit plane and a box under a point light (and a sun), with the given camera; with a
    1 m cube ``outlier`` metres away."""
    from tests.blender.test_export import add_mesh

    scene = new_scene(bpy, 16)
    scene.vpl_gi.bounces, scene.vpl_gi.vpl_count = 2, 16
    add_plane(bpy, "Floor", 3.0)
    add_mesh(bpy, "Box", [(x, y, z) for z in (0, 0.6) for y in (-0.3, 0.3) for x in (-0.3, 0.3)],
             [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
              (1, 5, 7, 3)], location=(0.5, 0, 0))
    add_light(bpy, "POINT", energy, location=(-0.5, 0.5, 1.5))
    add_light(bpy, "SUN", 0.2)
    data = scene.camera.data
    if camera == "perspective" or camera == "panoramic":
        data.type = "PERSP" if camera == "perspective" else "PANO"
    elif camera == "scale 0":
        scene.camera.scale = (1.0, 0.0, 1.0)
    elif camera == "empty":
        empty = bpy.data.objects.new("Empty", None)
        empty.location = (0, 0, 5)
        scene.collection.objects.link(empty)
        scene.camera = empty
    if outlier is not None:
        add_mesh(bpy, "Far", [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)],
                 [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                  (1, 5, 7, 3)], location=(outlier, 0, 0))
    return scene


def cli_case(bpy, folder, case: dict, outlier: float | None):
    """Save the case's scene and run the command line on it: (result, output path)."""
    from tests.blender.test_cli import run_cli

    build_scene(bpy, case["camera"], outlier, case["energy"])
    blend = folder / f"scene_{outlier}.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    out = folder / ("out" if case["output"] == "folder" else f"out_{outlier}{case['output']}")
    out.mkdir(exist_ok=True) if case["output"] == "folder" else None
    args = ["render", str(blend), "-o", str(out), "--set", "antialiasing=1"]
    if case["resolution"]:
        args += ["-r", case["resolution"]]
    if case["percentage"]:
        args += ["-p", str(case["percentage"])]
    if case["setting"]:
        args += ["--set", case["setting"]]
    return run_cli(*args), out


def mean_of(bpy, path) -> float:
    image = bpy.data.images.load(str(path))
    try:
        pixels = np.empty(len(image.pixels), np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    assert np.isfinite(pixels).all()
    return float(pixels.reshape(-1, 4)[:, :3].mean())


def test_random_bad_scenes_and_command_lines_end_cleanly(blender, tmp_path):
    """Property (hypothesis, derandomised: 2 examples and 2 fixed ones with far outliers): a
    degenerate camera, a far outlier, negative or infinite light power, with random
    command-line arguments, good and bad: exit code 0 or 2 (130 is Ctrl-C's, test_cli.py),
    never a traceback; a finished EXR is finite and its mean within ENERGY_BOUND of the same
    scene without the outlier."""
    import hypothesis
    from hypothesis import strategies as st

    codes: list[int] = []
    compared: list[float] = []  # relative energy changes the outliers made
    cases = st.fixed_dictionaries({
        "camera": st.sampled_from(CAMERAS), "outlier": st.sampled_from(OUTLIERS),
        "energy": st.sampled_from(ENERGIES), "output": st.sampled_from(OUTPUTS),
        "resolution": st.sampled_from(RESOLUTIONS), "percentage": st.sampled_from(PERCENTAGES),
        "setting": st.sampled_from(SETTINGS)})

    good = {"energy": 100.0, "output": ".exr", "resolution": None, "percentage": None}

    @hypothesis.settings(max_examples=2, derandomize=True, database=None, deadline=None,
                         suppress_health_check=list(hypothesis.HealthCheck))
    @hypothesis.example({**good, "camera": "perspective", "outlier": 1e30, "setting": None})
    @hypothesis.example({**good, "camera": "orthographic", "outlier": 1e4,
                         "setting": "visibility=exact"})
    @hypothesis.given(cases)
    def check(case: dict) -> None:
        folder = tmp_path / f"case{len(codes)}"
        folder.mkdir()
        result, out = cli_case(blender, folder, case, case["outlier"])
        codes.append(result.returncode)
        assert result.returncode in (0, 2, 130), result.stderr
        assert "Traceback" not in result.stderr, result.stderr
        if result.returncode == 2:
            assert result.stderr.strip().splitlines()[-1].startswith("error: ")
        if result.returncode == 0 and case["output"] == ".exr":
            image_mean = mean_of(blender, out)
            if case["outlier"] is not None:
                base, base_out = cli_case(blender, folder, case, None)
                assert base.returncode == 0, base.stderr
                reference = mean_of(blender, base_out)
                compared.append(abs(image_mean / reference - 1))
                assert compared[-1] <= ENERGY_BOUND

    check()
    assert 0 in codes and 2 in codes and compared, codes  # the examples reach both ends
