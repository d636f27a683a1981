"""Benchmark: the interior sample scene at 640×360 with default settings, with and without a
light portal in its window (an area light marked Portal, as a Cycles user would place it),
each rendered twice; error against the report's Cycles references (2 × 128 spp at the scene's
4 bounces, cached as `python -m devtools report` caches them; rendered first if missing).
Portals change Cycles' sampling, not its converged image, so the same references serve both.

    .venv/bin/python tools/bench_portal.py [--cache .cache/references]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
BLEND = REPO / "sample_scenes" / "interior.blend"
SIZE = (640, 360)


def add_portal(bpy, scene) -> None:
    """A portal filling the window (x -0.4..1.2, z 0.9..2.3 in the wall y = -2), facing in."""
    data = bpy.data.lights.new("Portal", "AREA")
    data.shape, data.size, data.size_y = "RECTANGLE", 1.6, 1.4
    data.cycles.is_portal = True
    portal = bpy.data.objects.new("Portal", data)
    portal.location = (0.4, -2.0, 1.6)
    portal.rotation_euler = (np.pi / 2, 0.0, 0.0)  # -Z (the portal's inside) along +y
    scene.collection.objects.link(portal)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cache", type=Path, default=REPO / ".cache" / "references")
    args = parser.parse_args()

    import bpy

    from addon.engine import monitor
    from devtools.registered import run_registered
    from devtools.report import (
        LADDERS,
        Options,
        error_metrics,
        file_digest,
        open_scene,
        render_references,
        render_timed,
    )

    def measure() -> None:
        scene = open_scene(BLEND, SIZE)
        options = Options(LADDERS["test"], SIZE, reference_samples=128, cache_dir=args.cache)
        refs = [image for image, *_ in render_references(
            scene, file_digest(BLEND), options, scene.vpl_gi.bounces,
            Path("/tmp/vplgi_portal_reference.exr"))]
        print("| portal | seconds | relRMSE | energy | VPLs lighting the view |")
        print("|---|---|---|---|---|")
        for portal in (False, True, False, True):
            scene = open_scene(BLEND, SIZE)
            scene.render.engine = "VPL_GI"
            if portal:
                add_portal(bpy, scene)
            image, seconds = render_timed(scene, Path(f"/tmp/vplgi_portal_{portal}.exr"))
            metrics = error_metrics(image, *refs)
            share = monitor.last_stats.counts.get("vpls_in_view_pct", "–")
            print(f"| {'yes' if portal else 'no'} | {seconds:.1f} | "
                  f"{metrics['relative_rmse_unbiased']:.1%} | "
                  f"{metrics['mean_relative_energy']:+.1%} | {share} % |", flush=True)
    run_registered(measure)


if __name__ == "__main__":
    main()
