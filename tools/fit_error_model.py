"""Fit the automatic mode's error model (addon/core/frame/error_model.json) on measurements.

- Noise and floor: from error-against-time reports (``python -m devtools report``), the VPL GI
  imperfect-shadow-map lines: relative RMSE² = floor² + noise² / paths, least squares of the
  residuals relative to each render's own RMSE² (one frame with a hot spot, or a scene with
  a large floor, does not decide the noise), per scene with a shared noise constant; the
  stored floor is that of the first report's scene.
  The interleave factor compares the first report's lines with and without interleaving.
- ISM term (``--ism`` alone: only it): on the sample scenes, VPL GI's indirect light with
  imperfect shadow maps against exact (ray-traced) visibility, the same VPLs (256 light paths,
  four bounces as the reports, no interleaving, seeds 0 and 1), for each resolution/points
  pair, relative to the exact frame's whole image (the model's other terms are errors of the
  whole image); stored as the error beyond the default pair's, averaged over the scenes and
  seeds in squares, at ``--size`` 360 (square frames of the report's 640×360 pixel scale).
- Maps' term (``maps``, ``--maps``): in scenes with more triangles than an ISM has points, the
  maps' visibility error that passes do not remove. From pairs of long-render reports of one
  scene, K passes with the maps throughout (``--set ray_traced_from_pass=0``) and with rays
  from pass s: their RMSE² differ by maps² (1 - ((s - 1) / K)²); averaged over the pairs in
  squares. Alone (no positional reports) it updates that term of the stored model only; a
  fit of the other terms without it keeps the stored one.

    .venv/bin/python tools/fit_error_model.py renders/fit_cornell_box/report.json \
        renders/fit_interior/report.json renders/fit_sponza/report.json

on reports made with ``--set bounces=4 --cycles-samples none --oidn-samples none --vpl-ladder
vpl_count=256,512,1024,2048,4096 --vpl-ladder interleave=1,4 --out renders/fit_SCENE`` (the
Cornell box with ``--reference-samples 256``, the interior 128, Sponza's OBJ 64), and

    .venv/bin/python tools/fit_error_model.py --maps \
        renders/fit_maps_interior_rays0/report.json renders/fit_maps_interior_rays3/report.json \
        renders/fit_maps_sponza_rays0/report.json renders/fit_maps_sponza_rays3/report.json

on reports made with ``--set bounces=4 --cycles-samples none --oidn-samples none --set
ray_traced_from_pass=R --vpl-ladder passes=K -o renders/fit_maps_SCENE_raysR`` (R = 0 and 3; the
interior with ``--reference-samples 128`` and K = 16, Sponza's OBJ 64 and 8). The ISM term
alone: ``.venv/bin/python tools/fit_error_model.py --ism``.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from itertools import product
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from addon.core.frame.autotune import ERROR_MODEL_FILE  # noqa: E402
from tools.bench_visibility import export  # noqa: E402

ISM_PAIRS = ((64, 1024), (64, 2048), (64, 4096), (64, 8192), (128, 1024), (128, 2048),
             (128, 4096), (128, 8192), (256, 1024), (256, 8192))
ISM_SEEDS = (0, 1)
DEFAULT_PAIR = (128, 8192)


def ism_lines(report: dict) -> dict[int, list[tuple[int, float]]]:
    """interleave -> [(paths, relative RMSE)] of the report's ISM lines."""
    lines: dict[int, list[tuple[int, float]]] = {}
    for entry in report["renders"]:
        s = entry.get("settings", {})
        if "metrics" in entry and s.get("visibility") == "ism":
            lines.setdefault(int(s["interleave"]), []).append(
                (int(s["vpl_count"]), entry["metrics"]["relative_rmse_unbiased"]))
    return lines


def fit_noise(reports: list[dict]) -> tuple[float, list[float], dict[str, float]]:
    """Shared noise, per-report floors and the interleave factors."""
    rows, targets, first_lines = [], [], ism_lines(reports[0])
    for i, report in enumerate(reports):
        for paths, error in (p for line in ism_lines(report).values() for p in line):
            row = np.zeros(len(reports) + 1)
            row[0], row[1 + i] = 1.0 / paths, 1.0
            rows.append(row / error**2)
            targets.append(1.0)
    from scipy.optimize import nnls

    solution, _ = nnls(np.array(rows), np.array(targets))
    noise, floors = float(np.sqrt(solution[0])), [float(np.sqrt(f)) for f in solution[1:]]
    factors = {"1": 1.0}
    plain = dict(first_lines.get(1, []))
    for k, line in first_lines.items():
        if k == 1 or not plain:
            continue
        ratios = [np.sqrt(max(e**2 - floors[0] ** 2, 1e-12) /
                          max(plain[p] ** 2 - floors[0] ** 2, 1e-12))
                  for p, e in line if p in plain]
        factors[str(k)] = float(np.median(ratios))
    return noise, floors, factors


