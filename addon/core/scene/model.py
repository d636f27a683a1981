"""Plain scene description handed from the Blender export to the renderer.

Everything here is numpy arrays and small dataclasses: no Blender types, so the renderer can be
tested and benchmarked without Blender. Units follow Blender/Cycles: metres, watts, W/m² for the
sun, radiance for emission and the world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from .ies import IesProfile
from .vectors import unit

Matrix4 = np.ndarray  # (4, 4) float64, column vectors (Blender's convention)


NO_BOUNCE_LIMIT = 1024
"""A light's or the world's Max Bounces by default (Cycles'): no limit in practice."""
EVERY_RECEIVER_SET = (1 << 64) - 1
"""An emitter's ``receivers`` when light linking leaves it lighting every object: bit s set
lights the objects of receiver set s (Blender's light linking allows 64 sets, 0 the objects
no receiver collection names)."""

INTERPOLATIONS = ("Closest", "Linear", "Cubic")  # Image Texture node names (Smart: Cubic)
EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")


@dataclass(eq=False)
class Texture:
    """An image sampled through the mesh's UVs as Cycles samples it: ``interpolation`` one of
    INTERPOLATIONS, ``extension`` one of EXTENSIONS (Blender's names; see
    ``scene/textures.py``).

    ``pixels`` are as Blender stores them, rows bottom-up (UV (0, 0) is the first texel);
    with ``srgb`` they are sRGB-encoded and decoded after interpolation, as Cycles does with
    byte images (measured: tests/blender/test_textures.py). ``eight_bit``: every value is a
    byte's code / 255 (an 8-bit image), which the GPU holds as bytes."""

    name: str
    pixels: np.ndarray  # (h, w, 4) float32 RGBA
    srgb: bool = False
    interpolation: str = "Linear"
    extension: str = "REPEAT"
    eight_bit: bool = False

    def __post_init__(self) -> None:
        if self.interpolation not in INTERPOLATIONS or self.extension not in EXTENSIONS:
            raise ValueError(f"texture '{self.name}': interpolation {self.interpolation!r} "
                             f"or extension {self.extension!r} is not one of "
                             f"{INTERPOLATIONS} / {EXTENSIONS}")


COVERAGE_ALPHA = 0  # Material.coverage_mode: the texture's alpha channel
COVERAGE_LUMINANCE = 1  # its colour's luminance (an Image Texture's Color output as a float)
COVERAGE_INVERTED = 2  # one minus it (a Transparent BSDF in a Mix Shader's second slot)


@dataclass
class Material:
    """A material: base colour (albedo), emitted radiance (colour × strength) and the
    Principled BSDF's specular layers (core/scene/principled.py).

    With ``base_color_texture`` the texture is the base colour (``base_color`` is unused);
    with ``emission_texture`` the emitted radiance is the texture times ``emission`` (the
    strength per channel). Roughness, metallic, IOR, specular IOR level and specular tint are
    the Principled BSDF's inputs; with level 0, metallic 0 and no coat (the defaults here, as
    for a Diffuse BSDF) the material is pure Lambert. A coat (``coat_weight`` above 0) is a
    dielectric GGX layer of its own roughness and IOR over the others, a sheen (``sheen_weight``
    above 0) a soft reflection over all of them. ``translucency`` (per channel) of the diffuse
    light leaves the other side of the surface (a Translucent BSDF's: a leaf, a lampshade).
    ``transmission`` is the colour of the light it lets straight through (Transparent, Glass
    and Refraction BSDFs, a Principled BSDF's Alpha and Transmission); a material that does
    nothing else is clear (``is_clear``).

    A cutout (a leaf, a fence: ``is_cutout``) is there in part: ``alpha`` of it, times, with
    ``coverage_texture``, that texture's alpha (``coverage_mode`` COVERAGE_ALPHA) or its
    colour's luminance (COVERAGE_LUMINANCE), or one minus those (| COVERAGE_INVERTED); light
    and rays pass the rest untouched, as a Principled BSDF's Alpha or a Transparent BSDF mixed
    in by a texture do in Cycles. ``normal_texture`` bends the shading normal in the mesh's
    UV tangent space (a Normal Map node's, by ``normal_strength``), or with ``bump_distance``
    its colour's luminance is a height (a Bump node's). A ``holdout`` (the Holdout shader) is
    a hole for the camera, as a holdout object is, and black to light."""

    name: str
    base_color: tuple[float, float, float] = (0.8, 0.8, 0.8)
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    roughness: float = 0.5
    metallic: float = 0.0
    ior: float = 1.5
    specular_ior_level: float = 0.0
    specular_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    coat_weight: float = 0.0  # the Principled BSDF's clear coat over every other layer
    coat_roughness: float = 0.03
    coat_ior: float = 1.5
    coat_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    sheen_weight: float = 0.0  # the Principled BSDF's sheen, over the coat (core/scene/sheen.py)
    sheen_roughness: float = 0.5
    sheen_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
    sheen_layered: bool = True  # it dims the layers below (a Sheen BSDF node's does not)
    sheen_dims_cast_light: bool = False  # and the light its emission casts (Blender 5.x)
    diffuse_roughness: float = 0.0  # Oren–Nayar (core/scene/oren_nayar.py)
    diffuse_multiscatter: int = 2  # its multiple-scattering term (oren_nayar.py's modes)
    translucency: tuple[float, float, float] = (0.0, 0.0, 0.0)  # per channel, the share of
    # the diffuse light let through to the other side (a Translucent BSDF's), not reflected
    base_color_texture: Texture | None = None
    emission_texture: Texture | None = None
    transmission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    transmission_ior: float = 0.0  # the Fresnel loss's IOR at each crossing (0: none)
    alpha: float = 1.0
    coverage_texture: Texture | None = None
    coverage_mode: int = 0  # COVERAGE_ALPHA or COVERAGE_LUMINANCE, | COVERAGE_INVERTED
    normal_texture: Texture | None = None  # a tangent-space normal map, or a bump map
    normal_strength: float = 1.0
    bump_distance: float | None = None  # a Bump node's Distance (negative: inverted)
    bump_filter_width: float = 0.1  # its Filter Width in pixels (4.3's default)
    holdout: bool = False  # a Holdout shader: a hole for the camera, black to light
    camera_sees_through: bool = False  # the camera sees through it, other rays see it (a
    # Transparent BSDF mixed in by Light Path's Is Camera Ray: a hidden emitter)
    shadow_rays_pass: bool = False  # shadow rays pass it (by Is Shadow Ray)
    pass_index: int = 0  # Blender's material Pass Index (the IndexMA pass)
    aovs: tuple[tuple[str, tuple[float, float, float, float]], ...] = ()  # its AOV Output
    # nodes' names and (colour, value): frame/id_passes.py writes them

    @property
    def is_cutout(self) -> bool:
        """Whether the surface is there only in part (``alpha`` below 1 or a coverage
        texture)."""
        return self.alpha < 1.0 or self.coverage_texture is not None

    @property
    def is_clear(self) -> bool:
        """Whether the surface only lets light through: no colour, emission or specular."""
        return (max(self.transmission) > 0 and max(self.base_color) <= 0
                and max(self.emission) <= 0 and self.specular_ior_level <= 0
                and self.base_color_texture is None and self.emission_texture is None)


RENDERED_OBJECT_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "FONT", "META", "CURVES",
                                   "POINTCLOUD"})
