"""Where objects and the camera are at two other times (the previous and next frame for the
Vector pass, the shutter's opening and closing for motion blur), read by moving the render's
depsgraph there and back, as Cycles reads its motion."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import bpy
import numpy as np

from .blender_read import positions
from .core.scene.model import RENDERED_OBJECT_TYPES, Mesh, MotionSpan
from .export_hair import read_hair
from .export_points import read_points

POSITION_OFFSET = {"START": 0.0, "CENTER": -0.5, "END": -1.0}
"""Where the shutter opens, in shutters from the frame (Blender's motion blur position)."""

InstanceKey = tuple[str, tuple[int, ...]]


def instance_key(instance: bpy.types.DepsgraphObjectInstance) -> InstanceKey:
    """What names one placed instance at every time: its object and, for an instance made
    by another object, its persistent id."""
    return (instance.object.name,
            tuple(instance.persistent_id) if instance.is_instance else ())


def motion_span(scene: bpy.types.Scene, vector_pass: bool) -> MotionSpan | None:
    """The times the frame needs placements at: the shutter's with motion blur on, the
    neighbouring frames' for the Vector pass (``vector_pass``), else None."""
    render = scene.render
    shutter = float(render.motion_blur_shutter)
    if render.use_motion_blur and math.isfinite(shutter) and shutter > 0:
        opening = POSITION_OFFSET.get(render.motion_blur_position, -0.5) * shutter
        return MotionSpan(-shutter / 2, shutter / 2, blur=True, centre=opening + shutter / 2)
    return MotionSpan() if vector_pass else None


@dataclass
class SampledMotion:
    """The placements at ``span``'s two times: each instance's world matrix by its key, and
    the camera's view matrix (None without a camera)."""

    span: MotionSpan
    matrices: tuple[dict[InstanceKey, np.ndarray], dict[InstanceKey, np.ndarray]]
    views: tuple[np.ndarray | None, np.ndarray | None]
    positions: tuple[dict[InstanceKey, np.ndarray], dict[InstanceKey, np.ndarray]] = \
        field(default_factory=lambda: ({}, {}))
    """The vertex positions (object space) of deforming meshes (and hair tubes) at the two
    times."""
    home: dict[InstanceKey, np.ndarray] = field(default_factory=dict)
    """Where the render is moved off the frame (a pass's part of the shutter): the world
    matrices at the frame of the instances whose motion blur is off, which stay there."""
    home_positions: dict[InstanceKey, np.ndarray] = field(default_factory=dict)
    """Likewise the vertex positions of deforming meshes whose Deformation is off."""
    home_view: np.ndarray | None = None
    """Likewise the camera's view where its motion blur is off."""


def _set_time(engine: bpy.types.RenderEngine, time: float) -> None:
    whole = math.floor(time)
    engine.frame_set(int(whole), time - whole)


def sample_motion(engine: bpy.types.RenderEngine, depsgraph: bpy.types.Depsgraph,
                  span: MotionSpan) -> SampledMotion:
    """Move the render to ``span``'s two times, read every instance's matrix and the camera's
    view there, and leave it at the rendered time (``span.centre`` from the frame: the
    caller goes back to the frame after exporting). With motion blur, objects (and a camera)
    whose Motion Blur (or Deformation) toggle is off are left still (``blurs``); the Vector
    pass moves them all, as Cycles' does."""
    scene = depsgraph.scene
    rendered = scene.frame_current + float(scene.frame_subframe) + span.centre
    matrices, views, shapes = [], [], []
    deforms: dict[int, bool] = {}  # by original object pointer
    held = False  # some object, deformation or camera is held still (its toggle off)
    try:
        for offset in (span.before, span.after):
            _set_time(engine, rendered + offset)
            placed, shaped = {}, {}
            for inst in depsgraph.object_instances:
                obj = inst.object
                if obj.type not in RENDERED_OBJECT_TYPES:
                    continue
                if span.blur and not blurs(inst, "use_motion_blur"):
                    held = True
                    continue
                key = instance_key(inst)
                placed[key] = np.array(inst.matrix_world, np.float64)
                if obj.type in DEFORMED_TYPES and _deforms(obj, scene, deforms):
                    if span.blur and not blurs(inst, "use_deform_motion"):
                        held = True
                    else:
                        shaped[key] = _shape(obj)
            matrices.append(placed)
            shapes.append(shaped)
            camera = depsgraph.scene_eval.camera
            still = span.blur and camera is not None \
                and not _toggled(camera, "use_motion_blur")
            held |= still
            views.append(None if camera is None or still else _view(camera.matrix_world))
        home = ({}, {}, None)
        if held and span.centre:  # rendered off the frame: what stays at the frame
            _set_time(engine, rendered - span.centre)
            home = _home(depsgraph, deforms)
    finally:
        _set_time(engine, rendered)
    return SampledMotion(span, (matrices[0], matrices[1]), (views[0], views[1]),
                         (shapes[0], shapes[1]), *home)


def _home(depsgraph: bpy.types.Depsgraph, deforms: dict[int, bool]
          ) -> tuple[dict[InstanceKey, np.ndarray], dict[InstanceKey, np.ndarray],
                     np.ndarray | None]:
    """At the frame (where the caller has moved the render): the matrices of the instances
    whose motion blur is off, the vertex positions of the deforming meshes whose Deformation
    is off, and the camera's view where its motion blur is off (SampledMotion.home)."""
    scene = depsgraph.scene
    matrices, shapes = {}, {}
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type not in RENDERED_OBJECT_TYPES:
            continue
        if not blurs(inst, "use_motion_blur"):
            matrices[instance_key(inst)] = np.array(inst.matrix_world, np.float64)
        elif obj.type in DEFORMED_TYPES and _deforms(obj, scene, deforms) \
                and not blurs(inst, "use_deform_motion"):
            shapes[instance_key(inst)] = _shape(obj)
    camera = depsgraph.scene_eval.camera
    view = None if camera is None or _toggled(camera, "use_motion_blur") \
        else _view(camera.matrix_world)
    return matrices, shapes, view


DEFORMED_TYPES = frozenset({"MESH", "CURVES", "POINTCLOUD"})
"""Object types whose deformation blurs (their exported vertices at both times)."""


def _shape(obj: bpy.types.Object) -> np.ndarray:
    """The exported mesh's vertex positions (object space) of a deforming object now: a
    mesh's vertices, a hair object's tubes (the same count at both times unless the
    spline's samples change with the curves' bends: then it stays still), a point cloud's
    spheres."""
    if obj.type == "CURVES":
        return read_hair(obj.data, obj.name, "")[0].positions
    if obj.type == "POINTCLOUD":
        return read_points(obj.data, obj.name, "")[0].positions
    return positions(obj.data)


def blurs(instance: bpy.types.DepsgraphObjectInstance, toggle: str) -> bool:
    """Whether motion blur moves the instance: its object's Cycles toggle (Object Properties
    > Motion Blur: ``use_motion_blur``, and its Deformation, ``use_deform_motion``) and, for
    an instance another object makes, that object's too, as Cycles' sync asks; on where
    Cycles' settings are missing."""
    owners = [instance.object]
    if instance.is_instance and instance.parent is not None:
        owners.append(instance.parent)
    return all(_toggled(owner, toggle) for owner in owners)


def _toggled(obj: bpy.types.Object, toggle: str) -> bool:
    """An object's Cycles motion-blur toggle (on where Cycles' settings are missing)."""
    return bool(getattr(getattr(obj.original, "cycles", None), toggle, True))


def _deforms(obj: bpy.types.Object, scene: bpy.types.Scene, known: dict[int, bool]) -> bool:
    """Whether modifiers or shape keys deform the object's mesh (Cycles' deformation blur),
    asked once per object."""
    pointer = obj.original.as_pointer()
    if pointer not in known:
        known[pointer] = bool(obj.original.is_deform_modified(scene, "RENDER"))
    return known[pointer]


def deformed_mesh(motion: SampledMotion, key: InstanceKey, mesh: Mesh) -> Mesh:
    """The mesh with how its vertices move by the two times (Mesh.deform), where it deforms
    and keeps its vertex count; itself otherwise."""
    before, after = (shapes.get(key) for shapes in motion.positions)
    if before is None or after is None \
            or not before.shape == after.shape == mesh.positions.shape:
        return mesh
    with np.errstate(all="ignore"):
        moved = np.nan_to_num(np.stack([before, after]) - mesh.positions[None])
    if not moved.any():
        return mesh
    return replace(mesh, deform=moved.astype(np.float32))


def at_home(motion: SampledMotion, key: InstanceKey, mesh: Mesh, matrix: np.ndarray
            ) -> tuple[Mesh, np.ndarray]:
    """The instance's mesh and matrix where its motion blur (or its Deformation) is off: at
    the frame (SampledMotion.home) where the render is moved off it; as given otherwise."""
    home = motion.home_positions.get(key)
    if home is not None and home.shape == mesh.positions.shape:
        mesh = replace(mesh, positions=home.astype(mesh.positions.dtype))
    return mesh, motion.home.get(key, matrix)


def placed_motion(motion: SampledMotion, key: InstanceKey
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """An instance's matrices at the two times; None where it is not there at both."""
    before, after = (matrices.get(key) for matrices in motion.matrices)
    return None if before is None or after is None else (before, after)


def _view(matrix_world) -> np.ndarray | None:
    """The view matrix of a camera placed at ``matrix_world``; None where it has none (not
    finite, or singular: the frame's own camera check says why)."""
    world = np.array(matrix_world, np.float64)
    if not np.isfinite(world).all():
        return None
    try:
        return camera_view(world)
    except np.linalg.LinAlgError:
        return None


def camera_view(matrix_world: np.ndarray) -> np.ndarray:
    """The view matrix of a camera placed at ``matrix_world`` (4, 4), its scale left out as
    Cycles leaves it out (measured, 4.5: a camera scaled by 0.01, 100 or (1, 2, 1) renders as
    unscaled; a negative scale still mirrors the image): each axis column made unit length.
    LinAlgError where the placement is singular."""
    placement = np.array(matrix_world, np.float64)
    lengths = np.linalg.norm(placement[:3, :3], axis=0)
    if not np.all(lengths > 0):
        raise np.linalg.LinAlgError("a camera axis of zero length")
    placement[:3, :3] /= lengths
    return np.linalg.inv(placement)
