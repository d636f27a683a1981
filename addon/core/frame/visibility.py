"""How a gathered light sample is occluded: one strategy class per visibility mode,
registered by name. A mode says how its samples are batched, which maps it renders per batch,
and the defines and rays of its branch of ``shadow_visibility()`` in lights_lib.glsl."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import moderngl
import numpy as np

from ..settings import VISIBILITY_MODES, Choice, Settings
from ..transport.lights import LightSamples
from .batches import Batch, ism_batches, shadow_map_batches, unmapped_batches
from .ism_maps import ImperfectShadowMapFrame
from .shadow_maps import ShadowAtlases


@dataclass
class FrameMaps:
    """The map renderers of one frame that visibility modes draw on."""

    shadow_atlases: ShadowAtlases
    ism: ImperfectShadowMapFrame | None
    centre: np.ndarray
    radius: float
    reuse_atlas: bool  # one light pass: its atlas serves every tile


class Visibility:
    """A visibility mode (the base is not registered)."""

    name: ClassVar[str]
    label: ClassVar[str]
    description: ClassVar[str]
    defines: ClassVar[dict[str, object]] = {}
    rays_per_sample: ClassVar[int] = 0
    """Rays the gather traces per pixel and light sample (needs the ray tracer's BVH)."""
    uses_ism: ClassVar[bool] = False

    def prepare(self, samples: LightSamples) -> LightSamples:
        """The samples as this mode gathers them."""
        return samples

    def batches(self, samples: LightSamples, settings: Settings, max_texture: int
                ) -> list[Batch]:
        return shadow_map_batches(samples, max_texture)

    def maps(self, batch: Batch, frame_maps: FrameMaps) -> moderngl.Texture:
        """The texture the gather reads this batch's occlusion from."""
        return frame_maps.shadow_atlases.atlas(batch, frame_maps.centre, frame_maps.radius,
                                                again=frame_maps.reuse_atlas)


VISIBILITY: dict[str, type[Visibility]] = {}
"""The visibility modes by name, in the order the user is offered them."""


def register(cls: type[Visibility]) -> type[Visibility]:
    """Offer a visibility mode (class decorator): the renderer, the setting's choices, the
    Blender property, the UI, the command line and the README table take it from here."""
    VISIBILITY[cls.name] = cls
    VISIBILITY_MODES.register(Choice(cls.name, cls.label, cls.description))
    return cls


@register
class ImperfectVisibility(Visibility):
    name = "ism"
    label = "Imperfect Shadow Maps"
    description = ("a point-splatted paraboloid map per VPL, holes filled by pull-push "
                   "(fast)")
    defines: ClassVar[dict[str, object]] = {"ISM_VISIBILITY": 1}
    uses_ism = True

    def batches(self, samples: LightSamples, settings: Settings, max_texture: int
                ) -> list[Batch]:
        return ism_batches(samples, settings.ism_resolution)

    def maps(self, batch: Batch, frame_maps: FrameMaps) -> moderngl.Texture:
        return frame_maps.ism.atlas(batch)


@register
class ShadowMapVisibility(Visibility):
    name = "classic"
    label = "Shadow Maps"
    description = "a triangle cube shadow map per VPL (Instant Radiosity)"


@register
class RayTracedVisibility(Visibility):
    name = "exact"
    label = "Ray Traced"
    description = "a ray per pixel and VPL (slow; the reference for visibility error)"
    defines: ClassVar[dict[str, object]] = {"EXACT_VISIBILITY": 1}
    rays_per_sample = 1

    def batches(self, samples: LightSamples, settings: Settings, max_texture: int
                ) -> list[Batch]:
        return unmapped_batches(samples)

    def maps(self, batch: Batch, frame_maps: FrameMaps) -> moderngl.Texture:
        return frame_maps.shadow_atlases.placeholder()
