"""Image textures: CPU sampling in every interpolation and extension, the g-buffer's texture
path against it, the texture variant compiled only when needed, and textures' average colour
for light sampling and VPLs."""

from __future__ import annotations

import moderngl
import numpy as np
import pytest

from addon.core.frame.renderer import Renderer, RenderError
from addon.core.gpu.texture_array import pack
from addon.core.scene import textures as tex
from addon.core.scene.geometry import flatten_instances
from addon.core.scene.model import (
    EXTENSIONS,
    INTERPOLATIONS,
    Instance,
    LightKind,
    Material,
    Mesh,
    Scene,
    Texture,
)
from addon.core.settings import Settings
from tests.core.builders import (
    floor_scene,
    light,
    pixel_centres,
    quad,
    top_down_camera,
    translation,
)

SIZE = 64
EXTENT = 6.0


def textured_quad(half: float, repeat: float = 1.0, z: float = 0.0) -> Mesh:
    """builders.quad with UVs spanning [0, repeat]² over the square."""
    mesh = quad(half, half, z)
    mesh.uvs = ((mesh.positions[:, :2] / half + 1) / 2 * repeat).astype(np.float32)
    return mesh


def image(seed: int, h: int, w: int) -> np.ndarray:
    """Random opaque pixels in steps of 1/255, as Blender's byte images hold them."""
    codes = np.random.default_rng(seed).integers(0, 256, size=(h, w, 4))
    pixels = (codes / 255).astype(np.float32)
    pixels[..., 3] = 1
    return pixels


def test_bilinear_repeat_decodes_srgb_after_interpolation():
    pixels = np.zeros((2, 2, 4), np.float32)
    pixels[0, 0, :3], pixels[0, 1, :3] = 0.2, 1.0  # bottom row: 0.2, 1.0
    texture = Texture("t", pixels, srgb=True)
    uv = np.array([[0.25, 0.25], [0.5, 0.25], [1.25, 0.25], [0.0, 0.25]])
    got = tex.sample(texture, uv)[:, 0]
    # texel centres at u = 0.25 and 0.75; u = 0.5 halfway; u = 0 halfway across the wrap
    expected = tex.decode_srgb(np.array([0.2, 0.6, 0.2, 0.6]))
    np.testing.assert_allclose(got, expected, rtol=1e-6)
    assert tex.decode_srgb(np.array([1.0]))[0] == pytest.approx(1.0)
    assert tex.decode_srgb(np.array([0.5]))[0] == pytest.approx(0.21404, abs=1e-5)


ROW = (0.1, 0.5, 0.9)  # a 1×3 image's red values, left to right
# u → red value per (interpolation, extension), worked out by hand from Cycles' rules (v is the
# row's centre): Closest takes texel floor(3u); Linear blends the texels around 3u − 0.5;
# Cubic is the B-spline (1/6, 4/6, 1/6) at a texel centre, whose rows above and below are
# outside the image with Clip (a factor 4/6).
HAND_VALUES = {
    ("Closest", "REPEAT"): {0.1: 0.1, 0.4: 0.5, -0.1: 0.9, 1.5: 0.5},
    ("Closest", "EXTEND"): {-0.5: 0.1, 1.7: 0.9, 0.4: 0.5},
    ("Closest", "CLIP"): {-0.1: 0.0, 1.01: 0.0, 0.9: 0.9},
    ("Closest", "MIRROR"): {-0.1: 0.1, 1.1: 0.9, -0.5: 0.5, 1.5: 0.5},
    ("Linear", "REPEAT"): {0.0: 0.5, 0.5: 0.5, 1 / 3: 0.3},
    ("Linear", "EXTEND"): {0.0: 0.1, -2.0: 0.1, 1.0: 0.9},
    ("Linear", "CLIP"): {0.0: 0.05, 1.0: 0.45, -0.2: 0.0},
    ("Linear", "MIRROR"): {0.0: 0.1, 1.0: 0.9, -1 / 6: 0.1, -1 / 3: 0.3},
    ("Cubic", "REPEAT"): {1 / 6: 0.3, 0.5: 0.5},
    ("Cubic", "EXTEND"): {1 / 6: 1 / 6, 5 / 6: 5 / 6},
    ("Cubic", "CLIP"): {1 / 6: 0.1, 5 / 6: 4.1 / 6 * 4 / 6, -1.0: 0.0},
    ("Cubic", "MIRROR"): {1 / 6: 1 / 6, 5 / 6: 5 / 6, -1 / 6: 1 / 6, 0.5: 0.5},
}


