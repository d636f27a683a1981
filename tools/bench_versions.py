"""Benchmark: an older commit of VPL GI against this working tree, side by side in one run.

For each sample scene it renders a command-line frame with default settings in each tree (`python
-m addon render`, every frame its own process, so nothing is reused between frames: each frame does
all of its work), alternating old and new, and prints the median of ``--repeat`` per stage and in
total, and each tree's error against Cycles where the report (devtools/report.py) has cached its
two references for that scene, size and ``--set bounces=N`` (``--reference-samples`` each);
``--new-set`` adds settings to this tree's frames only (to time a cheaper setting against the old
defaults at equal error); then, per tree, the viewport's first-frame latencies (this tree's
tools/bench_viewport.py on each tree's add-on) and the 10k-instance export + upload against Cycles'
sync (tools/bench_export.py). The ``error`` part renders each scene twice per tree and once with
``--reference`` overrides in this tree (default ``visibility=exact``: the same VPLs with ray-traced
visibility) and prints each tree's relative RMSE against it and whether its two frames are bit-
identical. ``--set`` overrides apply to every frame. The older commit is checked out with ``git
worktree`` in a temporary folder (removed at the end); both trees run with this interpreter.

    .venv/bin/python tools/bench_versions.py --old babc501 [--scenes interior cornell_box]
        [--size 640x360] [--repeat 3] [--parts frame viewport export error]
        [--set NAME=VALUE] [--new-set NAME=VALUE] [--reference NAME=VALUE]
        [--reference-samples 128]
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

import numpy as np

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


def frame_timings(tree: Path, scene: str, size: str, out: Path,
                  overrides: tuple[str, ...] = ()) -> dict[str, float]:
    """Stage times of one CLI frame (seconds, from its ``stages:`` line) and its ``total``."""
    stdout = run(tree, "-m", "addon", "render", str(tree / "sample_scenes" / f"{scene}.blend"),
                 "-r", size, "-o", str(out), *(a for o in overrides for a in ("--set", o)))
    line = next(x for x in stdout.splitlines() if x.startswith("stages:"))
    ran = line.split("| ran:", 1)[1].split("|", 1)[0]
    timings = {name.strip(): int(ms) / 1000 for name, ms in STAGE.findall(ran)}
    timings["total"] = float(SAVED.search(stdout).group(1))
    return timings


def cycles_references(scene: str, size: str, overrides: tuple[str, ...], samples: int
                      ) -> tuple[np.ndarray, np.ndarray] | None:
    """The report's two cached Cycles references of this scene, size and ``bounces=N``
    override, or None (no bounces override, or not rendered yet: run the report once)."""
    sys.path.insert(0, str(REPO))
    import bpy

    from devtools.report import (
        DEFAULT_CACHE,
        REFERENCE_SEEDS,
        cycles_settings,
        file_digest,
        reference_key,
    )

    bounces = next((int(o.split("=", 1)[1]) for o in overrides if o.startswith("bounces=")),
                   None)
    if bounces is None:
        return None
    width, height = (int(v) for v in size.split("x"))
    digest = file_digest(REPO / "sample_scenes" / f"{scene}.blend")
    paths = [DEFAULT_CACHE / (reference_key(digest, (width, height),
                                            cycles_settings(samples, bounces, seed),
                                            bpy.app.version_string) + ".npy")
             for seed in REFERENCE_SEEDS]
    return tuple(np.load(p) for p in paths) if all(p.is_file() for p in paths) else None


def frame_table(trees: dict[str, Path], scene: str, size: str, repeat: int,
                overrides: tuple[str, ...] = (), new_overrides: tuple[str, ...] = (),
                reference_samples: int = 128) -> None:
    samples: dict[str, list[dict[str, float]]] = {label: [] for label in trees}
    settings = {label: overrides + (new_overrides if tree == REPO else ())
                for label, tree in trees.items()}
    errors: dict[str, float] = {}
    references = cycles_references(scene, size, overrides, reference_samples)
    with tempfile.TemporaryDirectory() as folder:
        for i in range(repeat):
            for k, (label, tree) in enumerate(trees.items()):  # alternating: load drifts hit
                out = Path(folder) / f"{k}_{i}.exr"  # both alike
                samples[label].append(frame_timings(tree, scene, size, out, settings[label]))
                if references is not None and label not in errors:
                    from devtools.report import error_metrics, read_exr
                    errors[label] = error_metrics(read_exr(out), *references)[
                        "relative_rmse_unbiased"]
    stages = list(dict.fromkeys(s for label in trees for t in samples[label] for s in t))
    stages.remove("total")
    print(f"\n{scene}, {size}, {' '.join(overrides) or 'defaults'}"
          f"{'; this tree also ' + ' '.join(new_overrides) if new_overrides else ''}: median of "
          f"{repeat} command-line frames per tree (seconds; each frame its own process)")
    print("| stage | " + " | ".join(trees) + " | new / old |")
    print("|---|" + "---|" * (len(trees) + 1))
    for stage in [*stages, "total"]:
        ran = [[t[stage] for t in samples[label] if stage in t] for label in trees]
        medians = [statistics.median(times) if times else None for times in ran]
        # a ratio only where both trees ran the stage for at least a millisecond (the stages:
        # line rounds to ms); "–": the tree did not run it; "< 0.001": it ran in under 1 ms
        ratio = f"{medians[1] / medians[0]:.2f}" if all(medians) else "–"
        cells = " | ".join("–" if m is None else f"{m:.3f}" if m else "< 0.001"
                           for m in medians)
        print(f"| {'**total**' if stage == 'total' else stage} | {cells} | {ratio} |")
    if errors:
        print("| error against Cycles (noise-free relative RMSE, 2 × "
              f"{reference_samples} samples) | "
              + " | ".join(f"{errors[label]:.1%}" for label in trees) + " | |")
    else:
        print(f"(no error against Cycles: run `python -m devtools report "
              f"sample_scenes/{scene}.blend -r {size} --set bounces=N --reference-samples "
              f"{reference_samples}` once and pass the same --set bounces=N here)")


def error_table(trees: dict[str, Path], scene: str, size: str, overrides: tuple[str, ...],
                reference: tuple[str, ...]) -> None:
    sys.path.insert(0, str(REPO))
    from devtools.metrics import relative_rmse
    from devtools.report import read_exr

    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        for i in range(2):
            for k, tree in enumerate(trees.values()):
                frame_timings(tree, scene, size, out / f"{k}_{i}.exr", overrides)
        frame_timings(REPO, scene, size, out / "reference.exr", (*overrides, *reference))
        exact = read_exr(out / "reference.exr")
        print(f"\n{scene}, {size}, {' '.join(overrides) or 'defaults'}: relative RMSE against "
              f"{' '.join(reference)} (this tree), and whether two processes' frames are "
              "bit-identical")
        print("| tree | relative RMSE | identical |")
        print("|---|---|---|")
        for k, label in enumerate(trees):
            first, second = (read_exr(out / f"{k}_{i}.exr") for i in range(2))
            print(f"| {label} | {relative_rmse(first, exact):.4f} | "
                  f"{'yes' if np.array_equal(first, second) else 'no'} |")


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
    """Each tree's tools/bench_export.py row of the 10k instances, its columns found by the
    header's names (trees before the BVH column lack it: '–')."""
    print("\n10k instances (geometry nodes): export + upload against Cycles' sync, seconds")
    print("| tree | ours | our BVH | Cycles | ours / Cycles | (ours + BVH) / Cycles |")
    print("|---|---|---|---|---|---|")
    for label, tree in trees.items():
        lines = run(tree, "tools/bench_export.py", "--scenes", "inst10k", "--repeat",
                    str(repeat)).splitlines()
        names = next(x for x in lines if x.split()[:1] == ["scene"]).split()
        fields = next(x for x in lines if x.strip().startswith("inst10k")).split()
        column = {name: fields[k] for k, name in enumerate(names) if k < len(fields)}
        print(f"| {label} | " + " | ".join(column.get(name, "–") for name in
                                           ("ours", "BVH", "Cycles", "ratio", "+BVH")) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", required=True, help="the older commit (any git revision)")
    parser.add_argument("--scenes", nargs="+", default=["interior", "cornell_box"])
    parser.add_argument("--size", default="640x360", help="frame size, WIDTHxHEIGHT")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--parts", nargs="+", default=["frame", "viewport", "export"],
                        choices=["frame", "viewport", "export", "error"])
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a setting for every frame of the frame and error parts")
    parser.add_argument("--new-set", action="append", default=[], metavar="NAME=VALUE",
                        help="a setting for this tree's frames only (frame part)")
    parser.add_argument("--reference-samples", type=int, default=128,
                        help="samples of each cached Cycles reference the frame part uses")
    parser.add_argument("--reference", action="append", metavar="NAME=VALUE",
                        help="settings of the error part's reference (visibility=exact)")
    args = parser.parse_args()
    overrides, reference = tuple(args.set), tuple(args.reference or ["visibility=exact"])
    with old_tree(args.old) as old:
        trees = {f"old ({args.old})": old, "new (this tree)": REPO}
        if "frame" in args.parts:
            for scene in args.scenes:
                frame_table(trees, scene, args.size, args.repeat, overrides,
                            tuple(args.new_set), args.reference_samples)
        if "viewport" in args.parts:
            viewport_table(trees, args.scenes, int(args.size.split("x")[0]))
        if "export" in args.parts:
            export_table(trees, args.repeat)
        if "error" in args.parts:
            for scene in args.scenes:
                error_table(trees, scene, args.size, overrides, reference)


if __name__ == "__main__":
    main()
