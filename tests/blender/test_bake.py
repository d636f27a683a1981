"""Material bakes: procedural colours, a texture behind a Mapping node, a mesh without UVs
(xatlas), and textures on tiled UVs or none behind a colour node, or a UDIM image's tiles
(baked on xatlas UVs, read on the mesh's own) against Cycles; the bake cache; the user's
data left as it was."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

from addon import bake
from addon.export import ExportCache, export_scene
from tests.blender.rendering import configure_cycles, render_linear
from tests.blender.test_cli import run_cli
from tests.blender.test_cycles_direct import errors
from tests.blender.test_export import add_light, add_mesh, add_plane, new_scene
from tests.blender.test_textures import SQUARE_UVS, byte_image, gradient, with_uvs
from tests.blender.versions import ensure_nodes

SIZE = 48
CYCLES_SAMPLES = 64
# Measured (bpy 4.5, llvmpipe, Cycles 64 samples; VPL GI antialiasing 4, bake 256², 4 bake
# samples): docs/measurements.md. Energy within 0.5 %, relRMSE 0.03–2.9 % (the box's and the
# Brick/Wave textures' sharp edges, sampled differently by the two renderers, make the larger
# ones; away from edges at most 1.1 %). The old viewport-colour fallback is 3–240 % off in
# energy and 58–300 % in relRMSE, far outside every bound.
ENERGY_BOUND = 0.03
RMSE_BOUNDS = {"noise": 0.01, "mapping": 0.01, "generated": 0.05, "mix": 0.04,
               "named": 0.01, "principled": 0.02, "tiled": 0.05, "uvless": 0.05,
               "object_info": 0.01, "subdivided": 0.05, "instanced": 0.05, "text": 0.15,
               "object_attribute": 0.01, "udim": 0.05, "sphere": 0.05}
INTERIOR_BOUND = 0.02  # relRMSE away from edges (test_cycles_direct.edge_mask)


def procedural_material(bpy, name: str, kind: str, image=None):
    """A Diffuse BSDF coloured by a node chain: 'noise' (Noise Texture → ColorRamp),
    'mapping' (an image through a Mapping node on UVs), 'generated' (a Voronoi texture on
    Generated coordinates mixed with a colour by a Math node), 'mix' (the noise colour's
    Diffuse and an Emission of a Brick texture in a Mix Shader whose Fac is a Wave texture),
    'named' (an image through a UV Map node naming a map that is not the active render one),
    'tiled' and 'uvless' (an image on the default UVs through a Gamma node), 'udim' (a UDIM
    image of four tiles on UVs across them, straight into the colour), 'sphere' (an image
    projected as a sphere from the default UVs), 'object_info'
    and 'object_attribute' (the object's colour from Object Info, or a custom property of it
    from an Attribute node, through a Gamma node); case_scene's 'subdivided'
    is 'generated' on a box subdivided as Blender's modifier does by default (1 level in the
    viewport, 2 in renders: baked on the render's mesh), 'instanced' is it on a box only
    instanced (its collection excluded from the view layer), 'text' on a text object."""
    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.clear()
    nodes, links = tree.nodes, tree.links
    out = nodes.new("ShaderNodeOutputMaterial")
    shader = nodes.new("ShaderNodeBsdfDiffuse")
    links.new(shader.outputs[0], out.inputs["Surface"])
    if kind == "principled":  # the noise colour on a default Principled BSDF (specular 0.5)
        nodes.remove(shader)
        shader = nodes.new("ShaderNodeBsdfPrincipled")
        links.new(shader.outputs[0], out.inputs["Surface"])
    if kind in ("noise", "principled"):
        noise = nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 3.0
        ramp = nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].color = (0.9, 0.2, 0.1, 1.0)
        ramp.color_ramp.elements[1].color = (0.1, 0.3, 0.9, 1.0)
        links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
        links.new(ramp.outputs["Color"], shader.inputs[0])
    elif kind == "mapping":
        coords = nodes.new("ShaderNodeTexCoord")
        mapping = nodes.new("ShaderNodeMapping")
        mapping.inputs["Scale"].default_value = (2.0, 2.0, 1.0)
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, 0.4)
        texture = nodes.new("ShaderNodeTexImage")
        texture.image = image
        links.new(coords.outputs["UV"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
        links.new(texture.outputs["Color"], shader.inputs["Color"])
    elif kind == "named":
        uv_map = nodes.new("ShaderNodeUVMap")
        uv_map.uv_map = "Second"
        texture = nodes.new("ShaderNodeTexImage")
        texture.image = image
        links.new(uv_map.outputs["UV"], texture.inputs["Vector"])
        links.new(texture.outputs["Color"], shader.inputs["Color"])
    elif kind in ("udim", "sphere"):  # the image straight into the colour: read, it
        # repeated one tile, or was projected Flat
        texture = nodes.new("ShaderNodeTexImage")
        texture.image = image
        texture.projection = "SPHERE" if kind == "sphere" else "FLAT"
        links.new(texture.outputs["Color"], shader.inputs["Color"])
    elif kind in ("tiled", "uvless"):
        texture = nodes.new("ShaderNodeTexImage")
        texture.image = image
        gamma = nodes.new("ShaderNodeGamma")
        gamma.inputs["Gamma"].default_value = 1.5
        links.new(texture.outputs["Color"], gamma.inputs["Color"])
        links.new(gamma.outputs["Color"], shader.inputs["Color"])
    elif kind in ("object_info", "object_attribute"):
        info = nodes.new("ShaderNodeObjectInfo")
        if kind == "object_attribute":  # a custom property of the object
            info = nodes.new("ShaderNodeAttribute")
            info.attribute_type, info.attribute_name = "OBJECT", "tint"
        gamma = nodes.new("ShaderNodeGamma")
        links.new(info.outputs["Color"], gamma.inputs["Color"])
        links.new(gamma.outputs["Color"], shader.inputs["Color"])
    elif kind == "mix":
        procedural = procedural_material(bpy, "Inner", "noise").node_tree
        noise, ramp = (nodes.new(n.bl_idname) for n in (
            next(n for n in procedural.nodes if n.type == t) for t in ("TEX_NOISE", "VALTORGB")))
        noise.inputs["Scale"].default_value = 3.0
        links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
        links.new(ramp.outputs["Color"], shader.inputs["Color"])
        bpy.data.materials.remove(bpy.data.materials["Inner"])
        emission = nodes.new("ShaderNodeEmission")
        emission.inputs["Strength"].default_value = 0.5
        bricks = nodes.new("ShaderNodeTexBrick")
        links.new(bricks.outputs["Color"], emission.inputs["Color"])
        wave = nodes.new("ShaderNodeTexWave")
        mix = nodes.new("ShaderNodeMixShader")
        links.new(wave.outputs["Fac"], mix.inputs["Fac"])
        links.new(shader.outputs[0], mix.inputs[1])
        links.new(emission.outputs[0], mix.inputs[2])
        links.new(mix.outputs[0], out.inputs["Surface"])
    else:
        coords = nodes.new("ShaderNodeTexCoord")
        voronoi = nodes.new("ShaderNodeTexVoronoi")
        voronoi.inputs["Scale"].default_value = 2.5
        math = nodes.new("ShaderNodeMath")
        math.operation = "MULTIPLY"
        math.inputs[1].default_value = 0.8
        mix = nodes.new("ShaderNodeMixRGB")
        mix.inputs["Color1"].default_value = (0.1, 0.6, 0.2, 1.0)
        mix.inputs["Color2"].default_value = (0.9, 0.8, 0.1, 1.0)
        links.new(coords.outputs["Generated"], voronoi.inputs["Vector"])
        links.new(voronoi.outputs["Distance"], math.inputs[0])
        links.new(math.outputs[0], mix.inputs["Fac"])
        links.new(mix.outputs["Color"], shader.inputs["Color"])
    return material


def add_box(bpy, name: str, size: float):
    """A box without UV maps, seen from above at a slant."""
    h = size / 2
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    obj = add_mesh(bpy, name, verts, faces)
    obj.rotation_euler = (0.5, 0.3, 0.2)
    return obj


def udim_image(bpy):
    """A UDIM image of tiles 1001, 1002, 1011 and 1012, 4×4 sRGB gradients of their own,
    saved as files in Blender's temporary directory and loaded as Blender finds them."""
    folder = Path(bpy.app.tempdir or tempfile.gettempdir())
    for seed, tile in enumerate((1001, 1002, 1011, 1012)):
        tile_image = byte_image(bpy, f"Tile{tile}", gradient(4, 4, seed + 2), pack=False)
        tile_image.filepath_raw = str(folder / f"paint.{tile}.png")
        tile_image.file_format = "PNG"
        tile_image.save()
        bpy.data.images.remove(tile_image)
    image = bpy.data.images.load(str(folder / "paint.1001.png"))
    image.source = "TILED"
    assert sorted(t.number for t in image.tiles) == [1001, 1002, 1011, 1012]
    return image