"""Blender object types that are rendered (as Blender names them): their evaluated mesh, for
CURVES (hair) the tubes of its curves, for POINTCLOUD the spheres of its points."""
DEFAULT_MATERIAL = Material("(no material)")  # an empty slot, or an object without slots


@dataclass
class Mesh:
    """Triangles in object space: 3 corners per triangle, a material slot per triangle.

    Each corner attribute (position, normal, and the active render UV map's coordinates, None
    without a UV map) is either stored per corner (T*3 rows, its index None) or indexed: corner
    ``c`` takes row ``index[c]``, so shared vertices, flat face normals and UVs are stored once
    and transformed once per instance. Normals are Blender's (smooth/flat/custom)."""

    name: str
    positions: np.ndarray  # (T*3 | P, 3) float32
    normals: np.ndarray  # (T*3 | N, 3) float32
    material_slots: np.ndarray  # (T,) int32, index into the instance's material list
    uvs: np.ndarray | None = None  # (T*3 | U, 2) float32
    position_index: np.ndarray | None = None  # (T*3,) int32 rows of positions, or None
    normal_index: np.ndarray | None = None  # (T*3,) int32 rows of normals, or None
    uv_index: np.ndarray | None = None  # (T*3,) int32 rows of uvs, or None
    deform: np.ndarray | None = None  # (2, P, 3) float32: how far each row of positions
    # moves (object space) by Scene.motion's two times (a deforming mesh); None: it does not

    @property
    def triangle_count(self) -> int:
        return len(self.material_slots)

    def corner_positions(self) -> np.ndarray:
        """Positions per corner, (T*3, 3)."""
        return _per_corner(self.positions, self.position_index)

    def corner_normals(self) -> np.ndarray:
        """Normals per corner, (T*3, 3)."""
        return _per_corner(self.normals, self.normal_index)

    def corner_uvs(self) -> np.ndarray | None:
        """UVs per corner, (T*3, 2), or None without a UV map."""
        return None if self.uvs is None else _per_corner(self.uvs, self.uv_index)


