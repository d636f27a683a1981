"""Up-front limits on a scene's size. Instances are flattened into one triangle list, so the
triangle count after instancing must fit the machine's memory, the GPU's table of the
triangles' materials (a texture) and, when the frame traces rays, the GPU's largest storage
buffer. They are checked from the instances' triangle counts before any triangle is
flattened: a million-instance scatter is refused in a second, not after minutes and tens of
GiB (tools/bench_size_limits.py, cases inst-*)."""

from __future__ import annotations

import os
from dataclasses import dataclass

from ..gpu.raytrace import TRIANGLE_DTYPE
from ..gpu.scene_buffers import TABLE_WIDTH
from ..scene.model import Scene
from ..settings import Settings
from .state import RenderError

HOST_BYTES_PER_TRIANGLE = 300
"""Peak resident memory per flattened triangle of a frame, with headroom: measured 235 B
(tools/bench_size_limits.py inst-100k-maps: 2,233 MiB at 8.0M triangles, llvmpipe's
"GPU" buffers included)."""
MEMORY_SHARE = 0.8  # of the machine's physical memory a frame may plan to use


@dataclass(frozen=True)
class SceneLimits:
    """What one frame's flattened triangles must fit."""

    storage_bytes: int  # the GPU's largest storage buffer (0: no ray tracer to fit)
    texture_size: int  # the GPU's largest texture side
    memory_bytes: int | None  # the machine's physical memory (None: unknown, not checked)


def flattened_triangles(scene: Scene) -> int:
    """Triangles after instancing: every instance's mesh counted once per instance."""
    return sum(inst.mesh.triangle_count for inst in scene.instances)


def may_trace_rays(settings: Settings) -> bool:
    """Whether a frame with these settings may use the ray tracer: for VPL paths (any
    bounce) and for ray-traced or hybrid direct shadows."""
    return settings.bounces > 0 or settings.direct_shadows != "shadow_maps"


def physical_memory() -> int | None:
    """The machine's physical memory in bytes, where the platform reports it."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def check_scene_size(scene: Scene, settings: Settings, limits: SceneLimits) -> None:
    """Raise RenderError, naming the limit, when the flattened triangles cannot fit the
    machine's memory, the material table's texture or, when the frame may trace rays, a
    storage buffer."""
    triangles = flattened_triangles(scene)
    what = (f"the scene has {triangles:,} triangles after instancing "
            f"({len(scene.instances):,} instances, flattened into one triangle list)")
    advice = ("use fewer instances, simpler meshes or fewer hair strands (each strand is a "
              "tube of triangles; Simplify › Child Particles thins particle hair)")
    memory = limits.memory_bytes
    if memory is not None and triangles * HOST_BYTES_PER_TRIANGLE > MEMORY_SHARE * memory:
        most = int(MEMORY_SHARE * memory) // HOST_BYTES_PER_TRIANGLE
        raise RenderError(f"{what}: they need about "
                          f"{triangles * HOST_BYTES_PER_TRIANGLE / (1 << 30):.1f} GiB of memory "
                          f"and this machine has {memory / (1 << 30):.1f} GiB, enough for "
                          f"{most:,} triangles; {advice}")
    most = TABLE_WIDTH * limits.texture_size
    if triangles > most:
        raise RenderError(f"{what}: their material table exceeds this GPU's texture size "
                          f"({limits.texture_size:,} texels a side), enough for {most:,} "
                          f"triangles; {advice}")
    nbytes = triangles * TRIANGLE_DTYPE.itemsize
    if limits.storage_bytes and may_trace_rays(settings) and nbytes > limits.storage_bytes:
        most = limits.storage_bytes // TRIANGLE_DTYPE.itemsize
        raise RenderError(f"{what}: ray tracing them needs {nbytes >> 20} MiB of storage "
                          f"buffer and this GPU allows {limits.storage_bytes >> 20} MiB, "
                          f"enough for {most:,} triangles; {advice}, or render with bounces "
                          f"0 and direct shadows from shadow maps")
