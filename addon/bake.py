"""Material bakes: surfaces whose colour comes from nodes the exporter cannot read (procedural
textures, ColorRamp, Math, Mapping, Attribute, textures inside Mix Shader …) are evaluated by
Cycles' Emit bake into an image per object, then rendered like any image texture.

Where it runs: ``bpy.ops.object.bake`` inside ``RenderEngine.render`` runs with the rendering
engine instead of Cycles and frees the running engine's Python object (measured, bpy 4.5), so
bakes run before the render: in a ``render_pre`` handler when it is called on the main thread
(background renders: ``blender -b``, the bpy module, ``python -m addon render``), or by
``bake_scene`` directly. Renders and the viewport use what is in the cache; a material whose
bake is missing keeps the viewport-colour fallback with a warning saying why.

Nothing of the user's is changed: the bake works on a temporary scene holding a temporary
object with an evaluated copy of the mesh (triangulated, with an xatlas UV map, when the mesh
has no suitable UV map) and copies of its materials, all removed afterwards (errors and
Ctrl-C included). Bakes are cached by object, material node-tree hashes, original mesh and
modifier settings, and resolution, within a memory cap."""

from __future__ import annotations

import contextlib
import hashlib
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import ENGINE_ID, bake_tree
from .blender_compat import ensure_nodes
from .blender_read import (
    active_uvs,
    corner_verts,
    int_attribute,
    positions,
    read_array,
    surface_node,
    triangle_faces,
)
from .core.frame.result import Stats
from .core.scene.model import Material, Mesh, Texture
from .core.settings import DEFAULTS
from .uv_unwrap import unsuitable, unwrap

BAKE_SAMPLES = 4  # Cycles samples per texel: anti-aliases the texel's footprint
BAKE_MARGIN = 4  # texels the bake extends past each UV island (bilinear lookups at edges)
TEXEL_BYTES = 16  # float32 RGBA
NOT_BAKED = "not baked: bakes run before background renders, in the viewport and by Bake Materials"


@dataclass
class Baked:
    """One object's bake: a texture per channel baked, the mesh carrying the bake's UV map
    when it is not the object's own (xatlas), and how it was made."""

    textures: dict[str, Texture]
    mesh: Mesh | None
    seconds: float
    reasons: dict[str, str]  # material name -> why it was baked
    nbytes: int
    evaluated: str | None = None  # with xatlas UVs: the hash of the mesh they were made on
    used: int = 0  # the cache generation that last used it
    limits: tuple[str, ...] = ()  # what it cannot hold, as warnings (bake_limits)


@dataclass
class BakeCache:
    """Bakes by (object, slots' material tree hashes, mesh hash, resolution), the memory they
    hold, and what the last bake pass did."""

    entries: dict[tuple, Baked] = field(default_factory=dict)
    generation: int = 0
    baked: list[tuple[str, Baked]] = field(default_factory=list)  # the last pass's new bakes
    problems: list[str] = field(default_factory=list)  # the last pass's failures
    failed: dict[tuple, str] = field(default_factory=dict)  # key -> why that bake failed
    world_seconds: float = 0.0  # the last pass's world bake (world_bake.py); 0 if none

    @property
    def nbytes(self) -> int:
        return sum(entry.nbytes for entry in self.entries.values())

    def make_room(self, nbytes: int, cap: int) -> bool:
        """Drop bakes the current pass has not used, oldest first, until ``nbytes`` more fit
        under ``cap``; False if they cannot."""
        for key in sorted((k for k, e in self.entries.items() if e.used < self.generation),
                          key=lambda k: self.entries[k].used):
            if self.nbytes + nbytes <= cap:
                break
            del self.entries[key]
        return self.nbytes + nbytes <= cap

    def clear(self) -> None:
        self.entries.clear()
        self.failed.clear()


CACHE = BakeCache()


# -- what an object needs -------------------------------------------------------------------

def settings_of(scene: bpy.types.Scene) -> tuple[int, int]:
    """The bake resolution (texels per edge) and memory cap (bytes) of a scene."""
    values = getattr(scene, "vpl_gi", None)
    resolution = getattr(values, "bake_resolution", DEFAULTS.bake_resolution)
    memory = getattr(values, "bake_memory", DEFAULTS.bake_memory)
    return int(resolution), int(memory) << 20


