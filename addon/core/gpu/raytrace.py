"""Ray tracing of triangle scenes: a BVH built on the CPU (``bvh``, ``instanced_bvh``),
traversed on the GPU by ``gpu_shaders/raytrace_lib.glsl``.

Use it as a batch query (``RayTracer.intersect`` / ``occluded``) or from another shader: include
``raytrace_lib.glsl`` in a GLSL 4.30 shader, call ``RayTracer.bind()`` before its
dispatch or draw, and call ``rt_closest_hit`` / ``rt_occluded``.

Triangles are two-sided. A hit counts when ``t_min < t < t_max`` (open interval), ``t`` being
the distance along the normalised ray direction. The triangle test is watertight (Woop et al.
2013), so rays through shared edges and vertices of a closed mesh never slip through.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from ..scene.model import Texture
from .bvh import BVH
from .gl import ProgramCache, require_compute
from .instanced_bvh import build_instanced_bvh
from .texture_array import upload as upload_textures

BINDING_NODES = 10  # RT_BINDING_NODES in raytrace_lib.glsl
BINDING_TRIANGLES = 11  # RT_BINDING_TRIANGLES in raytrace_lib.glsl
BINDING_RAYS = 12  # RT_BINDING_RAYS in raytrace_comp.glsl
BINDING_RESULTS = 13  # RT_BINDING_RESULTS in raytrace_comp.glsl
BINDING_CUTOUTS = 14  # RT_BINDING_CUTOUTS in raytrace_lib.glsl
UNITS_TEXTURES = 16, 17  # RT_UNIT_TEXTURES, RT_UNIT_TEXTURE_SIZES in raytrace_lib.glsl
LOCAL_SIZE = 64  # local_size_x of raytrace_comp.glsl
MAX_BATCH = 1 << 20  # rays per dispatch
RT_SHADOW = 4  # raytrace_lib.glsl: a shadow ray, which shadowless triangles let through
RT_DIFFUSE = 16  # raytrace_lib.glsl: a diffuse bounce, which diffuse-hidden triangles pass
SHADOWLESS = 1  # RT_SHADOWLESS: RtTriangle.clear flag of a shadowless triangle
CUTOUT = 2  # RT_CUTOUT: RtTriangle.clear flag of a cutout triangle
DIFFUSE_HIDDEN = 4  # RT_DIFFUSE_HIDDEN: RtTriangle.clear flag of a diffuse-hidden triangle
BLOCKER_SHIFT = 8  # RT_BLOCKER_SHIFT: the blocker set's bits in RtTriangle.clear's flags
FLAGS = 0xFFFF  # RT_FLAGS: RtTriangle.clear values up to this are flags, not a colour

TRIANGLE_DTYPE = np.dtype([("v0", "<f4", 3), ("id", "<i4"), ("v1", "<f4", 3), ("clear", "<u4"),
                           ("v2", "<f4", 3), ("ior", "<f4")])
RAY_DTYPE = np.dtype([("origin", "<f4", 3), ("t_min", "<f4"), ("dir", "<f4", 3),
                      ("t_max", "<f4")])
RESULT_DTYPE = np.dtype([("t", "<f4"), ("triangle", "<i4"), ("uv", "<f4", 2),
                         ("transmittance", "<f4", 4)])


@dataclass
class Cutouts:
    """The cutout triangles of a scene (WorldGeometry.cutout_rows): their indices (n,), UVs
    (n, 3, 2) and cutout texels (n, 4), whose layers are ``textures``' (+ 1)."""

    triangle: np.ndarray
    uv: np.ndarray
    texel: np.ndarray
    textures: list[Texture]


PLACEHOLDER = Texture("(no coverage texture)", np.ones((1, 1, 4), np.float32))


@dataclass
class Hits:
    """Closest hits of a batch of rays."""

    distance: np.ndarray  # (R,) float32, inf where missed
    triangle: np.ndarray  # (R,) int32 original triangle index, -1 where missed
    barycentric: np.ndarray  # (R, 2) float32 weights of vertices 1 and 2, 0 where missed
    transmittance: np.ndarray  # (R, 3) float32 light let through by clear triangles on the way


