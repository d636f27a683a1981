"""Hair read as the tubes Cycles renders (core/scene/hair.py): Curves objects (hair, fur,
grass, Geometry Nodes curves) and meshes' hair particle systems."""

from __future__ import annotations

from collections.abc import Callable

import bpy
import numpy as np

from .blender_read import float_attribute, int_attribute, read_array
from .core.frame.state import RenderCancelled
from .core.scene.geometry import transform_points
from .core.scene.hair import hair_mesh, particle_radii
from .core.scene.model import Mesh, empty_mesh

CANCEL_STRANDS = 4096
"""Hair particle strands read between two checks for cancelling."""
DEFAULT_RADIUS = 0.005
"""Cycles' radius of curves without a radius attribute (measured: a strand 0.01 wide)."""


def read_hair(curves: bpy.types.Curves, name: str, label: str) -> tuple[Mesh, list[str]]:
    """The tubes of a Curves datablock's curves, and what was wrong with them (curves with
    points or radii that are not finite are left out, with a warning)."""
    point_count, curve_count = len(curves.points), len(curves.curves)
    if curve_count == 0 or point_count == 0:
        return empty_mesh(name), []
    points = read_array(curves.attributes["position"].data, "vector", point_count * 3,
                        np.float32).reshape(-1, 3)
    radii = float_attribute(curves, "radius", point_count)
    if radii is None:
        radii = np.full(point_count, DEFAULT_RADIUS, np.float32)
    offsets = read_array(curves.curve_offset_data, "value", curve_count + 1, np.int32)
    slots = int_attribute(curves, "material_index", curve_count)
    if slots is None:
        slots = np.zeros(curve_count, np.int32)
    mesh, dropped = hair_mesh(name, points, radii, offsets, slots)
    problems = [f"{label}: {dropped} of {curve_count} curves have NaN/Inf points or radii "
                f"and were left out"] if dropped else []
    return mesh, problems


def hair_systems(obj: bpy.types.Object, rendering: bool) -> list[bpy.types.ParticleSystem]:
    """The hair particle systems Cycles renders on an evaluated object: Hair drawn as Path,
    their modifier on for renders (``rendering``) or the viewport."""
    shown = "show_render" if rendering else "show_viewport"
    return [modifier.particle_system for modifier in getattr(obj, "modifiers", ())
            if modifier.type == "PARTICLE_SYSTEM" and getattr(modifier, shown)
            and modifier.particle_system.settings.type == "HAIR"
            and modifier.particle_system.settings.render_type == "PATH"]


def read_particle_hair(obj: bpy.types.Object, rendering: bool, label: str,
                       cancelled: Callable[[], bool] = lambda: False
                       ) -> tuple[Mesh, list[str]]:
    """The tubes of an evaluated object's hair particles in its object space, as Cycles reads
    them: children where it has them (and parents only without), each strand's keys from
    the particle system's paths (render or display steps), radii from the particle settings'
    root, tip, shape and scale, material from its slot; and what was wrong. Raises
    RenderCancelled when ``cancelled()`` (asked every CANCEL_STRANDS strands: a fur of a
    million strands takes seconds, a Python call a key)."""
    world = np.array(obj.matrix_world, np.float64)
    if not np.isfinite(world).all() or abs(np.linalg.det(world[:3, :3])) < 1e-30:
        return empty_mesh(obj.name), []
    to_object = np.linalg.inv(world)
    slots = max(len(obj.material_slots), 1)
    strands, radii, materials = [], [], []
    for system in hair_systems(obj, rendering):
        settings = system.settings
        parents, children = len(system.particles), len(system.child_particles)
        if not rendering:
            children = int(children * settings.display_percentage / 100)
        first, count = (parents, children) if settings.child_type != "NONE" and children \
            else (0, parents + children)
        keys = 2 ** (settings.render_step if rendering else settings.display_step) + 1
        if settings.kink == "SPIRAL":
            keys += settings.kink_extra_steps
        if count == 0:
            continue
        points = np.empty((count, keys, 3))
        for start in range(0, count, CANCEL_STRANDS):
            if cancelled():
                raise RenderCancelled("render cancelled while reading hair")
            strands_here = range(first + start, first + min(start + CANCEL_STRANDS, count))
            points[start:start + len(strands_here)] = np.reshape(
                [system.co_hair(obj, particle_no=strand, step=key)
                 for strand in strands_here for key in range(keys)], (-1, keys, 3))
        points = transform_points(to_object, points)
        scale = 0.5 * settings.radius_scale
        strands.append(points)
        radii.append(particle_radii(points, scale * settings.root_radius,
                                    scale * settings.tip_radius, settings.shape,
                                    settings.use_close_tip))
        materials.append(np.full(count, min(max(settings.material - 1, 0), slots - 1)))
    if not strands:
        return empty_mesh(obj.name), []
    lengths = np.concatenate([np.full(len(s), s.shape[1]) for s in strands])
    mesh, dropped = hair_mesh(obj.name, np.concatenate([s.reshape(-1, 3) for s in strands]),
                              np.concatenate([r.ravel() for r in radii]),
                              np.concatenate([[0], np.cumsum(lengths)]),
                              np.concatenate(materials).astype(np.int32))
    problems = [f"{label}: {dropped} hair strands have NaN/Inf points and were left out"] \
        if dropped else []
    return mesh, problems