def case_scene(bpy, kind: str):
    scene = new_scene(bpy, SIZE, ortho_scale=2.4)
    scene.vpl_gi.bake_resolution = "256"
    scene.vpl_gi.antialiasing = 4
    if kind in ("generated", "uvless", "subdivided", "instanced"):
        obj = add_box(bpy, "Box", 1.4)
    elif kind == "text":  # a text object: its surface is baked on its mesh
        obj = bpy.data.objects.new("Text", bpy.data.curves.new("Text", "FONT"))
        obj.data.body, obj.data.extrude, obj.data.size = "H", 0.1, 3.0  # a broad glyph
        obj.data.align_x, obj.data.align_y = "CENTER", "CENTER"
        scene.collection.objects.link(obj)
    else:  # "tiled": the image three times across, its UVs outside the unit square; "udim":
        # across four tiles
        scale = {"tiled": 3.0, "udim": 2.0}.get(kind, 1.0)
        obj = with_uvs(add_plane(bpy, "Plane", 2.0), scale * np.asarray(SQUARE_UVS))
    if kind == "subdivided":  # Blender's default: level 1 in the viewport, 2 in renders
        obj.modifiers.new("Subdivision", "SUBSURF")
    elif kind == "instanced":  # in a collection excluded from the view layer, instanced
        assets = bpy.data.collections.new("Assets")
        scene.collection.children.link(assets)
        scene.collection.objects.unlink(obj)
        assets.objects.link(obj)
        bpy.context.view_layer.layer_collection.children["Assets"].exclude = True
        instancer = bpy.data.objects.new("Instancer", None)
        instancer.instance_type, instancer.instance_collection = "COLLECTION", assets
        scene.collection.objects.link(instancer)
    elif kind not in ("generated", "uvless", "tiled", "text", "udim", "sphere"):
        # (xatlas bakes hold for the evaluation they were made on) the final render's
        # differs from the viewport's, where bakes run
        subdivision = obj.modifiers.new("Subdivision", "SUBSURF")
        subdivision.subdivision_type = "SIMPLE"  # Catmull-Clark smooths UVs and positions
        subdivision.levels, subdivision.render_levels = 0, 2  # differently: see the docs
    obj.color = (0.8, 0.3, 0.1, 1.0)  # Object Info's colour ('object_info')
    obj["tint"] = (0.2, 0.6, 0.9)  # a custom property ('object_attribute')
    if kind == "named":
        second = obj.data.uv_layers.new(name="Second")
        second.uv.foreach_set("vector", [0.1, 0.0, 0.6, 0.1, 0.7, 0.6, 0.2, 0.5])
        obj.data.uv_layers["UVMap"].active_render = True
    image = byte_image(bpy, "Paint", gradient(4, 4, 1)) \
        if kind in ("mapping", "named", "tiled", "uvless", "sphere") else udim_image(bpy) \
        if kind == "udim" else None
    obj.data.materials.append(procedural_material(
        bpy, kind.title(), "generated" if kind in ("subdivided", "instanced", "text") else kind,
        image))
    add_light(bpy, "SUN", 3.0, angle=0.0)
    return scene