def empty_mesh(name: str) -> Mesh:
    """A mesh without triangles (an object with nothing to render)."""
    empty = np.zeros((0, 3), np.float32)
    return Mesh(name, empty, empty, np.zeros(0, np.int32))


def _per_corner(values: np.ndarray, index: np.ndarray | None) -> np.ndarray:
    return values if index is None else values[index]


@dataclass(frozen=True)
class Identity:
    """What compositing knows an object by: its name, Pass Index (the IndexOB pass) and the
    name of its topmost parent (its asset, for Cryptomatte's asset layer)."""

    name: str = ""
    pass_index: int = 0
    asset: str = ""


NO_IDENTITY = Identity()


@dataclass
class Instance:
    """One placement of a mesh in the world with its resolved materials (one per slot); one
    not ``visible_to_camera`` still casts shadows and reflects light (Cycles' ray
    visibility), and so does a ``holdout``, which the camera sees as a hole: black, alpha 0
    (the view layer's holdout collections and objects); one that does not ``cast_shadow``
    lets the shadow rays of lights through (Cycles' Shadow ray visibility: a bulb round its
    lamp), and is seen and reflects light; one not ``visible_to_diffuse`` is passed by
    diffuse bounces (Cycles' Diffuse ray visibility): it neither reflects light onto other
    surfaces nor shades them from others' reflected light, and is seen, lit and casts
    shadows. ``identity`` names its object for the ID passes (id_passes.py). Light linking:
    an emitter lights it where bit ``receiver_set`` of the emitter's receivers is set (a
    light's ``Light.receivers``, an emissive object's ``emission_receivers``); shadow
    linking: it casts an emitter's shadows where bit ``blocker_set`` of the emitter's
    blockers is set (``Light.blockers``, ``emission_blockers``). A
    ``shadow_catcher`` (Cycles' Shadow Catcher) is composited as Cycles does: the shadows and
    light the other objects cast on it, over the backdrop (frame/shadow_catcher.py)."""

    mesh: Mesh
    matrix: Matrix4
    materials: list[Material]
    visible_to_camera: bool = True
    holdout: bool = False
    cast_shadow: bool = True
    visible_to_diffuse: bool = True
    identity: Identity = NO_IDENTITY
    receiver_set: int = 0
    emission_receivers: int = EVERY_RECEIVER_SET
    shadow_catcher: bool = False
    blocker_set: int = 0
    emission_blockers: int = EVERY_RECEIVER_SET
    lightgroup: str = ""  # its emission's light group (Object.lightgroup): frame/light_groups.py
    motion: tuple[Matrix4, Matrix4] | None = None  # its matrix at Scene.motion's two times

    @property
    def linking(self) -> tuple[int, int, int, int]:
        """Its light and shadow linking: (receiver_set, emission_receivers, blocker_set,
        emission_blockers)."""
        return (self.receiver_set, self.emission_receivers, self.blocker_set,
                self.emission_blockers)

    @property
    def flags(self) -> tuple[bool, bool, bool, bool]:
        """What its material rows mark: (visible_to_camera, holdout, cast_shadow,
        visible_to_diffuse)."""
        return self.visible_to_camera, self.holdout, self.cast_shadow, self.visible_to_diffuse


class LightKind(StrEnum):
    POINT = "POINT"
    SPOT = "SPOT"
    SUN = "SUN"
    AREA = "AREA"


class AreaShape(StrEnum):
    SQUARE = "SQUARE"
    RECTANGLE = "RECTANGLE"
    DISK = "DISK"
    ELLIPSE = "ELLIPSE"


