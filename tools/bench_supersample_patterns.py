"""Benchmark: how well 9 supersample positions per pixel estimate a straight edge's coverage.

A pixel is the unit square; an edge is a random line through it (uniform direction, offset
uniform over the pixel's extent across it). A pattern's error is the RMS, over the edges, of
its covered fraction of samples minus the exact covered area (the box filter's value). Patterns:
the ordered 3×3 grid (VPL GI's supersamples in one pass), the canonical N-rooks arrangement
(x = i + (j + ½)/3, y = j + (i + ½)/3 in ninths), the best of all 46,656 N-rooks arrangements
that keep one sample in each cell of the 3×3 grid (so a supersample stays in its cell: every
permutation of sub-rows and sub-columns), rank-1 lattices (k/9, g·k/9), and 9 free points
optimised by a seeded random search. Numpy only, a few seconds.

    .venv/bin/python tools/bench_supersample_patterns.py [--edges 4000] [--seed 0]
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

FACTOR = 3  # supersamples per pixel edge
EXACT_GRID = 200  # samples per edge of the grid that measures each edge's exact area


def random_edges(count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (count, 2) and offsets (count,) of lines n·p = c crossing the unit square."""
    angle = rng.uniform(0.0, np.pi, count)
    normal = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float) @ normal.T
    return normal, rng.uniform(corners.min(axis=0), corners.max(axis=0))


def coverage_error(points: np.ndarray, normal: np.ndarray, offset: np.ndarray,
                   area: np.ndarray) -> float:
    """RMS over the edges of the points' covered fraction minus the exact area."""
    covered = ((points @ normal.T) < offset).mean(axis=0)
    return float(np.sqrt(((covered - area) ** 2).mean()))


def cell_pattern(columns: tuple, rows: tuple) -> np.ndarray:
    """One sample per cell (i, j) of the 3×3 grid at sub-column columns[i][j] and sub-row
    rows[j][i] of that cell (an N-rooks arrangement for any permutations)."""
    return np.array([((i + (columns[i][j] + 0.5) / FACTOR) / FACTOR,
                      (j + (rows[j][i] + 0.5) / FACTOR) / FACTOR)
                     for i in range(FACTOR) for j in range(FACTOR)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--edges", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    normal, offset = random_edges(args.edges, rng)
    g = (np.arange(EXACT_GRID) + 0.5) / EXACT_GRID
    dense = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    area = ((dense @ normal.T) < offset).mean(axis=0)

    def error(points: np.ndarray) -> float:
        return coverage_error(points, normal, offset, area)

    centres = (np.arange(FACTOR) + 0.5) / FACTOR
    results = {"ordered 3×3 grid": error(np.stack(np.meshgrid(centres, centres), -1)
                                         .reshape(-1, 2))}
    identity = (tuple(range(FACTOR)),) * FACTOR
    results["canonical N-rooks"] = error(cell_pattern(identity, identity))
    permutations = list(itertools.permutations(range(FACTOR)))
    results["best N-rooks, one per cell"] = min(
        error(cell_pattern(columns, rows))
        for columns in itertools.product(permutations, repeat=FACTOR)
        for rows in itertools.product(permutations, repeat=FACTOR))
    k = np.arange(FACTOR * FACTOR)
    for g in (2, 4):
        results[f"rank-1 lattice, g = {g}"] = error(
            np.stack([(k + 0.5) / 9, ((g * k + 0.5) / 9) % 1.0], axis=1))
    points = np.stack(np.meshgrid(centres, centres), -1).reshape(-1, 2)
    best = error(points)
    for _ in range(4000):
        candidate = np.clip(points + rng.normal(0.0, 0.03, points.shape), 0.001, 0.999)
        e = error(candidate)
        if e < best:
            points, best = candidate, e
    results["9 free points, optimised"] = best
    ordered = results["ordered 3×3 grid"]
    print(f"{args.edges} random straight edges through a pixel; RMS coverage error of 9 samples")
    for name, value in results.items():
        print(f"  {name:28} {value:.4f}  ({value / ordered - 1:+.0%} against the ordered grid)")


if __name__ == "__main__":
    main()
