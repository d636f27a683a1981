"""Image textures through UV maps: against Cycles (every interpolation and extension too),
packed and external files, a missing file, and colour bleeding from a textured wall."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.frame.renderer import Renderer
from addon.core.scene.textures import decode_srgb
from addon.core.settings import Settings
from addon.export import export_scene
from devtools import metrics
from tests.blender.rendering import configure_cycles, render_linear
from tests.blender.test_export import add_light, add_mesh, add_plane, engine_export, new_scene

__all__ = ["engine_export"]  # the fixture, used by name

SQUARE_UVS = [(0, 0), (1, 0), (1, 1), (0, 1)]


def with_uvs(obj, uvs=SQUARE_UVS):
    """Give the object's mesh a UV map with the given coordinates per face corner."""
    layer = obj.data.uv_layers.new(name="UVMap")
    layer.uv.foreach_set("vector", np.asarray(uvs, np.float32).ravel())
    return obj


def byte_image(bpy, name: str, rgb: np.ndarray, pack: bool = True):
    """An 8-bit sRGB image of (h, w, 3) stored values (rows bottom-up), packed."""
    h, w = rgb.shape[:2]
    image = bpy.data.images.new(name, w, h)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb
    image.pixels.foreach_set(rgba.ravel())
    if pack:
        image.pack()
    return image


def textured_material(bpy, name: str, image, shader: str = "ShaderNodeBsdfPrincipled",
                      socket: str = "Base Color", uv_node: bool = False, **inputs):
    """A material whose ``socket`` of ``shader`` is the image, optionally through a UV Map
    node; other inputs as given."""
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    node = tree.nodes.new(shader)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    if uv_node:
        tree.links.new(tree.nodes.new("ShaderNodeUVMap").outputs["UV"], texture.inputs["Vector"])
    tree.links.new(texture.outputs["Color"], node.inputs[socket])
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return material


def gradient(h: int, w: int, seed: int) -> np.ndarray:
    """Random stored values in steps of 1/255."""
    return np.random.default_rng(seed).integers(0, 256, size=(h, w, 3)) / 255


SIZE = 48
# Measured (bpy 4.5, llvmpipe, Cycles 64 samples): relRMSE 0.25 % (base colour) and 0.14 %
# (emission); on the base-colour plane 89 % with the texture ignored (its average colour
# everywhere) and 29 % with sRGB decoded before interpolation instead of after (as Cycles).
TEXTURE_BOUND = 0.02


def test_textured_planes_match_cycles(blender, tmp_path):
    """A Principled plane whose Base Color is a 4×4 sRGB image (through a UV Map node), lit by
    a point light, beside an Emission plane whose Color is a 3×2 image: 0 bounces."""
    bpy = blender
    scene = new_scene(bpy, SIZE, ortho_scale=4.2)
    diffuse = with_uvs(add_plane(bpy, "Diffuse", 2.0, x=-1.05))
    diffuse.data.materials.append(textured_material(
        bpy, "Painted", byte_image(bpy, "Paint", gradient(4, 4, 1)), uv_node=True,
        **{"Specular IOR Level": 0.0}))
    glow = with_uvs(add_plane(bpy, "Glow", 2.0, x=1.05))
    glow.data.materials.append(textured_material(
        bpy, "Glowing", byte_image(bpy, "Glow", gradient(3, 2, 2)), "ShaderNodeEmission",
        "Color", Strength=2.0))
    add_light(bpy, "POINT", 150.0, location=(-1.2, 0.4, 1.5))
    configure_cycles(scene, 64)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")[..., :3]
    scene.vpl_gi.antialiasing = 4
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")[..., :3]
    columns = np.arange(SIZE)
    pixel = (columns + 0.5) / SIZE * 4.2 - 2.1  # world x (and y) of pixel centres
    rows = (np.abs(pixel) < 0.9)[:, None]
    for name, centre in (("base colour", -1.05), ("emission", 1.05)):
        inside = rows & (np.abs(pixel - centre) < 0.9)[None, :]
        error = metrics.relative_rmse(ours[inside], reference[inside])
        print(f"{name}: relRMSE {error:.4f}")
        assert error < TEXTURE_BOUND


