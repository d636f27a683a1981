"""VPL GI: a Blender render engine for global illumination with virtual point lights.

Importing this package does not import Blender; ``register()`` does.
"""

from __future__ import annotations

ENGINE_ID = "VPL_GI"
"""The render engine's identifier (``scene.render.engine``)."""


def register() -> None:
    """Register the engine, its properties and its panels with Blender."""
    from . import bake, engine, preferences, properties, ui, viewport

    preferences.register()
    properties.register()
    ui.register()
    bake.register()
    viewport.register()
    engine.register()


def unregister() -> None:
    """Undo register(); a bpy process must call this before it exits, or it hangs."""
    from . import bake, engine, preferences, properties, ui, viewport

    engine.unregister()
    viewport.unregister()
    bake.unregister()
    ui.unregister()
    properties.unregister()
    preferences.unregister()
