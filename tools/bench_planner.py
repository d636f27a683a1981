"""Benchmark of the planner (addon/core/planner.py): each scene rendered with the planner and
with a forced full pipeline (``planner = False``: every light sampled, every stage run, nothing
kept from the last frame), side by side in one process, with the time of each, their ratio and
the difference of their Combined images; "noise" is the difference between two full renders
of different seeds, the yardstick for "within noise".

Scenes: the sample scenes, and purpose-made ones that need little: direct light only
(bounces = 0), a light pointing away from the view, and a camera-only animation (4 frames
orbiting the Cornell box; the times are the sum over the frames). Only the Combined pass is
asked for, as in Blender's default view layer.

    .venv/bin/python tools/bench_planner.py [--size 128] [--repeat 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tools.bench_visibility import export  # noqa: E402


def orbit(camera, degrees: float):
    """The camera turned about the world's Z axis through the origin."""
    angle = np.radians(degrees)
    turn = np.eye(4)
    turn[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
    return replace(camera, view_matrix=camera.view_matrix @ turn)


def away_from_view(scene):
    """The scene with an extra spot light behind the camera, pointing away from the view."""
    from addon.core.scene.model import Light, LightKind

    behind = np.linalg.inv(scene.camera.view_matrix)  # a light at the camera, facing back
    flip = np.diag([1.0, -1.0, -1.0, 1.0])
    spot = Light("away", LightKind.SPOT, behind @ flip, power=500.0)
    area = Light("away area", LightKind.AREA, behind @ flip, power=500.0, size_x=0.5)
    return replace(scene, lights=[*scene.lights, spot, area])


def relative_rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(((a - b) ** 2).mean() / max((b**2).mean(), 1e-30)))


def timed(render: Callable[[], list[np.ndarray]], repeat: int) -> tuple[float, list]:
    """The fastest of ``repeat`` runs, and the images of the last."""
    best, images = float("inf"), []
    for _ in range(repeat):
        start = time.perf_counter()
        images = render()
        best = min(best, time.perf_counter() - start)
    return best, images


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()

    from addon.core.frame.renderer import Renderer
    from addon.core.settings import Settings

    files = ("cornell_box", "interior", "multi_light", "light_spot", "light_area")
    scenes = {name: export(REPO / "sample_scenes" / f"{name}.blend", args.size)
              for name in files}
    cornell = scenes["cornell_box"]
    base = Settings()
    cases = [(name, scene, base, 1) for name, scene in scenes.items()]
    cases += [("direct only (cornell, bounces 0)", cornell, replace(base, bounces=0), 1),
              ("light pointing away (cornell)", away_from_view(cornell), base, 1),
              ("camera-only animation (cornell, 4 frames)", cornell, base, 4)]

    renderer = Renderer()
    print(f"{args.size}² pixels, default settings, GL: {renderer.ctx.info['GL_RENDERER']}")
    print(f"{'scene':<44}{'planner':>10}{'full':>10}{'full/planner':>14}{'relRMSE':>10}"
          f"{'max |Δ|/max':>13}{'noise':>9}  skipped by the planner")
    for name, scene, settings, frames in cases:
        skipped: dict[str, str] = {}

        def render(planner: bool, scene=scene, settings=settings, frames=frames,
                   skipped=skipped) -> list:
            renderer.forget_frames()
            images = []
            for k in range(frames):
                view = replace(scene, camera=orbit(scene.camera, 3.0 * k))
                frame, stats = renderer.render(view, replace(settings, planner=planner),
                                               passes=frozenset() if planner else None)
                images.append(frame.passes["Combined"][..., :3])
                if planner and k == frames - 1:
                    skipped.update(stats.skipped)
            return images

        render(True)  # compile shaders, sample ISM points
        planned_time, planned = timed(lambda: render(True), args.repeat)
        full_time, full = timed(lambda: render(False), args.repeat)
        reseeded = render(False, settings=replace(settings, seed=1))
        error = max(relative_rmse(p, f) for p, f in zip(planned, full, strict=True))
        noise = max(relative_rmse(r, f) for r, f in zip(reseeded, full, strict=True))
        peak = max(float(np.abs(p - f).max() / max(f.max(), 1e-30))
                   for p, f in zip(planned, full, strict=True))
        print(f"{name:<44}{planned_time:>9.2f}s{full_time:>9.2f}s"
              f"{full_time / planned_time:>13.2f}x{error * 100:>9.2f}%{peak * 100:>12.2f}%"
              f"{noise * 100:>8.2f}%  {'; '.join(skipped)}", flush=True)
    renderer.release()


if __name__ == "__main__":
    main()