INTERPOLATIONS = ("Closest", "Linear", "Cubic", "Smart")
EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")
# 40 pixels per plane's cell, planes 30 pixels wide showing 7.5 texels: texel edges fall on
# pixel edges (a Closest texel's edge inside a pixel would be anti-aliased by the AA × AA
# supersampling grid, coverage quantised to 1/AA, like any geometric edge).
MODES_SIZE, CELL, PLANE = 160, 1.0, 0.75
UV_LOW, UV_SPAN = -0.75, 2.5  # UVs from −0.75 to 1.75: the extension shows on every side
# Measured (bpy 4.5, llvmpipe, Cycles 64 samples; docs/measurements.md, "Image texture modes"):
# every plane within 0.1 % in energy and 1.3 % relRMSE; with the mode ignored (Linear, Repeat:
# the add-on before it sampled modes) each other plane was off by 4.4–719 % in energy and
# 52–962 % in relRMSE.
MODES_ENERGY_BOUND = 0.01
MODES_RMSE_BOUND = 0.03


def modes_scene(bpy):
    """A 4 × 4 grid of planes lit by a point light: rows Closest, Linear, Cubic, Smart
    (bottom to top), columns Repeat, Extend, Clip, Mirror; each plane shows a 3×3 checker of
    distinct colours (no symmetry, so Mirror differs from Repeat) through UVs beyond 0..1."""
    scene = new_scene(bpy, MODES_SIZE, ortho_scale=4 * CELL)
    stored = np.array([[(0.9, 0.9, 0.9), (0.1, 0.1, 0.1), (0.8, 0.2, 0.1)],
                       [(0.1, 0.3, 0.9), (0.95, 0.95, 0.6), (0.15, 0.1, 0.1)],
                       [(0.7, 0.9, 0.2), (0.2, 0.05, 0.4), (1.0, 1.0, 1.0)]])
    image = byte_image(bpy, "Checker", stored)
    uvs = [(UV_LOW + UV_SPAN * u, UV_LOW + UV_SPAN * v) for u, v in SQUARE_UVS]
    for row, interpolation in enumerate(INTERPOLATIONS):
        for column, extension in enumerate(EXTENSIONS):
            material = textured_material(bpy, f"{interpolation} {extension}", image,
                                         **{"Specular IOR Level": 0.0})
            node = next(n for n in material.node_tree.nodes if n.type == "TEX_IMAGE")
            node.interpolation, node.extension = interpolation, extension
            plane = with_uvs(add_plane(bpy, material.name, PLANE * CELL), uvs)
            plane.location = ((column - 1.5) * CELL, (row - 1.5) * CELL, 0.0)
            plane.data.materials.append(material)
    add_light(bpy, "POINT", 400.0, location=(0.3, -0.2, 2.5))
    return scene


def mode_errors(ours: np.ndarray, reference: np.ndarray) -> dict[tuple[str, str], tuple]:
    """(energy error, relRMSE) per plane of modes_scene, over its pixels 2 pixels inside."""
    cell = MODES_SIZE // 4
    margin = round((1 - PLANE) / 2 * cell) + 2
    errors = {}
    for row, interpolation in enumerate(INTERPOLATIONS):
        for column, extension in enumerate(EXTENSIONS):
            window = (slice(row * cell + margin, (row + 1) * cell - margin),
                      slice(column * cell + margin, (column + 1) * cell - margin))
            got, expected = ours[window], reference[window]
            errors[interpolation, extension] = (metrics.mean_relative_energy(got, expected),
                                                metrics.relative_rmse(got, expected))
    return errors


