"""The engine inside Blender: registration, passes, export of the sample scenes, panels."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from addon.core.frame.renderer import Renderer
from addon.core.frame.result import ON_DEMAND_PASSES, PASS_CHANNELS
from addon.core.scene.model import LightKind
from addon.core.settings import Settings
from addon.export import export_scene
from tests.blender.rendering import against, open_scene, render_linear
from tests.blender.versions import compositor_output

PASS_TOGGLES = ("use_pass_z", "use_pass_normal", "use_pass_diffuse_direct",
                "use_pass_diffuse_indirect", "use_pass_diffuse_color", "use_pass_emit",
                "use_pass_mist", "use_pass_position")


def test_engine_is_listed_and_its_panels_show(blender):
    bpy = blender
    scene = bpy.context.scene
    scene.render.engine = "VPL_GI"
    assert scene.render.engine == "VPL_GI"
    assert "VPL_GI" in bpy.types.RENDER_PT_format.COMPAT_ENGINES
    assert "VPL_GI" in bpy.types.RENDER_PT_color_management.COMPAT_ENGINES
    assert "VPL_GI" in bpy.types.EEVEE_MATERIAL_PT_surface.COMPAT_ENGINES
    assert "VPL_GI" in bpy.types.DATA_PT_EEVEE_light.COMPAT_ENGINES
    assert "VPL_GI" in bpy.types.DATA_PT_camera_dof_aperture.COMPAT_ENGINES
    assert "VPL_GI" in bpy.types.EEVEE_WORLD_PT_mist.COMPAT_ENGINES
    assert bpy.types.RENDER_PT_vpl_gi.poll(bpy.context)


def test_passes_are_registered_under_blender_names(blender):
    """The compositor's Render Layers node offers our passes under the names it gives Cycles'
    (Blender 5.0 renamed DiffCol to "Diffuse Color" and so on)."""
    scene = open_scene("cornell_box", 16)
    layer = scene.view_layers[0]
    for toggle in PASS_TOGGLES:
        setattr(layer, toggle, True)
    tree, _ = compositor_output(scene)
    outputs = {}
    for engine in ("CYCLES", "VPL_GI"):
        scene.render.engine = engine
        node = tree.nodes.new("CompositorNodeRLayers")
        outputs[engine] = {socket.name for socket in node.outputs if socket.enabled}
    assert outputs["VPL_GI"] == outputs["CYCLES"]
    assert len(outputs["VPL_GI"]) == 2 + len(PASS_TOGGLES)  # Image, Alpha and the eight


def test_compositor_receives_the_diffuse_colour_pass(blender, tmp_path):
    """A render's Diffuse Color pass reaches the compositor under Blender's name: routed to the
    compositor's output, every pixel of the saved image is a material's albedo."""
    bpy = blender
    scene = open_scene("light_point", 8)
    scene.view_layers[0].use_pass_diffuse_color = True
    scene.vpl_gi.antialiasing = 1  # one sample per pixel: no edge mixes two albedos
    scene.render.engine = "VPL_GI"
    tree, output = compositor_output(scene)
    node = tree.nodes.new("CompositorNodeRLayers")
    (name,) = {s.name for s in node.outputs if s.enabled} - {"Image", "Alpha"}
    tree.links.new(node.outputs[name], output)
    image = render_linear(scene, "VPL_GI", tmp_path / "albedo.exr")[..., :3].reshape(-1, 3)
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    albedos = np.array([(0.0, 0.0, 0.0)]  # background
                       + [m.base_color for i in exported.instances for m in i.materials])
    nearest = np.abs(image[:, None, :] - albedos[None]).max(axis=2).min(axis=1)
    assert nearest.max() < 1e-4, image
    assert len(np.unique(image.round(4), axis=0)) >= 2  # several surfaces, not one colour


def test_sample_scene_exports_lights_camera_and_materials(blender):
    bpy = blender
    open_scene("multi_light", 32)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene = export_scene(depsgraph)
    kinds = sorted(light.kind for light in scene.lights)
    assert kinds == sorted([LightKind.POINT, LightKind.SPOT, LightKind.SUN, LightKind.AREA])
    assert scene.camera is not None and (scene.camera.width, scene.camera.height) == (32, 32)
    blender_camera = bpy.context.scene.camera
    np.testing.assert_allclose(np.linalg.inv(scene.camera.view_matrix),
                               np.array(blender_camera.matrix_world), atol=1e-6)
    colours = {m.name: m.base_color for inst in scene.instances for m in inst.materials}
    assert colours["Orange"] == pytest.approx((0.8, 0.4, 0.1))
    assert scene.world.radiance == pytest.approx([0.05, 0.06, 0.08])
    assert sum(inst.mesh.triangle_count for inst in scene.instances) > 500


@pytest.mark.parametrize("scale", [(100.0, 100.0, 100.0), (1.0, 2.0, 1.0), (-1.0, 1.0, 1.0)])
def test_a_cameras_scale_is_left_out_as_cycles_leaves_it_out(blender, tmp_path, scale):
    """Cycles renders a camera scaled by 100 or (1, 2, 1) as unscaled, and one scaled by -1
    mirrored (measured, 4.5). VPL GI took the scale into its view: 100 put the box beyond
    the clip range (a black frame, silently), (1, 2, 1) squeezed the image (energy −50 %)."""
    scene = open_scene("cornell_box", 24)
    scene.vpl_gi.bounces = 0
    unscaled = render_linear(scene, "VPL_GI", tmp_path / "unscaled.exr")
    scene.camera.scale = scale
    scaled = render_linear(scene, "VPL_GI", tmp_path / "scaled.exr")
    if scale[0] > 0:
        np.testing.assert_allclose(scaled, unscaled, atol=1e-4)
    else:  # the mirror image (its light samples and supersamples fall elsewhere)
        energy, error = against(scaled[..., :3], unscaled[:, ::-1, :3])
        assert abs(energy) < 0.01 and error < 0.1


def test_passes_compose_into_combined(blender):
    """Combined = (DiffDir + DiffInd) × DiffCol + Emit where there is a surface (Blender's pass
    algebra)."""
    bpy = blender
    open_scene("light_area", 32)
    exported = export_scene(bpy.context.evaluated_depsgraph_get())
    frame, _ = Renderer().render(exported, Settings(antialiasing=1, vpl_count=64))
    assert set(frame.passes) == set(PASS_CHANNELS) - ON_DEMAND_PASSES
    p = frame.passes
    covered = p["Depth"][..., 0] < 1e10
    rebuilt = (p["DiffDir"] + p["DiffInd"]) * p["DiffCol"] + p["Emit"]
    assert p["DiffInd"].max() > 0
    np.testing.assert_allclose(p["Combined"][covered][:, :3], rebuilt[covered], rtol=1e-5,
                               atol=1e-6)
    normals = np.linalg.norm(p["Normal"][covered], axis=-1)
    np.testing.assert_allclose(normals, 1.0, atol=1e-4)
    assert covered.mean() > 0.5 and np.all(p["Depth"][covered] > 0)
    np.testing.assert_allclose(p["Combined"][..., 3], 1.0)  # opaque film: background too


def test_render_without_camera_is_refused(blender):
    scene = open_scene("light_point", 16)
    scene.camera = None
    scene.render.engine = "VPL_GI"
    with pytest.raises(RuntimeError, match="no camera"):
        blender.ops.render.render(write_still=False)


def test_engine_failure_is_reported_not_raised_into_blender(blender, monkeypatch):
    from addon import engine
    from addon.core.gpu.gl import GLUnavailableError

    def no_gl():
        raise GLUnavailableError("could not create an OpenGL 4.1 context (test)")

    monkeypatch.setattr(engine, "shared_renderer", no_gl)
    scene = open_scene("light_point", 16)
    scene.render.engine = "VPL_GI"
    try:
        blender.ops.render.render(write_still=False)
    except RuntimeError as exc:  # Blender turns the engine's error report into an exception
        assert "OpenGL" in str(exc)
    assert engine.monitor.last_error and "OpenGL 4.1" in engine.monitor.last_error


def test_final_render_writes_an_image(blender, tmp_path):
    scene = open_scene("light_point", 24)
    image = render_linear(scene, "VPL_GI", tmp_path / "out.exr")
    assert image.shape == (24, 24, 4)
    assert np.isfinite(image).all() and image[..., :3].max() > 0


ASSETS = Path(__file__).resolve().parents[3] / "shared" / "assets"


SIBENIK_PANES = {"staklo", "staklo_crveno", "staklo_plavo", "staklo_zeleno", "staklo_zuto"}


@pytest.mark.skipif(not (ASSETS / "cornell-box").is_dir(), reason="shared assets not present")
@pytest.mark.parametrize("asset, emits, panes", [
    ("cornell-box/CornellBox-Original.obj", True, set()), ("sponza/sponza.obj", False, set()),
    ("sibenik/sibenik.obj", False, SIBENIK_PANES)])
def test_obj_assets_become_diffuse_benchmark_scenes(blender, asset, emits, panes):
    """Diffuse materials, opaque but for the window panes (Sibenik's glass: open), a camera,
    and a sun and sky where nothing emits."""
    from devtools.obj_scene import scene_from_obj

    scene = scene_from_obj(ASSETS / asset)
    assert scene.camera is not None
    assert (scene.world is None) == emits  # a sun and sky only where nothing emits
    assert any(o.type == "LIGHT" for o in scene.objects) != emits
    open_panes = set()
    for material in blender.data.materials:
        bsdf = material.node_tree.nodes.get("Principled BSDF")
        if bsdf is None:
            continue
        assert bsdf.inputs["Specular IOR Level"].default_value == 0.0
        assert bsdf.inputs["Transmission Weight"].default_value == 0.0
        if bsdf.inputs["Alpha"].default_value == 0.0:
            open_panes.add(material.name)
        else:
            assert bsdf.inputs["Alpha"].default_value == 1.0
    assert open_panes == panes
    exported = export_scene(blender.context.evaluated_depsgraph_get())
    assert sum(i.mesh.triangle_count for i in exported.instances) > 30


class _Layout:
    """Records the properties a panel draws and whether they were greyed out (Blender's
    UILayout is not available headless)."""

    def __init__(self, drawn: dict[str, bool]) -> None:
        self.drawn = drawn
        self.use_property_split = self.use_property_decorate = False
        self.active = True

    def column(self, **_kwargs) -> _Layout:
        return _Layout(self.drawn)

    def prop(self, data, name: str) -> None:
        assert hasattr(data, name) and name not in self.drawn, name
        self.drawn[name] = self.active

    def operator(self, idname: str) -> None:
        assert idname == "vpl_gi.bake_materials"  # the Material Bakes panel's button


def _draw_panels(context) -> dict[str, bool]:
    from types import SimpleNamespace

    from addon.ui import PANELS

    drawn: dict[str, bool] = {}
    for panel in PANELS:
        if hasattr(panel, "draw"):
            fake = SimpleNamespace(layout=_Layout(drawn), section=getattr(panel, "section", ""))
            panel.draw(fake, context)
    return drawn


def test_settings_panels_draw_every_setting_once(blender):
    from addon.core.settings import Settings

    drawn = _draw_panels(blender.context)
    viewport_only = ["viewport_display"]  # what the Rendered viewport shows; not a setting
    assert sorted(drawn) == sorted([f.name for f in fields(Settings)] + viewport_only)


def test_passes_panel_draws_the_toggles_the_engine_reads(blender):
    """The Passes panel draws every view-layer toggle of the optional passes once (Cycles'
    Denoising Data among them) and Cryptomatte's with its levels, on the property group
    layer_passes.toggled reads it from."""
    from types import SimpleNamespace

    from addon.layer_passes import CRYPTOMATTE_TOGGLES, OPTIONAL_PASSES, toggle_owner, toggled
    from addon.ui import VIEWLAYER_PT_vpl_gi_passes

    drawn: list[tuple[object, str]] = []

    class Recorder(_Layout):
        def column(self, **_kwargs) -> Recorder:
            return self

        def prop(self, data, name: str, **_kwargs) -> None:
            drawn.append((data, name))

    VIEWLAYER_PT_vpl_gi_passes.draw(SimpleNamespace(layout=Recorder({})), blender.context)
    toggles = {toggle.rpartition(".")[2]: toggle for *_, toggle in OPTIONAL_PASSES.values()}
    toggles |= {toggle: toggle for toggle in CRYPTOMATTE_TOGGLES.values()}
    assert sorted(name for _, name in drawn) == sorted([*toggles, "pass_cryptomatte_depth"])
    layer = blender.context.view_layer
    for data, name in drawn:
        if name == "pass_cryptomatte_depth":
            continue
        before = getattr(data, name)
        try:
            for value in (True, False):
                setattr(data, name, value)
                assert toggled(layer, toggles[name]) is value, name
        finally:
            setattr(data, name, before)
    assert toggle_owner(layer, "cycles.no_such_toggle") is None
    assert toggle_owner(layer, "no_such_group.use_pass_z") is None
    assert not toggled(layer, "no_such_group.use_pass_z")


class _LightGroupLayout:
    """Records what the light-group panels draw: the list, the fields and their buttons."""

    def __init__(self, calls: list[tuple]) -> None:
        self.calls = calls
        self.use_property_split = self.use_property_decorate = False
        self.enabled = True
        self.name = ""

    def row(self, **_kwargs) -> _LightGroupLayout:
        return _LightGroupLayout(self.calls)

    column = row

    def separator(self) -> None:
        pass

    def template_list(self, _kind, _id, data, name, active_data, active_name, **_kwargs):
        self.calls.append(("list", getattr(data, name), getattr(active_data, active_name)))

    def prop_search(self, data, name, search_data, search_name, **_kwargs) -> None:
        self.calls.append(("field", data, getattr(data, name), getattr(search_data, search_name)))

    def operator(self, idname: str, **_kwargs) -> _LightGroupLayout:
        self.calls.append(("button", idname, self.enabled))
        return self

    def menu(self, idname: str, **_kwargs) -> None:
        self.calls.append(("menu", idname))


def test_light_group_panels_draw_the_groups_and_fields(blender):
    """The view layer's light groups as a list with add, remove and sync, its Shader AOVs
    with add and remove; an object's and the world's Light Group field, its add button
    enabled only for a name the layer lacks."""
    from types import SimpleNamespace

    from addon.ui import (
        OBJECT_PT_vpl_gi_light_group,
        VIEWLAYER_PT_vpl_gi_aovs,
        VIEWLAYER_PT_vpl_gi_light_groups,
        WORLD_PT_vpl_gi_light_group,
    )

    context = blender.context
    layer, obj = context.view_layer, context.scene.objects[0]
    if context.scene.world is None:
        context.scene.world = blender.data.worlds.new("World")
    world = context.scene.world
    blender.ops.scene.view_layer_add_lightgroup(name="Key")
    try:
        calls: list[tuple] = []
        VIEWLAYER_PT_vpl_gi_light_groups.draw(SimpleNamespace(layout=_LightGroupLayout(calls)),
                                              context)
        assert calls[0][0] == "list" and [g.name for g in calls[0][1]] == ["Key"]
        assert [c[1] for c in calls[1:]] == ["scene.view_layer_add_lightgroup",
                                            "scene.view_layer_remove_lightgroup",
                                            "VIEWLAYER_MT_lightgroup_sync"]
        layer.aovs.add().name = "mask"
        calls = []
        VIEWLAYER_PT_vpl_gi_aovs.draw(SimpleNamespace(layout=_LightGroupLayout(calls)), context)
        assert calls[0][0] == "list" and [a.name for a in calls[0][1]] == ["mask"]
        assert [c[1] for c in calls[1:]] == ["scene.view_layer_add_aov",
                                            "scene.view_layer_remove_aov"]
        layer.aovs.remove(layer.aovs[0])
        for panel, owner in ((OBJECT_PT_vpl_gi_light_group, obj),
                             (WORLD_PT_vpl_gi_light_group, world)):
            for group, enabled in (("Key", False), ("Rim", True), ("", False)):
                owner.lightgroup = group
                calls = []
                fake = SimpleNamespace(layout=_LightGroupLayout(calls), owner=panel.owner)
                panel.draw(fake, SimpleNamespace(object=obj, world=world, view_layer=layer))
                assert calls[0][:3] == ("field", owner, group)
                assert calls[1] == ("button", "scene.view_layer_add_lightgroup", enabled)
    finally:
        obj.lightgroup = world.lightgroup = ""
        blender.ops.scene.view_layer_remove_lightgroup()  # the active group: Key
        assert not layer.lightgroups


def test_settings_that_do_not_apply_are_greyed_out(blender):
    settings = blender.context.scene.vpl_gi
    settings.visibility, settings.interleave, settings.auto_parameters = "classic", "1", "time"
    try:
        drawn = _draw_panels(blender.context)
    finally:
        settings.property_unset("visibility")
        settings.property_unset("interleave")
        settings.property_unset("auto_parameters")
    assert drawn["vpl_shadow_resolution"] and drawn["time_budget"] and drawn["bounces"]
    assert not drawn["ism_points"] and not drawn["blur_radius"]
    assert not drawn["rsm_resolution"] and not drawn["target_error"]


DENOISING_PASSES = ("Denoising Normal", "Denoising Albedo", "Denoising Depth")


def _composite(scene, make_output) -> None:
    """Compositor: Render Layers → make_output(nodes, links, render_layers) → the output."""
    scene.render.use_compositing = True
    tree, output = compositor_output(scene)
    layers = tree.nodes.new("CompositorNodeRLayers")
    tree.links.new(make_output(tree.nodes, tree.links, layers), output)


def test_denoising_data_passes_are_registered_and_filled(blender, tmp_path):
    """Cycles' Denoising Data checkbox gives VPL GI renders the passes under Cycles' names, and
    the compositor's Denoise node works on them as on Cycles' renders."""
    scene = open_scene("cornell_box", 24)
    layer = scene.view_layers[0]
    tree, _ = compositor_output(scene)
    node = tree.nodes.new("CompositorNodeRLayers")
    assert not {s.name for s in node.outputs if s.enabled} & set(DENOISING_PASSES)
    layer.cycles.denoising_store_passes = True
    scene.render.engine = "VPL_GI"
    assert set(DENOISING_PASSES) <= {s.name for s in node.outputs if s.enabled}

    _composite(scene, lambda nodes, links, layers: layers.outputs["Denoising Albedo"])
    albedo = render_linear(scene, "VPL_GI", tmp_path / "albedo.exr")[..., :3]
    assert np.isfinite(albedo).all() and albedo.max() > 0.1  # the box's walls
    _composite(scene, lambda nodes, links, layers: layers.outputs["Denoising Normal"])
    normal = render_linear(scene, "VPL_GI", tmp_path / "normal.exr")[..., :3]
    lengths = np.linalg.norm(normal, axis=-1)
    assert np.mean(np.abs(lengths - 1.0) < 0.05) > 0.5  # unit normals where the box is

    _composite(scene, lambda nodes, links, layers: layers.outputs["Image"])
    noisy = render_linear(scene, "VPL_GI", tmp_path / "noisy.exr")[..., :3]

    def denoised(nodes, links, layers):
        denoise = nodes.new("CompositorNodeDenoise")
        for name in ("Image", "Normal", "Albedo"):
            source = "Image" if name == "Image" else f"Denoising {name}"
            links.new(layers.outputs[source], denoise.inputs[name])
        return denoise.outputs["Image"]

    _composite(scene, denoised)
    clean = render_linear(scene, "VPL_GI", tmp_path / "denoised.exr")[..., :3]
    assert np.isfinite(clean).all()
    assert abs(clean.mean() / noisy.mean() - 1.0) < 0.1


def test_motion_blur_panel_draws_the_shutter_the_render_reads(blender):
    """Render Properties > Motion Blur: its checkbox, and the shutter and its position, greyed
    out while motion blur is off (Blender's own panel is EEVEE's)."""
    from types import SimpleNamespace

    from addon.ui import RENDER_PT_vpl_gi_motion_blur

    class Recorder(_Layout):
        def column(self, **_kwargs) -> Recorder:
            return Recorder(self.drawn)

        def prop(self, data, name: str, **_kwargs) -> None:
            super().prop(data, name)

        def label(self, **_kwargs) -> None:
            pass

    render = blender.context.scene.render
    for on in (False, True):
        render.use_motion_blur = on
        drawn: dict[str, bool] = {}
        fake = SimpleNamespace(layout=Recorder(drawn))
        RENDER_PT_vpl_gi_motion_blur.draw_header(fake, blender.context)
        RENDER_PT_vpl_gi_motion_blur.draw(fake, blender.context)
        assert drawn == {"use_motion_blur": True, "motion_blur_position": on,
                         "motion_blur_shutter": on}
    render.use_motion_blur = False


@pytest.mark.parametrize(("panel", "collection", "link"), [
    ("light_linking", "receiver_collection", "receivers"),
    ("shadow_linking", "blocker_collection", "blockers")])
def test_light_and_shadow_linking_panels_show_for_this_engine(blender, panel, collection,
                                                              link):
    """Object Properties > Light Linking and Shadow Linking (rendered: test_light_linking.py,
    test_shadow_linking.py): Blender's own panels where they serve any engine (4.5 on), this
    engine's where they are Cycles' (4.2)."""
    from types import SimpleNamespace

    from addon import ui

    bpy = blender
    bpy.context.scene.render.engine = "VPL_GI"
    ours = f"OBJECT_PT_vpl_gi_{panel}"
    if hasattr(bpy.types, f"OBJECT_PT_{panel}"):  # under OBJECT_PT_shading
        assert "VPL_GI" in bpy.types.OBJECT_PT_shading.COMPAT_ENGINES
        assert not hasattr(bpy.types, ours)
        return
    assert hasattr(bpy.types, ours)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    setattr(lamp.light_linking, collection, bpy.data.collections.new("Linked"))
    calls: list[str] = []

    class Recorder:
        use_property_split = use_property_decorate = False

        def column(self, **_kwargs) -> Recorder:
            return self

        row = column

        def template_ID(self, data, name: str, **_kwargs) -> None:
            calls.append(name)

        def template_light_linking_collection(self, _row, data, name: str) -> None:
            calls.append(f"entries of {name}")

        def operator(self, idname: str, **_kwargs) -> SimpleNamespace:
            calls.append(idname)
            return SimpleNamespace(link_state="")

    drawn = getattr(ui, ours)
    drawn.draw(SimpleNamespace(layout=Recorder(), collection=drawn.collection,
                               new_operator=drawn.new_operator,
                               link_operator=drawn.link_operator),
               SimpleNamespace(object=lamp))
    assert calls == [collection, f"entries of {collection}",
                     f"object.light_linking_{link}_link",
                     "object.light_linking_unlink_from_collection"]