def bake_reason(material: bpy.types.Material | None, fallback: str | None) -> str | None:
    """Why a material's surface is baked (the exporter's reason for falling back, and the
    nodes feeding the surface), or None when it is not bakeable or needs no bake."""
    if fallback is None or not _bakeable(material):
        return None
    nodes = sorted(set(bake_tree.linked_inputs(surface_node(material.node_tree))))
    return fallback + (f" (nodes: {', '.join(nodes)})" if nodes else "")


def mesh_hash(mesh: bpy.types.Mesh) -> str:
    """A hash of a mesh's content that a bake depends on: positions, faces, material
    indices, the active render UV map and colour and float attributes' values."""
    # SHA-1 for a cache key, not for security: hashlib's fastest digest here (about 3× as
    # fast as BLAKE2b over a mesh's megabytes)
    digest = hashlib.sha1(usedforsecurity=False)
    digest.update(positions(mesh).tobytes())
    digest.update(corner_verts(mesh).tobytes())
    # the face of each loop triangle: the faces' sizes (n - 2 triangles each), read as one
    # array where the polygons' loop_total is read face by face
    digest.update(triangle_faces(mesh).tobytes())
    material_index = int_attribute(mesh, "material_index", len(mesh.polygons))
    digest.update(b"no material index" if material_index is None else material_index.tobytes())
    uvs = active_uvs(mesh)
    digest.update(b"no uv" if uvs is None else uvs.tobytes())
    for attribute in mesh.attributes:
        if attribute.name.startswith(".") or attribute.name == "position":
            continue
        digest.update(f"{attribute.name}:{attribute.domain}:{attribute.data_type}".encode())
        if attribute.data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
            digest.update(read_array(attribute.data, "color", len(attribute.data) * 4,
                                 np.float32).tobytes())
        elif attribute.data_type == "FLOAT":
            digest.update(read_array(attribute.data, "value", len(attribute.data),
                                 np.float32).tobytes())
    return digest.hexdigest()


def evaluated_hash(obj: bpy.types.Object) -> str:
    """mesh_hash of an evaluated object's surface (a curve's, text's or metaball's as its
    mesh)."""
    if obj.type == "MESH":
        return mesh_hash(obj.data)
    mesh = obj.to_mesh()
    try:
        return mesh_hash(mesh) if mesh is not None else "no surface"
    finally:
        obj.to_mesh_clear()


def bake_key(obj: bpy.types.Object, resolution: int, render: bool = False) -> tuple:
    """The cache key of an evaluated mesh object's bake: its slots' node trees, its original
    mesh and modifier settings (not the evaluated mesh: a bake in the object's own UV map
    holds for any evaluation), the object's colour, pass index and custom properties (which
    Object Info and Attribute nodes read), the resolution, and whether it was made on the
    mesh as final renders evaluate it (``render``; render_differs)."""
    slots = tuple((slot.material.name_full, bake_tree.tree_hash(slot.material.node_tree))
                  if slot.material is not None and slot.material.node_tree is not None
                  else None for slot in obj.material_slots)
    original = obj.original
    shape_keys = original.data.shape_keys
    shapes = tuple((k.name, k.value, k.mute) for k in shape_keys.key_blocks) \
        if shape_keys is not None else ()
    modifiers = tuple(bake_tree.struct_hash(modifier) for modifier in original.modifiers)
    data = mesh_hash(original.data) if original.type == "MESH" else \
        bake_tree.struct_hash(original.data)  # a curve's splines, a text's body, …
    custom = tuple((name, repr(_plain_property(original[name])))
                   for name in original.keys())  # noqa: SIM118 (an ID, not a dict)
    return (original.name_full, slots, data, shapes, modifiers,
            tuple(original.color), original.pass_index, custom, resolution, render)


def _plain_property(value: object) -> object:
    """A custom property's value as plain Python (ID property arrays and groups converted)."""
    for convert in ("to_dict", "to_list"):
        if hasattr(value, convert):
            return getattr(value, convert)()
    return value


def _valid(entry: Baked | None, obj: bpy.types.Object) -> bool:
    """Whether a cached bake fits the evaluated object: a bake in xatlas UVs only on the
    geometry it was made on."""
    return entry is not None and (entry.evaluated is None or
                                  entry.evaluated == evaluated_hash(obj))


# -- the bake -------------------------------------------------------------------------------