def test_texture_modes_match_cycles(blender, tmp_path):
    """Every interpolation × extension against Cycles (0 bounces): each plane's energy and
    relRMSE within bounds that the add-on's former Linear/Repeat sampling exceeds."""
    scene = modes_scene(blender)
    configure_cycles(scene, 64)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")[..., :3]
    scene.vpl_gi.antialiasing = 4
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")[..., :3]
    errors = mode_errors(ours, reference)
    for (interpolation, extension), (energy, rmse) in errors.items():
        print(f"{interpolation:8s} {extension:7s} energy {energy:+.4f} relRMSE {rmse:.4f}")
    for mode, (energy, rmse) in errors.items():
        assert abs(energy) < MODES_ENERGY_BOUND and rmse < MODES_RMSE_BOUND, mode


def test_image_alpha_colours_like_cycles(blender, tmp_path):
    """Texels of alpha 0, 0.5 and 1 in an 8-bit image (Closest) on Emission planes: Cycles
    multiplies the stored colour by alpha for a Straight sRGB image (measured: 0.13 instead
    of 0.60 in red at alpha 0.5) and not for a Non-Color one; each texel within 0.5 %."""
    bpy = blender
    scene = new_scene(bpy, 48, ortho_scale=4.0)
    for k, space in enumerate(("sRGB", "Non-Color")):
        image = bpy.data.images.new(f"Alpha {space}", 3, 1, alpha=True)
        image.pixels.foreach_set(np.array([[0.8, 0.6, 0.4, a] for a in (0.0, 0.5, 1.0)],
                                          np.float32).ravel())
        image.pack()
        image.colorspace_settings.name = space
        material = textured_material(bpy, f"Glass {space}", image, "ShaderNodeEmission",
                                     "Color", Strength=1.0)
        next(n for n in material.node_tree.nodes if n.type == "TEX_IMAGE").interpolation = \
            "Closest"
        with_uvs(add_plane(bpy, space, 1.8, x=-1.0 + 2.0 * k)).data.materials.append(material)
    configure_cycles(scene, 4)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")[..., :3]
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")[..., :3]
    for k in range(2):
        for texel in range(3):  # plane k spans pixels 1.2 + 24k to 22.8 + 24k, 7.2 per texel
            x = round(1.2 + 24 * k + (texel + 0.5) * 7.2)
            window = (slice(20, 28), slice(x - 1, x + 2))
            got, expected = ours[window].mean(axis=(0, 1)), reference[window].mean(axis=(0, 1))
            np.testing.assert_allclose(got, expected, rtol=5e-3, atol=1e-4)