@pytest.mark.parametrize("kind", ["noise", "mapping", "generated", "mix",
                                  "named", "principled", "tiled", "uvless",
                                  "object_info", "subdivided", "instanced", "text",
                                  "object_attribute", "udim", "sphere"])
def test_baked_materials_match_cycles(blender, tmp_path, kind):
    """Each procedural material renders like Cycles (0 bounces, a sun); the old fallback
    (the viewport colour) is outside the bounds."""
    bpy = blender
    scene = case_scene(bpy, kind)
    configure_cycles(scene, CYCLES_SAMPLES)
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")[..., :3]
    bake.CACHE.clear()
    scene.render.engine = "VPL_GI"
    before = datablock_names(bpy)
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")[..., :3]
    assert len(bake.CACHE.entries) == 1
    assert datablock_names(bpy) == before  # the user's data as it was (render_linear's
    # loaded image is removed again)
    energy, inner, rmse = errors(ours, reference)
    bake.CACHE.clear()
    bpy.app.handlers.render_pre.remove(bake._before_render)  # no bake: the old fallback
    try:
        fallback = render_linear(scene, "VPL_GI", tmp_path / "old.exr")[..., :3]
    finally:
        bpy.app.handlers.render_pre.append(bake._before_render)
    old_energy, _, old_rmse = errors(fallback, reference)
    print(f"{kind}: energy {energy:+.4f} relRMSE {rmse:.4f} (interior {inner:.4f}) | "
          f"fallback energy {old_energy:+.4f} relRMSE {old_rmse:.4f}")
    assert abs(energy) < ENERGY_BOUND and rmse < RMSE_BOUNDS[kind] and inner < INTERIOR_BOUND
    assert abs(old_energy) > ENERGY_BOUND or old_rmse > RMSE_BOUNDS[kind]


