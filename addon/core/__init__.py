"""The renderer without Blender: scene data, light transport, GPU helpers and the frame.

The visibility modes register themselves as choices of the visibility setting on import."""

from .frame import visibility  # noqa: F401 (registers the visibility modes)
