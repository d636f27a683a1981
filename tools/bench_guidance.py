"""Benchmark of the camera-guidance decision (frame/vpl_stage.py): the VPL-generation stage's
time, with guidance on (the default) and off, for the sample scenes, each frame made afresh
(the median of ``--repeat`` frames after a warm-up), and the shares of VPLs lighting the view.
Run it from another checkout (``--repo``) to compare code versions side by side.

    .venv/bin/python tools/bench_guidance.py [--size 256] [--repeat 3] [--repo PATH]
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import replace
from pathlib import Path

SCENES = ("cornell_box", "interior")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[1])
    args = parser.parse_args()
    sys.path.insert(0, str(args.repo))
    from addon.core.frame.renderer import Renderer
    from addon.core.settings import Settings
    from tools.bench_visibility import export

    renderer = Renderer()
    for name in SCENES:
        scene = export(args.repo / "sample_scenes" / f"{name}.blend", args.size)
        for guidance in ("camera", "off"):
            settings = replace(Settings(), vpl_guidance=guidance)
            seconds, counts = [], {}
            for _ in range(args.repeat + 1):
                renderer.forget_frames()
                _, stats = renderer.render(scene, settings)
                seconds.append(sum(v for k, v in stats.timings.items()
                                   if k.startswith("vpl generation")))
                counts = {k: v for k, v in stats.counts.items()
                          if k in ("vpls", "vpl_candidates", "vpls_in_view_pct")}
                counts["decision"] = stats.skipped.get(
                    "vpl guidance", "guided" if guidance == "camera" else "off")
            print(f"{name:12s} guidance {guidance:6s} vpl generation "
                  f"{statistics.median(seconds[1:]) * 1000:6.0f} ms  {counts}", flush=True)
    renderer.release()


if __name__ == "__main__":
    main()