class Temporary:
    """Datablocks made for one bake, removed (in dependency order) on exit, whatever
    happens."""

    def __init__(self) -> None:
        self.made: list[tuple[bpy.types.bpy_prop_collection, bpy.types.ID]] = []

    def add(self, collection, datablock):
        self.made.append((collection, datablock))
        return datablock

    def __enter__(self) -> Temporary:
        return self

    def __exit__(self, *_exc) -> None:
        for kind in (bpy.types.Scene, bpy.types.World, bpy.types.Object, bpy.types.Mesh,
                     bpy.types.Material, bpy.types.Image):
            for collection, datablock in reversed(self.made):
                if isinstance(datablock, kind):
                    collection.remove(datablock)
        self.made.clear()


def _copy(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph,
          temporary: Temporary) -> bpy.types.Mesh:
    """A new mesh of the evaluated object, every attribute kept."""
    return temporary.add(bpy.data.meshes, bpy.data.meshes.new_from_object(
        obj, preserve_all_data_layers=True, depsgraph=depsgraph))


BAKED_TYPES = frozenset({"MESH", "CURVE", "FONT", "SURFACE", "META"})
"""Object types whose surfaces are baked (the others render as their viewport colour)."""
RENDER_LEVELS = frozenset({"SUBSURF", "MULTIRES"})
"""Modifiers with levels of their own for the viewport and for final renders."""


def render_differs(obj: bpy.types.Object) -> bool:
    """Whether final renders evaluate the object's mesh otherwise than the viewport: a
    modifier shown in one of them only, or with render levels of its own (Subdivision
    Surface's default: 1 in the viewport, 2 in renders)."""
    return any(m.show_viewport != m.show_render or
               (m.type in RENDER_LEVELS and m.levels != m.render_levels)
               for m in obj.original.modifiers)


def _render_copy(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph,
                 temporary: Temporary) -> bpy.types.Mesh:
    """A new mesh of the object as final renders evaluate it (every attribute kept): a copy
    of the object whose modifiers show what renders show, at their render levels, evaluated
    in a scene of its own at the frame (Python evaluates the viewport's settings only)."""
    twin = temporary.add(bpy.data.objects, obj.original.copy())
    for modifier in twin.modifiers:
        modifier.show_viewport = modifier.show_render
        if modifier.type in RENDER_LEVELS:
            modifier.levels = modifier.render_levels
    scene = temporary.add(bpy.data.scenes, bpy.data.scenes.new("VPL GI bake geometry"))
    scene.frame_current = depsgraph.scene.frame_current
    scene.collection.objects.link(twin)
    with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
        graph = bpy.context.evaluated_depsgraph_get()
    return temporary.add(bpy.data.meshes, bpy.data.meshes.new_from_object(
        twin.evaluated_get(graph), preserve_all_data_layers=True, depsgraph=graph))


def render_hash(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph) -> str:
    """mesh_hash of the object's mesh as final renders evaluate it."""
    with Temporary() as temporary:
        return mesh_hash(_render_copy(obj, depsgraph, temporary))


def _triangulate(mesh: bpy.types.Mesh) -> None:
    """Split every face of the mesh into triangles (attributes kept)."""
    import bmesh  # importable only once bpy is

    work = bmesh.new()
    try:
        work.from_mesh(mesh)
        bmesh.ops.triangulate(work, faces=work.faces[:])
        work.to_mesh(mesh)
    finally:
        work.free()


def _bake_uvs(mesh: bpy.types.Mesh, resolution: int) -> bpy.types.MeshUVLoopLayer | None:
    """The UV map to bake into: None where the mesh's own active render map suits (the mesh
    is left as Blender tessellates it, as Cycles renders it), else a new xatlas map on the
    mesh, triangulated first. The materials' default UVs stay the active render map's (all
    zero where the mesh had none, as Cycles reads them then)."""
    uvs = active_uvs(mesh)
    if uvs is not None:
        mesh.calc_loop_triangles()
        corners = read_array(mesh.loop_triangles, "loops", len(mesh.loop_triangles) * 3, np.int32)
        if unsuitable(uvs[corners], positions(mesh)[corner_verts(mesh)[corners]]) is None:
            return None
    _triangulate(mesh)
    if not mesh.uv_layers:
        mesh.uv_layers.new(name="UVMap", do_init=False).uv.foreach_set(
            "vector", np.zeros(2 * len(mesh.loops), np.float32))
    render_map = next((layer for layer in mesh.uv_layers if layer.active_render), None)
    corners = corner_verts(mesh).reshape(-1, 3)
    layer = mesh.uv_layers.new(name="VPL GI bake", do_init=False)
    if layer is None:
        raise RuntimeError("the mesh has no room for another UV map (8 at most)")
    layer.uv.foreach_set("vector", unwrap(positions(mesh), corners, resolution).ravel())
    if render_map is not None:
        render_map.active_render = True
    return layer


