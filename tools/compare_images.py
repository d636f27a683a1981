"""Prove that a change leaves every image bit-identical: render with a base commit and a head
(a working tree, by default this one, or a commit), each with its own code, and compare every
float pass of every render.

Cases: each sample scene (``sample_scenes/*.blend``, through ``python -m addon render`` with
every optional pass on: the core's passes and the EXR the command line writes) and each test of
the stability suite (``tests/stability``: every frame a test renders). Each tree renders in a
subprocess with cwd and PYTHONPATH set to it, through tools/compare_runner.py (taken from this
script's folder, so the base commit needs none), which finds the tree's Renderer wherever the
tree defines it. A commit is checked out in a temporary git worktree under /tmp (removed
afterwards); a commit's renders are kept in the cache, so later runs render only the head.

    .venv/bin/python tools/compare_images.py [--base REF] [--cache /work/compare-cache] \\
        [--head PATH_OR_REF] [--size 64] [--only 'scene:*'] [--allow CASE] [--out DIR]

Exit code 0 if every case is identical (or allowed), 1 if one differs or is missing, 2 if a
render crashed or the arguments are wrong.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

TOOLS = Path(__file__).resolve().parent
RUNNER = TOOLS / "compare_runner.py"
sys.path.insert(0, str(TOOLS))

from compare_runner import case_file, matches  # noqa: E402

BEFORE_RESTRUCTURING = "ecface338976fb9ad98373e72359b64a08940d81"  # main when this was written
STABILITY_CODES = (0, 1, 5)  # pytest: all passed, some failed, none collected


class CompareError(Exception):
    """A problem that stops the comparison; printed as one line, exit code 2."""


def git(repo: Path, *args: str) -> str:
    """git's output, or CompareError with its message."""
    result = subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True)
    if result.returncode:
        raise CompareError(f"git {' '.join(args)}: {result.stderr.strip()}")
    return result.stdout.strip()


def resolve_commit(repo: Path, ref: str) -> str:
    """The full hash of the commit ``ref`` names."""
    return git(repo, "rev-parse", "--verify", f"{ref}^{{commit}}")


@dataclass
class Side:
    """One tree to render with: a commit (checked out on demand, renders cached) or a folder."""

    label: str
    repo: Path
    commit: str | None
    path: Path | None
    out: Path
    scratch: Path
    seconds: float = 0.0
    rendered: list[str] = field(default_factory=list)

    def tree(self) -> Path:
        """The source tree, checked out into a temporary worktree on first use."""
        if self.path is None:
            self.path = self.scratch / f"vpl_gi_{self.label}"  # a valid package name
            print(f"[{self.label}] checking out {self.commit[:12]} into {self.path}", flush=True)
            git(self.repo, "worktree", "add", "--detach", str(self.path), self.commit)
        return self.path

    def scene_names(self) -> list[str]:
        """``scene:STEM`` of every sample_scenes/*.blend (a commit's: read without checkout)."""
        if self.commit is not None:
            listed = git(self.repo, "ls-tree", "--name-only", self.commit, "sample_scenes/")
            files = [Path(line) for line in listed.splitlines()]
        else:
            files = list((self.path / "sample_scenes").iterdir())
        return sorted(f"scene:{f.stem}" for f in files if f.suffix == ".blend")

    def run(self, args: list[str], log: Path) -> int:
        """Run the runner in this tree; its output goes to ``log``."""
        tree = self.tree()
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(
            [str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]),
            "PYTHONDONTWRITEBYTECODE": "1"}
        start = time.perf_counter()
        with log.open("w", encoding="utf-8") as stream:
            code = subprocess.run([sys.executable, str(RUNNER), *args], cwd=tree, env=env,
                                  stdout=stream, stderr=subprocess.STDOUT).returncode
        self.seconds += time.perf_counter() - start
        return code

    def render_scenes(self, names: list[str], size: int | None) -> None:
        folder = self.out / ("scenes" if size is None else f"scenes-{size}")
        folder.mkdir(parents=True, exist_ok=True)
        for name in names:
            target = folder / case_file(name)
            if target.exists() and self.commit is not None:
                continue
            print(f"[{self.label}] rendering {name}", flush=True)
            blend = self.tree() / "sample_scenes" / f"{name.removeprefix('scene:')}.blend"
            log = target.with_suffix(".log")
            code = self.run(["scene", str(blend), str(target),
                             *([] if size is None else ["--size", str(size)])], log)
            if code or not target.exists():
                raise CompareError(f"[{self.label}] {name}: the runner failed (exit code "
                                   f"{code}); see {log}")
            self.rendered.append(name)

    def scene_file(self, name: str, size: int | None) -> Path:
        """Where the renders of the scene case ``name`` at ``size`` are kept."""
        return self.out / ("scenes" if size is None else f"scenes-{size}") / case_file(name)

    def stability_names(self, only: list[str] | None) -> list[str]:
        """Render the stability cases matching ``only`` that are not on disk yet; return the
        names of all matching cases. Only a commit's renders are reused."""
        folder = self.out / "stability"
        folder.mkdir(parents=True, exist_ok=True)
        index = folder / "index.json"
        if self.commit is None:
            index.unlink(missing_ok=True)
        if index.exists():
            wanted = [n for n in json.loads(index.read_text(encoding="utf-8"))
                      if matches(n, only)]
            if all((folder / case_file(n)).exists() for n in wanted):
                return wanted
        done = [n for n in (json.loads(index.read_text(encoding="utf-8"))
                            if index.exists() else []) if (folder / case_file(n)).exists()]
        skip = folder / "skip.json"
        skip.write_text(json.dumps(done), encoding="utf-8")
        print(f"[{self.label}] running the stability suite", flush=True)
        log = folder / "stability.log"
        code = self.run(["stability", str(folder), "--skip", str(skip),
                         *[a for p in only or [] for a in ("--only", p)]], log)
        if code not in STABILITY_CODES or not index.exists():
            raise CompareError(f"[{self.label}] the stability suite did not run (exit code "
                               f"{code}); see {log}")
        wanted = [n for n in json.loads(index.read_text(encoding="utf-8")) if matches(n, only)]
        self.rendered += [n for n in wanted if n not in done]
        return wanted

    def close(self) -> None:
        """Remove the temporary worktree, if one was made."""
        if self.commit is not None and self.path is not None:
            git(self.repo, "worktree", "remove", "--force", str(self.path))