def bake_interrupted(bpy, module) -> None:
    """A bake pass with Ctrl-C inside ``module``'s Cycles bake (its ``run_bake`` raising
    KeyboardInterrupt), which the pass lets through."""
    def interrupted(*_args, **_kwargs):
        raise KeyboardInterrupt
    original, module.run_bake = module.run_bake, interrupted
    try:
        with pytest.raises(KeyboardInterrupt):
            bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    finally:
        module.run_bake = original


def datablock_names(bpy) -> dict[str, set[str]]:
    """Every datablock's name and the datablocks that use it, by collection, and each mesh's
    UV maps and material nodes. Users come from ``bpy.data.user_map()``: Blender 4.2's raw
    user count of an image stays one too high after a bake with no user behind it."""
    names = {}
    users = bpy.data.user_map()
    for attribute in dir(bpy.data):
        collection = getattr(bpy.data, attribute)
        if isinstance(collection, bpy.types.bpy_prop_collection) and attribute != "window_managers":
            try:
                names[attribute] = {(item.name_full, frozenset(
                    user.name_full for user in users.get(item, ()))) for item in collection}
            except (AttributeError, TypeError):
                continue
    names["uv maps"] = {(m.name, layer.name) for m in bpy.data.meshes for layer in m.uv_layers}
    names["nodes"] = {(m.name, len(m.node_tree.nodes), len(m.node_tree.links))
                      for m in bpy.data.materials if m.node_tree}
    return names


def test_cache_and_user_data(blender):
    """A second frame reuses the bake; a changed tree bakes again; the user's data is as it
    was (no UV map, no datablock left), also when the bake fails."""
    bpy = blender
    scene = case_scene(bpy, "generated")
    bake.CACHE.clear()
    before = datablock_names(bpy)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    first = bake.bake_scene(depsgraph)
    assert len(first.baked) == 1 and first.problems == []
    assert datablock_names(bpy) == before
    exported = export_scene(depsgraph)
    material = exported.instances[0].materials[0]
    assert material.base_color_texture is not None
    assert exported.instances[0].mesh.uvs is not None  # xatlas, on the copy only
    assert any("baked 'Generated'" in note for note in exported.notes)
    assert not exported.warnings

    scene.frame_set(2)
    second = bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    assert second.baked == [] and len(bake.CACHE.entries) == 1

    math = next(n for n in bpy.data.materials["Generated"].node_tree.nodes if n.type == "MATH")
    math.inputs[1].default_value = 0.5
    third = bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    assert len(third.baked) == 1 and len(bake.CACHE.entries) == 2
    assert datablock_names(bpy) == {**before, "nodes": datablock_names(bpy)["nodes"]}

    math.inputs[1].default_value = 0.4
    state = datablock_names(bpy)
    bake_interrupted(bpy, bake)
    assert datablock_names(bpy) == state
    bake.CACHE.clear()


