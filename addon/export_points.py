"""Point cloud objects (Geometry Nodes' points: scattered pebbles, dust, bubbles) read as the
spheres Cycles renders (core/scene/points.py)."""

from __future__ import annotations

import bpy
import numpy as np

from .blender_read import float_attribute, int_attribute, read_array
from .core.scene.model import Mesh
from .core.scene.points import sphere_mesh

DEFAULT_RADIUS = 0.01
"""Cycles' radius of points without a radius attribute (measured: a sphere 0.02 wide)."""


def read_points(cloud: bpy.types.PointCloud, name: str, label: str) -> tuple[Mesh, list[str]]:
    """The spheres of a point cloud's points, and what was wrong with them (points whose
    position or radius is not finite are left out, with a warning)."""
    count = len(cloud.points)
    centres = read_array(cloud.attributes["position"].data, "vector", count * 3,
                         np.float32).reshape(-1, 3) if count else np.zeros((0, 3))
    radii = float_attribute(cloud, "radius", count)
    if radii is None:
        radii = np.full(count, DEFAULT_RADIUS, np.float32)
    slots = int_attribute(cloud, "material_index", count)
    mesh, dropped = sphere_mesh(name, centres, radii,
                                np.zeros(count, np.int32) if slots is None else slots)
    problems = [f"{label}: {dropped} of {count} points have a NaN/Inf position or radius "
                f"and were left out"] if dropped else []
    return mesh, problems
