"""Denoisers against a converged Cycles image: the blur, OIDN, blur + OIDN and OIDN on the
indirect light, on the sample scenes, with the report's noise-free relative RMSE
(devtools/report.py) and render times.

    .venv/bin/python tools/bench_denoise.py                      # Cornell box and interior
    .venv/bin/python tools/bench_denoise.py --size 320x180 --reference-samples 64

Each scene renders two independently seeded Cycles references (cached in .cache/references,
like the report's), then VPL GI with the scene's own settings and each denoiser, after one
untimed warm-up render. Prints one table: time of the whole render, time of the blur and
denoise stages, error and energy against the references, and the noise left (from a second
render with the next seed).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

DENOISERS = ("blur", "oidn", "blur_oidn", "oidn_indirect")
SCENES = ("cornell_box", "interior")
REFERENCE_SAMPLES = {"cornell_box": 128, "interior": 32}


def parse_size(text: str) -> tuple[int, int]:
    width, _, height = text.partition("x")
    return int(width), int(height or width)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES),
                        help="sample scene names or .blend paths (cornell_box interior)")
    parser.add_argument("--size", type=parse_size, default=(640, 360),
                        help="WIDTHxHEIGHT (640x360)")
    parser.add_argument("--reference-samples", type=int,
                        help="Cycles samples of each of the two references (default: "
                             "cornell_box 128, interior 32, others 64); their noise does not "
                             "bias the error, only widens its spread")
    parser.add_argument("--no-noise", dest="noise", action="store_false",
                        help="leave out the noise column (a second render per denoiser)")
    parser.add_argument("--denoisers", nargs="+", default=list(DENOISERS), choices=DENOISERS)
    args = parser.parse_args()

    from addon import ENGINE_ID, register, unregister
    from addon.engine import monitor
    from devtools import metrics, report

    register()
    rows, used_samples = [], {}
    try:
        for name in args.scenes:
            path = Path(name) if name.endswith(".blend") else \
                REPO / "sample_scenes" / f"{name}.blend"
            scene = report.open_scene(path, args.size)
            bounces = scene.vpl_gi.bounces
            samples = args.reference_samples or REFERENCE_SAMPLES.get(path.stem, 64)
            used_samples[path.stem] = samples
            digest = report.file_digest(path)
            with tempfile.TemporaryDirectory(prefix="vpl_gi_bench_") as tmp:
                exr = Path(tmp) / "render.exr"
                options = report.Options(report.LADDERS["test"], args.size,
                                         reference_samples=samples)
                refs = [image for image, *_ in
                        report.render_references(scene, digest, options, bounces, exr)]
                scene.render.engine = ENGINE_ID
                scene.vpl_gi.denoiser = args.denoisers[0]
                report.render_timed(scene, exr)  # warm-up: GL context, shaders, OIDN weights
                for denoiser in args.denoisers:
                    scene.vpl_gi.denoiser = denoiser
                    image, seconds = report.render_timed(scene, exr)
                    stats = monitor.last_stats
                    stage = sum(stats.timings.get(k, 0.0)
                                for k in ("denoise", "blur", "supersample blur"))
                    errors = report.error_metrics(image, *refs)
                    warnings = list(stats.warnings)
                    noise = float("nan")
                    if args.noise:  # the same render with the next seed
                        seed = scene.vpl_gi.seed
                        scene.vpl_gi.seed = seed + 1
                        try:
                            other, _ = report.render_timed(scene, exr)
                        finally:
                            scene.vpl_gi.seed = seed
                        noise = metrics.rmse(image, other) / math.sqrt(2) / float(
                            ((refs[0] + refs[1]) / 2).mean())
                    rows.append((path.stem, denoiser, seconds, stage,
                                 errors["relative_rmse_unbiased"], noise,
                                 errors["mean_relative_energy"], warnings))
                    print(f"{path.stem} {denoiser}: {seconds:.1f} s, "
                          f"error {errors['relative_rmse_unbiased'] * 100:.2f} %", flush=True)
    finally:
        unregister()
    width, height = args.size
    refs = ", ".join(f"{name} 2 × {n} spp" for name, n in used_samples.items())
    print(f"\n{width}×{height}, Cycles references {refs}; error = noise-free relative RMSE "
          f"(devtools/report.py)\n")
    print("noise = RMS difference of two renders with seeds s and s + 1, / √2, relative to "
          "the reference's mean\n")
    print("| scene | denoiser | render | blur + denoise | error | noise | energy |")
    print("|---|---|---|---|---|---|---|")
    for scene_name, denoiser, seconds, stage, error, noise, energy, warnings in rows:
        note = f" ({'; '.join(warnings)})" if warnings else ""
        print(f"| {scene_name} | {denoiser}{note} | {seconds:.1f} s | {stage:.2f} s | "
              f"{error * 100:.1f} % | {noise * 100:.1f} % | {energy * 100:+.1f} % |")
    return 0 if all(math.isfinite(r[4]) for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
