"""Hair curves objects (Blender's Curves: hair, fur, grass, Geometry Nodes curves) read as
the tubes Cycles renders (core/scene/hair.py)."""

from __future__ import annotations

import bpy
import numpy as np

from .blender_read import int_attribute, read_array
from .core.scene.hair import hair_mesh
from .core.scene.model import Mesh

DEFAULT_RADIUS = 0.005
"""Cycles' radius of curves without a radius attribute (measured: a strand 0.01 wide)."""


def read_hair(curves: bpy.types.Curves, name: str, label: str) -> tuple[Mesh, list[str]]:
    """The tubes of a Curves datablock's curves, and what was wrong with them (curves with
    points or radii that are not finite are left out, with a warning)."""
    point_count, curve_count = len(curves.points), len(curves.curves)
    points = read_array(curves.attributes["position"].data, "vector", point_count * 3,
                        np.float32).reshape(-1, 3)
    radius = curves.attributes.get("radius")
    radii = np.full(point_count, DEFAULT_RADIUS, np.float32) \
        if radius is None or radius.data_type != "FLOAT" or len(radius.data) != point_count \
        else read_array(radius.data, "value", point_count, np.float32)
    offsets = read_array(curves.curve_offset_data, "value", curve_count + 1, np.int32)
    slots = int_attribute(curves, "material_index", curve_count)
    if slots is None:
        slots = np.zeros(curve_count, np.int32)
    mesh, dropped = hair_mesh(name, points, radii, offsets, slots)
    problems = [f"{label}: {dropped} of {curve_count} curves have NaN/Inf points or radii "
                f"and were left out"] if dropped else []
    return mesh, problems
