"""Blender properties of the engine: one PropertyGroup on the scene mirroring core Settings."""

from __future__ import annotations

import bpy

from .core.settings import Settings

_DEFAULTS = Settings()


class VPLGISceneSettings(bpy.types.PropertyGroup):
    """Render settings shown in Render Properties > VPL GI."""

    light_samples: bpy.props.IntProperty(
        name="Light Samples", default=_DEFAULTS.light_samples, min=1, max=1024, soft_max=256,
        description="Point samples per area light, per point/spot light with a radius and per "
                    "sun with an angle (each sample gets its own shadow map)")
    emission_samples: bpy.props.IntProperty(
        name="Emission Samples", default=_DEFAULTS.emission_samples, min=1, max=4096,
        soft_max=512, description="Point samples spread over all emissive surfaces")
    world_samples: bpy.props.IntProperty(
        name="World Samples", default=_DEFAULTS.world_samples, min=1, max=1024, soft_max=256,
        description="Directions the world colour is sampled in, each with a shadow map")
    shadow_resolution: bpy.props.IntProperty(
        name="Shadow Resolution", default=_DEFAULTS.shadow_resolution, min=16, max=8192,
        soft_max=4096, description="Texels per edge of point, spot and sun shadow maps")
    sample_shadow_resolution: bpy.props.IntProperty(
        name="Sample Shadow Resolution", default=_DEFAULTS.sample_shadow_resolution, min=16,
        max=4096, soft_max=1024,
        description="Texels per edge of the shadow maps of area-light, emission and world "
                    "samples")
    shadow_bias: bpy.props.FloatProperty(
        name="Shadow Bias", default=_DEFAULTS.shadow_bias, min=0.0, max=64.0, soft_max=8.0,
        description="Receiver offset along its normal in shadow-map texels; raise it against "
                    "shadow acne, lower it against light leaking at contacts")
    antialiasing: bpy.props.IntProperty(
        name="Anti-Aliasing", default=_DEFAULTS.antialiasing, min=1, max=8,
        description="Supersampling factor per axis (2 renders 4 samples per pixel)")
    seed: bpy.props.IntProperty(
        name="Seed", default=_DEFAULTS.seed, min=0,
        description="Seed of the light sampling pattern")

    def to_settings(self) -> Settings:
        """The core Settings for these values (validated)."""
        return Settings(light_samples=self.light_samples, emission_samples=self.emission_samples,
                        world_samples=self.world_samples,
                        shadow_resolution=self.shadow_resolution,
                        sample_shadow_resolution=self.sample_shadow_resolution,
                        shadow_bias=self.shadow_bias, antialiasing=self.antialiasing,
                        seed=self.seed).validate()


def register() -> None:
    bpy.utils.register_class(VPLGISceneSettings)
    bpy.types.Scene.vpl_gi = bpy.props.PointerProperty(type=VPLGISceneSettings)


def unregister() -> None:
    del bpy.types.Scene.vpl_gi
    bpy.utils.unregister_class(VPLGISceneSettings)
