"""Blender lights as VPL GI's lights: their kind and shape, their ray visibility, and their
strength as Cycles reads it (colour, Temperature, Exposure, Normalize and the light's
Emission node)."""

from __future__ import annotations

import math

import bpy
import numpy as np

from .blender_compat import uses_nodes
from .blender_read import UnsupportedNodes, constant, rgb, surface_node
from .core.scene.blackbody import blackbody_rgb
from .core.scene.model import AreaShape, Light, LightKind
from .export_images import linked_node


def is_portal(obj: bpy.types.Object) -> bool:
    """An area light marked Portal (Cycles' light portal): an opening that guides world
    light, not a light."""
    cycles = getattr(obj.data, "cycles", None)
    return obj.data.type == "AREA" and bool(getattr(cycles, "is_portal", False))


def export_light(obj: bpy.types.Object, matrix: np.ndarray,
                 warnings: list[str] | None = None) -> Light:
    """A light with its ray visibility: camera (area-light shapes) and diffuse are honoured;
    glossy is not (its highlights stay), transmission and volume scatter reach only closures
    VPL GI does not render, and
    a light object's shadow visibility changes nothing in Cycles (measured, 4.5).

    Its strength is Cycles': power × 2^Exposure × the shape's area where Normalize is off,
    colour × the Temperature's colour where it is used × the light's Emission node."""
    data = obj.data
    kind = LightKind(data.type)
    light = Light(obj.name, kind, matrix, color=rgb(data.color),
                  power=float(data.energy), cast_shadow=bool(getattr(data, "use_shadow", True)),
                  visible_to_camera=bool(getattr(obj, "visible_camera", True)),
                  visible_to_diffuse=bool(getattr(obj, "visible_diffuse", True)))
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
    tint, strength = node_emission(data, obj.name, [] if warnings is None else warnings)
    if getattr(data, "use_temperature", False):
        tint = tuple(t * c for t, c in zip(tint, data.temperature_color, strict=True))
    light.color = tuple(c * t for c, t in zip(light.color, tint, strict=True))
    light.power *= strength * 2.0 ** float(getattr(data, "exposure", 0.0))
    if not getattr(data, "normalize", True):
        light.power *= unnormalized_area(light)
    return light


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


def node_emission(data: bpy.types.Light, name: str, warnings: list[str]
                  ) -> tuple[tuple[float, float, float], float]:
    """The colour and strength of a light's Emission node, which Cycles multiplies the light
    by: its Color a constant or a Blackbody node of constant Temperature, its Strength a
    constant or a Light Falloff's Quadratic output of constant strength without smoothing.
    No node tree, nodes off or no output for Cycles: white, 1. Anything else
    (other nodes, a Light Output with nothing linked): white, 1 and one warning."""
    if not uses_nodes(data) or data.node_tree.get_output_node("CYCLES") is None:
        return (1.0, 1.0, 1.0), 1.0
    node = surface_node(data.node_tree, "OUTPUT_LIGHT")
    try:
        if node is None:
            raise UnsupportedNodes("its Light Output has no Surface linked")
        if node.type != "EMISSION":
            raise UnsupportedNodes(f"its Light Output is linked to '{node.bl_label}'")
        return _emission_color(node), _emission_strength(node)
    except UnsupportedNodes as reason:
        warnings.append(f"light '{name}': {reason}; rendered without its nodes (only an "
                        f"Emission node of constant or Blackbody colour and constant "
                        f"strength is read)")
        return (1.0, 1.0, 1.0), 1.0


def _emission_strength(node) -> float:
    """The Emission's Strength: a constant, or a Light Falloff node's Quadratic output without
    smoothing (Cycles passes its Strength through unchanged: the inverse square is the
    light's own)."""
    socket = node.inputs["Strength"]
    link = socket.links[0] if socket.is_linked else None
    if link is not None and link.from_node.type == "LIGHT_FALLOFF" \
            and link.from_socket.name == "Quadratic" \
            and float(constant(link.from_node, "Smooth", 0.0)) == 0.0:
        return float(constant(link.from_node, "Strength", 1.0))
    return float(constant(node, "Strength", 1.0))


def _emission_color(node) -> tuple[float, float, float]:
    socket = node.inputs["Color"]
    source = linked_node(socket) if socket.is_linked else None
    if source is not None and source.type == "BLACKBODY":
        return blackbody_rgb(constant(source, "Temperature", 6500.0))
    return rgb(constant(node, "Color", (1.0, 1.0, 1.0)))
