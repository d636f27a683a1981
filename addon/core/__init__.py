"""The renderer, free of Blender: scene description, settings, GPU passes. Never imports bpy."""