@pytest.mark.parametrize(("interpolation", "extension"), list(HAND_VALUES))
def test_cpu_sampling_follows_cycles_rules(interpolation, extension):
    pixels = np.ones((1, 3, 4), np.float32)
    pixels[0, :, 0] = ROW
    texture = Texture("row", pixels, interpolation=interpolation, extension=extension)
    cases = HAND_VALUES[interpolation, extension]
    uv = np.array([(u, 0.5) for u in cases])
    np.testing.assert_allclose(tex.sample(texture, uv)[:, 0], list(cases.values()), atol=1e-6)


def test_unknown_sampling_mode_is_refused():
    with pytest.raises(ValueError, match="interpolation 'Smart'"):
        Texture("t", image(0, 2, 2), interpolation="Smart")


def filter_tolerance(ctx: moderngl.Context) -> float:
    """Absolute tolerance of filtered lookups of texels in [0, 1] against the CPU sampler's
    float weights: a software rasteriser (llvmpipe) filters in float; GPUs filter with 8-bit
    subtexel weights (Direct3D's minimum; NVIDIA's H200 was off by up to 1.6e-3), up to 1/512
    of the step between two texels."""
    software = any(name in ctx.info["GL_RENDERER"] for name in ("llvmpipe", "softpipe"))
    return 2e-5 if software else 2e-5 + 1 / 512


