"""Small scenes built in code for the core (bpy-free) tests."""

from __future__ import annotations

import numpy as np

from addon.core.scene import Camera, Instance, Light, LightKind, Material, Mesh, Scene, World


def quad(half_x: float, half_y: float, z: float = 0.0, flip: bool = False) -> Mesh:
    """An axis-aligned rectangle in the XY plane at height z, normal +Z (or -Z)."""
    p = np.array([[-half_x, -half_y, z], [half_x, -half_y, z], [half_x, half_y, z],
                  [-half_x, -half_y, z], [half_x, half_y, z], [-half_x, half_y, z]],
                 dtype=np.float32)
    if flip:
        p = p[[0, 2, 1, 3, 5, 4]]
    normal = np.array([0, 0, -1 if flip else 1], dtype=np.float32)
    return Mesh("quad", p, np.tile(normal, (6, 1)), np.zeros(2, dtype=np.int32))


def translation(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def rotation_x(angle: float) -> np.ndarray:
    m = np.eye(4)
    c, s = np.cos(angle), np.sin(angle)
    m[1:3, 1:3] = [[c, -s], [s, c]]
    return m


def top_down_camera(size: int = 64, extent: float = 6.0, height: float = 5.0) -> Camera:
    """Orthographic camera at z = height looking down -Z over [-extent/2, extent/2]²."""
    view = translation(0, 0, -height)
    near, far = 0.01, 100.0
    projection = np.array([[2 / extent, 0, 0, 0], [0, 2 / extent, 0, 0],
                           [0, 0, -2 / (far - near), -(far + near) / (far - near)],
                           [0, 0, 0, 1]])
    return Camera(view, projection, size, size, is_orthographic=True)


def pixel_centres(size: int = 64, extent: float = 6.0) -> tuple[np.ndarray, np.ndarray]:
    """World x, y of each pixel centre of top_down_camera (row 0 at the bottom)."""
    xs = (np.arange(size) + 0.5) / size * extent - extent / 2
    return np.meshgrid(xs, xs)


def floor_scene(lights: list[Light], albedo: float = 0.8, extra: list[Instance] | None = None,
                world: World | None = None, size: int = 64) -> Scene:
    """A 10 m floor at z = 0 seen from above, with the given lights."""
    floor = Instance(quad(5, 5), np.eye(4), [Material("floor", (albedo,) * 3)])
    return Scene([floor, *(extra or [])], lights, world or World(), top_down_camera(size))


def light(kind: LightKind, matrix: np.ndarray, **kwargs) -> Light:
    return Light(kind.value.lower(), kind, matrix, **kwargs)
