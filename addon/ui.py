"""Panels: Blender's own panels that apply to this engine, and the engine's settings panels
(one per section of the settings schema)."""

from __future__ import annotations

from typing import ClassVar

import bpy

from . import ENGINE_ID
from .core.settings import SCHEMA, SECTIONS, Section, applies

# Panels written for EEVEE that show what this engine reads (material surface, world colour,
# light settings, the camera's depth of field, the Mist pass's settings); generic panels
# (format, output, colour management, ...) are found by their "BLENDER_RENDER" compatibility,
# Blender's marker for panels any engine can use.
_EXTRA_PANELS = ("EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface",
                 "EEVEE_WORLD_PT_surface", "DATA_PT_EEVEE_light", "DATA_PT_camera_dof",
                 "DATA_PT_camera_dof_aperture", "EEVEE_WORLD_PT_mist")
_EXCLUDED_PREFIXES = ("RENDER_PT_eevee", "DATA_PT_lightprobe", "EEVEE_MATERIAL_PT_viewport",
                      "RENDER_PT_simplify", "RENDER_PT_post_processing")


def _compatible_panels() -> list[type]:
    panels = []
    for name in dir(bpy.types):
        cls = getattr(bpy.types, name)
        engines = getattr(cls, "COMPAT_ENGINES", None)
        if not isinstance(engines, set) or name.startswith(_EXCLUDED_PREFIXES):
            continue
        if "BLENDER_RENDER" in engines or name in _EXTRA_PANELS:
            panels.append(cls)
    return panels


def _split(layout: bpy.types.UILayout) -> bpy.types.UILayout:
    """The panel's layout with labels beside the values and no animation dots, as Blender's
    property panels draw."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


class _EnginePanel:
    """Mixin: a panel in the Properties editor shown while this engine is selected."""

    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES: ClassVar[set[str]] = {ENGINE_ID}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.engine in cls.COMPAT_ENGINES


class _RenderPanel(_EnginePanel):
    """Mixin: a panel in Render Properties shown while this engine is selected."""

    bl_context = "render"


class RENDER_PT_vpl_gi(_RenderPanel, bpy.types.Panel):
    """VPL GI in Render Properties: what the Rendered viewport shows (a display choice, not a
    render setting), then one sub-panel per section of the settings schema."""

    bl_label = "VPL GI"

    def draw(self, context: bpy.types.Context) -> None:
        layout = _split(self.layout)
        layout.prop(context.scene.vpl_gi, "viewport_display")


class _SectionPanel(_RenderPanel):
    """Draws the settings of one schema section; those that do not apply are greyed out."""

    section: ClassVar[str]

    def draw(self, context: bpy.types.Context) -> None:
        layout = _split(self.layout)
        props = context.scene.vpl_gi
        values = props.values()
        for name, meta in SCHEMA.items():
            if meta.section == self.section:
                col = layout.column()
                col.active = applies(name, values)
                col.prop(props, name)
        if self.section == "bakes":
            layout.operator("vpl_gi.bake_materials")


class RENDER_PT_vpl_gi_motion_blur(_RenderPanel, bpy.types.Panel):
    """Render Properties > Motion Blur while this engine is selected: the render's shutter
    (Blender's own panel is EEVEE's and draws EEVEE's settings too)."""

    bl_label = "Motion Blur"
    bl_options: ClassVar[set[str]] = {"DEFAULT_CLOSED"}

    def draw_header(self, context: bpy.types.Context) -> None:
        self.layout.prop(context.scene.render, "use_motion_blur", text="")

    def draw(self, context: bpy.types.Context) -> None:
        layout = _split(self.layout)
        render = context.scene.render
        column = layout.column()
        column.active = render.use_motion_blur
        column.prop(render, "motion_blur_position", text="Position")
        column.prop(render, "motion_blur_shutter")
        column.label(text="Each pass renders its own part of the shutter (Sampling > Passes)")


class OBJECT_PT_vpl_gi_motion_blur(_EnginePanel, bpy.types.Panel):
    """Object Properties > Motion Blur while this engine is selected: Cycles' per-object
    toggles, which motion blur honours as Cycles does (Blender's panel is Cycles' own)."""

    bl_label = "Motion Blur"
    bl_context = "object"
    bl_options: ClassVar[set[str]] = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = context.object
        return super().poll(context) and obj is not None and hasattr(obj, "cycles") \
            and (obj.type in {"MESH", "CURVE", "SURFACE", "FONT", "META", "CAMERA"}
                 or (obj.instance_type == "COLLECTION" and obj.instance_collection is not None))

    def draw_header(self, context: bpy.types.Context) -> None:
        self.layout.active = context.scene.render.use_motion_blur
        self.layout.prop(context.object.cycles, "use_motion_blur", text="")

    def draw(self, context: bpy.types.Context) -> None:
        layout = _split(self.layout)
        obj = context.object
        layout.active = context.scene.render.use_motion_blur and obj.cycles.use_motion_blur
        if obj.type != "CAMERA":
            layout.column().prop(obj.cycles, "use_deform_motion", text="Deformation")


class VIEWLAYER_PT_vpl_gi_passes(_EnginePanel, bpy.types.Panel):
    """View Layer Properties > Passes while this engine is selected: the view-layer toggles of
    the passes it fills (Blender's own Passes panel is EEVEE's and Workbench's), Cycles'
    Denoising Data checkbox among them, and Cryptomatte's layers and levels."""

    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context: bpy.types.Context) -> None:
        from .layer_passes import CRYPTOMATTE_TOGGLES, OPTIONAL_PASSES, toggle_owner

        layout = _split(self.layout)
        column = layout.column(heading="Include", align=True)
        for toggle in dict.fromkeys(toggle for *_, toggle in OPTIONAL_PASSES.values()):
            found = toggle_owner(context.view_layer, toggle)
            if found is not None:
                group, name = found
                text = "Denoising Data" if name == "denoising_store_passes" else None
                column.prop(group, name, text=text)
        layer = context.view_layer
        column = layout.column(heading="Cryptomatte", align=True)
        for family, toggle in CRYPTOMATTE_TOGGLES.items():
            column.prop(layer, toggle, text=family.removeprefix("Crypto"))
        column = layout.column()
        column.active = any(getattr(layer, t) for t in CRYPTOMATTE_TOGGLES.values())
        column.prop(layer, "pass_cryptomatte_depth", text="Levels")


