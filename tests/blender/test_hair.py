"""Hair curves (Curves objects) rendered as Cycles renders them: a tuft of grass strands
against Cycles, and what the export reads (the radius, Cycles' default without one, material
slots per curve, a warning for curves that are not finite)."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from addon.core.scene.hair import CIRCUMRADIUS
from addon.export import export_scene
from addon.export_hair import DEFAULT_RADIUS
from tests.blender.rendering import (
    add_camera,
    add_primitive,
    add_sun,
    assert_near_cycles,
    cycles_and_ours,
    render_linear,
    shader_material,
)

SIZE = 96


def hair_object(name: str, points: np.ndarray, radii: np.ndarray | None = None
                ) -> bpy.types.Object:
    """A Curves object of equal-length curves (``points``: curves × points × 3) linked to the
    scene; ``radii`` (points per curve) set on every curve, or no radius attribute."""
    count, length = points.shape[:2]
    curves = bpy.data.hair_curves.new(name)
    curves.add_curves([length] * count)
    curves.attributes["position"].data.foreach_set(
        "vector", points.astype(np.float32).ravel())
    if radii is not None:
        radius = curves.attributes.new("radius", "FLOAT", "POINT")
        radius.data.foreach_set("value", np.tile(radii, count).astype(np.float32))
    obj = bpy.data.objects.new(name, curves)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def grass(count: int = 400, points: int = 5) -> np.ndarray:
    """Seeded strands 0.5 m tall, rooted in a 1.2 m square, leaning as they rise."""
    rng = np.random.default_rng(1)
    roots = np.stack([rng.uniform(-0.6, 0.6, count), rng.uniform(-0.6, 0.6, count),
                      np.zeros(count)], axis=1)
    lean = rng.normal(0.0, 0.15, (count, 2))
    t = np.linspace(0.0, 1.0, points)
    rise = np.stack([lean[:, None, 0] * t ** 2, lean[:, None, 1] * t ** 2,
                     np.broadcast_to(0.5 * t, (count, points))], axis=-1)
    return roots[:, None] + rise


def test_a_tuft_of_grass_against_cycles(blender, tmp_path):
    """Green strands (radius 12 → 3 mm) on a grey floor under a sun of angle 0, one bounce,
    96² against Cycles' 256 samples. Measured (bpy 4.5): energy −0.5 %, relRMSE 7.0 % (8-pixel
    blocks: 2.0 %; Cycles against itself, another seed: 1.2 %), most of it each pixel's
    coverage of strands one or two pixels wide (antialiasing 8: 0.9 points less); four-sided
    tubes measured 7.9 %; the grass left out 74 %."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    add_primitive("plane", shader_material("Grey", "ShaderNodeBsdfDiffuse",
                                           Color=(0.7, 0.7, 0.7, 1)), size=8)
    add_sun(scene, (40, 0, 30))
    scene.world = bpy.data.worlds.new("Dim")
    tuft = hair_object("Grass", grass(), np.linspace(0.012, 0.003, 5))
    tuft.data.materials.append(shader_material("Green", "ShaderNodeBsdfDiffuse",
                                               Color=(0.2, 0.6, 0.1, 1)))
    add_camera(scene, SIZE, location=(0, -2.2, 1.3), rotation=(math.radians(62), 0, 0))
    reference, ours = cycles_and_ours(scene, tmp_path, 256, 1)
    tuft.hide_render = True
    without = render_linear(scene, "VPL_GI", tmp_path / "without.exr")
    assert_near_cycles("grass", ours[..., :3], reference[..., :3], (0.015, 0.09),
                       without[..., :3], "without the grass")


def test_radius_slots_and_bad_curves(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    straight = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0], [1.0, 0.0, 1.0]],
                         [[2.0, 0.0, 0.0], [2.0, 0.0, np.nan]]])
    strands = hair_object("Strands", straight)
    strands.data.materials.append(shader_material("A", "ShaderNodeBsdfDiffuse"))
    strands.data.materials.append(shader_material("B", "ShaderNodeBsdfDiffuse"))
    index = strands.data.attributes.new("material_index", "INT", "CURVE")
    index.data.foreach_set("value", np.array([0, 1, 1], np.int32))
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    assert "object 'Strands': 1 of 3 curves have NaN/Inf points or radii and were left out" \
        in scene.warnings
    assert not any("not rendered" in warning for warning in scene.warnings)
    instance, = scene.instances
    mesh = instance.mesh
    assert [m.name for m in instance.materials] == ["A", "B"]
    first = mesh.positions[mesh.positions[:, 0] < 0.5]
    assert np.linalg.norm(first[:, :2], axis=1) == pytest.approx(
        np.full(len(first), CIRCUMRADIUS * DEFAULT_RADIUS), rel=1e-4)
    corners = mesh.corner_positions().reshape(-1, 3, 3)
    assert (mesh.material_slots == (corners[:, :, 0].mean(axis=1) > 0.5)).all()


def swaying(obj: bpy.types.Object, metres_per_frame: float) -> None:
    """A Geometry Nodes modifier that moves every point of ``obj`` along x by
    ``metres_per_frame`` × the frame: the curves deform, the object stays put."""
    tree = bpy.data.node_groups.new("Sway", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    move = nodes.new("GeometryNodeSetPosition")
    scale = nodes.new("ShaderNodeMath")
    scale.operation, scale.inputs[1].default_value = "MULTIPLY", metres_per_frame
    offset = nodes.new("ShaderNodeCombineXYZ")
    links.new(nodes.new("GeometryNodeInputSceneTime").outputs["Frame"], scale.inputs[0])
    links.new(scale.outputs[0], offset.inputs["X"])
    links.new(nodes.new("NodeGroupInput").outputs[0], move.inputs["Geometry"])
    links.new(offset.outputs[0], move.inputs["Offset"])
    links.new(move.outputs[0], nodes.new("NodeGroupOutput").inputs[0])
    obj.modifiers.new("Sway", "NODES").node_group = tree


def test_deforming_hair_moves_in_the_vector_pass_as_in_cycles(blender, tmp_path):
    """test_motion's scene with its box still and, before it, nine strands that a Geometry
    Nodes modifier moves sideways (0.1 m a frame, about 1.9 px). Measured (bpy 4.5): median
    error 0.04 px where they move over a pixel (read as still, the hair's own motion alone:
    1.9 px). Cycles' vectors of hair that bends come from the curve's keys interpolated
    linearly in the spline's parameter (its centre line is not linear in it), so only a
    uniform motion is compared."""
    from tests.blender.test_motion import motion_scene, vector_pass

    scene = motion_scene(False)
    bpy.data.objects["Cube"].animation_data_clear()
    points = np.array([[[x, -0.5, -1.0], [x, -0.5, 1.0]] for x in np.linspace(-1, 1, 9)])
    hair = hair_object("Hair", points, np.array([0.08, 0.08]))
    hair.data.materials.append(shader_material("Red", "ShaderNodeBsdfDiffuse"))
    swaying(hair, 0.1)
    reference = vector_pass(scene, "CYCLES", tmp_path / "cycles_vectors.exr")
    ours = vector_pass(scene, "VPL_GI", tmp_path / "ours_vectors.exr")
    moving = np.abs(reference[..., :2]).max(axis=2) > 1.0
    error = np.abs(ours - reference).max(axis=2)[moving]
    print(f"vector pass, deforming hair: {moving.mean():.3f} of pixels move over 1 px, "
          f"median error {np.median(error):.3f} px, mean {error.mean():.3f} px")
    assert moving.mean() > 0.1
    assert np.median(error) < 0.1
