"""Benchmark of addon/core/gpu/raytrace.py: BVH build and upload time, node count and depth, and
rays/s of closest-hit and any-hit queries, on a random triangle soup and a tessellated closed
box (rays from inside, so every ray hits).

    .venv/bin/python tools/bench_raytrace.py [--triangles 100000 1000000] [--rays 65536]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.core.gpu.bvh import build_bvh
from addon.core.gpu.gl import ProgramCache, shared_context
from addon.core.gpu.raytrace import RayTracer


def soup(count: int, rng: np.random.Generator) -> np.ndarray:
    """Random triangles of edge ~ 2/count^(1/3) in the cube [-1, 1]^3."""
    size = 2.0 / count ** (1 / 3)
    centres = rng.uniform(-1, 1, (count, 1, 3))
    return (centres + rng.normal(0, size, (count, 3, 3))).astype(np.float32)


def closed_box(count: int) -> np.ndarray:
    """The surface of [-1, 1]^3, each face an n×n grid of quads (12 n² triangles ≈ count)."""
    n = max(1, round((count / 12) ** 0.5))
    g = np.linspace(-1, 1, n + 1)
    a, b = np.meshgrid(g[:-1], g[:-1], indexing="ij")
    c, d = a + 2 / n, b + 2 / n
    quads = np.stack([np.stack([a, b], -1), np.stack([c, b], -1), np.stack([c, d], -1),
                      np.stack([a, d], -1)], axis=2).reshape(-1, 4, 2)
    faces = []
    for axis in range(3):
        for side in (-1.0, 1.0):
            q = np.insert(quads, axis, side, axis=2)
            faces += [q[:, [0, 1, 2]], q[:, [0, 2, 3]]]
    return np.concatenate(faces).astype(np.float32)


def rays_per_second(query, count: int) -> float:
    query(min(count, 1024))  # compile and warm up
    start = time.perf_counter()
    query(count)
    return count / (time.perf_counter() - start)


def bench(name: str, triangles: np.ndarray, tracer: RayTracer, rays: int,
          rng: np.random.Generator) -> None:
    start = time.perf_counter()
    bvh = build_bvh(triangles)
    build = time.perf_counter() - start
    start = time.perf_counter()
    tracer.upload_bvh(bvh)
    upload = time.perf_counter() - start
    origins = rng.uniform(-0.9, 0.9, (rays, 3))
    directions = rng.normal(size=(rays, 3))
    closest = rays_per_second(lambda n: tracer.intersect(origins[:n], directions[:n]), rays)
    any_hit = rays_per_second(lambda n: tracer.occluded(origins[:n], directions[:n], 0.5), rays)
    hits = (tracer.intersect(origins[:4096], directions[:4096]).triangle >= 0).mean()
    print(f"{name:>12} {len(triangles):>9} tris  build {build:6.2f} s  upload "
          f"{upload:5.2f} s  nodes {len(bvh.node_data):>8}  depth {bvh.depth:>2}  "
          f"closest {closest / 1e6:6.3f} Mrays/s  any-hit(t<0.5) {any_hit / 1e6:6.3f} Mrays/s"
          f"  hit rate {hits:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--triangles", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--rays", type=int, default=1 << 16)
    args = parser.parse_args()
    ctx = shared_context()
    print(ctx.info["GL_RENDERER"], ctx.info["GL_VERSION"])
    programs = ProgramCache(ctx)
    tracer = RayTracer(ctx, programs)
    rng = np.random.default_rng(1)
    for count in args.triangles:
        bench("soup", soup(count, rng), tracer, args.rays, rng)
        bench("closed box", closed_box(count), tracer, args.rays, rng)
    tracer.release()
    programs.release()


if __name__ == "__main__":
    main()
