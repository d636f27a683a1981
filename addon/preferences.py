"""The add-on's preferences (Preferences > Add-ons / Get Extensions > VPL GI): the GPU that
renders on machines with several, as Cycles' device choice lives in the preferences."""

from __future__ import annotations

from functools import cache

import bpy

from .core.gpu.gl import GPU_VARIABLE, GLUnavailableError, list_devices

ADDON_PACKAGE = __package__.rpartition(".")[0] or __package__
"""The installed add-on's module (the extension's root package, whose preferences these are)."""


@cache
def _devices() -> tuple[str, ...]:
    try:
        return tuple(list_devices())
    except GLUnavailableError as exc:
        return (str(exc),)


def _device_changed(_prefs: bpy.types.AddonPreferences, _context: bpy.types.Context) -> None:
    from .engine import release_renderer  # the next render makes a context on the new device

    release_renderer()


class VPLGIPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_PACKAGE

    gpu_device: bpy.props.IntProperty(  # type: ignore[valid-type]
        name="GPU", min=-1, max=15, default=-1, update=_device_changed,
        description=f"EGL device to render on (-1: ${GPU_VARIABLE} if set, else the first); "
                    "renders started after a change use it")

    def draw(self, _context: bpy.types.Context) -> None:
        self.layout.prop(self, "gpu_device")
        column = self.layout.column(align=True)
        for line in _devices():
            column.label(text=line)


def chosen_device() -> int | None:
    """The device the preferences name, or None (``VPLGI_GPU``, else the first device)."""
    addon = bpy.context.preferences.addons.get(ADDON_PACKAGE)
    device = addon.preferences.gpu_device if addon and addon.preferences else -1
    return device if device >= 0 else None


def register() -> None:
    bpy.utils.register_class(VPLGIPreferences)


def unregister() -> None:
    bpy.utils.unregister_class(VPLGIPreferences)
