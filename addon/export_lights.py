"""Blender lights as VPL GI's lights: their kind and shape, their ray visibility, and their
strength as Cycles reads it (colour, Temperature, Exposure, Normalize and the light's
Emission node, with an IES profile)."""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache
from typing import NamedTuple

import bpy
import numpy as np

from .blender_compat import IES_SPLINE_EDGE, uses_nodes
from .blender_read import UnsupportedNodes, constant, rgb, surface_node
from .core.scene.blackbody import blackbody_rgb
from .core.scene.ies import IesError, IesProfile, parse_ies
from .core.scene.model import NO_BOUNCE_LIMIT, AreaShape, Light, LightKind
from .core.transport.spot_scale import stretch_spot
from .export_images import linked_node


def is_portal(obj: bpy.types.Object) -> bool:
    """An area light marked Portal (Cycles' light portal): an opening that guides world
    light, not a light."""
    cycles = getattr(obj.data, "cycles", None)
    return obj.data.type == "AREA" and bool(getattr(cycles, "is_portal", False))


def visible_to_camera(obj: bpy.types.Object, view_layer: bpy.types.ViewLayer | None) -> bool:
    """The object's Camera ray visibility, off too in the view layer's Indirect Only
    collections (Cycles shows those only through the light they reflect and block)."""
    return bool(getattr(obj, "visible_camera", True)) and not (
        view_layer is not None and obj.original.indirect_only_get(view_layer=view_layer))


def export_light(obj: bpy.types.Object, matrix: np.ndarray,
                 warnings: list[str] | None = None,
                 view_layer: bpy.types.ViewLayer | None = None) -> Light:
    """A light with its ray visibility (``visible_to_camera`` in ``view_layer``): camera
    (area-light shapes) and diffuse are honoured;
    glossy is not (its highlights stay), transmission and volume scatter reach only closures
    VPL GI does not render, and
    a light object's shadow visibility changes nothing in Cycles (measured, 4.5).

    Its strength is Cycles': power × 2^Exposure × the shape's area where Normalize is off,
    colour × the Temperature's colour where it is used × the light's Emission node, whose
    Strength may come from an IES profile (a sun's: the profile straight down). A spot scaled
    unevenly gets its stretched cone (core/transport/spot_scale.py)."""
    data = obj.data
    kind = LightKind(data.type)
    light = Light(obj.name, kind, matrix, color=rgb(data.color),
                  power=float(data.energy), cast_shadow=bool(getattr(data, "use_shadow", True)),
                  visible_to_camera=visible_to_camera(obj, view_layer),
                  visible_to_diffuse=bool(getattr(obj, "visible_diffuse", True)),
                  lightgroup=str(getattr(obj, "lightgroup", "")),
                  max_bounces=max_bounces(data))
    if kind in (LightKind.POINT, LightKind.SPOT):
        light.radius = float(data.shadow_soft_size)
        light.soft_falloff = bool(getattr(data, "use_soft_falloff", False))
    if kind is LightKind.SPOT:
        light.spot_size, light.spot_blend = float(data.spot_size), float(data.spot_blend)
    if kind is LightKind.SUN:
        light.sun_angle = float(data.angle)
    if kind is LightKind.AREA:
        light.area_shape = AreaShape(data.shape)
        light.size_x, light.size_y = float(data.size), float(data.size_y)
        light.spread = float(getattr(data, "spread", np.pi))
    tint, strength, profile = node_emission(data, obj.name,
                                            [] if warnings is None else warnings)
    if profile is not None and profile.mean <= 0:  # no light in any direction, as in Cycles
        strength = 0.0
    elif profile is not None and kind is LightKind.SUN:  # a sun's light: the profile's nadir
        strength *= float(profile.towards(np.array([0.0, 0.0, -1.0])))
    elif profile is not None:
        light.profile = profile
    if getattr(data, "use_temperature", False):
        tint = tuple(t * c for t, c in zip(tint, data.temperature_color, strict=True))
    light.color = tuple(c * t for c, t in zip(light.color, tint, strict=True))
    light.power *= strength * 2.0 ** float(getattr(data, "exposure", 0.0))
    if not getattr(data, "normalize", True):
        light.power *= unnormalized_area(light)
    return stretch_spot(light)


def max_bounces(data: bpy.types.Light | bpy.types.World | None) -> int:
    """Cycles' Max Bounces of a light's or the world's light (its default, no limit, where
    there is none)."""
    cycles = getattr(data, "cycles", None)
    return max(0, int(getattr(cycles, "max_bounces", NO_BOUNCE_LIMIT)))