def run_bake(scene: bpy.types.Scene, obj: bpy.types.Object, kind: str = "EMIT",
             uv_map: str = "") -> None:
    """Cycles' bake of ``kind`` (Emit: the surface's colour; Environment: the world in the
    direction of each point) of ``obj`` in the temporary ``scene`` into its materials' active
    image nodes, laid out by ``uv_map`` (by default the mesh's active one)."""
    with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0],
                                   active_object=obj, object=obj, selected_objects=[obj],
                                   selected_editable_objects=[obj]):
        result = bpy.ops.object.bake(type=kind, margin=BAKE_MARGIN, use_clear=True,
                                     target="IMAGE_TEXTURES", save_mode="INTERNAL",
                                     uv_layer=uv_map)
    if "FINISHED" not in result:
        raise RuntimeError(f"Cycles' bake returned {result}")


def bake_object(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph, resolution: int,
                reasons: dict[str, str], channels: list[str], render: bool = False) -> Baked:
    """Bake ``channels`` (``channels_for`` the object's slots: the diffuse colour, and the
    emission where it is not a constant) of every slot of an evaluated mesh object into
    ``resolution``² images, on the mesh as the viewport evaluates it or with ``render`` as
    final renders do. RuntimeError if Cycles refuses."""
    from .export import read_mesh  # the exporter imports this module

    start = time.perf_counter()
    materials = [slot.material for slot in obj.material_slots]
    with Temporary() as temporary:
        mesh = _render_copy(obj, depsgraph, temporary) if render else \
            _copy(obj, depsgraph, temporary)
        evaluated = mesh_hash(mesh)
        source = obj.original.data  # Generated coordinates span the original mesh's bounds
        mesh.use_auto_texspace = False
        mesh.texspace_location, mesh.texspace_size = source.texspace_location, \
            source.texspace_size
        unwrapped = _bake_uvs(mesh, resolution)
        layout = next(layer.name for layer in mesh.uv_layers if layer.active_render) \
            if unwrapped is None else unwrapped.name
        scene = temporary.add(bpy.data.scenes, bpy.data.scenes.new("VPL GI bake"))
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = BAKE_SAMPLES
        scene.render.bake.margin_type = "EXTEND"
        proxy = temporary.add(bpy.data.objects, bpy.data.objects.new("VPL GI bake", mesh))
        proxy.matrix_world = obj.matrix_world
        proxy.color, proxy.pass_index = obj.color, obj.pass_index  # Object Info's
        for name in obj.original.keys():  # noqa: SIM118 (an ID) Attribute nodes (Object) read them
            proxy[name] = obj.original[name]
        scene.collection.objects.link(proxy)
        textures = {}
        for channel in channels:
            image = temporary.add(bpy.data.images, bpy.data.images.new(
                f"VPL GI bake {channel}", resolution, resolution, alpha=False,
                float_buffer=True))
            mesh.materials.clear()
            for material in materials:
                copy = temporary.add(bpy.data.materials, _channel_copy(material, channel))
                bake_tree.show_channel(copy, channel, image)
                mesh.materials.append(copy)
            run_bake(scene, proxy, uv_map=layout)
            pixels = np.empty(resolution * resolution * 4, np.float32)
            image.pixels.foreach_get(pixels)
            pixels = np.nan_to_num(pixels.reshape(resolution, resolution, 4), posinf=0.0)
            textures[channel] = Texture(f"{obj.original.name} ({channel} bake)", pixels)
        if unwrapped is not None:  # the export reads the active render map
            mesh.uv_layers[layout].active_render = True
        core_mesh = read_mesh(mesh, obj.name) if unwrapped is not None else None
    nbytes = sum(t.pixels.nbytes for t in textures.values())
    return Baked(textures, core_mesh, time.perf_counter() - start, reasons, nbytes,
                 evaluated if unwrapped is not None else None,
                 limits=bake_limits(obj, materials, reasons))


def _bakeable(material: bpy.types.Material | None) -> bool:
    if material is None or material.node_tree is None:
        return False
    try:
        bake_tree.check(surface_node(material.node_tree))
    except bake_tree.NotBakeable:
        return False
    return True


