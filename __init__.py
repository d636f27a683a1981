"""Blender extension entry point of VPL GI (see blender_manifest.toml)."""

from .addon import register, unregister

__all__ = ["register", "unregister"]
