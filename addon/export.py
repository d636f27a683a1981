"""Blender -> core.Scene: reads the evaluated depsgraph into numpy arrays with foreach_get."""

from __future__ import annotations

import math

import bpy
import numpy as np

from .core.scene import AreaShape, Camera, Instance, Light, LightKind, Material, Mesh, Scene, World

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
DEFAULT_MATERIAL = Material("(no material)")


def _matrix(m) -> np.ndarray:
    return np.array(m, dtype=np.float64)


def _rgb(value) -> tuple[float, float, float]:
    return (float(value[0]), float(value[1]), float(value[2]))


def _mesh_arrays(mesh: bpy.types.Mesh, name: str) -> Mesh:
    """Triangles of an evaluated mesh as corner arrays."""
    mesh.calc_loop_triangles()
    tris = mesh.loop_triangles
    count = len(tris)
    corner = np.empty(count * 3, dtype=np.int32)
    tris.foreach_get("loops", corner)
    slots = np.empty(count, dtype=np.int32)
    tris.foreach_get("material_index", slots)
    vertex_of_corner = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", vertex_of_corner)
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    normals = np.empty(len(mesh.loops) * 3, dtype=np.float32)
    mesh.corner_normals.foreach_get("vector", normals)
    positions = co.reshape(-1, 3)[vertex_of_corner[corner]]
    return Mesh(name, positions, normals.reshape(-1, 3)[corner], slots)


def _surface_node(tree: bpy.types.NodeTree | None, output_type: str):
    """The shader node linked to the active output's Surface socket, or None."""
    if tree is None:
        return None
    outputs = [n for n in tree.nodes if n.type == output_type]
    active = next((n for n in outputs if getattr(n, "is_active_output", False)),
                  outputs[0] if outputs else None)
    if active is None or not active.inputs["Surface"].is_linked:
        return None
    return active.inputs["Surface"].links[0].from_node


def _input_value(node, name: str, default):
    socket = node.inputs.get(name)
    return default if socket is None else socket.default_value


def export_material(material: bpy.types.Material | None, warnings: list[str]) -> Material:
    """Base colour and emission of a material's surface shader (constant values)."""
    if material is None:
        return DEFAULT_MATERIAL
    node = _surface_node(material.node_tree, "OUTPUT_MATERIAL") if material.use_nodes else None
    if node is None:
        return Material(material.name, _rgb(material.diffuse_color))
    if node.type == "BSDF_PRINCIPLED":
        strength = float(_input_value(node, "Emission Strength", 0.0))
        emission = np.array(_rgb(_input_value(node, "Emission Color", (0, 0, 0)))) * strength
        return Material(material.name, _rgb(_input_value(node, "Base Color", (0.8,) * 3)),
                        tuple(emission))
    if node.type == "BSDF_DIFFUSE":
        return Material(material.name, _rgb(_input_value(node, "Color", (0.8,) * 3)))
    if node.type == "EMISSION":
        strength = float(_input_value(node, "Strength", 1.0))
        color = np.array(_rgb(_input_value(node, "Color", (1, 1, 1)))) * strength
        return Material(material.name, (0.0, 0.0, 0.0), tuple(color))
    warnings.append(f"material '{material.name}': shader '{node.bl_label}' is not supported, "
                    f"using its viewport colour")
    return Material(material.name, _rgb(material.diffuse_color))


def export_light(obj: bpy.types.Object, matrix) -> Light:
    data = obj.data
    kind = LightKind(data.type)
    light = Light(obj.name, kind, _matrix(matrix), color=_rgb(data.color),
                  power=float(data.energy), cast_shadow=bool(getattr(data, "use_shadow", True)),
                  visible_to_camera=bool(getattr(obj, "visible_camera", True)))
    if kind in (LightKind.POINT, LightKind.SPOT):
        light.radius = float(data.shadow_soft_size)
    if kind is LightKind.SPOT:
        light.spot_size, light.spot_blend = float(data.spot_size), float(data.spot_blend)
    if kind is LightKind.SUN:
        light.sun_angle = float(data.angle)
    if kind is LightKind.AREA:
        light.area_shape = AreaShape(data.shape)
        light.size_x, light.size_y = float(data.size), float(data.size_y)
    return light


def export_world(world: bpy.types.World | None) -> World:
    if world is None:
        return World()
    node = _surface_node(world.node_tree, "OUTPUT_WORLD") if world.use_nodes else None
    if node is None:
        return World(_rgb(world.color), 1.0)
    if node.type == "BACKGROUND":
        return World(_rgb(_input_value(node, "Color", (0.05,) * 3)),
                     float(_input_value(node, "Strength", 1.0)))
    return World(_rgb(world.color), 1.0)


def export_camera(depsgraph: bpy.types.Depsgraph, camera_object: bpy.types.Object | None,
                  width: int, height: int) -> Camera | None:
    """Blender's own projection (sensor fit, shift, clipping) for the given resolution."""
    if camera_object is None:
        return None
    render = depsgraph.scene_eval.render
    cam = camera_object.evaluated_get(depsgraph)
    projection = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                        scale_x=render.pixel_aspect_x,
                                        scale_y=render.pixel_aspect_y)
    view = _matrix(cam.matrix_world.inverted())
    return Camera(view, _matrix(projection), width, height,
                  is_orthographic=cam.data.type == "ORTHO")


def render_size(scene: bpy.types.Scene) -> tuple[int, int]:
    """Output resolution in pixels, percentage applied (as Blender does)."""
    r = scene.render
    scale = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * scale)), max(1, int(r.resolution_y * scale))


def export_scene(depsgraph: bpy.types.Depsgraph) -> Scene:
    """Everything the renderer needs from the evaluated depsgraph."""
    scene_eval = depsgraph.scene_eval
    result = Scene()
    warnings = result.warnings
    meshes: dict[str, Mesh] = {}
    materials: dict[str, Material] = {}
    for inst in depsgraph.object_instances:
        obj = inst.object
        matrix = inst.matrix_world
        if not all(math.isfinite(v) for row in matrix for v in row):
            warnings.append(f"object '{obj.name}' has a non-finite transform and was skipped")
            continue
        if obj.type == "LIGHT":
            result.lights.append(export_light(obj, matrix))
            continue
        if obj.type not in GEOMETRY_TYPES:
            continue
        mesh = meshes.get(obj.name)
        if mesh is None:
            evaluated_mesh = obj.to_mesh()
            if evaluated_mesh is None:
                continue
            try:
                mesh = _mesh_arrays(evaluated_mesh, obj.name)
            finally:
                obj.to_mesh_clear()
            meshes[obj.name] = mesh
        slot_materials = []
        for slot in obj.material_slots:
            key = slot.material.name_full if slot.material else ""
            if key not in materials:
                materials[key] = export_material(slot.material, warnings)
            slot_materials.append(materials[key])
        result.instances.append(Instance(mesh, _matrix(matrix), slot_materials))
    result.world = export_world(scene_eval.world)
    result.film_transparent = bool(scene_eval.render.film_transparent)
    result.camera = export_camera(depsgraph, scene_eval.camera, *render_size(scene_eval))
    return result