def channels_for(materials: list[bpy.types.Material | None]) -> list[str]:
    """The channels an object's bake holds: the diffuse colour, and the emission where a
    bakeable slot's emission is not a constant."""
    emissive = any(bake_tree.constant_channel(m, "emission") is None
                   for m in materials if _bakeable(m))
    return ["albedo", "emission"] if emissive else ["albedo"]


def _channel_copy(material: bpy.types.Material | None, channel: str) -> bpy.types.Material:
    """A copy of the material to rewire, or for an empty or unbakeable slot a new material
    (black: such slots keep their own exported values)."""
    if _bakeable(material):
        return material.copy()
    blank = bpy.data.materials.new(f"VPL GI bake {channel}")
    ensure_nodes(blank)
    blank.node_tree.nodes.clear()
    blank.node_tree.nodes.new("ShaderNodeOutputMaterial")
    return blank


# -- a scene's bakes ------------------------------------------------------------------------

def named_uv_maps(material: bpy.types.Material | None) -> frozenset[str]:
    """The UV maps that UV Map nodes of a material's tree name (the exporter reads only the
    active render map)."""
    if material is None or material.node_tree is None:
        return frozenset()
    return frozenset(node.uv_map for node in material.node_tree.nodes
                     if node.type == "UVMAP" and node.uv_map)


def needed(obj: bpy.types.Object, fallbacks: dict[str, str],
           named: dict[str, frozenset[str]]) -> dict[str, str]:
    """Materials of an evaluated object that need a bake -> why: the exporter's fallback
    reasons (by material name), or UV Map nodes naming another map than the object's active
    render one (``named``: by material name)."""
    found = {}
    active = next((layer.name for layer in obj.data.uv_layers if layer.active_render), None) \
        if obj.original.type == "MESH" else None
    for slot in obj.material_slots:
        material = slot.material
        if material is None:
            continue
        other = sorted(named.get(material.name, frozenset()) - {active})
        reason = fallbacks.get(material.name) or (
            f"a UV Map node reads UV map '{other[0]}', not the active render map" if other
            else None)
        reason = bake_reason(material, reason)
        if reason is not None:
            found[material.name] = reason
    return found


def reads_random(material: bpy.types.Material | None) -> bool:
    """Whether a material's tree reads Object Info's Random, which a bake cannot give: the
    bake renders a stand-in object, with a random value of its own."""
    return material is not None and material.node_tree is not None and any(
        node.type == "OBJECT_INFO" and node.outputs["Random"].is_linked
        for node in material.node_tree.nodes)


def unbakeable_attributes(material: bpy.types.Material | None) -> list[str]:
    """The Attribute nodes of a material that read what a bake's stand-in object in a scene
    of its own cannot hold: an instance's attributes (Instancer), the view layer's or scene's
    (View Layer)."""
    if material is None or material.node_tree is None:
        return []
    return [f"'{node.attribute_name}' ({node.attribute_type.replace('_', ' ').title()})"
            for node in material.node_tree.nodes if node.type == "ATTRIBUTE"
            and node.attribute_type in ("INSTANCER", "VIEW_LAYER")
            and any(output.is_linked for output in node.outputs)]


def _failed(obj: bpy.types.Object, key: tuple, why: str) -> None:
    """Record why the object's bake (``key``) was not made, for the export and the report."""
    CACHE.failed[key] = why
    CACHE.problems.append(f"object '{obj.original.name}': not baked: {why}")


def _baked_objects(depsgraph: bpy.types.Depsgraph) -> list[bpy.types.Object]:
    """The original objects of BAKED_TYPES the evaluated scene renders, each once: those in
    the view layer and those only instanced (a collection of assets excluded from the view layer and
    instanced), not geometry an object's own nodes generate (not baked)."""
    found: dict[str, bpy.types.Object] = {}
    for inst in depsgraph.object_instances:
        original = inst.object.original
        parent = inst.parent
        generated = inst.is_instance and parent is not None and \
            parent.original.as_pointer() == original.as_pointer()
        if original.type in BAKED_TYPES and not generated:
            found.setdefault(original.name_full, original)
    return list(found.values())


