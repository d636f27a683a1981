"""What one VPL GI frame's error is made of, against the report's two Cycles references: the
VPLs' noise (frame to frame over seeds), the rest of the error (what averaging frames keeps),
the imperfect shadow maps' share (the same VPLs with ray-traced visibility) and the direct
light's (``bounces=0`` against direct-only references, at block sizes that tell pixel-sized
edges from larger areas).

    .venv/bin/python tools/error_parts.py SCENE [--seeds 0,1,2,3] [--reference-samples 64]
        [--size 640x360] [--set NAME=VALUE ...] [--no-exact] [--no-direct]

SCENE is a .blend or an .obj asset (the report's OBJ route: camera, sun and sky added). Every
frame is rendered as the report renders VPL GI (devtools/report.py ``render_vpl``: the
scene's settings, the automatic mode off, ``--set``, then afresh, nothing kept from the frame
before), after one untimed warm-up. Errors are the report's noise-free relative RMSE, all as a
share of the full image's mean (the direct light's too). The split over N seeds: the noise²
of one frame is (mean of the frames' error² − error² of their average) · N / (N − 1); the
rest is what is left of one frame's error².
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from functools import partial
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tools.bench_denoise import parse_size  # noqa: E402

BLOCKS = (1, 4, 8, 40)
"""Block edges (pixels) the direct light's error is measured at: averaging blocks keeps the
error of areas and removes that of edges inside a block."""


def block_mean(image: np.ndarray, edge: int) -> np.ndarray:
    """The mean of each edge × edge block (the image cropped to whole blocks)."""
    height, width = (s - s % edge for s in image.shape[:2])
    blocks = image[:height, :width, :3].reshape(height // edge, edge, width // edge, edge, 3)
    return blocks.mean(axis=(1, 3))


def split(errors2: list[float], average2: float) -> tuple[float, float]:
    """(noise², rest²) of one frame from its seeds' squared errors and their average's."""
    n, mean2 = len(errors2), float(np.mean(errors2))
    noise2 = max(0.0, (mean2 - average2) * n / (n - 1))
    return noise2, max(0.0, mean2 - noise2)


def percent(squared: float, mean: float) -> str:
    return f"{math.sqrt(max(0.0, squared)) / mean * 100:.1f} %"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", type=Path)
    parser.add_argument("--seeds", default="0,1,2,3", help="at least two (0,1,2,3)")
    parser.add_argument("--size", type=parse_size, default=(640, 360))
    parser.add_argument("--reference-samples", type=int, default=64)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a VPL GI setting of every frame (as the report's --set)")
    parser.add_argument("--no-exact", dest="exact", action="store_false",
                        help="leave out the frames with ray-traced visibility")
    parser.add_argument("--no-direct", dest="direct", action="store_false",
                        help="leave out the direct light's frames and references")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    if len(seeds) < 2:
        parser.error("--seeds needs at least two seeds")

    from addon import register, unregister
    from addon.cli import parse_overrides
    from devtools import report
    from devtools.metrics import unbiased_squared_error as squared_error

    register()
    try:
        scene = report.open_scene(args.scene, args.size)
        scene.vpl_gi.assign(parse_overrides(args.set))
        base = {**scene.vpl_gi.values(), "auto_parameters": "off"}
        digest = report.file_digest(args.scene)
        options = report.Options(report.LADDERS["test"], args.size,
                                 reference_samples=args.reference_samples)
        with tempfile.TemporaryDirectory(prefix="vpl_gi_parts_") as tmp:
            exr = Path(tmp) / "render.exr"

            def references(bounces: int) -> tuple[np.ndarray, np.ndarray]:
                (r1, *_), (r2, *_) = report.render_references(scene, digest, options,
                                                             bounces, exr)
                return r1, r2

            def frames(values: dict[str, object]) -> list[tuple[np.ndarray, float]]:
                out = []
                for seed in seeds:
                    out.append(report.render_vpl(scene, {**values, "seed": seed}, exr))
                    print(f"  {values.get('visibility')} bounces {values.get('bounces')} "
                          f"seed {seed}: {out[-1][1]:.2f} s", flush=True)
                return out

            full = references(base["bounces"])
            mean = float(((full[0] + full[1]) / 2)[..., :3].mean())
            report.warm_up(scene, [report.Job({}, partial(report.render_vpl, scene, base),
                                              warm_up=True)], exr)  # GL context, shaders
            lines = [("maps", base)]
            if args.exact:
                lines.append(("rays", {**base, "visibility": "exact"}))
            images = {}
            print(f"{args.scene.name}, {args.size[0]}×{args.size[1]}, seeds {args.seeds}, "
                  f"error as a share of the full image's mean:")
            for name, values in lines:
                rendered = frames(values)
                images[name] = [image for image, _ in rendered]
                errors2 = [squared_error(image, *full) for image in images[name]]
                average2 = squared_error(np.mean(images[name], axis=0), *full)
                noise2, rest2 = split(errors2, average2)
                seconds = [s for _, s in rendered]
                print(f"{values.get('visibility', '')} ({name}): one frame "
                      f"{', '.join(percent(e, mean) for e in errors2)} in "
                      f"{min(seconds):.2f}-{max(seconds):.2f} s; the average of "
                      f"{len(seeds)} {percent(average2, mean)}; one frame's noise "
                      f"{percent(noise2, mean)}, the rest {percent(rest2, mean)}", flush=True)
            if args.exact:
                differences = [m - r for m, r in zip(images["maps"], images["rays"],
                                                     strict=True)]
                per_frame = [float(np.mean(d[..., :3] ** 2)) for d in differences]
                average = np.mean(differences, axis=0)[..., :3]
                print(f"maps − rays, the same VPLs: one frame "
                      f"{', '.join(percent(e, mean) for e in per_frame)}; their average "
                      f"{percent(float(np.mean(average**2)), mean)} (energy "
                      f"{float(average.mean()) / mean * 100:+.1f} %)", flush=True)
            if args.direct:
                direct = references(0)
                shot = [image for image, _ in frames({**base, "bounces": 0})]
                errors2 = [squared_error(image, *direct) for image in shot]
                average = np.mean(shot, axis=0)
                share = float(((direct[0] + direct[1]) / 2)[..., :3].mean()) / mean
                print(f"direct light ({share * 100:.1f} % of the image's mean): one frame "
                      f"{', '.join(percent(e, mean) for e in errors2)}; their average "
                      f"{percent(squared_error(average, *direct), mean)}", flush=True)
                blocks = [squared_error(block_mean(average, b), block_mean(direct[0], b),
                                        block_mean(direct[1], b)) for b in BLOCKS]
                print("  their average in blocks of " + ", ".join(
                    f"{b} px {percent(e, mean)}" for b, e in zip(BLOCKS, blocks, strict=True)),
                    flush=True)
    except report.ReportError as exc:  # a scene that cannot be opened or has no camera
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        unregister()
    return 0


if __name__ == "__main__":
    sys.exit(main())
