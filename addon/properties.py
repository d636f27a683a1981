"""Blender properties of the engine: one PropertyGroup on the scene mirroring core Settings."""

from __future__ import annotations

from dataclasses import fields

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
        description="Directions the world is sampled in (by brightness for an environment "
                    "map), each with a shadow map")
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
    bounces: bpy.props.IntProperty(
        name="Bounces", default=_DEFAULTS.bounces, min=0, max=64, soft_max=16,
        description="Diffuse bounces, counted as Cycles does: 0 renders direct light only")
    vpl_count: bpy.props.IntProperty(
        name="Light Paths", default=_DEFAULTS.vpl_count, min=1, max=1 << 16, soft_max=4096,
        description="Light paths traced per frame; each leaves a virtual point light at "
                    "every bounce")
    vpl_source: bpy.props.EnumProperty(
        name="VPL Source", default=_DEFAULTS.vpl_source,
        items=[("paths", "Light Paths", "Trace light paths from every emitter (all bounces)"),
               ("rsm", "Reflective Shadow Maps",
                "Render what each light sees and importance-sample VPLs by reflected flux "
                "(one bounce, lights only)")])
    rsm_resolution: bpy.props.EnumProperty(
        name="RSM Resolution", default=str(_DEFAULTS.rsm_resolution),
        items=[(str(r), f"{r}²", f"{r}×{r} texels per reflective-shadow-map face")
               for r in (32, 64, 128, 256, 512)])
    termination: bpy.props.EnumProperty(
        name="Path Termination", default=_DEFAULTS.termination,
        items=[("fractional", "Fractional Absorption",
                "N paths start, ρ̄N continue, ρ̄²N after that (ρ̄: average reflectance): "
                "VPLs stay stratified; best for scenes of similar albedos"),
               ("roulette", "Russian Roulette",
                "Each path continues with its surface's albedo: better when albedos vary "
                "widely (dark and bright surfaces)")])
    visibility: bpy.props.EnumProperty(
        name="Visibility", default=_DEFAULTS.visibility,
        items=[("ism", "Imperfect Shadow Maps", "Point-splatted low-resolution maps for many "
                                                 "VPLs, holes filled by pull-push (fast)"),
               ("classic", "Shadow Maps", "One triangle shadow map per VPL (Instant Radiosity)"),
               ("exact", "Ray Traced", "Exact visibility of every pixel/VPL pair (slow; "
                                       "a reference)")])
    vpl_shadow_resolution: bpy.props.IntProperty(
        name="VPL Shadow Resolution", default=_DEFAULTS.vpl_shadow_resolution, min=16,
        max=2048, soft_max=1024, description="Texels per cube-face edge of each VPL shadow map")
    clamp_distance: bpy.props.FloatProperty(
        name="Clamp Distance", default=_DEFAULTS.clamp_distance, min=0.0, max=1.0,
        subtype="FACTOR",
        description="VPL distances below this fraction of the scene radius are clamped, "
                    "removing bright splotches near VPLs at the cost of some energy "
                    "(0 = no clamping)")
    bias_compensation: bpy.props.BoolProperty(
        name="Bias Compensation", default=_DEFAULTS.bias_compensation,
        description="Restore the energy removed by clamping with ray-traced gathering "
                    "(Kollig & Keller)")
    bias_samples: bpy.props.IntProperty(
        name="Compensation Rays", default=_DEFAULTS.bias_samples, min=1, max=1024,
        soft_max=128, description="Rays per pixel for bias compensation")

    interleave: bpy.props.EnumProperty(
        name="Interleave", default=str(_DEFAULTS.interleave),
        items=[("1", "Off", "Every pixel gathers every VPL"),
               ("2", "2×2", "Each pixel gathers every 4th VPL"),
               ("4", "4×4", "Each pixel gathers every 16th VPL"),
               ("8", "8×8", "Each pixel gathers every 64th VPL")],
        description="Interleaved sampling: pixels of a K×K pattern gather disjoint VPL subsets; "
                    "a geometry-aware blur then removes the pattern")
    blur_radius: bpy.props.IntProperty(
        name="Blur Radius", default=_DEFAULTS.blur_radius, min=1, max=32,
        description="Radius in pixels of the geometry-aware blur (used with interleaving)")

    soft_light_ism: bpy.props.BoolProperty(
        name="Soft Lights with ISMs", default=_DEFAULTS.soft_light_ism,
        description="Shadow the samples of area lights, sphere lights, suns with an angle and "
                    "the world with imperfect shadow maps (faster for many samples, slightly "
                    "less exact)")
    ism_points: bpy.props.IntProperty(
        name="Points per VPL", default=_DEFAULTS.ism_points, min=16, max=1 << 16,
        soft_max=32768, description="Surface points splatted into each imperfect shadow map")
    ism_resolution: bpy.props.EnumProperty(
        name="ISM Resolution", default=str(_DEFAULTS.ism_resolution),
        items=[(str(r), f"{r}²", f"{r}×{r} texels per imperfect shadow map")
               for r in (32, 64, 128, 256, 512)])
    pull_push_levels: bpy.props.IntProperty(
        name="Pull-Push Levels", default=_DEFAULTS.pull_push_levels, min=0, max=12,
        description="Levels of the pull-push hole filling (log2 of the resolution fills every "
                    "hole; 0 keeps the raw splats)")

    incremental: bpy.props.BoolProperty(
        name="Reuse VPLs Between Frames", default=_DEFAULTS.incremental,
        description="Incremental Instant Radiosity: keep the VPLs the lights still reach from "
                    "the previous frame and make new ones only where needed (smoother "
                    "animations of moving lights rendered in order; leave off when frames "
                    "are rendered separately, e.g. on a render farm)")
    incremental_budget: bpy.props.IntProperty(
        name="Redistributed per Frame", default=_DEFAULTS.incremental_budget, min=0, max=1024,
        soft_max=64, description="VPLs per light moved each frame from the most crowded spot "
                                 "to the emptiest one (invalid VPLs are always replaced)")

    auto_parameters: bpy.props.EnumProperty(
        name="Automatic Parameters", default=_DEFAULTS.auto_parameters,
        items=[("off", "Off", "Use the VPL and imperfect-shadow-map settings as set"),
               ("time", "Time Budget", "Choose VPL count, points per VPL, ISM resolution, "
                                       "interleaving and blur for the least error within the "
                                       "time budget per frame"),
               ("error", "Target Error", "Choose them for the least time that reaches the "
                                         "target error")],
        description="Choose the VPL and imperfect-shadow-map parameters from a cost model "
                    "measured once on this machine and an error model fitted on reports")
    time_budget: bpy.props.FloatProperty(
        name="Time Budget", default=_DEFAULTS.time_budget, min=0.01, max=86400.0,
        soft_max=600.0, unit="TIME_ABSOLUTE", description="Seconds per frame to aim at")
    target_error: bpy.props.FloatProperty(
        name="Target Error", default=_DEFAULTS.target_error, min=0.001, max=10.0, soft_max=1.0,
        subtype="FACTOR", description="Relative RMSE against a converged image to aim at")
    planner: bpy.props.BoolProperty(
        name="Leave Out Unneeded Work", default=_DEFAULTS.planner,
        description="Skip what a frame does not need: lights that cannot reach the view, a "
                    "black world, pull-push levels the point density does not need, passes "
                    "not enabled, work kept from the last frame (off: run every stage, for "
                    "comparisons)")

    viewport_display: bpy.props.EnumProperty(
        name="Viewport Display", default="combined",
        items=[("combined", "Combined", "The full image"),
               ("direct", "Direct Light", "Direct light and emission only"),
               ("indirect", "Indirect Light", "Only the light the VPLs bring"),
               ("vpls", "VPL Positions", "The image with each VPL as a dot coloured by its "
                                         "bounce (yellow first, then orange, pink, blue)"),
               ("ism", "ISM Atlas", "The imperfect shadow maps, near as white")],
        description="What the Rendered viewport shows (final renders are unaffected)")

    def to_settings(self) -> Settings:
        """The core Settings for these values (validated)."""
        values = {f.name: getattr(self, f.name) for f in fields(Settings)}
        values["interleave"] = int(values["interleave"])
        values["ism_resolution"] = int(values["ism_resolution"])
        values["rsm_resolution"] = int(values["rsm_resolution"])
        return Settings(**values).validate()


def register() -> None:
    bpy.utils.register_class(VPLGISceneSettings)
    bpy.types.Scene.vpl_gi = bpy.props.PointerProperty(type=VPLGISceneSettings)


def unregister() -> None:
    del bpy.types.Scene.vpl_gi
    bpy.utils.unregister_class(VPLGISceneSettings)
