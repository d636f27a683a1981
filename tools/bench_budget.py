"""Benchmark of the automatic mode 'time' (frame/budget.py): a scene rendered at time budgets
with the budget planned as 1, 2 or 4 passes (BUDGET_SPLIT), each render's time and noise-free
relative RMSE against the report's two cached Cycles references (see ``devtools report``;
render them first with ``--references-only``), and the choice (light paths, points and map
size of pass 0 / the later passes) and passes it made.

    .venv/bin/python tools/bench_budget.py sample_scenes/interior.blend --budgets 4.5,9 \\
        --splits 1,2,4 [--resolution 640x360] [--reference-samples 128] [--cache DIR] \\
        [--set bounces=4]

``--repo PATH`` renders with another checkout's add-on (one without frame/budget.py: each
budget once, the single frame the automatic mode chose before passes).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", type=Path)
    parser.add_argument("--budgets", default="4.5,9")
    parser.add_argument("--splits", default="1,2,4")
    parser.add_argument("--resolution", default="640x360")
    parser.add_argument("--reference-samples", type=int, default=128)
    parser.add_argument("--cache", type=Path, default=REPO / ".cache" / "references")
    parser.add_argument("--repo", type=Path, default=REPO)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a VPL GI setting for every render, as the report's --set")
    args = parser.parse_args()
    sys.path.insert(0, str(args.repo))
    sys.path.insert(1, str(REPO))

    from addon import register, unregister
    from addon.cli import parse_overrides
    from addon.engine import monitor
    from devtools import report

    width, height = (int(v) for v in args.resolution.split("x"))
    register()
    try:
        scene = report.open_scene(args.scene, (width, height))
        overrides = parse_overrides(args.set)
        scene.vpl_gi.assign(overrides)
        options = report.Options(report.LADDERS["test"], (width, height),
                                 reference_samples=args.reference_samples, cache_dir=args.cache)
        with tempfile.TemporaryDirectory() as tmp:
            exr = Path(tmp) / "render.exr"
            references = report.render_references(scene, report.file_digest(args.scene),
                                                  options, scene.vpl_gi.bounces, exr)
            (r1, *_), (r2, *_) = references
            values = report.vpl_values({}, overrides)
            report.render_auto(scene, values, 1.0, exr)  # warm-up: shaders, the cost model
            try:  # a checkout from before the budget module (--repo) has one split
                from addon.core.frame import budget as budget_module
                splits = [int(s) for s in args.splits.split(",")]
            except ImportError:
                budget_module, splits = None, [0]
            for budget in (float(b) for b in args.budgets.split(",")):
                for split in splits:
                    if budget_module is not None:
                        budget_module.BUDGET_SPLIT = split
                    image, seconds = report.render_auto(scene, values, budget, exr)
                    m = report.error_metrics(image, r1, r2)
                    stats = monitor.last_stats
                    chosen = [", ".join(part.strip() for part in n.split(":")[1].split(",")[:3])
                              for n in stats.notes if n.startswith("automatic parameters")]
                    print(f"budget {budget:5.1f} s  split {split}  {seconds:6.2f} s  "
                          f"error {m['relative_rmse_unbiased'] * 100:5.1f} %  energy "
                          f"{m['mean_relative_energy'] * 100:+5.1f} %  passes "
                          f"{stats.counts.get('passes')}  chosen {' / '.join(chosen)}"
                          + (f"  warning: {stats.warnings[0][:60]}…" if stats.warnings
                             else ""), flush=True)
    finally:
        unregister()


if __name__ == "__main__":
    main()