@dataclass
class Difference:
    """How one case's renders differ between base and head."""

    max_abs: float = 0.0
    pixels: int = 0
    total: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        return self.pixels == 0 and not self.notes


def compare_arrays(key: str, a: np.ndarray, b: np.ndarray, result: Difference) -> None:
    """Bitwise comparison of one pass; a pixel differs if any of its channels' bits differ."""
    if a.dtype.kind not in "fiub" or b.dtype.kind not in "fiub":  # error messages
        if str(a) != str(b):
            result.notes.append(f"{key}: '{a}' vs '{b}'")
        return
    if a.shape != b.shape or a.dtype != b.dtype:
        result.notes.append(f"{key}: {a.dtype}{a.shape} vs {b.dtype}{b.shape}")
        return
    pixel_shape = a.shape[:-1] if a.ndim == 3 else a.shape
    differs = np.frombuffer(a.tobytes(), np.uint8).reshape(*a.shape, -1) != \
        np.frombuffer(b.tobytes(), np.uint8).reshape(*b.shape, -1)
    differs = differs.reshape(*pixel_shape, -1).any(axis=-1)
    count = int(differs.sum())
    result.total += differs.size
    if count:
        with np.errstate(invalid="ignore", over="ignore"):
            delta = np.abs(a.astype(np.float64) - b.astype(np.float64))
        finite = delta[np.isfinite(delta)]
        worst = float(finite.max()) if finite.size else float("nan")
        result.max_abs = max(result.max_abs, worst)
        result.pixels += count
        result.notes.append(f"{key}: max |diff| {worst:.3g}, {count} of {differs.size} pixels")


def compare_case(base: Path, head: Path) -> tuple[Difference, float, float, str]:
    """Difference of two case files; their render seconds and the head's test outcome."""
    result = Difference()
    with np.load(base) as a, np.load(head) as b:
        for key in sorted(set(a.files) | set(b.files)):
            if key.startswith("meta/"):
                continue
            if key not in a.files or key not in b.files:
                result.notes.append(f"{key}: only in {'base' if key in a.files else 'head'}")
                continue
            compare_arrays(key, a[key], b[key], result)
        times = float(a["meta/seconds"]), float(b["meta/seconds"])
        outcome = str(b["meta/outcome"])
    return result, *times, outcome


def make_side(label: str, spec: str | None, repo: Path, cache: Path, scratch: Path) -> Side:
    """A side from a ref (rendered into the cache) or a folder (rendered into scratch)."""
    if spec is not None and not Path(spec).is_dir():
        commit = resolve_commit(repo, spec)
        return Side(label, repo, commit, None, cache / commit, scratch)
    return Side(label, repo, None, Path(spec or repo).resolve(), scratch / label, scratch)


