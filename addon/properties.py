"""Blender properties of the engine: one PropertyGroup on the scene, generated from the settings
schema (core/settings.py). Integer choices are string enums, read back as ints."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import bpy

from .core.settings import DEFAULTS, SCHEMA, Meta, Settings, Value
from .core.viewport_session import DISPLAY_MODES


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:]


def _property(name: str, meta: Meta) -> Any:
    """The bpy property for one setting: its default, range or choices, label, description."""
    default = getattr(DEFAULTS, name)
    common = {"name": meta.label, "description": meta.description}
    if meta.choices:
        items = [(str(c.value), c.label, _sentence(c.description)) for c in meta.choices]
        return bpy.props.EnumProperty(items=items, default=str(default), **common)
    if isinstance(default, bool):
        return bpy.props.BoolProperty(default=default, **common)
    limits = {"min": meta.low, "max": meta.high}
    if meta.soft_high is not None:
        limits["soft_max"] = meta.soft_high
    if isinstance(default, int):
        return bpy.props.IntProperty(default=default, **limits, **common)
    # Stored in single precision: validate() allows the rounding (0.01 reads as 0.0099999998).
    return bpy.props.FloatProperty(default=default, subtype=meta.subtype, unit=meta.unit,
                                   **limits, **common)


_VIEWPORT_DISPLAY = bpy.props.EnumProperty(
    name="Viewport Display", default="combined",
    items=[(mode.value, mode.label, mode.description) for mode in DISPLAY_MODES],
    description="What the Rendered viewport shows (final renders are unaffected)")


class VPLGISceneSettings(bpy.types.PropertyGroup):
    """Render settings shown in Render Properties > VPL GI: one property per Settings field,
    and the viewport's display mode (not a render setting)."""

    __annotations__ = {**{name: _property(name, meta) for name, meta in SCHEMA.items()},
                       "viewport_display": _VIEWPORT_DISPLAY}

    def values(self) -> dict[str, Value]:
        """Every setting's value as core Settings types it (integer choices as ints)."""
        return {name: int(getattr(self, name)) if meta.int_choices else getattr(self, name)
                for name, meta in SCHEMA.items()}

    def assign(self, values: Mapping[str, Value]) -> None:
        """Set settings from core-typed values (integer choices become their enum strings)."""
        for name, value in values.items():
            setattr(self, name, str(value) if SCHEMA[name].choices else value)

    def to_settings(self) -> Settings:
        """The core Settings for these values (validated)."""
        return Settings(**self.values()).validate()


def register() -> None:
    bpy.utils.register_class(VPLGISceneSettings)
    bpy.types.Scene.vpl_gi = bpy.props.PointerProperty(type=VPLGISceneSettings)


def unregister() -> None:
    del bpy.types.Scene.vpl_gi
    bpy.utils.unregister_class(VPLGISceneSettings)
