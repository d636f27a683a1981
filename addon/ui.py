"""Panels: Blender's own panels that apply to this engine, and the engine's settings panel."""

from __future__ import annotations

from typing import ClassVar

import bpy

ENGINE_ID = "VPL_GI"
# Panels written for EEVEE that show what this engine reads (material surface, world colour,
# light settings); generic panels (format, output, colour management, ...) are found by their
# "BLENDER_RENDER" compatibility, Blender's marker for panels any engine can use.
_EXTRA_PANELS = ("EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface",
                 "EEVEE_WORLD_PT_surface", "DATA_PT_EEVEE_light")
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


class RENDER_PT_vpl_gi(bpy.types.Panel):
    """VPL GI's settings in Render Properties."""

    bl_label = "VPL GI"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES: ClassVar[set[str]] = {ENGINE_ID}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.vpl_gi
        col = layout.column(heading="Indirect Light")
        col.prop(settings, "bounces")
        col.prop(settings, "vpl_count")
        col.prop(settings, "vpl_source")
        sub = col.column()
        sub.active = settings.vpl_source == "rsm"
        sub.prop(settings, "rsm_resolution")
        col.prop(settings, "termination")
        col.prop(settings, "visibility")
        sub = col.column()
        sub.active = settings.visibility == "ism"
        sub.prop(settings, "ism_points")
        sub.prop(settings, "ism_resolution")
        sub.prop(settings, "pull_push_levels")
        sub = col.column()
        sub.active = settings.visibility == "classic"
        sub.prop(settings, "vpl_shadow_resolution")
        col.prop(settings, "incremental")
        sub = col.column()
        sub.active = settings.incremental
        sub.prop(settings, "incremental_budget")
        col.prop(settings, "interleave")
        sub = col.column()
        sub.active = settings.interleave != "1"
        sub.prop(settings, "blur_radius")
        col.prop(settings, "clamp_distance")
        col.prop(settings, "bias_compensation")
        sub = col.column()
        sub.active = settings.bias_compensation
        sub.prop(settings, "bias_samples")
        col = layout.column(heading="Direct Light")
        col.prop(settings, "light_samples")
        col.prop(settings, "emission_samples")
        col.prop(settings, "world_samples")
        col.prop(settings, "soft_light_ism")
        col = layout.column(heading="Shadows")
        col.prop(settings, "shadow_resolution")
        col.prop(settings, "sample_shadow_resolution")
        col.prop(settings, "shadow_bias")
        col = layout.column(heading="Performance")
        col.prop(settings, "auto_parameters")
        sub = col.column()
        sub.active = settings.auto_parameters == "time"
        sub.prop(settings, "time_budget")
        sub = col.column()
        sub.active = settings.auto_parameters == "error"
        sub.prop(settings, "target_error")
        col.prop(settings, "planner")
        col = layout.column(heading="Viewport")
        col.prop(settings, "viewport_display")
        col = layout.column(heading="Image")
        col.prop(settings, "antialiasing")
        col.prop(settings, "seed")


def register() -> None:
    bpy.utils.register_class(RENDER_PT_vpl_gi)
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE_ID)


def unregister() -> None:
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    bpy.utils.unregister_class(RENDER_PT_vpl_gi)
