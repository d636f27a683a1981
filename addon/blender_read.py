"""Reads of Blender data that both the exporter and the bakes make (the exporter imports the
bake module, so what both need lives here, importing neither)."""

from __future__ import annotations

import bpy
import numpy as np

from .blender_compat import cycles_output_node


def rgb(value) -> tuple[float, float, float]:
    """The first three components of a colour property or socket value, as floats."""
    return (float(value[0]), float(value[1]), float(value[2]))


class UnsupportedNodes(Exception):
    """A node tree the export cannot turn into constant values (the reason is the text)."""


def constant(node, name: str, default):
    """An input's value (``default`` where the node has no such input); a linked input
    (texture, math …) raises UnsupportedNodes."""
    socket = node.inputs.get(name)
    if socket is None:
        return default
    if socket.is_linked:
        raise UnsupportedNodes(f"input '{name}' of '{node.bl_label}' is linked to "
                               f"'{socket.links[0].from_node.bl_label}'")
    return socket.default_value


def read_array(collection: bpy.types.bpy_prop_collection, attribute: str, count: int,
               dtype) -> np.ndarray:
    """``count`` values of ``attribute`` over ``collection`` (foreach_get), flat."""
    values = np.empty(count, dtype=dtype)
    collection.foreach_get(attribute, values)
    return values


def int_attribute(mesh: bpy.types.Mesh, name: str, size: int) -> np.ndarray | None:
    """The values of an INT attribute of ``size`` elements, or None without one."""
    attribute = mesh.attributes.get(name)
    if attribute is None or attribute.data_type != "INT" or len(attribute.data) != size:
        return None
    return read_array(attribute.data, "value", size, np.int32)


def float_attribute(data: bpy.types.ID, name: str, size: int) -> np.ndarray | None:
    """The values of a FLOAT attribute of ``size`` elements (float32), or None without one."""
    attribute = data.attributes.get(name)
    if attribute is None or attribute.data_type != "FLOAT" or len(attribute.data) != size:
        return None
    return read_array(attribute.data, "value", size, np.float32)


def positions(mesh: bpy.types.Mesh) -> np.ndarray:
    """The vertices' positions, (V, 3) float32 (from the position attribute: reading each
    vertex's ``co`` is about 200× slower)."""
    position = mesh.attributes.get("position")
    data, name = (mesh.vertices, "co") if position is None else (position.data, "vector")
    return read_array(data, name, len(mesh.vertices) * 3, np.float32).reshape(-1, 3)


def corner_verts(mesh: bpy.types.Mesh) -> np.ndarray:
    """The vertex of each face corner (loop), (L,) int32 (from the .corner_vert attribute:
    reading each loop's ``vertex_index`` is about 700× slower)."""
    found = int_attribute(mesh, ".corner_vert", len(mesh.loops))
    return read_array(mesh.loops, "vertex_index", len(mesh.loops), np.int32) \
        if found is None else found


def triangle_faces(mesh: bpy.types.Mesh) -> np.ndarray:
    """The face of each of Blender's loop triangles, (T,) int32 (one array read; the mesh is
    not triangulated)."""
    return read_array(mesh.loop_triangle_polygons, "value", len(mesh.loop_triangle_polygons),
                      np.int32)


def active_uvs(mesh: bpy.types.Mesh) -> np.ndarray | None:
    """The active render UV map's coordinates per corner, (L, 2) float32, or None without
    one."""
    layer = next((layer for layer in mesh.uv_layers if layer.active_render), None)
    attribute = mesh.attributes.get(layer.name) if layer is not None else None
    if attribute is None:
        return None
    return read_array(attribute.data, "vector", len(mesh.loops) * 2, np.float32).reshape(-1, 2)


def surface_node(tree: bpy.types.NodeTree | None, output_type: str = "OUTPUT_MATERIAL"):
    """The shader node linked to the Surface socket of the output Cycles renders from (an
    output for EEVEE only is skipped, as Cycles skips it; one of another type than
    ``output_type``, such as a World Output in a material's tree, is none), or None."""
    output = cycles_output_node(tree)
    if output is None or output.type != output_type or not output.inputs["Surface"].is_linked:
        return None
    return output.inputs["Surface"].links[0].from_node


def volume_linked(tree: bpy.types.NodeTree | None, output_type: str = "OUTPUT_MATERIAL") -> bool:
    """True if the output Cycles renders from (``surface_node``'s) has a Volume shader."""
    output = cycles_output_node(tree)
    return output is not None and output.type == output_type and \
        "Volume" in output.inputs and output.inputs["Volume"].is_linked
