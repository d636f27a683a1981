"""Stage timings of command-line frames, two code trees side by side in one run: each tree
renders each scene in its own process (``python -m addon render``, cwd and PYTHONPATH set to
the tree), the trees alternating, ``--repeat`` times; prints the median of every stage of the
renderer's ``stages:`` line and of the frame's wall time, and each tree's relative RMSE against
a reference the head tree renders with ``--reference`` overrides (default: exact visibility).

    git worktree add --detach /tmp/vplgi_base main
    .venv/bin/python tools/bench_stages.py --base /tmp/vplgi_base \\
        --scene sample_scenes/interior.blend --scene sample_scenes/cornell_box.blend \\
        [--head .] [--size 640x360] [--repeat 3] [--set NAME=VALUE] \\
        [--reference visibility=exact]

Every render is a fresh process, so nothing is reused between frames (the stages that a
second frame would skip all run).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from devtools.metrics import relative_rmse  # noqa: E402

STAGE = re.compile(r"^(.*) (\d+) ms$")
SAVED = re.compile(r"^Saved .* \(([\d.]+) s\)$", re.MULTILINE)


def render(tree: Path, scene: Path, size: str, overrides: list[str], output: Path
           ) -> dict[str, float]:
    """Render one frame with ``tree``'s code: its stage timings and ``frame`` (seconds), and
    its counts (``count vpls`` ...)."""
    command = [sys.executable, "-m", "addon", "render", str(scene.resolve()), "-r", size,
               "-o", str(output), *(a for o in overrides for a in ("--set", o))]
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode:
        sys.exit(f"{tree}: {' '.join(command)} failed:\n{done.stderr[-2000:]}")
    line = next(s for s in done.stdout.splitlines() if s.startswith("stages: "))
    counts, ran = line.removeprefix("stages: ").split(" | skipped: ")[0].split(" | ran: ")
    timings = {f"count {k}": float(v) for k, _, v in
               (item.rpartition(" ") for item in counts.split(", ")) if k}
    for item in ran.split(", "):
        match = STAGE.match(item)
        if match:
            timings[match.group(1)] = int(match.group(2)) / 1000
    timings["frame"] = float(SAVED.search(done.stdout).group(1))
    return timings


def read_exr(path: Path) -> np.ndarray:
    """Linear RGB of an EXR the renderer wrote."""
    import bpy

    image = bpy.data.images.load(str(path))
    try:
        pixels = np.empty(image.size[0] * image.size[1] * image.channels, np.float32)
        image.pixels.foreach_get(pixels)
        return pixels.reshape(-1, image.channels)[:, :3].copy()
    finally:
        bpy.data.images.remove(image)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", type=Path, required=True, help="the tree measured before")
    parser.add_argument("--head", type=Path, default=ROOT, help="the tree measured after")
    parser.add_argument("--scene", type=Path, action="append", required=True)
    parser.add_argument("--size", default="640x360")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--reference", action="append", default=None, metavar="NAME=VALUE",
                        help="overrides of the reference render (default visibility=exact)")
    args = parser.parse_args()
    trees = {"base": args.base.resolve(), "head": args.head.resolve()}
    reference_set = args.reference or ["visibility=exact"]
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        for scene in args.scene:
            runs: dict[str, list[dict[str, float]]] = {name: [] for name in trees}
            for k in range(args.repeat):
                for name, tree in trees.items():
                    runs[name].append(render(tree, scene, args.size, args.set,
                                             out / f"{name}{k}.exr"))
            render(trees["head"], scene, args.size, [*args.set, *reference_set],
                   out / "reference.exr")
            reference = read_exr(out / "reference.exr")
            print(f"\n{scene.name} at {args.size}, {' '.join(args.set) or 'defaults'}: median "
                  f"of {args.repeat} (ms; counts as counted)")
            stages = list(dict.fromkeys(s for name in trees for r in runs[name] for s in r))
            print(f"{'stage':<36}{'base':>10}{'head':>10}")
            for stage in stages:
                scale = 1 if stage.startswith("count ") else 1000
                cells = [statistics.median(r.get(stage, 0.0) for r in runs[name]) * scale
                         for name in trees]
                print(f"{stage:<36}{cells[0]:>10.0f}{cells[1]:>10.0f}")
            errors = [relative_rmse(read_exr(out / f"{name}0.exr"), reference)
                      for name in trees]
            same = [np.array_equal(read_exr(out / f"{name}0.exr"),
                                   read_exr(out / f"{name}{args.repeat - 1}.exr"))
                    for name in trees]
            print(f"{'relative RMSE vs ' + ' '.join(reference_set):<36}"
                  f"{errors[0]:>10.4f}{errors[1]:>10.4f}")
            print(f"{'first and last run identical':<36}{same[0]!s:>10}{same[1]!s:>10}")


if __name__ == "__main__":
    main()
