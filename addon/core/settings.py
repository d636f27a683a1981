"""Render settings of the engine: one schema for every setting (default, range or choices,
label, description, section, when it applies), from which validation, the command line's
parser, Blender's properties and panels and the README's table are all made."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

Value = int | float | str | bool


class SettingsError(ValueError):
    """A setting is outside the range the engine supports."""


class Section(NamedTuple):
    """A group of settings: one panel in Blender (a sub-panel where it has a parent)."""

    id: str
    label: str
    parent: str | None = None


SECTIONS = (
    Section("sampling", "Sampling"),
    Section("light_paths", "Light Paths"),
    Section("clamping", "Clamping", "light_paths"),
    Section("interleaving", "Interleaving", "light_paths"),
    Section("visibility", "Visibility"),
    Section("shadows", "Shadows"),
    Section("automatic", "Automatic Parameters"),
    Section("performance", "Performance"),
    Section("bakes", "Material Bakes"),
)


class Choice(NamedTuple):
    """One value a setting may take, with the label and description the UI shows."""

    value: int | str
    label: str
    description: str


class ChoiceRegistry(Sequence[Choice]):
    """Choices that modules offer by registering them (the visibility modes: each strategy
    class in frame/visibility.py registers itself)."""

    def __init__(self) -> None:
        self._choices: dict[int | str, Choice] = {}

    def register(self, choice: Choice) -> None:
        self._choices[choice.value] = choice

    def __getitem__(self, index: int) -> Choice:  # type: ignore[override] (no slices)
        return list(self._choices.values())[index]

    def __len__(self) -> int:
        return len(self._choices)

    def __iter__(self) -> Iterator[Choice]:
        return iter(list(self._choices.values()))


VISIBILITY_MODES = ChoiceRegistry()
"""The visibility modes, registered by their strategy classes (frame/visibility.py)."""


@dataclass(frozen=True)
class When:
    """A setting applies only while another one has (negated: has not) one of some values."""

    name: str
    values: tuple[Value, ...]
    negate: bool = False

    def holds(self, values: Mapping[str, Any]) -> bool:
        return (values[self.name] in self.values) != self.negate

    def __or__(self, other: When) -> AnyOf:
        return AnyOf((self, other))

    def __str__(self) -> str:
        if all(isinstance(v, bool) for v in self.values):
            return f"{self.name} {'on' if self.values[0] != self.negate else 'off'}"
        shown = " or ".join(_text(v) for v in self.values)
        return f"{self.name} {'≠' if self.negate else '='} {shown}"


@dataclass(frozen=True)
class AnyOf:
    """A setting applies while any of some conditions holds."""

    parts: tuple[When, ...]

    def holds(self, values: Mapping[str, Any]) -> bool:
        return any(part.holds(values) for part in self.parts)

    def __str__(self) -> str:
        return " or ".join(str(part) for part in self.parts)


def when(name: str, *values: Value) -> When:
    return When(name, values)


def unless(name: str, *values: Value) -> When:
    return When(name, values, negate=True)


@dataclass(frozen=True)
class Meta:
    """Everything about one setting except its name and default (the dataclass field's).
    A numeric setting has low/high (soft_high: the UI slider's end); a choice setting has
    choices; a boolean has neither. subtype and unit are Blender property hints."""

    label: str
    section: str
    description: str
    low: int | float | None = None
    high: int | float | None = None
    soft_high: int | float | None = None
    choices: Sequence[Choice] = ()
    applies: When | AnyOf | None = None
    subtype: str = "NONE"
    unit: str = "NONE"

    @property
    def values(self) -> tuple[int | str, ...]:
        return tuple(c.value for c in self.choices)

    @property
    def int_choices(self) -> bool:
        """Whether the choices are integers (sizes, factors) rather than names."""
        return bool(self.choices) and isinstance(self.choices[0].value, int)


_KEY = "schema"


def setting(default: Value, label: str, section: str, description: str, **meta: Any) -> Any:
    """A Settings field: its default and its Meta (keyword arguments as Meta's)."""
    return field(default=default, metadata={_KEY: Meta(label, section, description, **meta)})


def _sizes(what: str) -> tuple[Choice, ...]:
    return tuple(Choice(r, f"{r}²", f"{r}×{r} texels per {what}") for r in (32, 64, 128, 256, 512))


_ISM_USED = when("visibility", "ism") | when("soft_light_ism", True)
_SHADOW_MAPS = when("direct_shadows", "shadow_maps", "hybrid")


@dataclass(frozen=True)
class Settings:
    """All user-facing parameters of one render. Ranges are checked by :meth:`validate`."""

    light_samples: int = setting(
        16, "Light Samples", "sampling",
        "Point samples per area light, per sphere light (radius > 0) and per sun with an angle, "
        "each with its own shadow map; shadow-mapped samples are spread over each pixel's "
        "supersamples (each takes 1/antialiasing² of them, the pixel all of them once)",
        low=1, high=1024, soft_high=256)
    emission_samples: int = setting(
        64, "Emission Samples", "sampling",
        "Point samples spread over all emissive surfaces (by emitted power)",
        low=1, high=4096, soft_high=512)
    world_samples: int = setting(
        64, "World Samples", "sampling",
        "Directions the world colour is sampled in (by brightness for an environment map), "
        "each with its own shadow map", low=1, high=1024, soft_high=256)
    direct_shadows: str = setting(
        "hybrid", "Direct Shadows", "shadows",
        "How the shadows of direct light (lights, emissive surfaces, the world) are found",
        choices=(Choice("hybrid", "Hybrid",
                        "ray traced for point and spot lights of no size and for suns (a sun "
                        "with an angle: one of its samples per supersample): exact edges; "
                        "shadow maps for the samples of area and sphere lights, emission and "
                        "the world"),
                 Choice("ray_traced", "Ray Traced",
                        "a ray per pixel and light sample on the GPU ray tracer (exact; slow "
                        "for many samples without a hardware GPU)"),
                 Choice("shadow_maps", "Shadow Maps",
                        "a shadow map per light sample (faster for many samples on slow "
                        "ray tracing; edges as sharp as the map's texels)")))
    adaptive_shadows: bool = setting(
        True, "Adaptive Shadow Rays", "shadows",
        "Trace the shadow rays of ray-traced direct light once per pixel first, then at every "
        "supersample only where the pixels around it disagree (shadow edges, penumbrae, "
        "silhouettes); off, or with antialiasing 1: at every supersample. Shadows thinner "
        "than a pixel that fall between pixel centres can be missed",
        applies=when("direct_shadows", "hybrid", "ray_traced"))
    shadow_resolution: int = setting(
        1024, "Shadow Resolution", "shadows",
        "Texels per edge of each cube face / directional shadow map of point, spot and sun "
        "lights (each of a sun's angle samples too: its map spans the whole scene)",
        low=16, high=8192, soft_high=4096, applies=_SHADOW_MAPS)
    sample_shadow_resolution: int = setting(
        256, "Sample Shadow Resolution", "shadows",
        "Texels per edge of the shadow maps of area-light, sphere-light, emission and world "
        "samples", low=16, high=4096, soft_high=1024, applies=_SHADOW_MAPS)
    shadow_bias: float = setting(
        1.5, "Shadow Bias", "shadows",
        "Receiver offset in shadow-map texels (scale independent): in the cube maps of "
        "point, spot, area and sphere lights, emission and VPLs half of it along the normal "
        "and a quarter towards the light (grazing shadow edges stay nearer their place), in "
        "the maps of suns and the world all along the normal; raise it against shadow acne, "
        "lower it against light leaking at contacts",
        low=0.0, high=64.0, soft_high=8.0,
        applies=_SHADOW_MAPS | when("visibility", "classic"))
    antialiasing: int = setting(
        3, "Anti-Aliasing", "sampling",
        "Supersampling factor per axis, box filter (1 = one sample per pixel, 2 = four)",
        low=1, high=8)
    seed: int = setting(
        0, "Seed", "sampling",
        "Seed of every stochastic choice; a render is deterministic for (scene, settings)",
        low=0, high=2**31 - 1)
    passes: int = setting(
        1, "Passes", "sampling",
        "Passes of a final render, each with its own light samples and VPLs, averaged and "
        "shown after each pass; the VPL clamp distance shrinks as pass^(-1/6), so the image "
        "keeps converging",
        low=1, high=1 << 16, soft_high=64)
    viewport_passes: int = setting(
        16, "Viewport Passes", "sampling",
        "Passes the Rendered viewport adds while nothing changes, each with its own VPLs, "
        "showing their average (as Cycles' viewport samples); any edit starts over",
        low=1, high=1 << 16, soft_high=256)
    time_limit: float = setting(
        0.0, "Time Limit", "sampling",
        "Seconds a final render may take: no pass starts that would end past it, by the mean "
        "time of the passes so far like it (at least one pass; 0 = no limit)",
        low=0.0, high=7 * 86400.0, soft_high=600.0, applies=unless("passes", 1))
    noise_threshold: float = setting(
        0.0, "Noise Threshold", "sampling",
        "A final render stops once its estimated noise, relative to the image's mean (from "
        "the difference of the averages of even and odd passes), is below this (0 = off)",
        low=0.0, high=1.0, applies=unless("passes", 1))
    bounces: int = setting(
        4, "Bounces", "light_paths",
        "Diffuse bounces, as Cycles counts them: 0 = direct light only",
        low=0, high=64, soft_high=16)
    vpl_count: int = setting(
        1024, "Light Paths", "light_paths",
        "Light paths started per frame; each leaves a virtual point light (VPL) at every "
        "bounce it survives", low=1, high=1 << 16, soft_high=4096)
    vpl_guidance: str = setting(
        "camera", "VPL Guidance", "light_paths",
        "Which light paths' VPLs are kept",
        choices=(Choice("camera", "Camera",
                        "when under a quarter of the light paths' VPLs light the view (a room lit "
                        "through a window): trace more paths and keep VPLs by their estimated "
                        "contribution to what the camera sees, reweighted (Georgiev & "
                        "Slusallek 2010); not with incremental reuse"),
                 Choice("off", "Off", "keep every VPL the light paths leave")),
        applies=when("vpl_source", "paths"))
    guidance_candidates: int = setting(
        16, "Most Candidates", "light_paths",
        "With camera guidance, this many light paths are traced per path's worth of VPLs "
        "kept, as candidates to keep them from",
        low=2, high=64, soft_high=32, applies=when("vpl_guidance", "camera"))
    vpl_source: str = setting(
        "paths", "VPL Source", "light_paths", "Where VPLs come from",
        choices=(Choice("paths", "Light Paths",
                        "light tracing from every emitter, every bounce"),
                 Choice("rsm", "Reflective Shadow Maps",
                        "first hits importance-sampled by reflected flux from the lights' "
                        "reflective shadow maps (lights only, not the world or emission), "
                        "later bounces traced on from them")))
    rsm_resolution: int = setting(
        128, "RSM Resolution", "light_paths", "Texels per edge of each reflective-shadow-map face",
        choices=_sizes("reflective-shadow-map face"), applies=when("vpl_source", "rsm"))
    termination: str = setting(
        "fractional", "Path Termination", "light_paths", "How light paths end",
        choices=(Choice("fractional", "Fractional Absorption",
                        "N paths start, ρ̄N continue, ρ̄²N after that (ρ̄: area-weighted mean "
                        "albedo): VPL sets stay stratified; best when albedos are alike"),
                 Choice("roulette", "Russian Roulette",
                        "each path continues with its surface's albedo: better when albedos "
                        "differ widely")))
    visibility: str = setting(
        "ism", "Visibility", "visibility", "How the visibility of each VPL is found",
        choices=VISIBILITY_MODES)
    ray_traced_from_pass: int = setting(
        3, "Ray-Traced From Pass", "visibility",
        "Passes of a final render from this one on trace a ray per pixel and VPL instead of "
        "reading imperfect shadow maps, in scenes with more triangles than each map has "
        "points: the maps' visibility error is the same in every pass, so passes alone do "
        "not remove it (0 = never)",
        low=0, high=1 << 16, soft_high=64, applies=when("visibility", "ism"))
    map_error_limit: float = setting(
        0.25, "Map Error Limit", "visibility",
        "In scenes with more triangles than each imperfect shadow map has points, a frame "
        "(not with VPL reuse) first compares the light its maps let through with what rays "
        "let through at 4096 pairs of VPLs and points the camera sees; off by more than "
        "this share, it traces a ray per pixel and VPL instead, as thin occluders the maps "
        "miss let light through (0 = no check)",
        low=0.0, high=10.0, soft_high=1.0, applies=when("visibility", "ism"))
    vpl_shadow_resolution: int = setting(
        256, "VPL Shadow Resolution", "visibility",
        "Texels per cube-face edge of each VPL's shadow map",
        low=16, high=2048, soft_high=1024, applies=when("visibility", "classic"))
    clamp_distance: float = setting(
        0.1, "Clamp Distance", "clamping",
        "VPL distances below this fraction of the scene's radius are clamped: bounds the 1/d² "
        "spikes next to VPLs at the cost of some energy (0 = no clamp)",
        low=0.0, high=1.0, subtype="FACTOR")
    bias_compensation: str = setting(
        "image", "Bias Compensation", "clamping",
        "Restore the light the clamp removes next to corners and contacts: short rays from "
        "each pixel find the surfaces closer than the clamp distance and add their light "
        "(Kollig & Keller 2004, one level)",
        choices=(Choice("off", "Off", "leave the clamp's bias (darker corners and contacts)"),
                 Choice("full", "Full", "each ray's hit gathers every VPL again: also where "
                        "the camera cannot see the hit, but one gather per ray (slow)"),
                 Choice("image", "From the Image",
                        "each ray's hit takes its light from the image already gathered (one "
                        "ray per supersample costs about one hard light's shadows); hits the "
                        "camera cannot see gather their light there (direct light; with "
                        "more than one bounce and imperfect shadow maps also the VPLs')")),
        applies=unless("clamp_distance", 0.0))
    bias_samples: int = setting(
        1, "Compensation Rays", "clamping",
        "Rays per supersample for bias compensation (the blur averages its neighbours' rays)",
        low=1, high=1024, soft_high=128, applies=unless("bias_compensation", "off"))
    interleave: int = setting(
        8, "Interleave", "interleaving",
        "Interleaved sampling: each supersample of a K×K pattern gathers every K²-th VPL and "
        "every K²-th world sample (1 = off); a geometry-aware blur then removes the pattern",
        choices=(Choice(1, "Off", "every pixel gathers every VPL"),
                 Choice(2, "2×2", "each pixel gathers every 4th VPL"),
                 Choice(4, "4×4", "each pixel gathers every 16th VPL"),
                 Choice(8, "8×8", "each pixel gathers every 64th VPL")))
    blur_radius: int = setting(
        4, "Blur Radius", "interleaving",
        "Radius in (supersampled) pixels of the geometry-aware blur that removes the "
        "interleaving pattern without crossing depth or normal edges; rounded up to a multiple "
        "of K/2 so the pattern cancels exactly on flat surfaces",
        low=1, high=32, applies=unless("interleave", 1))
    indirect_resolution: str = setting(
        "auto", "Indirect Resolution", "interleaving",
        "Where the light of VPLs is gathered",
        choices=(Choice("pixel", "Pixel", "once per pixel, then brought to every supersample "
                        "along the g-buffer's geometry: indirect light varies slowly, so direct "
                        "light, colours, edges and the bias compensation (sharp next to "
                        "contacts and sunlit patches) keep the supersampling; surfaces "
                        "thinner than the interleaving pattern gather every VPL"),
                 Choice("supersample", "Supersample", "at every supersample (antialiasing² "
                        "times the work)"),
                 Choice("auto", "Automatic", "per pixel where no material is glossy, else "
                        "per supersample (glossy indirect light is sharper than a pixel)")),
        applies=unless("antialiasing", 1))
    denoiser: str = setting(
        "blur", "Denoiser", "sampling",
        "What removes the noise of the light gathered from VPLs (Intel Open Image Denoise: "
        "the pyoidn wheel bundled for this platform, else the blur with a warning)",
        choices=(Choice("blur", "Blur", "the geometry-aware blur of the interleaved indirect "
                        "light only (the least error of the four on the sample scenes)"),
                 Choice("oidn", "OIDN", "Open Image Denoise on the final image, with the "
                        "Denoising Albedo and Normal passes as guides, instead of the blur "
                        "(it keeps much of the interleaving pattern)"),
                 Choice("blur_oidn", "Blur + OIDN", "the blur, then Open Image Denoise on the "
                        "final image"),
                 Choice("oidn_indirect", "OIDN Indirect", "Open Image Denoise on the indirect "
                        "light only (DiffInd × DiffCol), instead of the blur")))
    soft_light_ism: bool = setting(
        False, "Soft Lights with ISMs", "shadows",
        "Shadow the samples of area lights, sphere lights, suns with an angle and the world "
        "with imperfect shadow maps instead of triangle shadow maps (the seed's soft shadows "
        "and natural illumination from many point lights: faster for many samples, slightly "
        "less exact)", applies=_SHADOW_MAPS)
    ism_points: int = setting(
        8192, "Points per VPL", "visibility",
        "Surface points splatted into each imperfect shadow map (drawn on the GPU from the "
        "seed: every VPL its own set, uniform by area and stratified over the surfaces)",
        low=16, high=1 << 16, soft_high=32768, applies=_ISM_USED)
    ism_resolution: int = setting(
        128, "ISM Resolution", "visibility",
        "Texels per edge of each imperfect shadow map (paraboloid, one per VPL)",
        choices=_sizes("imperfect shadow map"), applies=_ISM_USED)
    incremental: bool = setting(
        False, "Reuse VPLs Between Frames", "performance",
        "Incremental Instant Radiosity: reuse last frame's VPLs (and their shadow maps) where "
        "the lights still reach them; only invalid ones and a few redistributed ones are new. "
        "For animations rendered in order in one process and the viewport; off, every frame is "
        "made afresh (the same image whichever machine renders the frame)")
    incremental_budget: int = setting(
        8, "Redistributed per Frame", "performance",
        "VPLs per light moved per frame from the most crowded place to the emptiest one "
        "(invalid VPLs are always replaced at once)",
        low=0, high=1024, soft_high=64, applies=when("incremental", True))
    pull_push_levels: int = setting(
        7, "Pull-Push Levels", "visibility",
        "Pull-push levels that fill the holes between splatted points (capped at "
        "log2(ism_resolution), which fills every hole; 0 keeps the raw splats)",
        low=0, high=12, applies=_ISM_USED)
    auto_parameters: str = setting(
        "off", "Automatic Parameters", "automatic",
        "Choose vpl_count, ism_points, ism_resolution, interleave and blur_radius for final "
        "renders from a cost model measured once on this machine and an error model fitted "
        "on reports",
        choices=(Choice("off", "Off", "use the settings as set"),
                 Choice("time", "Time Budget",
                        "the least error within time_budget: passes until it is spent, the "
                        "first sized from the cost model, the others from its measured time, "
                        "averaged by their light paths (adapts to the machine: farms pin the "
                        "parameters instead)"),
                 Choice("error", "Target Error",
                        "the least predicted time within target_error")))
    time_budget: float = setting(
        2.0, "Time Budget", "automatic",
        "Seconds per frame the automatic mode 'time' renders passes for (the passes, time "
        "limit and noise threshold settings do not apply); below the cheapest useful frame "
        "(64 VPLs lighting the view) that frame is rendered, with a warning",
        low=0.01, high=86400.0, soft_high=600.0, unit="TIME_ABSOLUTE",
        applies=when("auto_parameters", "time"))
    target_error: float = setting(
        0.1, "Target Error", "automatic",
        "Relative RMSE against a converged image that the automatic mode 'error' aims at",
        low=0.001, high=10.0, soft_high=1.0, subtype="FACTOR",
        applies=when("auto_parameters", "error"))
    planner: bool = setting(
        True, "Leave Out Unneeded Work", "performance",
        "Leave out work the frame does not need (lights that cannot reach the view, a black "
        "world, pull-push levels the point density does not need, passes not asked for, work "
        "kept from the last frame). Off runs every stage: for comparisons only")

    bake_resolution: int = setting(
        512, "Bake Resolution", "bakes",
        "Texels per edge of the image each object's material colours are baked into, where "
        "they come from nodes read no other way (procedural textures, ColorRamp, Mapping …); "
        "baked by Cycles before background renders and by Bake Materials",
        choices=tuple(Choice(r, f"{r}²", f"{r}×{r} texels per baked object")
                      for r in (64, 128, 256, 512, 1024, 2048, 4096)))
    bake_memory: int = setting(
        1024, "Bake Memory", "bakes",
        "MiB that baked images may hold together (16 bytes per texel and channel); an object "
        "whose bake does not fit keeps its viewport colour, with a warning",
        low=16, high=65536, soft_high=8192)

    def validate(self) -> Settings:
        """Return self, or raise SettingsError naming the first setting out of range."""
        for f in fields(self):
            _check(f.name, getattr(self, f.name), f.metadata[_KEY], type(f.default))
        return self

    @staticmethod
    def parse(name: str, text: str) -> Value:
        """A setting's value from text (as typed on a command line), checked against its range
        or choices; booleans accept true/false, 1/0, yes/no and on/off."""
        if name not in SCHEMA:
            raise SettingsError(f"unknown setting '{name}' (choose from "
                                f"{', '.join(sorted(SCHEMA))})")
        meta, kind, text = SCHEMA[name], type(getattr(DEFAULTS, name)), text.strip()
        if meta.choices:
            matches = [v for v in meta.values if str(v) == text]
            if not matches:
                raise SettingsError(f"{name} = {text!r} is not one of {_listed(meta.values)}")
            return matches[0]
        if kind is bool:
            if text.lower() not in _TRUE + _FALSE:
                raise SettingsError(f"{name} = {text!r} must be true or false "
                                    "(or 1/0, yes/no, on/off)")
            return text.lower() in _TRUE
        try:
            value = kind(text)
        except ValueError:
            raise SettingsError(f"{name} = {text!r} is not a valid "
                                f"{'integer' if kind is int else 'number'}") from None
        _check(name, value, meta, kind)
        return value


_TRUE, _FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")
# Blender stores float properties in single precision: 0.01 comes back as 0.0099999998.
_FLOAT32_TOLERANCE = 1e-6


def _text(value: Value) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _listed(values: tuple[int | str, ...]) -> str:
    return ", ".join(str(v) for v in values)


def _check(name: str, value: Any, meta: Meta, kind: type) -> None:
    """Raise SettingsError unless value is one of the setting's choices, within its range, or
    (a setting with neither) a boolean."""
    if meta.choices:
        if value not in meta.values:
            raise SettingsError(f"{name} = {value!r} is not one of {_listed(meta.values)}")
    elif meta.low is None or meta.high is None:
        if not isinstance(value, bool):
            raise SettingsError(f"{name} = {value!r} must be true or false")
    else:
        low, high = meta.low, meta.high
        slack = _FLOAT32_TOLERANCE if kind is float else 0.0
        if not isinstance(value, int | float) or not (
                low - slack * abs(low) <= value <= high + slack * abs(high)):
            raise SettingsError(f"{name} = {value!r} is outside the supported range "
                                f"[{low}, {high}]")


SCHEMA: dict[str, Meta] = {f.name: f.metadata[_KEY] for f in fields(Settings)}
"""Every setting's Meta by name, in declaration order."""
DEFAULTS = Settings()


def applies(name: str, values: Mapping[str, Any]) -> bool:
    """Whether setting name has an effect given the other settings' values."""
    condition = SCHEMA[name].applies
    return condition is None or condition.holds(values)