def report(args: argparse.Namespace, base: Side, head: Side, names: list[str],
           files: dict[str, tuple[Path, Path]]) -> int:
    """Print the table and each differing case's passes; return the exit code."""
    print(f"\n{'result':<17} {'max|diff|':>9} {'pixels':>15} {'base s':>7} {'head s':>7}  case")
    failed = []
    for name in names:
        pair = files.get(name)
        if pair is None or not pair[0].exists() or not pair[1].exists():
            side = "base" if pair is None or not pair[0].exists() else "head"
            print(f"{'MISSING in ' + side:<17} {'':>9} {'':>15} {'':>7} {'':>7}  {name}")
            failed.append(name)
            continue
        diff, base_s, head_s, outcome = compare_case(*pair)
        allowed = matches(name, args.allow) if args.allow else False
        verdict = "identical" if diff.identical else ("differs (allowed)" if allowed
                                                      else "DIFFERS")
        test = "" if outcome == "passed" else f" [head test: {outcome}]"
        print(f"{verdict:<17} {diff.max_abs:>9.3g} {f'{diff.pixels}/{diff.total}':>15} "
              f"{base_s:>7.1f} {head_s:>7.1f}  {name}{test}")
        for note in diff.notes[:12]:
            print(f"    {note}")
        if not diff.identical and not allowed:
            failed.append(name)
    print(f"\nbase {base.commit[:12]}: rendered {len(base.rendered)} cases in "
          f"{base.seconds:.0f} s ({len(names) - len(base.rendered)} from {base.out}); "
          f"head {head.path or head.commit}: rendered {len(head.rendered)} cases in "
          f"{head.seconds:.0f} s")
    if failed:
        print(f"NOT IDENTICAL: {len(failed)} of {len(names)} cases: {', '.join(failed)}")
        return 1
    print(f"IDENTICAL: all {len(names)} cases")
    return 0


def compare(args: argparse.Namespace) -> int:
    repo = Path(git(Path.cwd(), "rev-parse", "--show-toplevel"))
    scratch = Path(tempfile.mkdtemp(prefix="vpl_gi_compare_"))
    cache = args.cache.resolve()
    base = make_side("base", args.base, repo, cache, scratch)
    head = make_side("head", args.head, repo, cache, scratch)
    if base.commit is None:
        raise CompareError(f"--base must name a commit, not a folder: {args.base}")
    if args.out and head.commit is None:
        head.out = args.out.resolve()
    print(f"base: {args.base} = {base.commit}\nhead: "
          f"{head.path if head.commit is None else f'{args.head} = {head.commit}'}\n"
          f"cache: {cache}", flush=True)
    start = time.perf_counter()
    try:
        scenes = [n for n in sorted(set(base.scene_names()) | set(head.scene_names()))
                  if matches(n, args.only)]
        for side in (base, head):
            side.render_scenes([n for n in scenes if n in side.scene_names()], args.size)
        files = {n: (base.scene_file(n, args.size), head.scene_file(n, args.size))
                 for n in scenes}
        stability: list[str] = []
        if not args.only or not all(p.startswith("scene:") for p in args.only):
            found = [side.stability_names(args.only) for side in (base, head)]
            stability = sorted(set(found[0]) | set(found[1]))
            files.update({n: (base.out / "stability" / case_file(n),
                              head.out / "stability" / case_file(n)) for n in stability})
        code = report(args, base, head, scenes + stability, files)
    finally:
        for side in (base, head):
            side.close()
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"total {time.perf_counter() - start:.0f} s")
    return code


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", default=BEFORE_RESTRUCTURING,
                        help="commit or branch to compare against (default: main before the "
                             "core's restructuring, %(default).12s)")
    parser.add_argument("--head", help="a source folder or a commit (default: this working "
                                       "tree)")
    parser.add_argument("--out", type=Path, help="keep the head's renders in this folder (a "
                                                 "folder head; a commit's go to the cache)")
    parser.add_argument("--cache", type=Path,
                        default=Path(__file__).resolve().parents[1] / ".cache" / "compare",
                        help="folder of commits' renders, one subfolder per commit (default: "
                             ".cache/compare in this repository)")
    parser.add_argument("--size", type=int, help="sample scenes: longest edge in pixels "
                                                 "(default: each scene's own resolution)")
    parser.add_argument("--only", action="append", help="cases whose name matches this glob "
                        "or contains it, e.g. 'scene:*', 'cornell', 'wedge' (repeatable)")
    parser.add_argument("--allow", action="append", help="a case (glob or substring) allowed "
                        "to differ: a fixed bug (repeatable)")
    args = parser.parse_args(argv)
    # on SIGTERM, still remove the temporary worktree (the cache keeps every finished case)
    signal.signal(signal.SIGTERM, lambda signum, _frame: sys.exit(128 + signum))
    try:
        return compare(args)
    except CompareError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