def bake_scene(depsgraph: bpy.types.Depsgraph, evaluations: tuple[bool, ...] = (False,)
               ) -> BakeCache:
    """Bake every mesh object of the evaluated scene whose materials need it and whose bake
    is not cached, and the world where its nodes need it (world_bake.py); returns the cache,
    with this pass's object bakes and problems. ``evaluations``: for the viewport's mesh
    (False) and/or final renders' (True: made apart only where render_differs)."""
    from . import world_bake  # it imports this module
    from .export import fallback_reasons, world_bake_reason  # the exporter imports this module

    resolution, cap = settings_of(depsgraph.scene)
    CACHE.generation += 1
    CACHE.baked, CACHE.problems, CACHE.failed = [], [], {}
    materials: dict[str, dict[str, str]] = {}  # each material's fallback, exported once
    for original in _baked_objects(depsgraph):
        obj = original.evaluated_get(depsgraph)
        if obj.type == "MESH" and not obj.data.polygons:
            continue
        reasons = needed(obj, fallback_reasons(obj, materials), {slot.material.name: named_uv_maps(
            slot.material) for slot in obj.material_slots if slot.material is not None})
        if not reasons:
            continue
        for render in sorted({r and render_differs(obj) for r in evaluations}):
            _bake_if_stale(obj, depsgraph, resolution, cap, reasons, render)

    world = depsgraph.scene_eval.world
    CACHE.world_seconds = world_bake.bake_if_needed(world, world_bake_reason(world))
    return CACHE


def _bake_if_stale(obj: bpy.types.Object, depsgraph: bpy.types.Depsgraph, resolution: int,
                   cap: int, reasons: dict[str, str], render: bool) -> None:
    """Bake one evaluation of an object unless its cached bake still fits (a bake in its own
    UV map fits any), within the bake memory ``cap`` (bytes)."""
    key = bake_key(obj, resolution, render)
    entry = CACHE.entries.get(key)
    if entry is not None and (entry.evaluated is None or entry.evaluated == (
            render_hash(obj, depsgraph) if render else evaluated_hash(obj))):
        entry.used = CACHE.generation
        return
    channels = channels_for([slot.material for slot in obj.material_slots])
    nbytes = len(channels) * resolution * resolution * TEXEL_BYTES
    if not CACHE.make_room(nbytes, cap):
        _failed(obj, key, f"its {nbytes / 2**20:.0f} MiB bake does not fit the bake memory cap "
                     f"of {cap >> 20} MiB ({CACHE.nbytes / 2**20:.0f} MiB in use): lower "
                     f"Bake Resolution or raise Bake Memory")
        return
    try:
        entry = bake_object(obj, depsgraph, resolution, reasons, channels, render)
    except (RuntimeError, ValueError) as exc:
        _failed(obj, key, f"the bake failed: {str(exc).strip()}")
        return
    entry.used = CACHE.generation
    CACHE.entries[key] = entry
    CACHE.baked.append((obj.original.name, entry))


# -- what the export uses -------------------------------------------------------------------

def baked_material(material: Material, source: bpy.types.Material, entry: Baked) -> Material:
    """The exported material with the bake's textures for its baked channels, and the
    specular inputs of a Principled surface where they are constants (a Diffuse BSDF or a
    mix is diffuse: the bake holds the diffuse colour only); its normal or bump map and its
    cutout stay, their textures where the bake is in the mesh's own UVs (xatlas UVs would
    misplace them)."""
    emission_constant = bake_tree.constant_channel(source, "emission")
    emission_texture = entry.textures.get("emission") if emission_constant is None else None
    emission = (1.0, 1.0, 1.0) if emission_texture is not None else \
        (emission_constant.constant if emission_constant is not None else (0.0, 0.0, 0.0))
    own_uvs = entry.mesh is None
    return Material(material.name, (1.0, 1.0, 1.0), emission,
                    base_color_texture=entry.textures["albedo"],
                    emission_texture=emission_texture, pass_index=material.pass_index,
                    aovs=material.aovs, alpha=material.alpha, holdout=material.holdout,
                    coverage_texture=material.coverage_texture if own_uvs else None,
                    coverage_mode=material.coverage_mode,
                    normal_texture=material.normal_texture if own_uvs else None,
                    normal_strength=material.normal_strength,
                    bump_distance=material.bump_distance,
                    bump_filter_width=material.bump_filter_width,
                    **bake_tree.specular_constants(source))  # type: ignore[arg-type]


def lost_textures(material: Material, entry: Baked) -> list[str]:
    """What of an exported material a bake in xatlas UVs leaves out: its normal or bump map
    and its cutout's texture, which the mesh's own UVs place."""
    if entry.mesh is None:
        return []
    return [what for what, texture in (("normal map", material.normal_texture),
                                       ("cutout texture", material.coverage_texture))
            if texture is not None]


