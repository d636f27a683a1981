"""Blender -> core.Scene: reads the evaluated depsgraph into numpy arrays with foreach_get.

Each mesh is read once per export and shared by all its instances; an ExportCache keeps meshes
between exports (the viewport), so only geometry the caller forgets is read again. Blender's
unit scale (``scene.unit_settings.scale_length``) is ignored, as Cycles ignores it: one Blender
unit is one metre for light falloff (measured with Cycles 4.5, tests/blender/test_export.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import bpy
import numpy as np

from . import bake, world_bake
from .blender_compat import (
    DEFAULT_SURFACE_IS_PRINCIPLED,
    OREN_NAYAR_MULTISCATTER,
    SHEEN_DIMS_CAST_LIGHT,
    uses_nodes,
)
from .blender_read import (
    UnsupportedNodes,
    active_uvs,
    constant,
    corner_verts,
    cycles_output_node,
    int_attribute,
    positions,
    read_array,
    rgb,
    surface_node,
    triangle_faces,
    volume_linked,
)
from .core.frame.panorama import KINDS as PANORAMA_KINDS
from .core.frame.state import RenderError
from .core.scene.environment import mean_radiance
from .core.scene.hair_fibre import colour_from_absorption, melanin_absorption
from .core.scene.model import (
    COVERAGE_INVERTED,
    DEFAULT_MATERIAL,
    RENDERED_OBJECT_TYPES,
    Aperture,
    Camera,
    EnvironmentMap,
    Identity,
    Instance,
    Light,
    LightKind,
    Material,
    Mesh,
    Mist,
    Panorama,
    Scene,
    World,
    empty_mesh,
)
from .core.scene.sun_disc import take_out_map_sun
from .core.scene.textures import MISSING_COLOR, decode_srgb
from .export_hair import hair_systems, read_hair, read_particle_hair
from .export_images import ImageReader, UnsupportedLink, linked_node, read_pixels
from .export_light_linking import scene_light_linking
from .export_lights import export_light, is_portal, max_bounces, visible_to_camera
from .export_motion import (
    InstanceKey,
    SampledMotion,
    at_home,
    camera_view,
    deformed_mesh,
    instance_key,
    placed_motion,
)
from .export_points import read_points

RAY_FLAGS = ("visible_camera", "visible_diffuse", "visible_shadow")
"""An object's ray visibility that VPL GI honours (glossy, transmission and volume rays reach
closures it does not render)."""


def _matrix(m) -> np.ndarray:
    return np.array(m, dtype=np.float64)


# -- placements: every object's world matrix is checked here --------------------------------

class TransformError(RenderError):
    """The scene camera cannot be rendered from; the message names it and says why."""


def transform_problems(matrices: np.ndarray, invertible: bool = False) -> list[str | None]:
    """Per world matrix (k, 4, 4), why it cannot place an object, or None: NaN/Inf entries,
    or, where the matrix must be inverted (the camera's), a linear part without an inverse
    (a scale of 0). One call for all instances: scenes may hold many thousands."""
    finite = np.isfinite(matrices).all(axis=(1, 2))
    problems: list[str | None] = [None if ok else "has a non-finite transform"
                                  for ok in finite.tolist()]
    if invertible and finite.any():
        scales = np.linalg.svd(matrices[finite, :3, :3], compute_uv=False)
        singular = ~(scales[:, -1] > 1e-9 * scales[:, 0])
        for row in np.flatnonzero(finite)[singular]:
            problems[row] = "has a transform without an inverse (a scale of 0 on some axis)"
    return problems


def check_camera(camera_object: bpy.types.Object) -> None:
    """Raise TransformError unless the object can be the scene camera: a camera object with
    a finite, invertible world matrix and a clipping range to see in."""
    if camera_object.type != "CAMERA":
        raise TransformError(f"the scene camera '{camera_object.name}' is not a camera but "
                             f"an object of type {camera_object.type.title()} (choose a "
                             f"camera in the scene's properties)")
    start, end = camera_object.data.clip_start, camera_object.data.clip_end
    if not start < end:
        raise TransformError(f"camera '{camera_object.name}' clips everything: its Clip Start "
                             f"({start:g} m) is not below its Clip End ({end:g} m)")
    problem, = transform_problems(_matrix(camera_object.matrix_world)[None], invertible=True)
    if problem:
        raise TransformError(f"camera '{camera_object.name}' {problem}")


# -- meshes ---------------------------------------------------------------------------------

def _vectors(collection: bpy.types.bpy_prop_collection, size: int) -> np.ndarray:
    """The 'vector' of each of ``size`` items (normals), (size, 3) float32."""
    return read_array(collection, "vector", size * 3, np.float32).reshape(-1, 3)


def _cross(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """a × b from component arrays, rounded as np.cross rounds (float32 products, then their
    difference)."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


def _edges(xyz: np.ndarray, vertex: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """Components of the vectors from each row's first vertex to its others (``vertex``:
    (n, k) indices into the positions' components ``xyz``, (3, P))."""
    columns = np.ascontiguousarray(vertex.T, dtype=np.intp)  # else each np.take converts
    origin = [np.take(c, columns[0]) for c in xyz]
    return [tuple(np.take(c, end) - o for c, o in zip(xyz, origin, strict=True))
            for end in columns[1:]]


def _zero_area(xyz: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """Triangles (rows of ``vertex``) whose (v1 - v0) × (v2 - v0) is exactly zero."""
    c = _cross(*_edges(xyz, vertex))
    return (c[0] == 0) & (c[1] == 0) & (c[2] == 0)


def _quad_dot(xyz: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """(d12 × d13) · (d14 × d13) of quads (rows of ``vertex``), di = vi - v0, summed in x, y,
    z order: Blender's is_quad_flip_v3_first_third_fast is dot > 0.

    The two cross products are (up to sign, exactly) those of triangles 0-1-2 and 0-2-3, so
    where dot < 0 neither triangle has zero area."""
    d12, d13, d14 = _edges(xyz, vertex)
    a, b = _cross(d12, d13), _cross(d14, d13)
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


QUAD_SPLIT = np.array([0, 1, 2, 0, 2, 3])  # a quad's two triangles; flipped: 0 1 3, 1 2 3


def _split(quads: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """Rows of the two triangles (Q*2, 3) of quads (Q, 4) split along 0-2, or 1-3 if flip."""
    # C order, unlike quads[:, QUAD_SPLIT]; "clip" skips checking these in-range indices
    triangles = np.take(quads, QUAD_SPLIT, axis=1, mode="clip")
    flipped = np.flatnonzero(flip)
    triangles[flipped, 2:4] = quads[flipped][:, [3, 1]]
    return triangles.reshape(-1, 3)


PER_TRIANGLE_READ_RATIO = 32  # reading one loop triangle's corners costs about as much as
# reading 32 triangles' in one foreach_get over all (measured: 7 µs against 0.2 µs)


def _ngon_triangles(mesh: bpy.types.Mesh, face: np.ndarray, is_ngon: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Blender's triangles of the n-gons (in its order): their indices among the loop
    triangles and their corners (N, 3), read one by one when they are few, else all at once."""
    rows = np.flatnonzero(is_ngon[face])
    mesh.calc_loop_triangles()
    triangles = mesh.loop_triangles
    if len(rows) * PER_TRIANGLE_READ_RATIO < len(face):
        corners = [triangles[i].loops[:] for i in rows.tolist()]
        return rows, np.array(corners, dtype=np.int32).reshape(-1, 3)
    corner = np.empty((len(face), 3), dtype=np.int32)
    triangles.foreach_get("loops", corner.ravel())
    return rows, corner[rows]


def _triangles(mesh: bpy.types.Mesh, xyz: np.ndarray, corner_vert: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Corners and vertices (T, 3), face (T) and zero area (T, bool) of each triangle, as
    Blender's loop triangles: triangle faces first, then quads, then n-gons.

    Triangles and quads are split in numpy with Blender's own rule (about 20× faster than
    reading loop_triangles through RNA); n-gons take Blender's triangulation. Zero area:
    (v1 - v0) × (v2 - v0) of the positions (``xyz``, (3, P)) is exactly zero."""
    face = triangle_faces(mesh)
    # faces' sizes from their triangle counts: reading loop_start is much slower
    size = np.bincount(face, minlength=len(mesh.polygons)).astype(np.int32) + 2
    is_quad = size == 4
    in_quad = np.repeat(is_quad, size)  # per corner
    in_tri = np.repeat(size == 3, size)
    quad_corner = np.flatnonzero(in_quad).astype(np.int32).reshape(-1, 4)
    quad_vertex = corner_vert[in_quad].reshape(-1, 4)
    dot = _quad_dot(xyz, quad_vertex)
    flip = dot > 0
    tri_corner = np.flatnonzero(in_tri).astype(np.int32).reshape(-1, 3)
    tri_vertex = corner_vert[in_tri].reshape(-1, 3)
    quad_triangles = _split(quad_vertex, flip)
    # zero area: quads' triangles only where the dot does not rule it out
    unsure = (2 * np.flatnonzero(~(dot < 0))[:, None] + [0, 1]).ravel()
    quad_zero = np.zeros(len(quad_triangles), dtype=bool)
    quad_zero[unsure] = _zero_area(xyz, quad_triangles[unsure])
    quad = np.flatnonzero(is_quad).astype(np.int32)
    parts = [(tri_corner, tri_vertex, np.flatnonzero(size == 3).astype(np.int32),
              _zero_area(xyz, tri_vertex)),
             (_split(quad_corner, flip), quad_triangles, np.repeat(quad, 2), quad_zero)]
    is_ngon = size > 4
    if is_ngon.any():
        rows, ngon_corner = _ngon_triangles(mesh, face, is_ngon)
        ngon_vertex = corner_vert[ngon_corner]
        parts.append((ngon_corner, ngon_vertex, face[rows], _zero_area(xyz, ngon_vertex)))
    corner, vertex, faces, zero = (np.concatenate(column) for column in zip(*parts, strict=True))
    return corner, vertex, faces, zero


def _normals(mesh: bpy.types.Mesh, corner: np.ndarray, face: np.ndarray,
             position_index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Blender's normals in their own domain (vertex, face or corner) and their row per corner
    (Blender's corner normals are these, gathered)."""
    domain = mesh.normals_domain
    if domain == "POINT":
        return _vectors(mesh.vertex_normals, len(mesh.vertices)), position_index
    if domain == "FACE":
        return _vectors(mesh.polygon_normals, len(mesh.polygons)), np.repeat(face, 3)
    return _vectors(mesh.corner_normals, len(mesh.loops)), corner


def _mesh_arrays(mesh: bpy.types.Mesh, name: str, label: str, faces_expected: bool
                 ) -> tuple[Mesh, list[str]]:
    """Triangles of an evaluated mesh, indexing its vertices, normals (in their own domain) and
    UVs, and what was wrong with them. Index arrays may be shared: a smooth mesh's normals use
    the positions' index, corner normals the UVs'.

    Triangles with NaN/Inf corners or zero area are left out (one warning each kind); a mesh
    object with vertices but no faces gets a warning (curves without bevel do not)."""
    problems: list[str] = []
    co = positions(mesh)
    corner_vert = corner_verts(mesh)
    with np.errstate(invalid="ignore", over="ignore"):  # NaN/Inf vertices are reported below
        corner, vertex, face, zero = _triangles(mesh, co.T.copy(), corner_vert)
    count = len(face)
    if count == 0:
        if faces_expected and len(mesh.vertices):
            problems.append(f"{label} has no faces ({len(mesh.vertices)} vertices): "
                            f"nothing to render")
        return empty_mesh(name), problems
    keep = np.ones(count, dtype=bool)
    if not np.isfinite(co).all():
        keep = np.isfinite(co).all(axis=1)[vertex].all(axis=1)
        problems.append(f"{label}: {count - int(keep.sum())} of {count} triangles have NaN/Inf "
                        f"vertices and were left out")
    degenerate = keep & zero
    if degenerate.any():
        keep &= ~degenerate
        problems.append(f"{label}: {int(degenerate.sum())} of {count} triangles have zero area "
                        f"and were left out")
    if not keep.all():
        corner, vertex, face = corner[keep], vertex[keep], face[keep]
    material_index = int_attribute(mesh, "material_index", len(mesh.polygons))
    slots = np.zeros(len(face), np.int32) if material_index is None else material_index[face]
    corner, position_index = corner.ravel(), vertex.ravel()
    normals, normal_index = _normals(mesh, corner, face, position_index)
    uvs = active_uvs(mesh)
    return Mesh(name, co, normals, slots, uvs, position_index, normal_index,
                None if uvs is None else corner), problems


def read_mesh(mesh: bpy.types.Mesh, name: str) -> Mesh:
    """The triangles of a mesh datablock (a bake's temporary copy), problems left out."""
    return _mesh_arrays(mesh, name, f"mesh '{name}'", faces_expected=True)[0]


@dataclass
class _Entry:
    """A mesh read from Blender, the names whose change invalidates it, and its problems."""

    mesh: Mesh
    names: set[str]
    fingerprint: tuple[int, ...]
    problems: list[str] = field(default_factory=list)


class ExportCache:
    """Meshes of earlier exports, reused by ``export_scene`` until forgotten.

    Keys: an unmodified mesh object's mesh datablock (shared by every object using it), an
    evaluated object otherwise, and an instancer for geometry it generates (geometry nodes).
    The caller (the viewport) forgets what Blender reports as changed; meshes no export used
    are dropped at the end of each export. ``unbaked``: the materials the last export showed
    in their viewport colour for want of a bake that a bake pass would make."""

    def __init__(self) -> None:
        self._entries: dict[tuple, _Entry] = {}
        self.stats: dict[str, int] = {"meshes_read": 0, "meshes_reused": 0}
        self.unbaked: set[str] = set()

    def forget(self, name: str) -> None:
        """Read the geometry of the object, mesh datablock or instancer ``name`` again."""
        self._entries = {k: e for k, e in self._entries.items() if name not in e.names}

    def clear(self) -> None:
        """Forget every mesh."""
        self._entries.clear()


def _fingerprint(obj: bpy.types.Object) -> tuple[int, ...]:
    data = obj.data
    if obj.type != "MESH":
        return ()
    return len(data.vertices), len(data.loops), len(data.polygons)


# -- materials ------------------------------------------------------------------------------

def _input_value(node, name: str, default):
    socket = node.inputs.get(name)
    return default if socket is None else socket.default_value


def _linked_shader(socket):
    return socket.links[0].from_node if socket.is_linked else None


def _emissive(name: str, base, base_texture, color, color_texture, strength: float,
              **values) -> Material:
    """A material whose emission is ``color`` (or its texture) times ``strength``."""
    return Material(name, base, tuple(np.array(color) * strength), base_color_texture=base_texture,
                    emission_texture=color_texture if strength != 0 else None, **values)


AS_DIFFUSE = {
    "SUBSURFACE_SCATTERING": "of its colour (no light scattered under the surface)",
    "BSDF_HAIR": "of its colour (no highlights along the fibres)",
}
"""Shaders rendered as a Diffuse BSDF of their Color, with what that leaves out (skin's or
wax's subsurface scattering, hair's highlights): nearer than the viewport colour."""


def _principled_hair(node, name: str, warnings: list[str]) -> Material:
    """A Principled Hair BSDF as a Diffuse BSDF of the colour a mass of its fibres shows
    (core/scene/hair_fibre.py): Direct Coloring's colour, or the one its melanin and tint or
    absorption coefficient give; one warning."""
    radial = float(constant(node, "Radial Roughness", constant(node, "Roughness", 0.3)))
    mode = getattr(node, "parametrization", "COLOR")
    if mode == "MELANIN":
        absorption = melanin_absorption(float(constant(node, "Melanin", 0.8)),
                                        float(constant(node, "Melanin Redness", 1.0)),
                                        rgb(constant(node, "Tint", (1, 1, 1))), radial)
        colour = colour_from_absorption(absorption, radial)
    elif mode == "ABSORPTION":
        colour = colour_from_absorption(
            rgb(constant(node, "Absorption Coefficient", (0.245, 0.52, 1.365))), radial)
    else:
        colour = tuple(float(c) for c in np.clip(rgb(constant(node, "Color", (0.8,) * 3)),
                                                 0.0, 1.0))
    message = (f"material '{name}': Principled Hair BSDF rendered as a Diffuse BSDF of the "
               f"colour of its fibres (no highlights along them, no light through them)")
    if message not in warnings:
        warnings.append(message)
    return Material(name, colour, roughness=1.0)


CLEAR_SHADERS = ("BSDF_TRANSPARENT", "BSDF_GLASS", "BSDF_REFRACTION")
"""Shaders that let light straight through (Glass and Refraction: their reflection, Fresnel
and roughness are not rendered)."""


def _mixed_ior(a: Material, b: Material) -> float:
    """The Fresnel IOR of a mix of two shaders' transmission: none where either has none (a
    Transparent BSDF: the shadow-ray side of the archviz glass, which Cycles' direct light
    passes without loss)."""
    iors = [m.transmission_ior for m in (a, b) if max(m.transmission) > 0]
    return 0.0 if not iors or min(iors) == 0.0 else max(iors)


def _principled_clear(node, name: str, warnings: list[str]) -> Material | None:
    """A Principled BSDF that is all transmission (Alpha 0, or Transmission Weight 1 and not
    metallic) as a clear material; None otherwise, with a warning where some Transmission
    (constant or linked) is not rendered (the surface is rendered opaque; Alpha below 1 makes
    a cutout: ``_shader``)."""
    def unlinked(label: str, default: float) -> float:
        socket = node.inputs.get(label)
        return default if socket is None or socket.is_linked else float(socket.default_value)

    alpha = float(np.clip(unlinked("Alpha", 1.0), 0.0, 1.0))
    weight = float(np.clip(unlinked("Transmission Weight", 0.0), 0.0, 1.0))
    metallic = float(np.clip(unlinked("Metallic", 0.0), 0.0, 1.0))
    transmitted = weight * (1.0 - metallic)
    base = node.inputs["Base Color"]
    if alpha == 0.0 or (transmitted == 1.0 and not base.is_linked):
        tint = (1.0, 1.0, 1.0) if alpha == 0.0 else rgb(base.default_value)
        return Material(name, (0.0, 0.0, 0.0), roughness=1.0,
                        transmission=tuple(float(1.0 - alpha + alpha * c) for c in tint),
                        transmission_ior=0.0 if alpha < 1.0 else unlinked("IOR", 1.5))
    socket = node.inputs.get("Transmission Weight")
    message = None
    if socket is not None and socket.is_linked:
        message = (f"material '{name}': Principled BSDF's Transmission Weight linked to "
                   f"'{socket.links[0].from_node.bl_label}' is not rendered (an opaque "
                   f"surface)")
    elif transmitted > 0.0:
        message = (f"material '{name}': Principled BSDF's Transmission Weight {weight:g} is "
                   f"not rendered (an opaque surface)")
    if message is not None and message not in warnings:
        warnings.append(message)
    return None


PRINCIPLED_LAYERS_LEFT_OUT = (
    ("Subsurface Weight", "Subsurface is rendered as diffuse"),
    ("Anisotropic", "Anisotropic is rendered isotropic"),
    ("Thin Film Thickness", "Thin Film is not rendered"),
)
"""A Principled BSDF's inputs whose layer VPL GI leaves out where it is on (a weight above 0,
or linked), and what the warning says."""


def _warn_layers_left_out(node, name: str, warnings: list[str]) -> None:
    """One warning naming the Principled BSDF's layers that are on and not rendered."""
    left_out = [what for socket_name, what in PRINCIPLED_LAYERS_LEFT_OUT
                if (socket := node.inputs.get(socket_name)) is not None
                and (socket.is_linked or float(socket.default_value) > 0.0)]
    if left_out:
        warnings.append(f"material '{name}': {'; '.join(left_out)}")


COAT_INPUTS = ("Coat Weight", "Coat Roughness", "Coat IOR")
SHEEN_INPUTS = ("Sheen Weight", "Sheen Roughness")


def _principled_layer(node, name: str, warnings: list[str], layer: str,
                      inputs: tuple[str, ...]) -> dict[str, object]:
    """A Principled BSDF's clear coat or sheen (``layer``: "Coat", "Sheen") as Material
    fields named after its ``inputs`` (COAT_INPUTS, SHEEN_INPUTS: the weight first; none
    where it is 0) and its tint; one warning for what of it is not rendered: the layer where
    one of ``inputs`` is linked, its tint where that is linked (white instead), its own normal
    where one is linked."""
    weight = node.inputs.get(inputs[0])
    if weight is None or (not weight.is_linked and float(weight.default_value) <= 0.0):
        return {}
    linked = [socket_name for socket_name in inputs if node.inputs[socket_name].is_linked]
    left_out = []
    if linked:
        left_out.append(f"{layer} is not rendered (its {', '.join(linked)} linked)")
    tint = node.inputs.get(f"{layer} Tint")
    tinted = tint is not None and not tint.is_linked
    if not linked and tint is not None and tint.is_linked:
        left_out.append(f"{layer} Tint is not rendered (linked to "
                        f"'{tint.links[0].from_node.bl_label}')")
    normal = node.inputs.get(f"{layer} Normal")
    if not linked and normal is not None and normal.is_linked:
        left_out.append(f"{layer} Normal is not rendered (the {layer.lower()} follows the "
                        f"surface's normal)")
    if left_out:
        message = f"material '{name}': {'; '.join(left_out)}"
        if message not in warnings:
            warnings.append(message)
    if linked:
        return {}
    fields: dict[str, object] = {socket_name.lower().replace(" ", "_"):
                                 float(node.inputs[socket_name].default_value)
                                 for socket_name in inputs}
    fields[f"{layer.lower()}_tint"] = rgb(tint.default_value) if tinted else (1.0, 1.0, 1.0)
    return fields


def _normal_map(node, name: str, images: ImageReader) -> dict[str, object]:
    """A shader's Normal input as Material fields: a tangent-space Normal Map node's image
    and strength, or a Bump node's image (its colour's luminance the height), strength and
    distance (normal_texture, normal_strength, bump_distance); none, with one warning, for a
    Normal input linked to anything else (smooth shading normals instead)."""
    socket = node.inputs.get("Normal")
    if socket is None or not socket.is_linked:
        return {}
    source = linked_node(socket)
    fields: dict[str, object] = {}
    try:
        if source.type == "BUMP":
            if source.inputs["Normal"].is_linked:
                raise UnsupportedNodes("a Normal input chained into 'Bump'")
            distance = float(constant(source, "Distance", 1.0))
            fields["bump_distance"] = -distance if source.invert else distance
            # Blender 4.2's Bump node has no Filter Width: Cycles 4.3's default
            fields["bump_filter_width"] = float(constant(source, "Filter Width", 0.1))
            image_input = "Height"
        elif source.type == "NORMAL_MAP" and source.space == "TANGENT":
            image_input = "Color"
        else:
            raise UnsupportedNodes(f"linked to '{source.bl_label}'"
                               + (f" in {source.space.title()} space"
                                  if source.type == "NORMAL_MAP" else ""))
        fields["normal_strength"] = float(constant(source, "Strength", 1.0))
        texture = images.color(source, image_input, (0.5, 0.5, 1.0), name)[1] \
            if source.inputs[image_input].is_linked else None
    except (UnsupportedNodes, UnsupportedLink) as reason:
        images.warn(f"material '{name}': the Normal input of '{node.bl_label}' is not "
                    f"rendered ({reason}): smooth shading normals")
        return {}
    return {} if texture is None else {**fields, "normal_texture": texture}


def _principled_alpha(node, name: str, images: ImageReader) -> dict[str, object]:
    """A Principled BSDF's Alpha as a cutout's fields (Material.alpha, coverage_texture,
    coverage_mode); none, with a warning, where it is linked to something other than an
    Image Texture (the surface is rendered opaque)."""
    try:
        alpha, texture, mode = images.coverage(node, "Alpha", name)
    except UnsupportedLink as reason:
        images.warn(f"material '{name}': Principled BSDF's Alpha not rendered ({reason})")
        return {}
    return {"alpha": alpha, "coverage_texture": texture, "coverage_mode": mode}


def _shader(node, name: str, images: ImageReader) -> Material:
    """Values of a shader node (recursing through Mix and Add Shader): constants, or image
    textures linked to a colour; the Principled BSDF's specular inputs as constants.

    An empty shader socket is black, as in Cycles."""
    if node is None:
        return Material(name, (0.0, 0.0, 0.0))
    if node.type == "REROUTE":
        return _shader(_linked_shader(node.inputs[0]), name, images)
    if node.type == "BSDF_PRINCIPLED":
        clear = _principled_clear(node, name, images.warnings)
        if clear is not None:
            return clear
        _warn_layers_left_out(node, name, images.warnings)
        return _emissive(name, *images.color(node, "Base Color", (0.8,) * 3, name),
                         *images.color(node, "Emission Color", (0, 0, 0), name),
                         float(constant(node, "Emission Strength", 0.0)),
                         roughness=float(constant(node, "Roughness", 0.5)),
                         metallic=float(constant(node, "Metallic", 0.0)),
                         ior=float(constant(node, "IOR", 1.5)),
                         specular_ior_level=float(constant(node, "Specular IOR Level", 0.5)),
                         specular_tint=rgb(constant(node, "Specular Tint", (1, 1, 1))),
                         **_principled_layer(node, name, images.warnings, "Coat",
                                             COAT_INPUTS),
                         **_principled_layer(node, name, images.warnings, "Sheen",
                                             SHEEN_INPUTS),
                         sheen_dims_cast_light=SHEEN_DIMS_CAST_LIGHT,
                         **_principled_alpha(node, name, images),
                         **_diffuse_roughness(node, "Diffuse Roughness", name,
                                              images.warnings),
                         **_normal_map(node, name, images))
    if node.type == "BSDF_HAIR_PRINCIPLED":
        return _principled_hair(node, name, images.warnings)
    if node.type == "BSDF_SHEEN":
        return _sheen(node, name, images)
    if node.type == "HOLDOUT":
        return Material(name, (0.0, 0.0, 0.0), roughness=1.0, holdout=True)
    if node.type in CLEAR_SHADERS:
        ior = 0.0 if node.type == "BSDF_TRANSPARENT" else float(constant(node, "IOR", 1.5))
        return Material(name, (0.0, 0.0, 0.0), roughness=1.0, transmission_ior=ior,
                        transmission=rgb(constant(node, "Color", (1, 1, 1))))
    if node.type == "BSDF_GLOSSY":  # no Fresnel: a metal whose Schlick edge brightens a bit
        base, texture = images.color(node, "Color", (0.8,) * 3, name)
        return Material(name, base, roughness=float(constant(node, "Roughness", 0.5)),
                        metallic=1.0, base_color_texture=texture,
                        **_normal_map(node, name, images))
    if node.type == "BSDF_TRANSLUCENT":  # diffuse light let through to the other side
        base, texture = images.color(node, "Color", (0.8,) * 3, name)
        return Material(name, base, roughness=1.0, base_color_texture=texture,
                        translucency=(1.0, 1.0, 1.0), **_normal_map(node, name, images))
    if node.type in ("BSDF_DIFFUSE", *AS_DIFFUSE):
        if node.type in AS_DIFFUSE:
            images.warn(f"material '{name}': {node.bl_label} rendered as a Diffuse BSDF "
                        f"{AS_DIFFUSE[node.type]}")
        base, texture = images.color(node, "Color", (0.8,) * 3, name)
        rough = _diffuse_roughness(node, "Roughness", name, images.warnings) \
            if node.type == "BSDF_DIFFUSE" else {}
        return Material(name, base, roughness=1.0, base_color_texture=texture,
                        **rough, **_normal_map(node, name, images))
    if node.type == "EMISSION":
        return _emissive(name, (0.0, 0.0, 0.0), None,
                         *images.color(node, "Color", (1, 1, 1), name),
                         float(constant(node, "Strength", 1.0)), roughness=1.0)
    if node.type in ("MIX_SHADER", "ADD_SHADER"):
        first_socket, second_socket = (node.inputs[1], node.inputs[2]) \
            if node.type == "MIX_SHADER" else (node.inputs[0], node.inputs[1])
        a = _shader(_linked_shader(first_socket), name, images)
        b = _shader(_linked_shader(second_socket), name, images)
        if a.holdout or b.holdout:
            raise UnsupportedNodes(f"a Holdout shader inside '{node.bl_label}' is not supported")
        by_ray = _ray_type_mix(node, a, b) if node.type == "MIX_SHADER" else None
        if by_ray is not None:
            return by_ray
        if node.type == "MIX_SHADER" and node.inputs["Fac"].is_linked and a.is_clear \
                and b.is_clear:  # e.g. glass for camera rays, transparent for shadow rays
            return Material(name, (0.0, 0.0, 0.0), roughness=1.0, transmission=tuple(
                np.maximum(a.transmission, b.transmission)),
                transmission_ior=_mixed_ior(a, b))
        cutout = _transparent_mix(node, a, b, name, images) \
            if node.type == "MIX_SHADER" else None
        if cutout is not None:
            return cutout
        layered = _fresnel_mix(node, a, b) if node.type == "MIX_SHADER" else None
        if layered is not None:
            return layered
        if node.type == "ADD_SHADER":
            wa = wb = 1.0
        else:
            wb = float(np.clip(constant(node, "Fac", 0.5), 0.0, 1.0))
            wa = 1.0 - wb
        mix = [tuple(wa * np.array(x) + wb * np.array(y)) for x, y in
               ((a.base_color, b.base_color), (a.emission, b.emission),
                (a.transmission, b.transmission))]
        weight = max(wa + wb, 1e-30)
        maps = _mixed_maps(node, a, b, wa, wb)
        glossy = a if a.specular_ior_level >= b.specular_ior_level else b
        coated = a if a.coat_weight >= b.coat_weight else b
        sheened = a if a.sheen_weight >= b.sheen_weight else b
        return Material(name, mix[0], mix[1], transmission=mix[2],
                        coat_weight=(wa * a.coat_weight + wb * b.coat_weight) / weight,
                        coat_roughness=coated.coat_roughness, coat_ior=coated.coat_ior,
                        coat_tint=coated.coat_tint,
                        sheen_weight=wa * a.sheen_weight + wb * b.sheen_weight,
                        sheen_roughness=sheened.sheen_roughness, sheen_tint=sheened.sheen_tint,
                        sheen_layered=sheened.sheen_layered,
                        sheen_dims_cast_light=sheened.sheen_dims_cast_light,
                        diffuse_roughness=(wa * a.diffuse_roughness
                                           + wb * b.diffuse_roughness) / weight,
                        diffuse_multiscatter=min(a.diffuse_multiscatter,
                                                 b.diffuse_multiscatter),
                        transmission_ior=_mixed_ior(a, b),
                        roughness=(wa * a.roughness + wb * b.roughness) / weight,
                        metallic=(wa * a.metallic + wb * b.metallic) / weight,
                        ior=glossy.ior, specular_tint=glossy.specular_tint,
                        specular_ior_level=(wa * a.specular_ior_level
                                            + wb * b.specular_ior_level) / weight,
                        translucency=_mixed_translucency(a, b, wa, wb, mix[0]), **maps)
    raise UnsupportedNodes(f"shader '{node.bl_label}' is not supported")


def _fresnel_ior(fac) -> float | None:
    """The IOR of a Fresnel node's, or a Layer Weight's Fresnel output's (IOR 1 / (1 −
    Blend), as Cycles computes it), constant dielectric Fresnel linked to ``fac``; None for
    anything else (or a Normal input linked: the Fresnel of another normal)."""
    if not fac.is_linked:
        return None
    link = fac.links[0]
    source = link.from_node
    if source.inputs.get("Normal") is not None and source.inputs["Normal"].is_linked:
        return None
    if source.type == "FRESNEL" and not source.inputs["IOR"].is_linked:
        return max(float(source.inputs["IOR"].default_value), 1.0)
    if source.type == "LAYER_WEIGHT" and link.from_socket.name == "Fresnel" \
            and not source.inputs["Blend"].is_linked:
        return 1.0 / max(1.0 - float(source.inputs["Blend"].default_value), 1e-5)
    return None


def _fresnel_mix(node, a: Material, b: Material) -> Material | None:
    """A Mix Shader of a diffuse surface and a Glossy BSDF by their Fresnel (Fac from a
    Fresnel node or a Layer Weight's Fresnel) — the layered plastic of materials made before
    the Principled BSDF — as a Principled BSDF of the diffuse colour with a specular layer of
    that IOR, the glossy roughness and its colour as tint; None for other mixes."""
    ior = _fresnel_ior(node.inputs["Fac"])
    glossy = _linked_shader(node.inputs[2])
    if ior is None or glossy is None or glossy.type != "BSDF_GLOSSY":
        return None
    diffuse_only = a.metallic == 0.0 and a.specular_ior_level == 0.0 and a.coat_weight == 0.0 \
        and a.sheen_weight == 0.0 and not a.is_clear and not a.is_cutout
    if not diffuse_only or b.base_color_texture is not None:
        return None
    normal = a if a.normal_texture is not None else b  # mixed normals: one side's map
    return replace(a, roughness=b.roughness, ior=ior, specular_ior_level=0.5,
                   specular_tint=b.base_color, normal_texture=normal.normal_texture,
                   normal_strength=normal.normal_strength, bump_distance=normal.bump_distance,
                   bump_filter_width=normal.bump_filter_width)


def _diffuse_roughness(node, socket_name: str, name: str, warnings: list[str]
                       ) -> dict[str, object]:
    """A shader's diffuse roughness (``socket_name``: Roughness of a Diffuse BSDF, Diffuse
    Roughness of a Principled BSDF) as Material fields; none, with a warning, where it is
    linked (the surface is rendered smooth)."""
    socket = node.inputs.get(socket_name)
    if socket is None:
        return {}
    if socket.is_linked:
        message = (f"material '{name}': {node.bl_label}'s {socket_name} linked to "
                   f"'{socket.links[0].from_node.bl_label}' is not rendered (a smooth diffuse "
                   f"surface)")
        if message not in warnings:
            warnings.append(message)
        return {}
    return {"diffuse_roughness": float(socket.default_value),
            "diffuse_multiscatter": OREN_NAYAR_MULTISCATTER}


def _sheen(node, name: str, images: ImageReader) -> Material:
    """A Sheen BSDF: a sheen of weight 1 that dims nothing it is mixed or added to (its
    Ashikhmin distribution rendered as Microfiber, with a warning)."""
    if node.distribution != "MICROFIBER":
        images.warn(f"material '{name}': {node.bl_label}'s {node.distribution.title()} "
                    f"distribution is rendered as Microfiber")
    return Material(name, (0.0, 0.0, 0.0), roughness=1.0, sheen_weight=1.0, sheen_layered=False,
                    sheen_roughness=float(constant(node, "Roughness", 0.5)),
                    sheen_tint=rgb(constant(node, "Color", (1, 1, 1))),
                    **_normal_map(node, name, images))


def _mixed_maps(node, a: Material, b: Material, wa: float, wb: float) -> dict[str, object]:
    """The image textures and cutout of a mix of two shaders with weights ``wa`` and ``wb``
    (summing to 1 in a Mix Shader): one base colour texture both use (the mix of a texture
    with itself is the texture), no emission texture, one side's normal map, and one coverage
    texture both use or constant alphas, mixed by the weights (Cycles mixes the Transparent
    closures they hold)."""
    label = node.bl_label
    if a.emission_texture is not None or b.emission_texture is not None or \
            a.base_color_texture is not b.base_color_texture:
        raise UnsupportedNodes(f"image textures inside '{label}' other than one base colour "
                           f"texture both shaders use are not supported")
    normal = a if a.normal_texture is not None else b  # mixed normals: one side's map
    maps: dict[str, object] = {"base_color_texture": a.base_color_texture,
                               "normal_texture": normal.normal_texture,
                               "normal_strength": normal.normal_strength,
                               "bump_distance": normal.bump_distance,
                               "bump_filter_width": normal.bump_filter_width}
    if not (a.is_cutout or b.is_cutout):
        return maps
    if node.type == "ADD_SHADER":
        raise UnsupportedNodes(f"an Alpha inside '{label}' is not supported")
    if (a.coverage_texture, a.coverage_mode) == (b.coverage_texture, b.coverage_mode):
        return {**maps, "alpha": wa * a.alpha + wb * b.alpha,
                "coverage_texture": a.coverage_texture, "coverage_mode": a.coverage_mode}
    raise UnsupportedNodes(f"an Alpha texture on one side of '{label}' is not supported")


def _mixed_translucency(a: Material, b: Material, wa: float, wb: float,
                        base: tuple[float, ...]) -> tuple[float, float, float]:
    """The translucency of a mix of two shaders with weights ``wa`` and ``wb`` whose mixed
    base colour is ``base``: per channel, the share of the mix's diffuse light either lets
    through (of one base colour texture both use, the weights' mix)."""
    if a.base_color_texture is not None:  # _mixed_maps: both use it
        share = (wa * np.array(a.translucency) + wb * np.array(b.translucency)) \
            / max(wa + wb, 1e-30)
    else:
        through = wa * np.array(a.base_color) * a.translucency \
            + wb * np.array(b.base_color) * b.translucency
        share = np.divide(through, base, out=np.zeros(3), where=np.array(base) > 0)
    return tuple(float(v) for v in np.clip(share, 0.0, 1.0))


RAY_TYPE_MIXES = {"Is Camera Ray": "camera_sees_through", "Is Shadow Ray": "shadow_rays_pass"}
"""Light Path outputs a Mix Shader's Fac may take to show one kind of ray a white Transparent
BSDF (its second slot) and the others its first shader: the Material flag that does so."""


def _ray_type_mix(node, a: Material, b: Material) -> Material | None:
    """A Mix Shader whose Fac is Light Path's Is Camera Ray or Is Shadow Ray and whose second
    shader is a white Transparent BSDF: the first shader, which the camera sees through (a
    hidden emitter) or shadow rays pass; None for other mixes (an unsupported link)."""
    fac = node.inputs["Fac"]
    if not fac.is_linked or fac.links[0].from_node.type != "LIGHT_PATH":
        return None
    flag = RAY_TYPE_MIXES.get(fac.links[0].from_socket.name)
    if flag is None or not _is_transparent(b) or _is_transparent(a):
        return None
    return replace(a, **{flag: True})


def _is_transparent(material: Material) -> bool:
    """A white Transparent BSDF: light passes untouched."""
    return material.is_clear and material.transmission == (1.0, 1.0, 1.0) \
        and material.transmission_ior == 0.0


def _transparent_mix(node, a: Material, b: Material, name: str, images: ImageReader
                     ) -> Material | None:
    """A Mix Shader of a white Transparent BSDF and a surface as that surface made a cutout
    by the Fac (a constant or an Image Texture: a leaf's mask); None for other mixes."""
    if _is_transparent(a) == _is_transparent(b) or (a if _is_transparent(b) else b).is_clear:
        return None
    try:
        fac, texture, mode = images.coverage(node, "Fac", name)
    except UnsupportedLink:
        return None
    surface = b if _is_transparent(a) else a  # Fac weighs the second slot
    if surface is a:
        fac, mode = 1.0 - fac, mode | COVERAGE_INVERTED
    if texture is not None and surface.coverage_texture is not None:
        raise UnsupportedNodes(f"two coverage textures in '{node.bl_label}' are not supported")
    if texture is None:
        return replace(surface, alpha=surface.alpha * fac)
    return replace(surface, coverage_texture=texture, coverage_mode=mode)


DEFAULT_PRINCIPLED = Material(DEFAULT_MATERIAL.name, specular_ior_level=0.5)


CLEAR_VOLUME_ONLY = Material("", (0.0, 0.0, 0.0), roughness=1.0,
                             transmission=(1.0, 1.0, 1.0), transmission_ior=0.0)
"""A material with a Volume shader and no Surface: in Cycles rays pass its surface untouched."""


def _default_surface() -> Material:
    """An empty slot or an object without slots: Cycles 4.x renders it diffuse 0.8 grey,
    Cycles 5.x as a default Principled BSDF."""
    return DEFAULT_PRINCIPLED if DEFAULT_SURFACE_IS_PRINCIPLED else DEFAULT_MATERIAL


def material_aovs(material: bpy.types.Material | None, warnings: list[str]
                  ) -> tuple[tuple[str, tuple[float, float, float, float]], ...]:
    """The material's AOV Output nodes (Shader AOV passes): each one's name and its Color and
    Value, constants (a linked input is read at its node's own value, with a warning)."""
    if material is None or material.node_tree is None or not uses_nodes(material):
        return ()
    found = []
    for node in material.node_tree.nodes:
        if node.bl_idname != "ShaderNodeOutputAOV" or not node.aov_name or node.mute:
            continue
        color, value = node.inputs["Color"], node.inputs["Value"]
        for socket in (color, value):
            if socket.is_linked:
                warnings.append(f"material '{material.name}': AOV '{node.aov_name}''s "
                                f"{socket.name} is linked: written as its own value "
                                f"{tuple(round(v, 3) for v in _socket_values(socket))}")
        found.append((node.aov_name, (*_socket_values(color)[:3],
                                      _socket_values(value)[0])))
    return tuple(found)


def _socket_values(socket: bpy.types.NodeSocket) -> tuple[float, ...]:
    """A socket's default value as floats (a colour's channels, or one number)."""
    value = socket.default_value
    return tuple(float(v) for v in value) if hasattr(value, "__len__") else (float(value),)


def export_material(material: bpy.types.Material | None, warnings: list[str],
                    images: ImageReader | None = None,
                    fallbacks: dict[str, str] | None = None) -> Material:
    """Base colour, emission, roughness and metallic of a material's surface (constant values
    or image textures, read by ``images``).

    A material without nodes (Blender 4.x) is diffuse in its viewport colour (as in Cycles),
    with a warning;
    an unsupported node tree falls back to the viewport colour with one warning (none where
    the tree can be baked: ``fallbacks`` gets the reason, and bake.apply says what it did)."""
    if material is None:
        return _default_surface()
    viewport = Material(material.name, rgb(material.diffuse_color),
                        roughness=float(material.roughness), metallic=float(material.metallic))
    if not uses_nodes(material):
        warnings.append(f"material '{material.name}' has no shader nodes: rendered as a "
                        f"diffuse surface in its viewport colour (as Cycles does)")
        return viewport
    node = surface_node(material.node_tree)
    if volume_linked(material.node_tree):
        if node is None:
            warnings.append(f"material '{material.name}': its Volume shader is not rendered; "
                            f"without a Surface, light passes through it (as in Cycles)")
            return replace(CLEAR_VOLUME_ONLY, name=material.name)
        warnings.append(f"material '{material.name}': its Volume shader is not rendered")
    images = images or ImageReader(warnings)
    try:
        return _displaced(material, _shader(node, material.name, images), images)
    except (UnsupportedNodes, UnsupportedLink) as reason:
        if fallbacks is not None:
            fallbacks[material.name] = str(reason)
        if fallbacks is None or bake.bake_reason(material, str(reason)) is None:
            warnings.append(f"material '{material.name}': {reason}; using its viewport colour")
        return _with_surface_maps(viewport, node, images)


def _with_surface_maps(viewport: Material, node, images: ImageReader) -> Material:
    """A fallback material with what its surface's own BSDF reads apart from its colour:
    the normal or bump map, and a Principled BSDF's cutout (a bake keeps them)."""
    if node is None or node.type not in ("BSDF_PRINCIPLED", "BSDF_DIFFUSE"):
        return viewport
    fields = _normal_map(node, viewport.name, images)
    if node.type == "BSDF_PRINCIPLED":
        fields.update(_principled_alpha(node, viewport.name, images))
    return replace(viewport, **fields)


def _displaced(material: bpy.types.Material, exported: Material,
               images: ImageReader) -> Material:
    """The material with its Material Output's Displacement as Cycles' default renders it, a
    bump (Displacement Method Bump Only): a Displacement node's Height from an Image Texture
    is a bump map of Distance = its Scale (the Bump node's rendering); anything else, a
    Displacement besides a shader's own normal or bump map, and true displacement (rendered
    as bump) get a warning."""
    output = cycles_output_node(material.node_tree)
    socket = None if output is None else output.inputs.get("Displacement")
    if socket is None or not socket.is_linked:
        return exported
    name = material.name
    if getattr(material, "displacement_method", "BUMP") != "BUMP":
        images.warn(f"material '{name}': its displacement is rendered as a bump (Displacement "
                    f"Method Bump Only)")
    source = linked_node(socket)
    reason = None
    if source.type != "DISPLACEMENT" or source.space != "OBJECT":
        reason = f"linked to '{source.bl_label}'"
    elif exported.normal_texture is not None:
        reason = "besides the shader's own normal or bump map"
    elif not source.inputs["Height"].is_linked:
        return exported  # a constant height moves the surface, never bends it
    else:
        try:
            texture = images.color(source, "Height", (0.0, 0.0, 0.0), name)[1]
        except (UnsupportedNodes, UnsupportedLink) as exc:
            reason = str(exc)
    if reason is not None:
        images.warn(f"material '{name}': its Displacement is not rendered ({reason})")
        return exported
    return replace(exported, normal_texture=texture, normal_strength=1.0,
                   bump_distance=float(constant(source, "Scale", 1.0)))


def fallback_reasons(obj: bpy.types.Object,
                     known: dict[str, dict[str, str]] | None = None) -> dict[str, str]:
    """Why each of the object's materials falls back to its viewport colour (by name);
    ``known`` keeps each material's answer across calls, so objects that share a material
    export it (and read its images) once."""
    known = {} if known is None else known
    fallbacks: dict[str, str] = {}
    for slot in obj.material_slots:
        material = slot.material
        if material is None:
            continue
        if material.name_full not in known:
            known[material.name_full] = {}
            export_material(material, [], fallbacks=known[material.name_full])
        fallbacks.update(known[material.name_full])
    return fallbacks


# -- lights, world, camera ------------------------------------------------------------------

def _image_pixels(image: bpy.types.Image, warnings: list[str]) -> np.ndarray | None:
    """Linear RGB (h, w, 3) float32 of an image, rows bottom-up, or None if it cannot be read.

    Float images (.hdr, .exr) are linear; 8-bit images in sRGB are decoded; NaN/Inf values
    are read as 0 and negative ones capped at 0."""
    pixels = read_pixels(image, warnings)
    if pixels is None:
        return None
    rgb = pixels[..., :3]
    if not image.is_float and image.colorspace_settings.name == "sRGB":
        rgb = decode_srgb(rgb)
    return np.maximum(rgb, 0.0).astype(np.float32)


def _map_rotation(texture) -> float:
    """Z rotation of the Environment Texture's vector (default, or Texture Coordinate
    Generated through a Mapping node that only turns about Z); UnsupportedNodes otherwise."""
    socket = texture.inputs["Vector"]
    if not socket.is_linked:
        return 0.0
    node = socket.links[0].from_node
    if node.type == "TEX_COORD" and socket.links[0].from_socket.name == "Generated":
        return 0.0
    if node.type != "MAPPING" or node.vector_type not in ("POINT", "VECTOR", "TEXTURE"):
        raise UnsupportedNodes(f"its vector comes from '{node.bl_label}'")
    rotation = np.array(constant(node, "Rotation", (0.0, 0.0, 0.0)))
    scale = np.array(constant(node, "Scale", (1.0, 1.0, 1.0)))
    moved = node.vector_type != "VECTOR" and np.any(np.array(
        constant(node, "Location", (0.0, 0.0, 0.0))) != 0)
    source = node.inputs["Vector"]
    generated = not source.is_linked or (source.links[0].from_node.type == "TEX_COORD" and
                                         source.links[0].from_socket.name == "Generated")
    if moved or np.any(rotation[:2] != 0) or np.any(scale != 1) or not generated:
        raise UnsupportedNodes("its Mapping node does more than a Z rotation of the default vector")
    return float(-rotation[2] if node.vector_type == "TEXTURE" else rotation[2])


def _environment_world(texture, strength: float, warnings: list[str],
                       lights: list[Light] | None = None, name: str = "") -> World:
    """A world lit by an equirectangular Environment Texture (magenta if its image is
    missing, as in Cycles; its mean colour, without a bake, for what world_bake_reason
    names); with ``lights``, its sun disc, if any, taken out of the map as a sun light
    there (core/scene/sun_disc.py)."""
    image = texture.image
    pixels = _image_pixels(image, warnings) if image is not None else None
    if pixels is None:
        label = f"'{image.name}'" if image is not None else "(none)"
        warnings.append(f"world: the Environment Texture's image {label} could not be loaded: "
                        f"rendered magenta, as Cycles does")
        return World(MISSING_COLOR, strength)
    env = EnvironmentMap(pixels * np.float32(strength))
    mean = tuple(mean_radiance(env) / strength) if strength != 0 else (0.0, 0.0, 0.0)
    try:
        if texture.projection != "EQUIRECTANGULAR":
            return World(mean, strength)
        env.rotation = _map_rotation(texture)
    except UnsupportedNodes:
        return World(mean, strength)
    sun = take_out_map_sun(env, f"{name} sun disc") if lights is not None else None
    if sun is not None:
        lights.append(sun)
        mean = tuple(mean_radiance(env) / strength)
    return World(mean, strength, env, sun)


def world_bake_reason(world: bpy.types.World | None) -> str | None:
    """Why the export cannot read the world's light from its nodes (Cycles then bakes it,
    world_bake.py), or None where it can: a colour, or an Environment Texture of an
    equirectangular image turned about Z at most."""
    if world is None or not uses_nodes(world):
        return None
    node = surface_node(world.node_tree, "OUTPUT_WORLD")
    if node is None:
        return None
    if node.type != "BACKGROUND":
        return f"its surface is a '{node.bl_label}' node"
    if node.inputs["Strength"].is_linked:
        return "its Background strength comes from nodes"
    color = node.inputs["Color"]
    source = color.links[0].from_node if color.is_linked else None
    if source is None:
        return None
    if source.type != "TEX_ENVIRONMENT":
        return f"its Background colour comes from '{source.bl_label}'"
    if source.projection != "EQUIRECTANGULAR":
        return f"its Environment Texture's projection is {source.projection.lower()}"
    try:
        _map_rotation(source)
    except UnsupportedNodes as reason:
        return f"its Environment Texture: {reason}"
    return None


def export_world(world: bpy.types.World | None, warnings: list[str],
                 notes: list[str] | None = None, unbaked: set[str] | None = None,
                 lights: list[Light] | None = None) -> World:
    """The world's Background colour × strength, its Environment Texture, or its bake where
    the nodes are more than that (with a note, and ``lights`` gets the sun disc the bake
    took out; without a bake, one colour and a warning naming why, and ``unbaked`` gets the
    world where a bake pass would make it). Its Volume shader (fog) is left out, with a
    warning; a colour × strength that is negative or not finite is black, with a warning."""
    read = _world_of(world, warnings, notes, unbaked, lights)
    radiance = read.radiance
    if world is not None and not (np.isfinite(radiance).all() and radiance.min() >= 0):
        warnings.append(f"world '{world.original.name}': its colour × strength "
                        f"{tuple(radiance.round(3).tolist())} is negative or not finite: "
                        f"rendered black")
        return World(lightgroup=read.lightgroup)
    return read


def _world_of(world: bpy.types.World | None, warnings: list[str], notes: list[str] | None,
              unbaked: set[str] | None, lights: list[Light] | None) -> World:
    """export_world's world before its check."""
    if world is not None and uses_nodes(world) and volume_linked(world.node_tree,
                                                                 "OUTPUT_WORLD"):
        warnings.append(f"world '{world.original.name}': its Volume shader (fog) is not "
                        f"rendered")
    reason = world_bake_reason(world)
    if reason is None:
        read = _read_world(world, warnings, lights)
        if notes is not None and read.visible_sun is not None:
            notes.append(f"world '{world.original.name}': its map's sun disc "
                         f"({np.degrees(read.visible_sun.sun_angle):.2f}°) as a sun light")
        return read
    name = world.original.name
    baked = world_bake.cached(world)
    if baked is not None:
        if notes is not None:
            height, width = baked.pixels.shape[:2]
            sun = "" if baked.sun is None else \
                f"; its sun disc ({np.degrees(baked.sun.sun_angle):.2f}°) as a sun light"
            notes.append(f"world '{name}' baked by Cycles ({width} × {height} px, "
                         f"{baked.seconds:.2f} s{sun}): {reason}")
        if lights is not None and baked.sun is not None:
            lights.append(replace(baked.sun))  # the scene's own copy: the bake is kept
        return baked.world()
    why = world_bake.why_not_baked(world)
    if unbaked is not None and why == bake.NOT_BAKED:
        unbaked.add(f"world '{name}'")
    warnings.append(f"world '{name}': {reason}; lit by one colour instead ({why})")
    return _read_world(world, [])


def _read_world(world: bpy.types.World | None, warnings: list[str],
                lights: list[Light] | None = None) -> World:
    """The world's Background colour × strength, or its Environment Texture (its sun disc
    into ``lights``); for what world_bake_reason names, one colour: the viewport colour for
    surfaces other than a Background, the socket's colour for other colour nodes, the map's
    mean."""
    if world is None:
        return World()
    node = surface_node(world.node_tree, "OUTPUT_WORLD") if uses_nodes(world) else None
    if node is None or node.type != "BACKGROUND":
        return World(rgb(world.color), 1.0)
    strength = float(_input_value(node, "Strength", 1.0))
    color = node.inputs["Color"]
    source = color.links[0].from_node if color.is_linked else None
    if source is not None and source.type == "TEX_ENVIRONMENT":
        return _environment_world(source, strength, warnings, lights, world.original.name)
    return World(rgb(color.default_value), strength)


def export_camera(depsgraph: bpy.types.Depsgraph, camera_object: bpy.types.Object | None,
                  width: int, height: int, warnings: list[str]) -> Camera | None:
    """Blender's own projection (sensor fit, shift, clipping) for the given resolution;
    TransformError for an object that cannot be the camera (``check_camera``). A panoramic
    camera is rendered as a perspective one, with a warning."""
    if camera_object is None:
        return None
    render = depsgraph.scene_eval.render
    cam = camera_object.evaluated_get(depsgraph)
    check_camera(cam)
    panorama = camera_panorama(cam, width * render.pixel_aspect_x,
                               height * render.pixel_aspect_y)
    if cam.data.type == "PANO" and panorama is None:
        warnings.append(f"camera '{cam.name}': its panorama type "
                        f"{cam.data.panorama_type.replace('_', ' ').title()} is not rendered: "
                        f"rendered as a perspective camera of the same lens")
    aperture = camera_aperture(cam)
    if panorama is not None and aperture is not None:
        warnings.append(f"camera '{cam.name}': depth of field is not rendered for a "
                        f"panoramic camera")
        aperture = None
    projection = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                        scale_x=render.pixel_aspect_x,
                                        scale_y=render.pixel_aspect_y)
    view = camera_view(_matrix(cam.matrix_world))
    return Camera(view, _matrix(projection), width, height,
                  is_orthographic=cam.data.type == "ORTHO", aperture=aperture,
                  panorama=panorama)


def camera_panorama(cam: bpy.types.Object, fit_x: float, fit_y: float) -> Panorama | None:
    """A panoramic camera's lens (the types frame/panorama.py renders; else None), its
    fisheye sensor fitted to the image (``fit_x`` × ``fit_y``) as Cycles fits it."""
    data = cam.data
    if data.type != "PANO" or data.panorama_type not in PANORAMA_KINDS:
        return None
    horizontal = fit_x > fit_y if data.sensor_fit == "AUTO" else data.sensor_fit == "HORIZONTAL"
    size = data.sensor_height if data.sensor_fit == "VERTICAL" else data.sensor_width
    sensor = (size, size * fit_y / fit_x) if horizontal else (size * fit_x / fit_y, size)
    return Panorama(data.panorama_type, data.latitude_min, data.latitude_max,
                    data.longitude_min, data.longitude_max, data.fisheye_fov, data.fisheye_lens,
                    *sensor)


def camera_aperture(cam: bpy.types.Object) -> Aperture | None:
    """The camera's lens for depth of field as Cycles sets it up (blender/camera.cpp): a
    radius of lens / (2 f-stop) (orthographic: 1 / (2 f-stop)), focused at the focus
    object's (or bone's) distance along the view, else the focus distance; None where depth
    of field is off."""
    dof = cam.data.dof
    if not dof.use_dof:
        return None
    fstop = max(float(dof.aperture_fstop), 1e-5)
    radius = 1.0 / (2.0 * fstop) if cam.data.type == "ORTHO" \
        else float(cam.data.lens) * 1e-3 / (2.0 * fstop)
    focus = float(dof.focus_distance)
    target = dof.focus_object
    if target is not None:
        matrix = target.matrix_world
        bone = getattr(dof, "focus_subtarget", "")
        if target.pose is not None and bone and bone in target.pose.bones:
            matrix = matrix @ target.pose.bones[bone].matrix
        view_axis = cam.matrix_world.to_3x3().normalized().col[2]
        focus = abs(view_axis.dot(cam.matrix_world.translation - matrix.translation))
    return Aperture(radius, focus, int(dof.aperture_blades), float(dof.aperture_rotation),
                    float(dof.aperture_ratio))


def render_size(scene: bpy.types.Scene) -> tuple[int, int]:
    """Output resolution in pixels, percentage applied (as Blender does)."""
    r = scene.render
    scale = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * scale)), max(1, int(r.resolution_y * scale))


# -- the scene ------------------------------------------------------------------------------

class _Export:
    """State of one export: per-pointer memos (valid for this depsgraph evaluation only)."""

    def __init__(self, depsgraph: bpy.types.Depsgraph, cache: ExportCache, result: Scene,
                 cancelled: Callable[[], bool]):
        self.depsgraph = depsgraph
        self.rendering = depsgraph.mode == "RENDER"  # hair particles' steps and children
        self.cancelled = cancelled
        self.cache = cache
        self.result = result
        self.used: dict[tuple, _Entry] = {}
        self.meshes: dict[tuple, _Entry] = {}
        self.materials: dict[str, Material] = {}
        self.visibility: dict[int, bool] = {}
        self.images = ImageReader(result.warnings)
        self.generated: dict[str, dict[int, int]] = {}
        self.fallbacks: dict[str, str] = {}
        self.named_uvs: dict[str, frozenset[str]] = {}
        self.bake_resolution = bake.settings_of(depsgraph.scene)[0]

    def include(self, obj: bpy.types.Object) -> bool:
        """False for geometry no ray sees (camera, diffuse and shadow visibility all off;
        each alone is honoured: ``Instance``)."""
        pointer = obj.original.as_pointer()
        known = self.visibility.get(pointer)
        if known is None:
            known = self.visibility[pointer] = any(getattr(obj, flag, True)
                                                   for flag in RAY_FLAGS)
        return known

    def holdout(self, obj: bpy.types.Object) -> bool:
        """Whether the view layer renders the object as a holdout (``Instance.holdout``)."""
        return bool(obj.original.holdout_get(view_layer=self.depsgraph.view_layer))

    def _key(self, inst, obj: bpy.types.Object, pointer: int) -> tuple[tuple, set[str]]:
        """The cache key of an instance's geometry and the names that invalidate it."""
        original = obj.original
        parent = inst.parent
        if inst.is_instance and parent is not None and \
                parent.original.as_pointer() == original.as_pointer():
            ordinals = self.generated.setdefault(original.name, {})
            ordinal = ordinals.setdefault(pointer, len(ordinals))
            return ("generated", original.name_full, ordinal), {original.name}
        if obj.type == "MESH" and not original.modifiers and original.data.shape_keys is None:
            mesh = original.data
            return ("mesh", mesh.name_full), {mesh.name, mesh.name_full, original.name}
        names = {original.name, original.name_full}
        if obj.type in ("MESH", "CURVES", "POINTCLOUD"):
            names.add(original.data.name)
        return ("object", original.name_full), names

    def mesh(self, inst, obj: bpy.types.Object) -> Mesh:
        """The instance's mesh: from this export, from the cache, or read now."""
        pointer = obj.data.as_pointer()
        memo = (pointer,) if obj.type == "MESH" else (obj.original.as_pointer(), pointer)
        known = self.meshes.get(memo)
        if known is not None:
            known.names.add(obj.original.name)
            self.cache.stats["meshes_reused"] += 1
            return known.mesh
        key, names = self._key(inst, obj, pointer)
        fingerprint = _fingerprint(obj) if key[0] == "generated" else ()
        entry = self.meshes[memo] = self._entry(key, names, fingerprint,
                                                lambda: self._read(obj, key))
        return entry.mesh

    def _entry(self, key: tuple, names: set[str], fingerprint: tuple[int, ...],
               read: Callable[[], tuple[Mesh, list[str]]]) -> _Entry:
        """The geometry under ``key``: from this export or the cache where its fingerprint
        still holds, else ``read()`` now; its problems warned once an export."""
        entry = self.used.get(key) or self.cache._entries.get(key)
        if entry is not None and entry.fingerprint == fingerprint:
            entry.names |= names
            self.cache.stats["meshes_reused"] += 1
        else:
            mesh, problems = read()
            entry = _Entry(mesh, names, fingerprint, problems)
            self.cache.stats["meshes_read"] += 1
        if key not in self.used:
            self.result.warnings.extend(entry.problems)
        self.used[key] = entry
        return entry

    def _read(self, obj: bpy.types.Object, key: tuple) -> tuple[Mesh, list[str]]:
        label = f"mesh '{key[1]}'" if key[0] == "mesh" else f"object '{obj.original.name}'"
        if obj.type == "MESH":
            return _mesh_arrays(obj.data, obj.name, label, faces_expected=True)
        if obj.type == "CURVES":
            return read_hair(obj.data, obj.name, label)
        if obj.type == "POINTCLOUD":
            return read_points(obj.data, obj.name, label)
        evaluated_mesh = obj.to_mesh()
        if evaluated_mesh is None:
            return empty_mesh(obj.name), []
        try:
            return _mesh_arrays(evaluated_mesh, obj.name, label, faces_expected=False)
        finally:
            obj.to_mesh_clear()

    def materials_of(self, obj: bpy.types.Object) -> list[Material]:
        if not obj.material_slots:
            return [_default_surface()]
        found = []
        for slot in obj.material_slots:
            key = slot.material.name_full if slot.material else ""
            if key not in self.materials:
                exported = export_material(slot.material, self.result.warnings,
                                           self.images, self.fallbacks)
                if slot.material is not None and slot.material.pass_index:
                    exported = replace(exported, pass_index=int(slot.material.pass_index))
                aovs = material_aovs(slot.material, self.result.warnings)
                if aovs:
                    exported = replace(exported, aovs=aovs)
                self.materials[key] = exported
                named = bake.named_uv_maps(slot.material)
                if named:
                    self.named_uvs[slot.material.name] = named
            found.append(self.materials[key])
        return found

    def identity(self, obj: bpy.types.Object) -> Identity:
        """The object's name, Pass Index and topmost parent's name (its asset), as the ID
        passes know it."""
        top = obj
        while top.parent is not None:
            top = top.parent
        return Identity(obj.name, int(obj.pass_index), top.name)

    def hair(self, obj: bpy.types.Object) -> tuple[Mesh, list[Material], str]:
        """The tubes of the object's hair particles (from this export, the cache, or read
        now), its materials and name."""
        original = obj.original
        entry = self._entry(("hair", original.name_full),
                            {original.name, original.name_full, original.data.name}, (),
                            lambda: read_particle_hair(obj, self.rendering,
                                                       f"object '{original.name}'",
                                                       self.cancelled))
        return entry.mesh, self.materials_of(obj), obj.name

    def placed(self, inst, obj: bpy.types.Object) -> tuple[Mesh, list[Material], str]:
        """The instance's mesh and materials (with its object's bake, if any) and name."""
        mesh, materials = self.mesh(inst, obj), self.materials_of(obj)
        if self.fallbacks or self.named_uvs:
            mesh, materials = bake.apply(obj, mesh, materials, self.fallbacks, self.named_uvs,
                                         self.bake_resolution, self.result.notes,
                                         self.result.warnings, self.cache.unbaked,
                                         self.rendering)
        return mesh, materials, obj.name


UNRENDERED = {
    "VOLUME": "volume objects are not rendered: {}",
}
"""What Cycles renders and VPL GI does not, by Blender's object type (keys of
``export_scene``'s skipped objects); each a warning naming them."""


def unrendered_objects(skipped: dict[str, set[str]]) -> list[str]:
    """One warning per kind of thing left out, naming up to three of its objects."""
    warnings = []
    for kind, names in sorted(skipped.items()):
        shown = ", ".join(f"'{name}'" for name in sorted(names)[:3])
        more = f" and {len(names) - 3} more" if len(names) > 3 else ""
        warnings.append(UNRENDERED[kind].format(shown + more))
    return warnings


def export_scene(depsgraph: bpy.types.Depsgraph, cache: ExportCache | None = None,
                 motion: SampledMotion | None = None,
                 cancelled: Callable[[], bool] = lambda: False) -> Scene:
    """Everything the renderer needs from the evaluated depsgraph; with ``motion``, each
    instance's and the camera's placement at its two times too (export_motion.py). Raises
    RenderCancelled where ``cancelled()`` during a long read (hair particles).

    With a cache, meshes read by earlier exports are reused unless forgotten (see ExportCache);
    ``cache.stats`` counts the meshes this export read and reused, ``cache.unbaked`` names the
    materials waiting for a bake."""
    scene_eval = depsgraph.scene_eval
    result = Scene()
    cache = cache if cache is not None else ExportCache()
    cache.stats.update(meshes_read=0, meshes_reused=0)
    cache.unbaked.clear()
    state = _Export(depsgraph, cache, result, cancelled)
    linking = scene_light_linking(depsgraph)
    result.warnings.extend(linking.warnings)
    hairy: dict[bpy.types.Object, bool] = {}  # whether an object has hair particles shown
    placed: list[tuple[Mesh, list[Material], str]] = []
    skipped: dict[str, set[str]] = {}  # what VPL GI does not render (UNRENDERED): objects
    # Per (object, data, "self" or "hair": its particle hair): its mesh, materials and name,
    # or None when no ray sees it. Keyed by
    # the structs themselves (hashed and compared by pointer: no as_pointer() call each).
    # Each entry also says whether the mesh has triangles (instances of one without are left
    # out): one lookup per instance, scenes may hold many thousands.
    placements: dict[tuple[bpy.types.Object, bpy.types.ID, str],
                     tuple[tuple[Mesh, list[Material], str] | None, bool]] = {}
    ordinals: list[int] = []  # of the placed instances in depsgraph.object_instances
    keys: list[InstanceKey] = []  # with motion: theirs (export_motion.instance_key)
    count = reused = 0
    for count, inst in enumerate(depsgraph.object_instances, start=1):
        obj = inst.object
        kind = obj.type
        if kind == "LIGHT":
            matrix = _matrix(inst.matrix_world)
            problem, = transform_problems(matrix[None])
            if problem:
                result.warnings.append(f"light '{obj.name}' {problem} and was skipped")
            elif is_portal(obj):
                result.portals.append(export_light(obj, matrix))
            else:
                light = export_light(obj, matrix, result.warnings, depsgraph.view_layer)
                if light.kind is LightKind.AREA and light.world_area <= 0:
                    result.warnings.append(f"area light '{obj.name}' has zero size: it gives "
                                           f"no light, as in Cycles")
                    continue
                light.receivers = linking.receivers_of(obj)
                light.blockers = linking.blockers_of(obj)
                result.lights.append(light)
            continue
        hair = False
        if kind == "MESH" and inst.show_particles:
            hair = hairy.get(obj.original)
            if hair is None:
                hair = hairy[obj.original] = bool(hair_systems(obj, state.rendering))
        if kind not in RENDERED_OBJECT_TYPES or not (inst.show_self or hair):
            if kind in UNRENDERED and inst.show_self:
                skipped.setdefault(kind, set()).add(obj.name)
            continue
        for part, shown in (("self", inst.show_self), ("hair", hair)):
            if not shown:
                continue
            memo = (obj.original, obj.data, part)
            entry = placements.get(memo)
            if entry is None:
                made = state.placed(inst, obj) if part == "self" else state.hair(obj)
                known = (*made, visible_to_camera(obj, depsgraph.view_layer),
                         state.holdout(obj), bool(getattr(obj, "visible_shadow", True)),
                         bool(getattr(obj, "visible_diffuse", True)), state.identity(obj),
                         linking.receiver_set(obj), linking.receivers_of(obj),
                         bool(getattr(obj, "is_shadow_catcher", False)),
                         linking.blocker_set(obj), linking.blockers_of(obj),
                         str(getattr(obj, "lightgroup", ""))) \
                    if state.include(obj) else None
                entry = placements[memo] = (known, bool(known and known[0].triangle_count))
            elif entry[0]:
                reused += 1
            if entry[1]:
                ordinals.append(count - 1)
                placed.append(entry[0])
                if motion is not None:
                    keys.append(instance_key(inst))
    cache.stats["meshes_reused"] += reused
    # every instance's world matrix in one foreach_get over the same (deterministic) instance
    # iteration, as RNA stores them (float32, column by column)
    columns = np.empty(count * 16, dtype=np.float32)
    depsgraph.object_instances.foreach_get("matrix_world", columns)
    matrices = columns.reshape(-1, 4, 4)[ordinals].transpose(0, 2, 1).astype(np.float64)
    problems = transform_problems(matrices)
    for index, ((mesh, materials, name, *flags), matrix, problem) in enumerate(
            zip(placed, matrices, problems, strict=True)):
        if problem:
            result.warnings.append(f"object '{name}' {problem} and was skipped")
        else:
            if motion is not None:
                mesh, matrix = at_home(motion, keys[index], mesh, matrix)
                mesh = deformed_mesh(motion, keys[index], mesh)
            result.instances.append(Instance(mesh, matrix, materials, *flags))
            if motion is not None:
                result.instances[-1].motion = placed_motion(motion, keys[index])
    cache._entries = state.used
    lights_before_world = len(result.lights)  # a world's sun disc joins them
    result.world = export_world(scene_eval.world, result.warnings, result.notes, cache.unbaked,
                                result.lights)
    world_group = str(getattr(scene_eval.world, "lightgroup", "")) if scene_eval.world else ""
    world_bounces = max_bounces(scene_eval.world)
    result.world = replace(result.world, lightgroup=world_group,  # a bake's world is kept
                           max_bounces=world_bounces)
    for light in result.lights[lights_before_world:]:
        light.lightgroup, light.max_bounces = world_group, world_bounces
    result.warnings.extend(unrendered_objects(skipped))
    result.film_transparent = bool(scene_eval.render.film_transparent)
    result.camera = export_camera(depsgraph, scene_eval.camera, *render_size(scene_eval),
                                  result.warnings)
    if scene_eval.world is not None:
        result.mist = export_mist(scene_eval.world.mist_settings)
        result.ao_distance = ao_distance(scene_eval.world.light_settings.distance)
    if motion is not None:
        result.motion = motion.span
        if result.camera is not None and motion.home_view is not None:
            result.camera = replace(result.camera, view_matrix=motion.home_view)
        elif result.camera is not None and all(v is not None for v in motion.views):
            result.camera = replace(result.camera, motion_views=motion.views)
    return result


MIST_FALLOFF = {"QUADRATIC": 2.0, "LINEAR": 1.0, "INVERSE_QUADRATIC": 0.5}


def ao_distance(distance: float) -> float:
    """The world's AO distance as the Ambient Occlusion pass's rays run (finite, >= 0)."""
    return float(np.clip(np.nan_to_num(float(distance), nan=0.0), 0.0, MAX_AO_DISTANCE))


MAX_AO_DISTANCE = 1e30


def export_mist(settings: bpy.types.WorldMistSettings) -> Mist:
    """The world's mist settings (the Mist pass) as Cycles reads them."""
    return Mist(float(settings.start), float(settings.depth),
                MIST_FALLOFF.get(settings.falloff, 2.0))