@dataclass
class Light:
    """A Blender light. ``power`` is watts (point/spot/area) or W/m² (sun strength).

    The light emits along its local -Z axis (spot, sun, area), as in Blender.
    """

    name: str
    kind: LightKind
    matrix: Matrix4
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    power: float = 10.0
    radius: float = 0.0  # point/spot sphere radius
    soft_falloff: bool = False  # point/spot: Cycles' Soft Falloff (transport/lights.py)
    spot_size: float = np.pi / 4  # full cone angle, radians
    spot_blend: float = 0.15
    sun_angle: float = 0.0  # angular diameter, radians
    area_shape: AreaShape = AreaShape.SQUARE
    size_x: float = 1.0
    size_y: float = 1.0
    spread: float = np.pi  # area lights: full angle of the emission cone, radians (Cycles)
    cast_shadow: bool = True
    visible_to_camera: bool = True  # area lights: the shape shows in the image (Cycles' default)
    visible_to_diffuse: bool = True  # off: lights no diffuse surface, directly or not (Cycles)
    max_bounces: int = NO_BOUNCE_LIMIT  # Cycles' Max Bounces: its light bounces at most so
    # often (0: direct light only)
    profile: IesProfile | None = None  # an IES profile its light is multiplied by (ies.py),
    # towards directions in ``frame`` (point, spot and area lights)
    receivers: int = EVERY_RECEIVER_SET  # light linking: the receiver sets it lights
    # (Instance.receiver_set)
    blockers: int = EVERY_RECEIVER_SET  # shadow linking: the blocker sets that cast its
    # shadows (Instance.blocker_set)
    lightgroup: str = ""  # its light group (Object.lightgroup): frame/light_groups.py

    @property
    def area_size(self) -> tuple[float, float]:
        """Width and height of an area light's shape (square and disk use size_x for both)."""
        square = self.area_shape in (AreaShape.SQUARE, AreaShape.DISK)
        return self.size_x, self.size_x if square else self.size_y

    @property
    def is_round(self) -> bool:
        return self.area_shape in (AreaShape.DISK, AreaShape.ELLIPSE)

    @property
    def local_area(self) -> float:
        """Area of the shape in the light's own (unscaled) plane."""
        width, height = self.area_size
        return (np.pi / 4 if self.is_round else 1.0) * width * height

    @property
    def frame(self) -> np.ndarray:
        """(3, 3) orthonormal columns: the light's own x, y and z axes in the world (its
        matrix's rotation without its scale); a direction d is ``d @ frame`` in its frame."""
        m = np.asarray(self.matrix, dtype=np.float64)[:3, :3]
        x, z = unit(m[:, 0]), unit(m[:, 2])
        return np.stack([x, unit(np.cross(z, x)), z], axis=1)

    @property
    def world_area(self) -> float:
        """Area of the shape in the world (the light's matrix may scale it)."""
        m = np.asarray(self.matrix, dtype=np.float64)
        return self.local_area * float(np.linalg.norm(np.cross(m[:3, 0], m[:3, 1])))


@dataclass
class EnvironmentMap:
    """An equirectangular environment (Blender's Environment Texture) seen from the world.

    ``radiance`` is (h, w, 3) float32, rows bottom-up as Blender stores images (row 0 looks
    down), already multiplied by the Background strength. The map is looked up in direction
    Rz(rotation) · d for a world direction d (a Mapping node's Z rotation)."""

    radiance: np.ndarray
    rotation: float = 0.0


@dataclass
class World:
    """The environment: background radiance = colour × strength, or an environment map.

    With a map, ``color`` × ``strength`` is the map's mean radiance over the sphere, so code
    that needs one colour (skipping a black world, light-path allocation) works unchanged.
    ``visible_sun``: a sun disc taken out of the map as this sun light (scene/sun_disc.py),
    which camera rays still see in the background. ``background``: what camera rays see
    instead of the map, for a world that shows the camera something else than its light."""

    color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    strength: float = 1.0
    environment: EnvironmentMap | None = None
    visible_sun: Light | None = None
    background: EnvironmentMap | None = None
    lightgroup: str = ""  # its light group (World.lightgroup): frame/light_groups.py
    max_bounces: int = NO_BOUNCE_LIMIT  # Cycles' Max Bounces of the world's light

    @property
    def radiance(self) -> np.ndarray:
        return np.asarray(self.color, dtype=np.float64) * self.strength


@dataclass(frozen=True)
class Aperture:
    """A camera's thin lens for depth of field, as Cycles samples it: a disc (or a regular
    polygon of ``blades`` corners turned by ``rotation``) of ``radius`` in scene units, its
    width divided by ``ratio`` (anamorphic), focused at ``focus_distance`` along the view."""

    radius: float
    focus_distance: float
    blades: int = 0  # under 3: a disc
    rotation: float = 0.0  # radians
    ratio: float = 1.0