def test_gbuffer_samples_every_mode_like_the_cpu(renderer):
    """Twelve quads, one per interpolation and extension, with UVs from −0.8 to 1.9 (so the
    extension matters) on a 5×3 sRGB image: DiffCol equals the CPU sampler at each pixel's
    UV, and the modes give different images."""
    size, extent, half, spacing = 96, 6.0, 0.6, 1.5  # spacing: 24 pixels
    pixels = image(7, 3, 5)
    modes = [(i, e) for i in INTERPOLATIONS for e in EXTENSIONS]
    textures = [Texture(f"{i} {e}", pixels, True, i, e, eight_bit=True) for i, e in modes]
    mesh = quad(half, half)
    mesh.uvs = ((mesh.positions[:, :2] / half + 1) / 2 * 2.7 - 0.8).astype(np.float32)
    centres = [((k % 4 - 1.5) * spacing, (k // 4 - 1) * spacing) for k in range(len(modes))]
    instances = [Instance(mesh, translation(x, y, 0), [Material(t.name, base_color_texture=t)])
                 for t, (x, y) in zip(textures, centres, strict=True)]
    scene = Scene(instances, [], camera=top_down_camera(size, extent))
    frame, _ = renderer.render(scene, Settings(bounces=0, antialiasing=1))
    x, y = pixel_centres(size, extent)
    colours = []
    for texture, (cx, cy) in zip(textures, centres, strict=True):
        inside = (np.abs(x - cx) < half - 0.03) & (np.abs(y - cy) < half - 0.03)
        local = np.stack([x[inside] - cx, y[inside] - cy], axis=1)
        uv = (local / half + 1) / 2 * 2.7 - 0.8
        expected = tex.sample(texture, uv)
        got = frame.passes["DiffCol"][inside]
        np.testing.assert_allclose(got, expected, atol=filter_tolerance(renderer.ctx),
                                   err_msg=texture.name)
        colours.append(got)
    for a in range(len(colours)):  # every mode differs from every other one somewhere
        for b in range(a):
            assert np.abs(colours[a] - colours[b]).max() > 0.05, (modes[a], modes[b])


def test_packing_keeps_images_apart_and_within_their_pages():
    """Shelves of rectangles in pages no larger than the limit: inside their page, none
    overlapping another, a second page where one is full; an image larger than the limit is
    refused."""
    rng = np.random.default_rng(3)
    sizes = [(int(w), int(h)) for w, h in rng.integers(1, 40, size=(60, 2))]
    places, (width, height, pages) = pack(sizes, 64)
    assert width <= 64 and height <= 64 and pages > 1
    cover = np.zeros((pages, height, width), int)
    for (w, h), (x, y, page) in zip(sizes, places, strict=True):
        assert x + w <= width and y + h <= height
        cover[page, y:y + h, x:x + w] += 1
    assert cover.max() == 1 and cover.sum() == sum(w * h for w, h in sizes)
    with pytest.raises(ValueError, match="larger than this GPU's textures"):
        pack([(65, 2)], 64)


def test_textures_of_other_sizes_sample_like_the_cpu(renderer):
    """Three images of different sizes in one frame (each in its own rectangle of the packed
    pages; two 8-bit, held as bytes, one as floats), with UVs from −0.8 to 1.9: each repeats,
    mirrors or extends within its own texels, as the CPU sampler does (a texel of a
    neighbour would show)."""
    size, extent, half = 96, 6.0, 0.6
    textures = [Texture("wide", image(2, 3, 17), True, "Linear", "REPEAT", eight_bit=True),
                Texture("tall", image(3, 11, 2), True, "Cubic", "MIRROR"),
                Texture("small", image(4, 2, 3), False, "Closest", "EXTEND", eight_bit=True)]
    mesh = quad(half, half)
    mesh.uvs = ((mesh.positions[:, :2] / half + 1) / 2 * 2.7 - 0.8).astype(np.float32)
    centres = [(-1.5, 0.0), (0.0, 0.0), (1.5, 0.0)]
    instances = [Instance(mesh, translation(x, y, 0), [Material(t.name, base_color_texture=t)])
                 for t, (x, y) in zip(textures, centres, strict=True)]
    scene = Scene(instances, [], camera=top_down_camera(size, extent))
    frame, _ = renderer.render(scene, Settings(bounces=0, antialiasing=1))
    x, y = pixel_centres(size, extent)
    for texture, (cx, cy) in zip(textures, centres, strict=True):
        inside = (np.abs(x - cx) < half - 0.03) & (np.abs(y - cy) < half - 0.03)
        uv = (np.stack([x[inside] - cx, y[inside] - cy], axis=1) / half + 1) / 2 * 2.7 - 0.8
        np.testing.assert_allclose(frame.passes["DiffCol"][inside], tex.sample(texture, uv),
                                   atol=filter_tolerance(renderer.ctx), err_msg=texture.name)


def test_gbuffer_samples_albedo_and_emission_like_the_cpu():
    """Two textures of different sizes (layer packing), repeated 3× (wrapping), one sRGB:
    DiffCol and Emit equal the CPU sampler at each pixel's UV."""
    albedo = Texture("albedo", image(1, 5, 7), srgb=True)
    glow = Texture("glow", image(2, 3, 2))
    material = Material("m", emission=(2.0, 2.0, 2.0), base_color_texture=albedo,
                        emission_texture=glow)
    half, repeat = 2.5, 3.0
    floor = Instance(textured_quad(half, repeat), np.eye(4), [material])
    scene = Scene([floor], [], camera=top_down_camera(SIZE, EXTENT))
    renderer = Renderer()
    try:
        frame, _ = renderer.render(scene, Settings(bounces=0, antialiasing=1))
        tolerance = filter_tolerance(renderer.ctx)
    finally:
        renderer.release()
    x, y = pixel_centres(SIZE, EXTENT)
    inside = (np.abs(x) < half - 0.05) & (np.abs(y) < half - 0.05)
    uv = ((np.stack([x[inside], y[inside]], axis=1) / half + 1) / 2 * repeat)
    np.testing.assert_allclose(frame.passes["DiffCol"][inside], tex.sample(albedo, uv),
                               atol=tolerance)
    np.testing.assert_allclose(frame.passes["Emit"][inside], 2.0 * tex.sample(glow, uv),
                               atol=2.5 * tolerance)


def test_texture_variant_is_compiled_only_for_textured_scenes():
    plain = floor_scene([light(LightKind.SUN, np.eye(4), power=1.0)], size=8)
    textured = floor_scene([light(LightKind.SUN, np.eye(4), power=1.0)], size=8)
    textured.instances[0] = Instance(textured_quad(5), np.eye(4), [
        Material("t", base_color_texture=Texture("t", image(3, 2, 2)))])
    renderer = Renderer()
    try:
        def variants() -> list[tuple]:
            return [key for key in renderer.gpu.programs._programs
                    if key[:2] == ("gbuffer_vert.glsl", "gbuffer_frag.glsl")]
        renderer.render(plain, Settings(bounces=0, antialiasing=1))
        assert not flatten_instances(plain, []).has_textures
        assert variants() and all(("TEXTURED", 1) not in key[2] for key in variants())
        renderer.render(textured, Settings(bounces=0, antialiasing=1))
        assert flatten_instances(textured, []).has_textures
        assert any(("TEXTURED", 1) in key[2] for key in variants())
    finally:
        renderer.release()


def test_textures_count_with_their_average_for_light_sampling(renderer):
    """An emission-textured lamp lights the floor as a lamp of the texture's average colour;
    its triangles' albedo and emission columns hold the averages too."""
    pixels = image(4, 4, 4)
    texture = Texture("glow", pixels, srgb=True)
    mean = tex.decode_srgb(pixels[..., :3]).reshape(-1, 3).mean(axis=0)
    lamp_mesh = textured_quad(0.3, z=1.5)

    def lamp(material: Material) -> Scene:
        return floor_scene([], extra=[Instance(lamp_mesh, np.eye(4), [material])], size=32)
    textured = Material("lamp", (0, 0, 0), (10.0,) * 3, emission_texture=texture,
                        base_color_texture=texture)
    geometry = flatten_instances(lamp(textured), [])
    np.testing.assert_allclose(geometry.emission[-1], 10 * mean, rtol=1e-5)
    np.testing.assert_allclose(geometry.albedo[-1], mean, rtol=1e-5)
    settings = Settings(bounces=0, antialiasing=1, emission_samples=256)
    ours, _ = renderer.render(lamp(textured), settings)
    flat, _ = renderer.render(lamp(Material("lamp", (0, 0, 0), tuple(10 * mean))), settings)
    np.testing.assert_allclose(ours.passes["DiffDir"], flat.passes["DiffDir"], rtol=1e-4,
                               atol=1e-6)


def test_vpls_take_the_albedo_of_the_texel_they_hit():
    pixels = np.ones((1, 2, 4), np.float32)
    pixels[0, 0, :3], pixels[0, 1, :3] = (0.9, 0.1, 0.1), (0.1, 0.9, 0.1)  # red, green
    texture = Texture("rg", pixels)
    floor = Instance(textured_quad(1.0), np.eye(4), [Material("m", base_color_texture=texture)])
    geometry = flatten_instances(Scene([floor]), [])
    # the quad's triangle 0 lies below the diagonal y = x, triangle 1 above it
    points = np.array([[-0.5, 0.2, 0.0], [0.5, -0.2, 0.0], [0.0, -0.6, 0.0]])
    got = geometry.albedo_at(np.array([1, 0, 0]), points)
    np.testing.assert_allclose(got[:2], [(0.9, 0.1, 0.1), (0.1, 0.9, 0.1)], atol=1e-6)
    np.testing.assert_allclose(got[2], (0.5, 0.5, 0.1), atol=1e-6)  # halfway between texels


def test_vpls_take_the_albedo_of_the_mode_they_sample():
    """albedo_at follows the texture's extension and interpolation: Clip is black outside
    0..1, Closest takes whole texels."""
    pixels = np.ones((1, 2, 4), np.float32)
    pixels[0, 0, :3], pixels[0, 1, :3] = (0.9, 0.1, 0.1), (0.1, 0.9, 0.1)
    points = np.array([[-0.7, -0.8, 0.0], [0.4, -0.8, 0.0]])  # u = x + 1: 0.3 and 1.4; v = 0.2
    albedo = {}
    for interpolation, extension in (("Closest", "CLIP"), ("Linear", "REPEAT")):
        texture = Texture("rg", pixels, interpolation=interpolation, extension=extension)
        floor = Instance(textured_quad(1.0, repeat=2.0), np.eye(4),
                         [Material("m", base_color_texture=texture)])
        geometry = flatten_instances(Scene([floor]), [])
        albedo[interpolation] = geometry.albedo_at(np.array([0, 0]), points)
    np.testing.assert_allclose(albedo["Closest"], [(0.9, 0.1, 0.1), (0, 0, 0)], atol=1e-6)
    # Linear, Repeat: u = 0.3 is 0.9 of texel 0 and 0.1 of texel 1; u = 1.4 (0.4) 0.7 and 0.3
    np.testing.assert_allclose(albedo["Linear"], [(0.82, 0.18, 0.1), (0.66, 0.34, 0.1)],
                               atol=1e-6)


def test_byte_alpha_is_associated_in_integer_bytes_as_cycles():
    """c·a/255 rounded down in byte codes: 204·128/255 = 102.4 → 102, 153·128/255 → 76."""
    pixels = np.array([[[204, 153, 255, 128], [204, 153, 255, 0], [10, 20, 30, 255]]],
                      np.float32) / 255
    got = np.rint(tex.associate_bytes(pixels) * 255)
    np.testing.assert_array_equal(got, [[[102, 76, 128, 128], [0, 0, 0, 0], [10, 20, 30, 255]]])


def test_a_new_sampling_mode_makes_new_vpls():
    """The scene version VPLs are keyed by changes when only a texture's extension does."""
    from addon.core.frame.reuse import SceneVersions

    versions = SceneVersions()
    for extension, expected in (("REPEAT", 1), ("REPEAT", 1), ("CLIP", 2)):
        texture = Texture("t", image(5, 2, 2), extension=extension)
        floor = Instance(textured_quad(1.0), np.eye(4), [Material("m", base_color_texture=texture)])
        versions.note(flatten_instances(Scene([floor]), []))
        assert versions.geometry == expected


def test_bad_normal_maps_render_finite(renderer):
    """A normal map's texels of (0.5, 0.5, 0.5) (no direction), NaN and infinity, and a NaN
    strength: the surface's own normal there, every pixel finite."""
    from addon.core.scene.model import LightKind
    from tests.core.builders import floor_scene, light, rotation_x
    pixels = np.ones((2, 2, 4), np.float32)
    pixels[0, 0, :3], pixels[0, 1, :3], pixels[1, 0, :3] = 0.5, np.nan, np.inf
    bad = Texture("bad normals", pixels, interpolation="Closest")
    sun = light(LightKind.SUN, rotation_x(0.5), power=3.0)
    for strength in (1.0, 0.5, float("nan")):
        scene = floor_scene([sun])
        floor = scene.instances[0]
        floor.mesh.uvs = ((floor.mesh.positions[:, :2] / 5 + 1) / 2).astype(np.float32)
        floor.materials[0] = Material("floor", normal_texture=bad, normal_strength=strength)
        frame, _ = renderer.render(scene, Settings(bounces=1, antialiasing=1, vpl_count=64))
        assert all(np.isfinite(p).all() for p in frame.passes.values())
        assert frame.passes["DiffDir"].min() > 0  # lit everywhere: no texel turns it away


def test_an_image_larger_than_the_gpus_textures_is_one_clear_error(renderer):
    """An image one texel wider than the GPU's largest texture: a RenderError that says so,
    not a failed upload."""
    limit = int(renderer.ctx.info["GL_MAX_TEXTURE_SIZE"])
    mesh = quad(1, 1)
    mesh.uvs = ((mesh.positions[:, :2] + 1) / 2).astype(np.float32)
    huge = Texture("huge", np.ones((1, limit + 1, 4), np.float32))
    scene = Scene([Instance(mesh, np.eye(4), [Material("m", base_color_texture=huge)])], [],
                  camera=top_down_camera(16))
    with pytest.raises(RenderError, match="larger than this GPU's textures"):
        renderer.render(scene, Settings(bounces=0, antialiasing=1))


def test_an_eight_bit_image_wider_than_the_gpus_textures_still_renders(renderer):
    """An 8-bit image packs four texels into one, so one up to four times the GPU's largest
    texture wide fits (before stop 68 the upload refused it, though the packing took it):
    rendered with its colour, sampled at its right end too."""
    limit = int(renderer.ctx.info["GL_MAX_TEXTURE_SIZE"])
    mesh = quad(1, 1)
    mesh.uvs = ((mesh.positions[:, :2] + 1) / 2).astype(np.float32)
    pixels = np.full((1, 2 * limit + 3, 4), 1.0, np.float32)
    pixels[..., :3] = (0.2, 0.4, 0.6)
    pixels[:, -(limit // 2):, :3] = (0.6, 0.4, 0.2)  # the right quarter (x > 0.5)
    wide = Texture("wide", pixels, interpolation="Closest", eight_bit=True)
    scene = Scene([Instance(mesh, np.eye(4), [Material("m", base_color_texture=wide)])], [],
                  camera=top_down_camera(16))
    frame, _ = renderer.render(scene, Settings(bounces=0, antialiasing=1))
    colour = frame.passes["DiffCol"]
    np.testing.assert_allclose(colour[8, 6, :3], (0.2, 0.4, 0.6), atol=0.01)
    np.testing.assert_allclose(colour[8, 10, :3], (0.6, 0.4, 0.2), atol=0.01)
