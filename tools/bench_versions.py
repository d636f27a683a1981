"""Benchmark: an older commit of VPL GI against this working tree, side by side in one run.

For each sample scene it renders a command-line frame with default settings in each tree
(`python -m addon render`, every frame its own process, so nothing is reused between frames:
each frame does all of its work), alternating old and new, and prints the median of
``--repeat`` per stage and in total; then, per tree, the viewport's first-frame latencies
(this tree's tools/bench_viewport.py on each tree's add-on) and the 10k-instance export +
upload against Cycles' sync (tools/bench_export.py). The older commit is checked out with
``git worktree`` in a temporary folder (removed at the end); both trees run with this
interpreter.

    .venv/bin/python tools/bench_versions.py --old babc501 [--scenes interior cornell_box]
        [--size 640x360] [--repeat 3] [--parts frame viewport export]
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
STAGE = re.compile(r"([a-z_()\- ]+?) (\d+) ms")
SAVED = re.compile(r"^Saved .* \(([\d.]+) s\)$", re.MULTILINE)


@contextmanager
def old_tree(rev: str) -> Iterator[Path]:
    """A detached worktree of ``rev`` in a temporary folder, removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="vplgi-old-") as folder:
        tree = Path(folder) / "old"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "--quiet",
                        str(tree), rev], check=True)
        try:
            yield tree
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force",
                            str(tree)], check=False)


def run(tree: Path, *args: str, timeout: float = 1800) -> str:
    """stdout of ``python ARGS`` in ``tree``; a failure stops the benchmark with its output."""
    result = subprocess.run([sys.executable, *args], cwd=tree, capture_output=True, text=True,
                            timeout=timeout)
    if result.returncode != 0:
        raise SystemExit(f"{tree}: {' '.join(args)} failed:\n{result.stderr[-3000:]}")
    return result.stdout


def frame_timings(tree: Path, scene: str, size: str, out: Path) -> dict[str, float]:
    """Stage times of one CLI frame (seconds, from its ``stages:`` line) and its ``total``."""
    stdout = run(tree, "-m", "addon", "render", str(tree / "sample_scenes" / f"{scene}.blend"),
                 "-r", size, "-o", str(out))
    line = next(x for x in stdout.splitlines() if x.startswith("stages:"))
    ran = line.split("| ran:", 1)[1].split("|", 1)[0]
    timings = {name.strip(): int(ms) / 1000 for name, ms in STAGE.findall(ran)}
    timings["total"] = float(SAVED.search(stdout).group(1))
    return timings


def frame_table(trees: dict[str, Path], scene: str, size: str, repeat: int) -> None:
    samples: dict[str, list[dict[str, float]]] = {label: [] for label in trees}
    with tempfile.TemporaryDirectory() as folder:
        for i in range(repeat):
            for label, tree in trees.items():  # alternating, so load drifts hit both alike
                samples[label].append(frame_timings(tree, scene, size,
                                                    Path(folder) / f"{label}{i}.png"))
    stages = list(dict.fromkeys(s for label in trees for t in samples[label] for s in t))
    stages.remove("total")
    print(f"\n{scene}, {size}, defaults: median of {repeat} command-line frames per tree "
          "(seconds; each frame its own process)")
    print("| stage | " + " | ".join(trees) + " | new / old |")
    print("|---|" + "---|" * (len(trees) + 1))
    for stage in [*stages, "total"]:
        medians = [statistics.median(t.get(stage, 0.0) for t in samples[label])
                   for label in trees]
        ratio = f"{medians[1] / medians[0]:.2f}" if medians[0] > 0 else "–"
        cells = " | ".join(f"{m:.3f}" if m else "–" for m in medians)
        print(f"| {'**total**' if stage == 'total' else stage} | {cells} | {ratio} |")


def viewport_table(trees: dict[str, Path], scenes: list[str], width: int) -> None:
    rows: dict[tuple[str, str], dict[str, str]] = {}
    for label, tree in trees.items():
        scene = None
        for line in run(REPO, "tools/bench_viewport.py", "--repo", str(tree), "--scenes",
                        *scenes, "--size", str(width)).splitlines():
            if ".blend:" in line:
                scene = line.split(":", 1)[0]
            cells = [c.strip() for c in line.strip("|").split("|")]
            if line.startswith("| ") and scene and len(cells) >= 4 and cells[3].endswith("ms"):
                rows.setdefault((scene, cells[0]), {})[label] = cells[3]
    print(f"\nViewport, {width} px wide: latency from an edit to its first frame")
    print("| scene | edit | " + " | ".join(trees) + " |")
    print("|---|---|" + "---|" * len(trees))
    for (scene, edit), by_tree in rows.items():
        print(f"| {scene} | {edit} | " + " | ".join(by_tree.get(t, "–") for t in trees) + " |")


def export_table(trees: dict[str, Path], repeat: int) -> None:
    print("\n10k instances (geometry nodes): export + upload against Cycles' sync, seconds")
    print("| tree | ours | Cycles | ours / Cycles |")
    print("|---|---|---|---|")
    for label, tree in trees.items():
        row = next(x for x in run(tree, "tools/bench_export.py", "--scenes", "inst10k",
                                  "--repeat", str(repeat)).splitlines()
                   if x.strip().startswith("inst10k"))
        fields = row.split()
        ours, cycles, ratio = fields[5], fields[6], fields[7]
        print(f"| {label} | {ours} | {cycles} | {ratio} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", required=True, help="the older commit (any git revision)")
    parser.add_argument("--scenes", nargs="+", default=["interior", "cornell_box"])
    parser.add_argument("--size", default="640x360", help="frame size, WIDTHxHEIGHT")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--parts", nargs="+", default=["frame", "viewport", "export"],
                        choices=["frame", "viewport", "export"])
    args = parser.parse_args()
    with old_tree(args.old) as old:
        trees = {f"old ({args.old})": old, "new (this tree)": REPO}
        if "frame" in args.parts:
            for scene in args.scenes:
                frame_table(trees, scene, args.size, args.repeat)
        if "viewport" in args.parts:
            viewport_table(trees, args.scenes, int(args.size.split("x")[0]))
        if "export" in args.parts:
            export_table(trees, args.repeat)


if __name__ == "__main__":
    main()