@dataclass(frozen=True)
class Panorama:
    """A panoramic camera's lens as Cycles reads it (``kind``: Blender's panorama_type; angles
    in radians, lens and sensor in mm)."""

    kind: str
    latitude_min: float = -math.pi / 2
    latitude_max: float = math.pi / 2
    longitude_min: float = -math.pi
    longitude_max: float = math.pi
    fisheye_fov: float = math.pi
    fisheye_lens: float = 10.5
    sensor_width: float = 36.0
    sensor_height: float = 24.0


@dataclass
class Camera:
    """A camera as OpenGL matrices (Blender computes the projection, including sensor fit and
    shift), plus the output resolution in pixels and, for depth of field, its aperture."""

    view_matrix: Matrix4  # world -> camera (camera looks along -Z)
    projection_matrix: Matrix4  # camera -> clip, OpenGL convention
    width: int
    height: int
    is_orthographic: bool = False
    aperture: Aperture | None = None  # None: everything in focus (a pinhole)
    panorama: Panorama | None = None  # rendered from six views (frame/panorama.py)
    motion_views: tuple[Matrix4, Matrix4] | None = None  # its view at Scene.motion's times

    @property
    def defocused(self) -> bool:
        """Whether the camera has depth of field to render (an aperture wider than a point)."""
        return self.aperture is not None and self.aperture.radius > 0

    @property
    def position(self) -> np.ndarray:
        return np.linalg.inv(self.view_matrix)[:3, 3]

    def rays(self, ndc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World origins on the near plane and unit directions (…, 3) of the camera rays
        through points ``ndc`` (…, 2) of the image in normalised device coordinates. The
        direction aims at depth 0, not the far plane, which Blender's float32 projection puts
        at infinity once Clip End / Clip Start passes about 3e7."""
        clip_to_world = np.linalg.inv(self.projection_matrix @ self.view_matrix)
        column = (*ndc.shape[:-1], 1)
        ends = []
        for depth in (-1.0, 0.0):
            clip = np.concatenate([ndc, np.full(column, depth), np.ones(column)], axis=-1)
            world = clip @ clip_to_world.T
            ends.append(world[..., :3] / world[..., 3:4])
        return ends[0], unit(ends[1] - ends[0])

    @property
    def forward(self) -> np.ndarray:
        """The unit direction the camera looks along (its -Z) in world space."""
        axis = np.linalg.inv(self.view_matrix)[:3, 2]
        return -axis / np.linalg.norm(axis)

    @property
    def view_uniforms(self) -> dict[str, object]:
        """u_camera_position, u_camera_forward and u_orthographic for shaders that need the
        view direction (the g-buffer, the view through clear surfaces)."""
        return {"u_camera_position": tuple(self.position),
                "u_camera_forward": tuple(self.forward),
                "u_orthographic": self.is_orthographic}


@dataclass(frozen=True)
class MotionSpan:
    """The two times, in frames from the rendered one, at which instances and the camera
    know their placement (Instance.motion, Camera.motion_views): -1 and 1 for the Vector
    pass (the previous and next frame), the shutter's opening and closing with ``blur``; the
    rendered time is ``centre`` frames from the frame's (the shutter's middle)."""

    before: float = -1.0
    after: float = 1.0
    blur: bool = False
    centre: float = 0.0


@dataclass(frozen=True)
class Mist:
    """The world's mist settings for the Mist pass: 0 at ``start`` from the camera, 1 at
    ``start + depth``, raised to ``falloff`` (2 quadratic, 1 linear, 0.5 inverse quadratic)."""

    start: float = 5.0
    depth: float = 25.0
    falloff: float = 2.0


@dataclass
class Scene:
    """Everything one frame needs."""

    instances: list[Instance] = field(default_factory=list)
    lights: list[Light] = field(default_factory=list)
    world: World = field(default_factory=World)
    camera: Camera | None = None
    film_transparent: bool = False
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # informational, not problems
    portals: list[Light] = field(default_factory=list)  # area lights marked Portal (Cycles):
    # openings that world light enters through; they emit nothing themselves
    mist: Mist = field(default_factory=Mist)
    motion: MotionSpan | None = None  # None: nothing moves (no Vector pass, no motion blur)
    ao_distance: float = 10.0  # the world's AO distance: the Ambient Occlusion pass's rays

    @property
    def surface_lights(self) -> list[Light]:
        """The lights that light surfaces: in Cycles (measured, 4.5) a light hidden from
        diffuse rays lights no diffuse surface, neither directly nor through bounces."""
        return [light for light in self.lights if light.visible_to_diffuse]
