"""A furnace for measuring Cycles' materials (tools/measure_sheen.py,
tools/measure_oren_nayar.py): a large plane of one material under a uniform world, seen by
an orthographic camera from the cosine asked for, each render read back as its mean, so that
under a white world every pixel reads the material's albedo towards the view."""

from __future__ import annotations

import math
from pathlib import Path

import bpy
import numpy as np

GRAZING = 0.01  # the cosine seen for μ = 0 (a plane seen edge-on shows nothing)


class Furnace:
    """The scene: ``world_color`` (the Background's Color socket, white at first) and the
    camera; ``view_at`` turns the camera, ``render`` renders and reads."""

    def __init__(self, material: bpy.types.Material, size: int, samples: int) -> None:
        from tests.blender.rendering import configure_cycles

        scene = bpy.context.scene
        scene.render.engine = "CYCLES"
        configure_cycles(scene, samples, bounces=0)
        scene.render.resolution_x = scene.render.resolution_y = size
        scene.view_settings.view_transform = "Standard"
        world = bpy.data.worlds.new("White")
        world.use_nodes = True
        scene.world = world
        self.world_color = world.node_tree.nodes["Background"].inputs["Color"]
        self.world_color.default_value = (1, 1, 1, 1)
        bpy.ops.mesh.primitive_plane_add(size=1000.0)
        bpy.context.object.data.materials.append(material)
        self.camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        self.camera.data.type, self.camera.data.ortho_scale = "ORTHO", 0.1
        scene.collection.objects.link(self.camera)
        scene.camera = self.camera
        self.path = Path(bpy.app.tempdir or "/tmp") / "furnace.exr"
        scene.render.filepath = str(self.path)
        scene.render.image_settings.file_format = "OPEN_EXR"
        scene.render.image_settings.color_depth = "32"
        self.scene = scene

    def view_at(self, mu: float) -> None:
        """Turn the camera to see the plane at cosine ``mu`` (at least GRAZING), from −y:
        the view's projection on the plane is −y."""
        theta = math.acos(max(float(mu), GRAZING))
        self.camera.location = (0.0, -10.0 * math.sin(theta), 10.0 * math.cos(theta))
        self.camera.rotation_euler = (theta, 0.0, 0.0)

    def render(self) -> float:
        """Render and return the image's mean over pixels and colour channels."""
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(str(self.path))
        value = float(np.asarray(image.pixels[:]).reshape(-1, 4)[:, :3].mean())
        bpy.data.images.remove(image)
        return value