def _pack_rays(origins: np.ndarray, directions: np.ndarray, t_min: float | np.ndarray,
               t_max: float | np.ndarray) -> np.ndarray:
    """Rays in the GPU layout, directions normalised. Rays with a zero or non-finite direction
    or origin get an empty interval, so they miss."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    if len(o) != len(d):
        raise ValueError(f"{len(o)} origins but {len(d)} directions")
    with np.errstate(invalid="ignore", over="ignore"):
        length = np.linalg.norm(d, axis=1)
    ok = np.isfinite(o).all(axis=1) & np.isfinite(length) & (length > 0)
    rays = np.zeros(len(o), RAY_DTYPE)
    rays["origin"] = np.where(ok[:, None], o, 0.0)
    rays["dir"] = np.where(ok[:, None], d / np.where(ok, length, 1.0)[:, None], [0.0, 0.0, 1.0])
    rays["t_min"] = np.where(ok, t_min, 0.0)
    rays["t_max"] = np.where(ok, t_max, 0.0)
    return rays


def _flags(shadow: bool, diffuse: bool) -> int:
    """raytrace_lib.glsl's query flags of a shadow ray or a diffuse bounce."""
    return (RT_SHADOW if shadow else 0) | (RT_DIFFUSE if diffuse else 0)


class RayTracer:
    """One uploaded triangle scene and its GPU queries (needs OpenGL 4.3)."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache) -> None:
        require_compute(ctx)
        self.ctx = ctx
        self.programs = programs
        self.batch_size = MAX_BATCH
        self._nodes: moderngl.Buffer | None = None
        self._triangles: moderngl.Buffer | None = None
        self._rays: moderngl.Buffer | None = None
        self._results: moderngl.Buffer | None = None
        self._cutouts: list = []  # the cutouts' buffer and textures
        self.upload(np.zeros((0, 3, 3), np.float32))

    def upload(self, triangles: np.ndarray, leaf_size: int = 4,
               instanced: np.ndarray | tuple = (), clear: np.ndarray | None = None,
               transmission: np.ndarray | None = None,
               shadowless: np.ndarray | None = None, cutouts: Cutouts | None = None,
               diffuse_hidden: np.ndarray | None = None,
               blocker_set: np.ndarray | None = None) -> None:
        """Build the BVH of ``triangles`` (T, 3, 3) and upload it; T = 0 is an empty scene.
        ``instanced`` rows (first triangle, instances, triangles each) mark runs of one mesh's
        copies, whose tree is built once (``instanced_bvh``). ``clear`` triangles (C, 3, 3)
        let rays through, each with its ``transmission`` row (colour, Fresnel IOR or 0): no
        query hits them, and closest hits and shadow rays get the light they let through
        (raytrace_lib.glsl). ``shadowless`` (T,) bool: triangles shadow rays pass (Shadow ray
        visibility off), ``diffuse_hidden`` (T,) bool those diffuse bounces pass (Diffuse
        visibility off). ``cutouts``: triangles rays hit with probability their coverage and
        shadow rays pass dimmed by it (RT_CUTOUTS). ``blocker_set`` (T,) int: each triangle's
        shadow-linking blocker set (0-63), which rays of an emitter that set does not cast
        shadows of pass (RT_SHADOW_LINKING). Raises ValueError before building when the
        triangles cannot fit a storage buffer."""
        triangles = np.asarray(triangles, np.float32).reshape(-1, 3, 3)
        clear = np.zeros((0, 3, 3), np.float32) if clear is None else clear
        flagged = [(np.asarray(mask, bool), flag) for mask, flag in
                   ((shadowless, SHADOWLESS), (diffuse_hidden, DIFFUSE_HIDDEN))
                   if mask is not None and np.any(mask)]
        cutouts = None if cutouts is None or len(cutouts.triangle) == 0 else cutouts
        linked = blocker_set is not None and bool(np.any(blocker_set))
        codes = None
        if len(clear) or flagged or cutouts is not None or linked:
            codes = np.zeros((len(triangles) + len(clear), 2), np.uint32)
        for mask, flag in flagged:
            codes[:len(triangles)][mask, 0] |= flag
        if linked:
            codes[:len(triangles), 0] |= np.asarray(blocker_set, np.uint32) << BLOCKER_SHIFT
        if cutouts is not None:
            codes[cutouts.triangle, 0] |= CUTOUT
            codes[cutouts.triangle, 1] = np.arange(len(cutouts.triangle), dtype=np.uint32)
        if len(clear):
            rows = np.asarray(transmission, np.float32)
            colour = np.clip(rows[:, :3], 0.0, 1.0)
            codes[len(triangles):, 0] = (np.round(colour * 255).astype(np.uint32)
                                         << np.array([0, 8, 16], np.uint32)).sum(axis=1) \
                | np.uint32(255 << 24)  # packUnorm4x8(colour, 1): never 0
            codes[len(triangles):, 1] = rows[:, 3].view(np.uint32)
            triangles = np.concatenate([triangles, np.asarray(clear, np.float32)])
        count = len(triangles)
        self._check_size(count, count * TRIANGLE_DTYPE.itemsize)
        self.upload_bvh(build_instanced_bvh(triangles, instanced, leaf_size), codes, cutouts)

    def _upload_cutouts(self, cutouts: Cutouts | None) -> None:
        """The cutouts' rows (raytrace_lib.glsl's RtCutout) and the textures they read, with
        layers renumbered to those; RT_CUTOUTS in the programs' defines while there are any."""
        self._release_cutouts()
        self.programs.ray_defines = {} if cutouts is None else {"RT_CUTOUTS": 1}
        if cutouts is None:
            return
        texel = np.array(cutouts.texel, np.float32)
        used = np.unique(texel[:, 0][texel[:, 0] > 0]).astype(int)
        texel[:, 0] = np.searchsorted(used, texel[:, 0].astype(int)) + (texel[:, 0] > 0)
        rows = np.zeros((len(texel), 12), np.float32)
        rows[:, 0:6] = np.asarray(cutouts.uv, np.float32).reshape(-1, 6)
        rows[:, 8:12] = texel
        textures = [cutouts.textures[k - 1] for k in used] or [PLACEHOLDER]
        self._cutouts = [self.ctx.buffer(rows), *upload_textures(self.ctx, textures)]

    def _check_size(self, triangles: int, nbytes: int) -> None:
        limit = int(self.ctx.info["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
        if nbytes > limit:
            raise ValueError(f"{triangles} triangles need {nbytes >> 20} MiB of storage buffer; "
                             f"this GPU allows {limit >> 20} MiB")

    def upload_bvh(self, bvh: BVH, clear: np.ndarray | None = None,
                   cutouts: Cutouts | None = None) -> None:
        """Upload a BVH from ``build_bvh``, replacing the scene; ``clear`` (T, 2) uint32 per
        original triangle: its packed colour and its IOR's bits, or (0 for an opaque one) its
        flags (SHADOWLESS for one shadow rays pass, DIFFUSE_HIDDEN, CUTOUT, its blocker set
        shifted by BLOCKER_SHIFT) and its row of ``cutouts``."""
        # raytrace_lib.glsl's RtNode (lo, a, hi, b) and RtTriangle (TRIANGLE_DTYPE) as float32
        # rows, the int fields as their bits, the vertices moved as 12-byte records (a
        # structured array filled field by field took 3× the time)
        nodes = np.empty((len(bvh.node_data), 2, 4), np.float32)
        nodes[:, 0, :3], nodes[:, 1, :3] = bvh.node_min, bvh.node_max
        nodes[:, :, 3] = bvh.node_data.astype(np.int32, copy=False).view(np.float32)
        count = len(bvh.triangles)
        tris = np.empty((max(1, count), 3, 4), np.float32)  # GL has no empty buffers
        tris[count:] = 0.0
        rows = tris[:count].reshape(-1, 4).view([("xyz", "V12"), ("w", "V4")])[:, 0]
        rows["xyz"] = np.ascontiguousarray(bvh.triangles, np.float32).reshape(-1, 3).view(
            "V12")[:, 0]
        tris[:count, :, 3] = 0.0
        tris[:count, 0, 3] = bvh.triangle_ids.astype(np.int32, copy=False).view(np.float32)
        # closest hits trace their transmittance only where a clear triangle can dim it
        self.has_clear = clear is not None and bool(np.any(clear[:, 0] > FLAGS))
        if clear is not None:
            tris[:count, 1:, 3] = clear[bvh.triangle_ids].view(np.float32)
        self._check_size(len(bvh.triangles), max(nodes.nbytes, tris.nbytes))
        self._release_scene()
        self._nodes, self._triangles = self.ctx.buffer(nodes), self.ctx.buffer(tris)
        self._upload_cutouts(cutouts)

    def bind(self) -> None:
        """Bind the scene at RT_BINDING_NODES / RT_BINDING_TRIANGLES for another program's
        dispatch or draw (again after each upload: it makes new buffers)."""
        self._nodes.bind_to_storage_buffer(BINDING_NODES)
        self._triangles.bind_to_storage_buffer(BINDING_TRIANGLES)
        if self._cutouts:
            buffer, array, sizes = self._cutouts
            buffer.bind_to_storage_buffer(BINDING_CUTOUTS)
            array.use(UNITS_TEXTURES[0])
            sizes.use(UNITS_TEXTURES[1])

    def intersect(self, origins: np.ndarray, directions: np.ndarray,
                  t_min: float | np.ndarray = 0.0, t_max: float | np.ndarray = np.inf,
                  shadow: bool = False, diffuse: bool = False) -> Hits:
        """Closest hit of each ray (R, 3) with ``t_min < t < t_max`` (per ray or shared);
        ``shadow``: light's rays, which shadowless triangles let through; ``diffuse``: diffuse
        bounces, which diffuse-hidden ones do."""
        out = self._run(_pack_rays(origins, directions, t_min, t_max), 0, RESULT_DTYPE,
                        _flags(shadow, diffuse))
        hit = out["triangle"] >= 0
        return Hits(np.where(hit, out["t"], np.float32(np.inf)), out["triangle"].copy(),
                    np.where(hit[:, None], out["uv"], np.float32(0.0)),
                    out["transmittance"][:, :3].copy())

    def occluded(self, origins: np.ndarray, directions: np.ndarray, t_max: float | np.ndarray,
                 t_min: float | np.ndarray = 0.0, shadow: bool = False,
                 diffuse: bool = False) -> np.ndarray:
        """Whether each ray hits anything with ``t_min < t < t_max`` (any hit, early exit);
        ``shadow`` and ``diffuse`` as for ``intersect``."""
        return self._run(_pack_rays(origins, directions, t_min, t_max), 1, np.dtype("<i4"),
                         _flags(shadow, diffuse)) != 0

    def release(self) -> None:
        self._release_scene()
        self._release_cutouts()
        for buffer in (self._rays, self._results):
            if buffer is not None:
                buffer.release()
        self._rays = self._results = None

    def _release_scene(self) -> None:
        for buffer in (self._nodes, self._triangles):
            if buffer is not None:
                buffer.release()
        self._nodes = self._triangles = None

    def _release_cutouts(self) -> None:
        for obj in self._cutouts:
            obj.release()
        self._cutouts = []

    def _run(self, rays: np.ndarray, any_hit: int, out_dtype: np.dtype, flags: int
             ) -> np.ndarray:
        """Trace ``rays`` in batches of at most ``batch_size`` with raytrace_comp.glsl."""
        shader = self.programs.compute("raytrace_comp.glsl", {"RT_ANY_HIT": any_hit})
        out = np.empty(len(rays), out_dtype)
        self.bind()
        for start in range(0, len(rays), self.batch_size):
            batch = rays[start:start + self.batch_size]
            self._reserve(len(batch))
            self._rays.write(batch.tobytes())
            self._rays.bind_to_storage_buffer(BINDING_RAYS)
            self._results.bind_to_storage_buffer(BINDING_RESULTS)
            shader["rt_ray_count"] = len(batch)
            shader["rt_flags"] = flags
            if not any_hit:
                shader["rt_has_clear"] = self.has_clear
            shader.run(-(-len(batch) // LOCAL_SIZE))
            self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
            data = self._results.read(len(batch) * out_dtype.itemsize)
            out[start:start + len(batch)] = np.frombuffer(data, out_dtype)
        return out

    def _reserve(self, rays: int) -> None:
        """Grow the ray and result buffers to hold ``rays`` rays."""
        if self._rays is not None and self._rays.size >= rays * RAY_DTYPE.itemsize:
            return
        if self._rays is not None:
            self._rays.release()
            self._results.release()
        self._rays = self.ctx.buffer(reserve=rays * RAY_DTYPE.itemsize)
        self._results = self.ctx.buffer(reserve=rays * RESULT_DTYPE.itemsize)