def test_a_bake_names_what_it_cannot_give(blender):
    """Object Info's Random comes from the bake's stand-in object, not the object, a
    view-dependent node is baked as seen straight on, Ambient Occlusion sees the object alone
    and an instance's attributes are not there: the export says so on every frame, the bake
    itself is kept."""
    bpy = blender
    scene = case_scene(bpy, "object_info")
    tree = bpy.data.materials["Object_Info"].node_tree
    info = next(n for n in tree.nodes if n.type == "OBJECT_INFO")
    tree.links.new(info.outputs["Random"], next(
        n for n in tree.nodes if n.type == "GAMMA").inputs["Gamma"])
    bake.CACHE.clear()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert len(bake.bake_scene(depsgraph).baked) == 1
    for _frame in range(2):
        warnings = export_scene(bpy.context.evaluated_depsgraph_get()).warnings
        assert warnings == ["object 'Plane': Object Info's Random in its bake is not the "
                            "object's (a stand-in object's, one value)"]
    gamma = next(n for n in tree.nodes if n.type == "GAMMA").inputs["Gamma"]

    def warnings_once_linked(output, into=gamma) -> list[str]:
        """The export's warnings once ``output`` feeds ``into`` and the object is baked."""
        tree.links.new(output, into)
        assert len(bake.bake_scene(bpy.context.evaluated_depsgraph_get()).baked) == 1
        return export_scene(bpy.context.evaluated_depsgraph_get()).warnings

    weight = tree.nodes.new("ShaderNodeLayerWeight")  # seen along the normal by the bake
    assert warnings_once_linked(weight.outputs["Facing"]) == [
        "material 'Object_Info': its bake holds Layer Weight as seen looking straight at the "
        "surface, not from the camera"]
    occlusion = tree.nodes.new("ShaderNodeAmbientOcclusion")  # sees the bake's scene alone
    assert warnings_once_linked(occlusion.outputs["AO"]) == [
        "material 'Object_Info': its bake holds Ambient Occlusion of the object alone, not of "
        "the scene around it"]
    occlusion.only_local = True  # the object alone is what it asks for
    assert warnings_once_linked(occlusion.outputs["AO"]) == []
    attribute = tree.nodes.new("ShaderNodeAttribute")  # each instance's own
    attribute.attribute_type, attribute.attribute_name = "INSTANCER", "tone"
    assert warnings_once_linked(attribute.outputs["Fac"], occlusion.inputs["Distance"]) == [
        "material 'Object_Info': its bake cannot read the attributes 'tone' (Instancer): "
        "rendered as 0"]
    bake.CACHE.clear()
    assert scene.objects["Plane"].color[0] == np.float32(0.8)


def test_a_bake_in_new_uvs_names_the_maps_it_leaves_out(blender):
    """A normal map on tiled UVs, which the bake's xatlas map would misplace: left out with
    a warning (on the mesh's own UVs a bake keeps it: test_normal_maps.py's 'baked')."""
    bpy = blender
    case_scene(bpy, "tiled")
    tree = bpy.data.materials["Tiled"].node_tree
    normal_map, texture = tree.nodes.new("ShaderNodeNormalMap"), tree.nodes.new(
        "ShaderNodeTexImage")
    texture.image = next(n for n in tree.nodes if n.type == "TEX_IMAGE" and n.image).image
    tree.links.new(texture.outputs["Color"], normal_map.inputs["Color"])
    tree.links.new(normal_map.outputs["Normal"], tree.nodes["Diffuse BSDF"].inputs["Normal"])
    bake.CACHE.clear()
    assert len(bake.bake_scene(bpy.context.evaluated_depsgraph_get()).baked) == 1
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    assert exported.warnings == ["material 'Tiled': its normal map is not rendered: the mesh "
                                 "has no UV map a bake can use, and the bake's new one would "
                                 "misplace it"]
    assert exported.instances[0].materials[0].normal_texture is None
    bake.CACHE.clear()