def test_external_and_missing_image_files(blender, engine_export, tmp_path):
    """An image saved to a file renders as the packed one; a missing file, or an image
    sequence, gives one warning and magenta, in a finite frame."""
    bpy = blender
    scene = new_scene(bpy, 16)
    scene.vpl_gi.bounces = 1
    scene.vpl_gi.vpl_count = 64
    plane = with_uvs(add_plane(bpy, "Plane", 3.0))
    packed = byte_image(bpy, "Packed", gradient(4, 4, 3))
    material = textured_material(bpy, "Wall", packed, **{"Specular IOR Level": 0.0})
    plane.data.materials.append(material)
    add_light(bpy, "SUN", 2.0)
    first, _, warnings = engine_export(scene, tmp_path / "packed.exr")
    assert warnings == []
    path = tmp_path / "texture.png"
    saved = byte_image(bpy, "Saved", gradient(4, 4, 3), pack=False)
    saved.filepath_raw, saved.file_format = str(path), "PNG"
    saved.save()
    external = bpy.data.images.load(str(path))
    assert external.packed_file is None
    texture_node = next(n for n in material.node_tree.nodes if n.type == "TEX_IMAGE")
    texture_node.image = external
    second, exported, warnings = engine_export(scene, tmp_path / "external.exr")
    assert warnings == []
    assert exported.instances[0].materials[0].base_color_texture.srgb
    np.testing.assert_allclose(second, first, rtol=1e-5, atol=1e-6)

    external.filepath = str(tmp_path / "gone.png")
    external.reload()
    image, exported, warnings = engine_export(scene, tmp_path / "missing.exr")
    assert warnings == [f"material 'Wall': image 'texture.png' is missing or cannot be read "
                        f"({tmp_path / 'gone.png'}): shown in magenta (1, 0, 1) as Cycles does"]
    assert np.isfinite(image).all()
    albedo = exported.instances[0].materials[0].base_color_texture.pixels
    np.testing.assert_array_equal(albedo, [[[1, 0, 1, 1]]])
    assert image[8, 8, 1] == pytest.approx(0.0, abs=1e-6) and image[8, 8, 0] > 0.1

    external.filepath = str(path)
    external.source = "SEQUENCE"  # the frame Blender has loaded, named as such
    image, _, warnings = engine_export(scene, tmp_path / "sequence.exr")
    assert warnings == ["material 'Wall': image 'texture.png' is an image sequence: rendered "
                        "with the frame Blender has loaded, which need not be the scene "
                        "frame's"]
    np.testing.assert_allclose(image, first, rtol=1e-5, atol=1e-6)
    frames = tmp_path / "frame_0001.png"
    frames.write_bytes(path.read_bytes())
    unloaded = bpy.data.images.load(str(frames))
    unloaded.source = "SEQUENCE"  # a numbered file: no frame loaded, magenta
    texture_node.image = unloaded
    image, _, warnings = engine_export(scene, tmp_path / "unloaded.exr")
    assert warnings == ["material 'Wall': image 'frame_0001.png' is an image sequence, which "
                        "VPL GI does not read: shown in magenta (1, 0, 1)"]
    assert np.isfinite(image).all() and image[8, 8, 1] == pytest.approx(0.0, abs=1e-6)


def bleeding_scene(bpy, textured: bool):
    """A white floor and a wall whose left half is red and right half blue: one textured
    wall, or two plain halves of the texture's decoded colours."""
    scene = new_scene(bpy, 32, ortho_scale=2.0)
    floor = add_plane(bpy, "Floor", 2.0)
    floor.data.materials.append(plain_material(bpy, "White", (0.8, 0.8, 0.8)))
    stored = np.zeros((1, 16, 3))
    stored[0, :8] = (0.9, 0.25, 0.2)
    stored[0, 8:] = (0.2, 0.25, 0.9)
    if textured:
        wall = with_uvs(add_mesh(bpy, "Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)],
                                 [(0, 1, 2, 3)]))
        wall.data.materials.append(textured_material(
            bpy, "Painted", byte_image(bpy, "Halves", stored), "ShaderNodeBsdfDiffuse",
            "Color"))
    else:
        for name, x0, colour in (("Left", -1, stored[0, 0]), ("Right", 0, stored[0, -1])):
            half = add_mesh(bpy, name, [(x0, 1, 0), (x0 + 1, 1, 0), (x0 + 1, 1, 2),
                                        (x0, 1, 2)], [(0, 1, 2, 3)])
            half.data.materials.append(plain_material(bpy, name, decode_srgb(colour)))
    add_light(bpy, "POINT", 300.0, location=(0.0, 0.2, 1.0))
    return scene


