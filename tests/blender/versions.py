"""The Blender API the tests use that differs between the supported versions (4.2 LTS, 4.5 LTS,
5.x), in one place. What the add-on itself needs is in addon/blender_compat.py."""

from __future__ import annotations

import bpy

from addon.blender_compat import BLENDER_5, VERSION, ensure_nodes

__all__ = ["BLENDER_5", "VERSION", "compositor_output", "ensure_nodes", "nodeless_material"]


def compositor_output(scene: bpy.types.Scene):
    """An empty compositor node tree that renders of ``scene`` run, and the input socket whose
    image becomes the render result.

    4.x: the scene's own tree (``use_nodes``, ``node_tree``) ending in a Composite node.
    5.x: a compositor node group ending in its Group Output: assigned through a compositor
    effect where the scene has them (5.3), through ``compositing_node_group`` before."""
    if not BLENDER_5:
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        return tree, tree.nodes.new("CompositorNodeComposite").inputs["Image"]
    tree = bpy.data.node_groups.new("Compositor", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    if hasattr(scene, "compositor_effects"):
        scene.compositor_effects.new(name="Compositor").node_group = tree
    else:
        scene.compositing_node_group = tree
    return tree, tree.nodes.new("NodeGroupOutput").inputs["Image"]


def nodeless_material(name: str, color) -> tuple[bpy.types.Material, bool]:
    """A material Cycles renders as a diffuse surface in its viewport colour ``color``, and
    whether VPL GI warns that it has no shader nodes.

    4.x: ``use_nodes`` off (warned). 5.x has no such material: it is built as Blender 5.x
    converts one from a 4.x file (a Cycles-only output fed by a Diffuse BSDF in the viewport
    colour, an EEVEE-only output fed by a Principled BSDF), which renders without a warning."""
    material = bpy.data.materials.new(name)
    material.diffuse_color = color
    if not BLENDER_5:
        material.use_nodes = False
        return material, True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    for target, shader in (("EEVEE", "ShaderNodeBsdfPrincipled"),
                           ("CYCLES", "ShaderNodeBsdfDiffuse")):
        output = nodes.new("ShaderNodeOutputMaterial")
        output.target = target
        node = nodes.new(shader)
        node.inputs[0].default_value = color  # Base Color / Color
        if shader == "ShaderNodeBsdfDiffuse":
            node.inputs["Roughness"].default_value = 0.0
        links.new(node.outputs[0], output.inputs["Surface"])
    return material, False