def test_missing_bake_and_memory_cap(blender):
    """Without a bake the material keeps its viewport colour with a warning naming why, and
    the export names it as waiting for a bake; a bake over the memory cap is refused with a
    message naming the settings, and the material no longer waits."""
    bpy = blender
    scene = case_scene(bpy, "noise")
    bake.CACHE.clear()
    exports = ExportCache()
    exported = export_scene(bpy.context.evaluated_depsgraph_get(), exports)
    assert exported.instances[0].materials[0].base_color_texture is None
    assert exports.unbaked == {"Noise"}
    assert len(exported.warnings) == 1 and "Noise Texture" in exported.warnings[0]
    text = bpy.data.objects.new("Text", bpy.data.curves.new("Text", "FONT"))
    text.data.materials.append(bpy.data.materials["Noise"])
    scene.collection.objects.link(text)
    warnings = export_scene(bpy.context.evaluated_depsgraph_get()).warnings
    about = [w for w in warnings if w.startswith("material 'Noise'")]
    assert about == exported.warnings  # a text object waits for its bake as the mesh does
    bpy.data.objects.remove(text)
    assert "not baked: bakes run before background renders" in exported.warnings[0]
    scene.vpl_gi.bake_resolution = "4096"
    scene.vpl_gi.bake_memory = 16
    cache = bake.bake_scene(bpy.context.evaluated_depsgraph_get())
    assert cache.baked == [] and len(cache.problems) == 1
    assert "Bake Resolution" in cache.problems[0] and "16 MiB" in cache.problems[0]
    warnings = export_scene(bpy.context.evaluated_depsgraph_get(), exports).warnings
    assert exports.unbaked == set()
    assert len(warnings) == 1 and "not baked: its 256 MiB bake does not fit the bake memory " \
        "cap of 16 MiB" in warnings[0]


def test_command_line_bakes_once_and_reports_it(blender, tmp_path):
    """``python -m addon render`` bakes before the first frame (render_pre), reuses the bake
    on the second, and says what it baked, why and how long it took."""
    bpy = blender
    case_scene(bpy, "noise")
    path = tmp_path / "noise.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    result = run_cli("render", str(path), "-o", str(tmp_path / "frame_#.png"), "-f", "1..2",
                     "-r", "16x16", "--set", "bake_resolution=64")
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr
    notes = [line for line in result.stdout.splitlines() if line.startswith("note: baked")]
    assert len(notes) == 2 and "'Noise' on object 'Plane' (64 px" in notes[0]
    assert "Noise Texture" in notes[0] and "Color Ramp" in notes[0]
    stages = [line for line in result.stdout.splitlines() if line.startswith("stages:")]
    assert "material bake" in stages[0] and "material bake" not in stages[1]
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["frame_1.png", "frame_2.png"]


def test_viewport_bakes_on_a_timer_then_exports_again(blender, monkeypatch):
    """The Rendered viewport's first export has no bake: it schedules one on a timer (outside
    drawing), which bakes, asks the engine for an update, and the next export uses it."""

    from addon.viewport import ViewportState
    from tests.blender.test_viewport_glue import FakeEngine, viewport_context

    bpy = blender
    scene = case_scene(bpy, "noise")
    scene.vpl_gi.bake_resolution = "64"
    scene.vpl_gi.vpl_count = 16
    bake.CACHE.clear()
    timers: list = []
    monkeypatch.setattr(bake.bpy.app.timers, "register",
                        lambda function, first_interval=0.0: timers.append(function))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    context = viewport_context(scene, depsgraph, 16, 16, perspective=False)
    calls: list = []
    engine = FakeEngine(calls)
    engine.tag_update = lambda: calls.append("update")
    state = ViewportState(engine)
    try:
        state.update(context, depsgraph)
        assert len(timers) == 2  # the redraw poll (registered first) and the bake
        assert state.session._scene.instances[0].materials[0].base_color_texture is None
        assert timers[1]() == bake.BAKE_POLL or state.session.idle  # waits for the frames
        assert state.session.wait_idle(300)  # in flight: no bake beside the worker's GL work
        assert timers[1]() is None
        assert "update" in calls and len(bake.CACHE.entries) == 1
        state.update(context, bpy.context.evaluated_depsgraph_get())
        material = state.session._scene.instances[0].materials[0]
        assert material.base_color_texture is not None
        assert state.session.wait_idle(300) and state.session.error is None
    finally:
        state.close()
        bake.CACHE.clear()