def apply(obj: bpy.types.Object, mesh: Mesh, materials: list[Material],
          fallbacks: dict[str, str], named: dict[str, frozenset[str]], resolution: int,
          notes: list[str], warnings: list[str], unbaked: set[str], rendering: bool = False
          ) -> tuple[Mesh, list[Material]]:
    """An exported object's mesh and materials with its cached bake applied (the bake's UV
    mesh and textures), or unchanged with a warning per material when the bake is missing;
    ``unbaked`` gets the materials whose bake a bake pass would make (not those whose bake
    failed or cannot be made). ``rendering``: the object is a final render's evaluation,
    whose own bake is made apart where it differs from the viewport's (render_differs); a
    viewport bake in the object's own UV map fits it too."""
    reasons = needed(obj, fallbacks, named) if mesh.triangle_count else {}
    if not reasons:
        return mesh, materials
    differs = rendering and render_differs(obj)
    key, entry = None, None
    if obj.original.type in BAKED_TYPES:
        keys = [bake_key(obj, resolution, True), bake_key(obj, resolution)] if differs \
            else [bake_key(obj, resolution)]
        fitting = next((k for k in keys if _valid(CACHE.entries.get(k), obj)), None)
        key, entry = (keys[0], None) if fitting is None else (fitting, CACHE.entries[fitting])
    if entry is None:
        if key is None:
            why = f"not baked: {obj.original.type.lower()} objects are not baked"
        elif key in CACHE.failed:
            why = f"not baked: {CACHE.failed[key]}"
        elif differs and threading.current_thread() is not threading.main_thread():
            why = ("not baked: renders started in Blender's window cannot bake, and the "
                   "viewport's bake, made on its own subdivision levels and modifiers, does "
                   "not fit the render's mesh; press Bake Materials first")
        else:
            why = NOT_BAKED
            unbaked.update(reasons)
        _warn(warnings, [f"material '{name}': {reason}; using its viewport colour ({why})"
                         for name, reason in reasons.items()])
        return mesh, materials
    entry.used = CACHE.generation
    sources = [slot.material for slot in obj.material_slots]
    baked = [(m, source) for m, source in zip(materials, sources, strict=True)
             if source is not None and source.name in reasons]
    _warn(warnings, [f"material '{m.name}': its {' and '.join(lost)} is not rendered: the "
                     f"mesh has no UV map a bake can use, and the bake's new one would "
                     f"misplace it" for m, _ in baked if (lost := lost_textures(m, entry))])
    result = [baked_material(m, source, entry) if source is not None and (
        source.name in reasons or (entry.mesh is not None and _bakeable(source) and
        (m.base_color_texture, m.emission_texture) != (None, None))) else m
        for m, source in zip(materials, sources, strict=True)]
    note = (f"baked {', '.join(repr(n) for n in sorted(reasons))} on object "
            f"'{obj.original.name}' ({entry.textures['albedo'].pixels.shape[0]} px, "
            f"{entry.seconds:.2f} s{', xatlas UVs' if entry.mesh is not None else ''}): "
            f"{'; '.join(sorted(set(reasons.values())))}")
    _warn(notes, [note])
    _warn(warnings, list(entry.limits))
    return (entry.mesh if entry.mesh is not None else mesh), result


def bake_limits(obj: bpy.types.Object, materials: list[bpy.types.Material | None],
                reasons: dict[str, str]) -> tuple[str, ...]:
    """What an object's bake of the materials named in ``reasons`` cannot hold, as warnings
    (found once, when it is made: its trees key it): Object Info's Random, and each
    material's _unbaked_parts."""
    baked = [m for m in materials if m is not None and m.name in reasons]
    random = [f"object '{obj.original.name}': Object Info's Random in its bake is not the "
              f"object's (a stand-in object's, one value)"] if any(map(reads_random, baked)) \
        else []
    return (*random, *(message for m in baked for message in _unbaked_parts(m)))


