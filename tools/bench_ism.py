"""Benchmark of addon/core/gpu/ism.py: area-table pre-process, splat and pull-push times and atlas
memory of imperfect shadow maps on a synthetic scene (a tessellated box room with boxes inside,
about 70k triangles), with VPLs on its surfaces facing into the room.

    .venv/bin/python tools/bench_ism.py [--vpls 1024] [--points 8192] [--resolutions 128 256]
        [--footprint-scale 1.25] [--max-footprint 0.125] [--levels N] [--repeat 3]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from addon.core.gpu.gl import ProgramCache, shared_context
from addon.core.gpu.ism import FOOTPRINT_SCALE, MAX_FOOTPRINT, ImperfectShadowMaps


def box(lo: np.ndarray, hi: np.ndarray, n: int, inward: bool) -> np.ndarray:
    """The surface of the box [lo, hi], each face an n×n grid of quads (12 n² triangles), wound
    so that normals (e1 × e2) face out, or in when ``inward``."""
    g = np.linspace(0.0, 1.0, n + 1)
    a, b = np.meshgrid(g[:-1], g[:-1], indexing="ij")
    c, d = a + 1 / n, b + 1 / n
    quads = np.stack([np.stack([a, b], -1), np.stack([c, b], -1), np.stack([c, d], -1),
                      np.stack([a, d], -1)], axis=2).reshape(-1, 4, 2)
    faces = []
    for axis in range(3):
        for side in (0.0, 1.0):
            q = np.insert(quads, axis, side, axis=2)
            tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
            # (u, v) run along the two other axes in order: e1 × e2 is +x, -y, +z.
            outward_is_ccw = (side == 1.0) != (axis == 1)
            faces.append(tris if outward_is_ccw != inward else tris[:, ::-1])
    unit = np.concatenate(faces)
    return (lo + unit * (hi - lo)).astype(np.float32)


def room_scene(triangles: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A 10 × 10 × 4 room (half the triangles) with 8 boxes on its floor (the other half, which
    may overlap); also the boxes' (8, 2, 3) bounds."""
    n_room = max(1, round(math.sqrt(triangles / 2 / 12)))
    n_box = max(1, round(math.sqrt(triangles / 2 / 12 / 8)))
    parts = [box(np.array([0.0, 0.0, 0.0]), np.array([10.0, 10.0, 4.0]), n_room, inward=True)]
    bounds = []
    for _ in range(8):
        size = rng.uniform([0.6, 0.6, 0.5], [2.0, 2.0, 2.5])
        corner = np.r_[rng.uniform(0.5, 9.5 - size[:2]), 0.0]
        parts.append(box(corner, corner + size, n_box, inward=False))
        bounds.append([corner, corner + size])
    return np.concatenate(parts), np.array(bounds)


def vpls_on(ism: ImperfectShadowMaps, triangles: np.ndarray, boxes: np.ndarray, count: int,
            seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` VPLs uniform on the surfaces outside the boxes (where light paths can reach),
    facing along their triangles' normals (ISM points of ``seed``, drawn by ``ism``)."""
    ism.prepare(triangles, 4 * count, seed)
    points = ism.points(0, 1)
    tris = triangles[points.triangle].astype(np.float64)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    uv = points.barycentric.astype(np.float64)
    position = tris[:, 0] + uv[:, :1] * e1 + uv[:, 1:] * e2
    normal = np.cross(e1, e2)
    tolerance = 1e-6 * np.abs(boxes).max()
    inside = ((position[:, None] > boxes[None, :, 0] + tolerance)
              & (position[:, None] < boxes[None, :, 1] - tolerance)).all(axis=2).any(axis=1)
    keep = np.flatnonzero(~inside)[:count]
    return position[keep], normal[keep] / np.linalg.norm(normal[keep], axis=1, keepdims=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--triangles", type=int, default=70_000)
    parser.add_argument("--vpls", type=int, default=1024)
    parser.add_argument("--points", type=int, default=8192)
    parser.add_argument("--resolutions", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--footprint-scale", type=float, default=FOOTPRINT_SCALE)
    parser.add_argument("--max-footprint", type=float, default=MAX_FOOTPRINT)
    parser.add_argument("--levels", type=int, help="pull-push levels (default: log2 of the "
                        "resolution, every hole filled)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    ctx = shared_context()
    print(ctx.info["GL_RENDERER"], ctx.info["GL_VERSION"])
    rng = np.random.default_rng(0)
    triangles, boxes = room_scene(args.triangles, rng)
    programs = ProgramCache(ctx)
    ism = ImperfectShadowMaps(ctx, programs, args.footprint_scale, args.max_footprint)
    position, normal = vpls_on(ism, triangles, boxes, args.vpls, 1)
    start = time.perf_counter()
    ism.prepare(triangles, args.points, 2, version="bench")  # a new version: built again
    print(f"{len(triangles)} triangles, {args.vpls} VPLs x {args.points} points; footprint "
          f"scale {args.footprint_scale}, max {args.max_footprint}; area table "
          f"{time.perf_counter() - start:.3f} s")
    for resolution in args.resolutions:
        levels = int(math.log2(resolution)) if args.levels is None else args.levels
        ism.render(triangles, position, normal, resolution, levels)  # compile, allocate
        runs = []
        for _ in range(args.repeat):
            ism.render(triangles, position, normal, resolution, levels)
            runs.append(ism.timings)
        splat = np.median([t["splat"] for t in runs])
        pull_push = np.median([t["pull_push"] for t in runs])
        upload = np.median([t["upload"] for t in runs])
        atlas = ism.read_atlas()
        print(f"{resolution:>4}² tiles, {levels} levels: splat {splat * 1e3:8.1f} ms  pull-push "
              f"{pull_push * 1e3:8.1f} ms  upload {upload * 1e3:6.1f} ms  atlas "
              f"{atlas.shape[1]}x{atlas.shape[0]}  memory {ism.memory_bytes() / 2**20:7.1f} MB"
              f" (atlas alone {atlas.nbytes / 2**20:.1f} MB)")
    ism.release()
    programs.release()


if __name__ == "__main__":
    main()