def draw_layer_list(layout: bpy.types.UILayout, layer: bpy.types.ViewLayer, ui_list: str,
                    collection: str, active: str, noun: str) -> bpy.types.UILayout:
    """A view layer's list (light groups, Shader AOVs) with Blender's add and remove
    buttons (scene.view_layer_add_<noun>, _remove_<noun>); returns the buttons' column."""
    row = _split(layout).row()
    row.column().template_list(ui_list, collection, layer, collection, layer, active, rows=3)
    column = row.column(align=True)
    column.operator(f"scene.view_layer_add_{noun}", icon="ADD", text="")
    column.operator(f"scene.view_layer_remove_{noun}", icon="REMOVE", text="")
    return column


class VIEWLAYER_PT_vpl_gi_light_groups(_EnginePanel, bpy.types.Panel):
    """View Layer Properties > Passes > Light Groups while this engine is selected: the view
    layer's light groups, whose Combined_<group> passes the engine fills (Blender's panel is
    Cycles' own)."""

    bl_label = "Light Groups"
    bl_context = "view_layer"
    bl_parent_id = "VIEWLAYER_PT_vpl_gi_passes"

    def draw(self, context: bpy.types.Context) -> None:
        column = draw_layer_list(self.layout, context.view_layer, "UI_UL_list", "lightgroups",
                                 "active_lightgroup_index", "lightgroup")
        column.separator()
        column.menu("VIEWLAYER_MT_lightgroup_sync", icon="DOWNARROW_HLT", text="")


class VIEWLAYER_PT_vpl_gi_aovs(_EnginePanel, bpy.types.Panel):
    """View Layer Properties > Passes > Shader AOV while this engine is selected: the view
    layer's AOVs, whose passes the materials' AOV Output nodes write (Blender's panel is
    Cycles' and EEVEE's)."""

    bl_label = "Shader AOV"
    bl_context = "view_layer"
    bl_parent_id = "VIEWLAYER_PT_vpl_gi_passes"

    def draw(self, context: bpy.types.Context) -> None:
        layer = context.view_layer
        draw_layer_list(self.layout, layer, "VIEWLAYER_UL_aov", "aovs", "active_aov_index",
                        "aov")
        if layer.active_aov is not None and not layer.active_aov.is_valid:
            self.layout.label(text="Conflicts with another render pass with the same name",
                              icon="ERROR")


def draw_light_group(layout: bpy.types.UILayout, owner: bpy.types.ID,
                     layer: bpy.types.ViewLayer) -> None:
    """An object's or world's Light Group field, with a button that adds a group of the name
    typed where the view layer has none (as Cycles draws it)."""
    row = _split(layout).row(align=True)
    row.column(align=True).prop_search(owner, "lightgroup", layer, "lightgroups",
                                       text="Light Group", results_are_suggestions=True)
    add = row.column(align=True)
    add.enabled = bool(owner.lightgroup) and owner.lightgroup not in layer.lightgroups
    add.operator("scene.view_layer_add_lightgroup", icon="ADD", text="").name = owner.lightgroup