def _unbaked_parts(source: bpy.types.Material) -> list[str]:
    """What a baked material's bake cannot hold, as warnings: Attribute nodes it cannot read,
    view-dependent nodes seen straight on, Ambient Occlusion of the object alone."""
    surface = surface_node(source.node_tree) if source.node_tree is not None else None
    parts = [(unbakeable_attributes(source), "its bake cannot read the attributes {}: "
              "rendered as 0"),
             (bake_tree.view_dependent(surface), "its bake holds {} as seen looking straight "
              "at the surface, not from the camera"),
             (bake_tree.scene_dependent(surface), "its bake holds {} of the object alone, not "
              "of the scene around it")]
    return [f"material '{source.name}': " + text.format(", ".join(found))
            for found, text in parts if found]


def _warn(messages: list[str], new: list[str]) -> None:
    """Add each of ``new`` to ``messages`` unless it is there already."""
    messages.extend(m for m in dict.fromkeys(new) if m not in messages)


def report(stats: Stats, notes: list[str]) -> None:
    """Put the export's bake notes and the bake pass's problems into a frame's stats, and the
    time of the bakes made since the last report as its 'material bake' and 'world bake'
    stages (a frame that reused its bakes has none)."""
    from . import world_bake  # it imports this module

    world_bake.report(stats)
    stats.notes[:0] = [note for note in notes if note not in stats.notes]
    stats.warnings.extend(p for p in CACHE.problems if p not in stats.warnings)
    CACHE.problems = []
    if CACHE.baked:
        stats.timings["material bake"] = sum(entry.seconds for _, entry in CACHE.baked)
        CACHE.baked = []


# -- when bakes run -------------------------------------------------------------------------

_baking = threading.Lock()


@contextlib.contextmanager
def _bake_turn() -> Iterator[bool]:
    """Hold the bake lock for the block if no other bake pass holds it (one pass at a time,
    none waits for another); yields whether this block may bake."""
    if not _baking.acquire(blocking=False):
        yield False
        return
    try:
        yield True
    finally:
        _baking.release()


@persistent
def _before_render(scene: bpy.types.Scene, *_args) -> None:
    """render_pre: bake what the frame needs, on the main thread only (a render started from
    Blender's UI calls this from its render thread, where operators must not run)."""
    if scene is None or scene.render.engine != ENGINE_ID or \
            threading.current_thread() is not threading.main_thread():
        return
    with _bake_turn() as free:
        if free and bpy.context.scene == scene:
            bake_scene(bpy.context.evaluated_depsgraph_get(), (True,))


class VPLGI_OT_bake_materials(bpy.types.Operator):
    """Bake the material colours and the world VPL GI cannot read from nodes (for the
    viewport and renders started from this window, which cannot bake while they render)"""

    bl_idname = "vpl_gi.bake_materials"
    bl_label = "Bake Materials"

    def execute(self, context: bpy.types.Context) -> set[str]:
        cache = bake_scene(context.evaluated_depsgraph_get(), (False, True))
        for problem in cache.problems:
            self.report({"WARNING"}, f"VPL GI: {problem}")
        seconds = sum(entry.seconds for _, entry in cache.baked) + cache.world_seconds
        world = " and the world" if cache.world_seconds else ""
        self.report({"INFO"}, f"VPL GI: baked {len(cache.baked)} object(s){world} in "
                              f"{seconds:.2f} s")
        return {"FINISHED"}


BAKE_POLL = 0.1  # seconds between a waiting bake timer's checks


def bake_soon(on_baked: Callable[[], None], ready: Callable[[], bool] = lambda: True) -> None:
    """Bake the context's scene on a timer (the main thread, outside drawing: the viewport)
    once ``ready()`` (checked every BAKE_POLL seconds), then call ``on_baked`` if anything
    was baked. The viewport waits for its worker to finish the frames in flight: Cycles'
    bake and the worker's OpenGL work never run side by side (the suite crashed once when
    they did)."""
    def run() -> float | None:
        if not ready():
            return BAKE_POLL
        with _bake_turn() as free:
            if not free:
                return None
            cache = bake_scene(bpy.context.evaluated_depsgraph_get())
        if cache.baked or cache.world_seconds:
            on_baked()
        return None
    bpy.app.timers.register(run, first_interval=0.0)


def register() -> None:
    """The Bake Materials operator (a button in the Material Bakes panel) and the
    render_pre handler."""
    bpy.utils.register_class(VPLGI_OT_bake_materials)
    bpy.app.handlers.render_pre.append(_before_render)


def unregister() -> None:
    if _before_render in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.remove(_before_render)
    from . import world_bake  # it imports this module

    bpy.utils.unregister_class(VPLGI_OT_bake_materials)
    CACHE.clear()
    world_bake.clear()