def unnormalized_area(light: Light) -> float:
    """What Cycles multiplies a light's power by when its Normalize is off: the area it
    would have divided the power by. A sphere light's 4πr², a sun disc's π sin²(angle/2), an
    area light's shape in the world (measured against Cycles 4.5 and 5.3); 1 for a point or
    a sun of size 0."""
    if light.kind in (LightKind.POINT, LightKind.SPOT):
        area = 4.0 * math.pi * light.radius ** 2
    elif light.kind is LightKind.SUN:
        area = math.pi * math.sin(light.sun_angle / 2) ** 2
    else:
        area = light.world_area
    return area if area > 0 else 1.0


class NodeEmission(NamedTuple):
    """What a light's nodes multiply it by: a colour, a strength and an IES profile."""

    color: tuple[float, float, float]
    strength: float
    profile: IesProfile | None


def node_emission(data: bpy.types.Light, name: str, warnings: list[str]) -> NodeEmission:
    """The colour and strength of a light's Emission node, which Cycles multiplies the light
    by: its Color a constant or a Blackbody node of constant Temperature, its Strength a
    constant, a Light Falloff's Quadratic output of constant strength without smoothing, or
    an IES Texture's Fac (of constant strength and its own vector). No node tree, nodes off
    or no output for Cycles: white, 1. Anything else (other nodes, a Light Output with
    nothing linked, an IES file that cannot be read, which Cycles renders at 100 times its
    strength, measured 4.5 and 5.3): white, 1 and one warning."""
    plain = NodeEmission((1.0, 1.0, 1.0), 1.0, None)
    if not uses_nodes(data) or data.node_tree.get_output_node("CYCLES") is None:
        return plain
    node = surface_node(data.node_tree, "OUTPUT_LIGHT")
    try:
        if node is None:
            raise UnsupportedNodes("its Light Output has no Surface linked")
        if node.type != "EMISSION":
            raise UnsupportedNodes(f"its Light Output is linked to '{node.bl_label}'")
        return NodeEmission(_emission_color(node), *_emission_strength(node))
    except UnsupportedNodes as reason:
        warnings.append(f"light '{name}': {reason}; rendered without its nodes (only an "
                        f"Emission node of constant or Blackbody colour and constant, IES "
                        f"or Light Falloff strength is read)")
        return plain


def _emission_strength(node) -> tuple[float, IesProfile | None]:
    """The Emission's Strength and IES profile: a constant; a Light Falloff node's Quadratic
    output without smoothing (Cycles passes its Strength through unchanged: the inverse
    square is the light's own); or an IES Texture's Fac, its Strength times its profile."""
    socket = node.inputs["Strength"]
    link = socket.links[0] if socket.is_linked else None
    if link is not None and link.from_node.type == "LIGHT_FALLOFF" \
            and link.from_socket.name == "Quadratic" \
            and float(constant(link.from_node, "Smooth", 0.0)) == 0.0:
        return float(constant(link.from_node, "Strength", 1.0)), None
    if link is not None and link.from_node.type == "TEX_IES":
        ies = link.from_node
        if ies.inputs["Vector"].is_linked:
            raise UnsupportedNodes(f"the Vector of its IES Texture '{ies.name}' is linked")
        return float(constant(ies, "Strength", 1.0)), ies_profile(ies)
    return float(constant(node, "Strength", 1.0)), None


def ies_profile(node: bpy.types.ShaderNodeTexIES) -> IesProfile:
    """The profile of an IES Texture node: its internal text or its file (relative to the
    blend file or its library), as this Blender's Cycles interpolates it."""
    if node.mode == "INTERNAL":
        if node.ies is None:
            raise UnsupportedNodes(f"its IES Texture '{node.name}' has no text")
        text, source = node.ies.as_string(), f"text '{node.ies.name}'"
    else:
        path = bpy.path.abspath(node.filepath, library=node.id_data.library)
        source = f"file '{node.filepath}'"
        try:
            with open(path, encoding="latin-1") as file:
                text = file.read()
        except OSError as error:
            raise UnsupportedNodes(f"its IES {source} cannot be read "
                                   f"({error.strerror or error}: Cycles lights it 100 times as "
                                   f"bright)") from error
    try:
        return _read_profile(text)
    except IesError as error:
        raise UnsupportedNodes(f"its IES {source} is not a profile Cycles reads ({error}: "
                               f"Cycles lights it 100 times as bright)") from error


@lru_cache(maxsize=64)
def _read_profile(text: str) -> IesProfile:
    """A profile read once per text: lamps that share a file share one profile, and so do
    the exports of every frame (what ``light_profiles`` derives from it is cached by it)."""
    return dataclasses.replace(parse_ies(text), edge=IES_SPLINE_EDGE)


def _emission_color(node) -> tuple[float, float, float]:
    socket = node.inputs["Color"]
    source = linked_node(socket) if socket.is_linked else None
    if source is not None and source.type == "BLACKBODY":
        return blackbody_rgb(constant(source, "Temperature", 6500.0))
    return rgb(constant(node, "Color", (1.0, 1.0, 1.0)))