def ism_errors(size: int) -> dict[str, float]:
    """Per 'resolution/points': ISM visibility error beyond the default pair's, relative to
    the whole image."""
    from addon.core.frame.renderer import Renderer
    from addon.core.settings import Settings

    renderer = Renderer()
    squares: dict[tuple[int, int], list[float]] = {pair: [] for pair in ISM_PAIRS}
    scenes = {name: export(REPO / "sample_scenes" / f"{name}.blend", size)
              for name in ("cornell_box", "interior")}
    for (name, scene), seed in product(scenes.items(), ISM_SEEDS):
        base = Settings(bounces=4, antialiasing=1, vpl_count=256, interleave=1, seed=seed)
        passes = renderer.render(scene, replace(base, visibility="exact"))[0].passes
        exact, whole = passes["DiffInd"], passes["Combined"][..., :3]
        for resolution, points in ISM_PAIRS:
            frame, _ = renderer.render(scene, replace(base, ism_resolution=resolution,
                                                      ism_points=points))
            image = frame.passes["DiffInd"]
            error2 = ((image - exact) ** 2).mean() / (whole**2).mean()
            squares[(resolution, points)].append(float(error2))
            print(f"{name} seed {seed} {resolution}²/{points}: {np.sqrt(error2) * 100:.2f} %",
                  flush=True)
    renderer.release()
    default = np.mean(squares[DEFAULT_PAIR])
    return {f"{r}/{p}": float(np.sqrt(max(0.0, np.mean(v) - default)))
            for (r, p), v in squares.items()}


def longest_render(report: dict) -> tuple[int, int, float]:
    """(passes, ray_traced_from_pass, relative RMSE) of the report's VPL GI render of most
    passes."""
    entries = [e for e in report["renders"] if "metrics" in e and "settings" in e]
    entry = max(entries, key=lambda e: int(e["settings"]["passes"]))
    s = entry["settings"]
    return (int(s["passes"]), int(s["ray_traced_from_pass"]),
            float(entry["metrics"]["relative_rmse_unbiased"]))


def fit_maps(pairs: list[tuple[dict, dict]]) -> float:
    """The maps' error passes do not remove, from (maps throughout, rays from pass s) pairs of
    long-render reports of one scene each (see the module docstring)."""
    squares = []
    for maps_report, rays_report in pairs:
        passes, never, maps_error = longest_render(maps_report)
        same, switch, rays_error = longest_render(rays_report)
        if never != 0 or switch < 1 or same != passes:
            raise SystemExit("--maps takes pairs of reports of equal passes: ray_traced_from_pass"
                             f" 0, then from a pass (got {never} and {switch}, {passes} and "
                             f"{same} passes)")
        mapped = min(switch - 1, passes) / passes
        square = (maps_error**2 - rays_error**2) / (1.0 - mapped**2)
        print(f"{passes} passes: maps {maps_error * 100:.2f} %, rays from pass {switch} "
              f"{rays_error * 100:.2f} %: maps' term {np.sqrt(max(square, 0.0)) * 100:.2f} %")
        squares.append(square)
    return float(np.sqrt(max(0.0, np.mean(squares))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("reports", type=Path, nargs="*")
    parser.add_argument("--maps", type=Path, nargs="+", default=[],
                        help="pairs of long-render reports: maps throughout, rays from a pass")
    parser.add_argument("--ism", action="store_true",
                        help="fit the ISM term only, keeping the stored model's others")
    parser.add_argument("--size", type=int, default=360)
    parser.add_argument("-o", "--output", type=Path, default=ERROR_MODEL_FILE)
    args = parser.parse_args()
    if len(args.maps) % 2:
        parser.error("--maps takes pairs of reports")
    maps_source = f"tools/fit_error_model.py --maps {' '.join(str(p) for p in args.maps)}"
    pairs = [tuple(json.loads(p.read_text()) for p in args.maps[i:i + 2])
             for i in range(0, len(args.maps), 2)]
    if not args.reports and not pairs and not args.ism:
        parser.error("give the reports to fit, --maps pairs, or --ism")
    stored = json.loads(args.output.read_text()) if args.output.is_file() else {}
    model = stored
    if args.reports:
        reports = [json.loads(p.read_text()) for p in args.reports]
        noise, floors, factors = fit_noise(reports)
        for path, floor in zip(args.reports, floors, strict=True):
            print(f"{path}: floor {floor * 100:.1f} %")
        model = {"source": f"tools/fit_error_model.py {' '.join(str(p) for p in args.reports)}",
                 "floor": floors[0], "noise": noise, "interleave": factors,
                 "ism": ism_errors(args.size),  # the maps' term kept unless fitted again:
                 **{k: stored[k] for k in ("maps", "maps_source") if k in stored}}
    elif args.ism:
        model.update(ism=ism_errors(args.size), ism_source=f"tools/fit_error_model.py --ism "
                     f"--size {args.size}")
    if pairs:
        model.update(maps=fit_maps(pairs), maps_source=maps_source)
    args.output.write_text(json.dumps(model, indent=2) + "\n")
    print(json.dumps(model, indent=2))

if __name__ == "__main__":
    main()