def plain_material(bpy, name: str, colour):
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    node = tree.nodes.new("ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (*colour, 1.0)
    tree.links.new(node.outputs[0], tree.nodes.new("ShaderNodeOutputMaterial").inputs[0])
    return material


def test_textured_wall_bleeds_its_texels_colours(blender):
    """The floor's indirect light under the red half is red, under the blue half blue, and
    both match plain walls of the same colours within 5 % (one bounce, 4096 paths; measured
    within 2.7 %; with VPLs taking the texture's average colour both halves are purple and the
    ratios fail)."""
    bpy = blender
    settings = Settings(bounces=1, vpl_count=4096, antialiasing=1)
    regions = {}
    renderer = Renderer()
    try:
        for textured in (True, False):
            bleeding_scene(bpy, textured)
            scene = export_scene(bpy.context.evaluated_depsgraph_get())
            frame, _ = renderer.render(scene, settings)
            indirect = frame.passes["DiffInd"]
            # floor pixels near the wall: rows y in (0.25, 0.85), left and right of x = 0
            rows = slice(20, 29)
            regions[textured] = (indirect[rows, 3:13].mean(axis=(0, 1)),
                                 indirect[rows, 19:29].mean(axis=(0, 1)))
    finally:
        renderer.release()
    left, right = regions[True]
    print("textured", left, right, "plain", *regions[False])
    assert left[0] / left[1] > 1.5 and left[0] > left[2]
    assert right[2] / right[1] > 1.5 and right[2] > right[0]
    for got, expected in zip(regions[True], regions[False], strict=True):
        np.testing.assert_allclose(got, expected, rtol=0.05)


def test_unsupported_texture_settings_warn_once_per_material(blender):
    """Closest/Clip is exported as such, silently; a Box projection, a texture in a Mix
    Shader or behind a Mapping node fall back to the viewport colour where no bake runs (one
    warning each); UVs are read per corner from the active render UV map."""
    bpy = blender
    new_scene(bpy)
    image = byte_image(bpy, "Tiles", gradient(2, 2, 5))
    closest = textured_material(bpy, "Closest", image)
    node = next(n for n in closest.node_tree.nodes if n.type == "TEX_IMAGE")
    node.interpolation, node.extension = "Closest", "CLIP"
    boxed = textured_material(bpy, "Boxed", image)
    next(n for n in boxed.node_tree.nodes if n.type == "TEX_IMAGE").projection = "BOX"
    mixed = textured_material(bpy, "Mixed", image)
    tree = mixed.node_tree
    principled = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(principled.outputs[0], mix.inputs[1])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    mapped = textured_material(bpy, "Mapped", image)
    node = next(n for n in mapped.node_tree.nodes if n.type == "TEX_IMAGE")
    mapped.node_tree.links.new(mapped.node_tree.nodes.new("ShaderNodeMapping").outputs[0],
                               node.inputs["Vector"])
    uvs = [(0.1, 0.2), (0.3, 0.4), (0.5, 0.6), (0.7, 0.8)]
    for i, material in enumerate([closest, closest, mixed, mapped, boxed]):
        obj = with_uvs(add_plane(bpy, f"P{i}", 0.5, x=i - 1.5), uvs)
        obj.data.materials.append(material)
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    assert sorted(scene.warnings) == [
        "material 'Boxed': image 'Tiles': its projection Box is read only through a bake "
        "(nodes: Image Texture); using its viewport colour (not baked: bakes run before "
        "background renders, in the viewport and by Bake Materials)",
        "material 'Mapped': input 'Vector' of 'Image Texture' is linked to 'Mapping' (nodes: "
        "Image Texture, Mapping); using its viewport colour (not baked: bakes run before "
        "background renders, in the viewport and by Bake Materials)",
        "material 'Mixed': image textures inside 'Mix Shader' other than one base colour "
        "texture both shaders use are not supported (nodes: Image Texture); using its viewport "
        "colour (not baked: bakes run before background renders, in the viewport and by Bake "
        "Materials)"]
    mesh = scene.instances[0].mesh
    # triangles (0, 1, 2) and (0, 2, 3) of the quad (Blender's split of this one)
    np.testing.assert_allclose(mesh.corner_uvs(), np.array(uvs)[[0, 1, 2, 0, 2, 3]])
    texture = scene.instances[0].materials[0].base_color_texture
    assert texture.pixels.shape == (2, 2, 4)
    assert (texture.interpolation, texture.extension) == ("Closest", "CLIP")