class _LightGroupPanel(_EnginePanel):
    """Mixin: the Light Group field of the context's ``owner`` (its object or world) while
    this engine is selected (Blender's panels are Cycles' own)."""

    bl_label = "Light Group"
    bl_options: ClassVar[set[str]] = {"DEFAULT_CLOSED"}
    owner = "object"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return super().poll(context) and getattr(context, cls.owner, None) is not None

    def draw(self, context: bpy.types.Context) -> None:
        draw_light_group(self.layout, getattr(context, self.owner), context.view_layer)


class OBJECT_PT_vpl_gi_light_group(_LightGroupPanel, bpy.types.Panel):
    """Object Properties > Light Group: the group whose pass the object's light or emission
    goes to."""

    bl_context = "object"


class WORLD_PT_vpl_gi_light_group(_LightGroupPanel, bpy.types.Panel):
    """World Properties > Light Group: the group whose pass the world's light goes to."""

    bl_context = "world"
    owner = "world"


class OBJECT_PT_vpl_gi_light_linking(_EnginePanel, bpy.types.Panel):
    """Object Properties > Light Linking while this engine is selected, where Blender's own
    panel is Cycles' (4.2; later versions' is any engine's): the receiver collection an
    emitter lights, and its entries to include or exclude."""

    bl_label = "Light Linking"
    bl_context = "object"
    bl_options: ClassVar[set[str]] = {"DEFAULT_CLOSED"}
    collection = "receiver_collection"
    link_operator = "object.light_linking_receivers_link"
    new_operator = "object.light_linking_receiver_collection_new"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return super().poll(context) and context.object is not None \
            and context.object.type in {"LIGHT", "MESH", "CURVE", "SURFACE", "META", "FONT"}

    def draw(self, context: bpy.types.Context) -> None:
        layout = _split(self.layout)
        linking = context.object.light_linking
        layout.column().template_ID(linking, self.collection, new=self.new_operator)
        if getattr(linking, self.collection) is None:
            return
        row = layout.row()
        row.column().template_light_linking_collection(row, linking, self.collection)
        column = row.column(align=True)
        column.operator(self.link_operator, icon="ADD", text="").link_state = "INCLUDE"
        column.operator("object.light_linking_unlink_from_collection", icon="REMOVE", text="")


class OBJECT_PT_vpl_gi_shadow_linking(OBJECT_PT_vpl_gi_light_linking):
    """Object Properties > Shadow Linking, as Light Linking: the blocker collection whose
    objects cast an emitter's shadows."""

    bl_label = "Shadow Linking"
    collection = "blocker_collection"
    link_operator = "object.light_linking_blockers_link"
    new_operator = "object.light_linking_blocker_collection_new"


def _panel_id(section: str | None) -> str:
    return f"RENDER_PT_vpl_gi_{section}" if section else RENDER_PT_vpl_gi.__name__


def _section_panel(section: Section) -> type:
    return type(_panel_id(section.id), (_SectionPanel, bpy.types.Panel),
                {"bl_label": section.label, "bl_parent_id": _panel_id(section.parent),
                 "section": section.id})


PANELS: tuple[type, ...] = (RENDER_PT_vpl_gi, *(_section_panel(s) for s in SECTIONS))
"""Registered in this order: every parent before its sub-panels."""


OWN_PANELS = (RENDER_PT_vpl_gi_motion_blur, OBJECT_PT_vpl_gi_motion_blur,
              VIEWLAYER_PT_vpl_gi_passes, VIEWLAYER_PT_vpl_gi_light_groups,
              VIEWLAYER_PT_vpl_gi_aovs, OBJECT_PT_vpl_gi_light_group, WORLD_PT_vpl_gi_light_group)
"""Panels drawn for this engine that are not settings sections."""


def _version_panels() -> tuple[type, ...]:
    """Panels drawn for this engine where this Blender version's own are another engine's."""
    return () if hasattr(bpy.types, "OBJECT_PT_light_linking") \
        else (OBJECT_PT_vpl_gi_light_linking, OBJECT_PT_vpl_gi_shadow_linking)


_registered: list[type] = []


def register() -> None:
    _registered[:] = (*PANELS, *OWN_PANELS, *_version_panels())
    for panel in _registered:
        bpy.utils.register_class(panel)
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE_ID)


def unregister() -> None:
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    for panel in reversed(_registered):
        bpy.utils.unregister_class(panel)
    _registered.clear()
