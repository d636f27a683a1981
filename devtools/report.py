"""Error against render time, VPL GI compared with Cycles (``python -m devtools report``).

One scene, one process, one resolution: Cycles (CPU, diffuse bounces only) at a ladder of sample
counts, VPL GI at a ladder of light-path counts per mode (visibility, clamping), and two
independently seeded converged Cycles references r1, r2, cached on disk. Every image's error is
measured against r = (r1 + r2) / 2, and written to ``report.json`` and ``error_vs_time.png``.
:func:`run` expects the add-on to be registered.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import suppress
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from typing import BinaryIO

import bpy
import numpy as np
from matplotlib.figure import Figure

from addon import ENGINE_ID
from addon.core.gpu.gl import GLUnavailableError, shared_context
from addon.engine import monitor

from . import metrics
from .obj_scene import scene_from_obj

DEFAULT_CACHE = Path(__file__).resolve().parents[1] / ".cache" / "references"
REFERENCE_SEEDS = (1, 2)
LADDER_SEED = 100
"""Cycles ladder renders use seeds LADDER_SEED + i, independent of the references'."""
TIMING = ("wall-clock seconds of bpy.ops.render.render(), scene export included (Cycles: sync "
          "and BVH build), writing and reading the image excluded; after one untimed warm-up "
          "render per engine and VPL GI mode (GL context, shader compilation, Cycles kernels)")
METRICS = {
    "relative_rmse_unbiased": "sqrt(max(0, mean((x - r1)(x - r2)))) / mean(r): relative RMSE "
                              "against the converged image, free of the references' noise",
    "relative_rmse": "RMSE(x, r) / mean(r)",
    "rmse": "RMSE(x, r) over pixels and RGB",
    "relative_mse": "mean((x - r)² / (r² + 0.01))",
    "mean_relative_energy": "(sum x - sum r) / sum r",
    "unbiased_squared_error": "mean((x - r1)(x - r2)), may be negative",
}


class ReportError(Exception):
    """The scene cannot be reported on (unreadable, no camera, reference failed): one line."""


class ReportCancelled(Exception):
    """Ctrl-C (``monitor.cancel_requested``) stopped the report after a render."""


class RenderFailed(Exception):
    """One render failed; the message is the engine's."""


@dataclass(frozen=True)
class VPLMode:
    """VPL GI settings held fixed along one line of the plot while vpl_count grows."""

    visibility: str
    clamp_distance: float
    interleave: str = "1"  # the enum property's value: "1" (off), "2", "4", "8"

    @property
    def label(self) -> str:
        pattern = "" if self.interleave == "1" else f", interleave {self.interleave}×"
        return f"VPL GI {self.visibility}, clamp {self.clamp_distance:g}{pattern}"


@dataclass(frozen=True)
class Ladder:
    """What one report renders besides the references."""

    cycles_samples: tuple[int, ...]
    vpl_counts: tuple[int, ...]
    vpl_modes: tuple[VPLMode, ...]
    auto_budgets: tuple[float, ...] = ()  # seconds per frame for the automatic mode 'time'


_ISM_MODES = (VPLMode("ism", 0.05, "4"), VPLMode("ism", 0.05), VPLMode("exact", 0.05))
_ALL_MODES = (*_ISM_MODES, VPLMode("classic", 0.05), VPLMode("exact", 0.0))
LADDERS = {
    "quick": Ladder((4, 16, 64, 256), (16, 64, 256, 1024), _ALL_MODES),
    "full": Ladder((4, 16, 64, 256, 1024, 4096), (16, 64, 256, 1024, 4096), _ALL_MODES),
    "ism": Ladder((4, 16, 64, 256), (64, 256, 1024, 4096), _ISM_MODES),
    "large": Ladder((4, 16, 64, 256), (1024, 4096, 16384), (VPLMode("ism", 0.05, "4"),)),
    "test": Ladder((4, 64), (16, 256), (VPLMode("classic", 0.05),), (0.5,)),
    "auto": Ladder((4, 16, 64, 256), (16, 64, 256, 1024), _ISM_MODES[:2], (1, 2, 4, 8, 16)),
}
AUTO_LINE = "VPL GI automatic (time budget)"


def cycles_settings(samples: int, bounces: int, seed: int) -> dict[str, object]:
    """Cycles set up like VPL GI: CPU, diffuse bounces only, no denoiser, adaptive sampling,
    clamping or light-sampling cut-off, a one-pixel box filter."""
    return {
        "device": "CPU", "samples": samples, "seed": seed,
        "max_bounces": bounces, "diffuse_bounces": bounces, "glossy_bounces": 0,
        "transmission_bounces": 0, "volume_bounces": 0, "transparent_max_bounces": 0,
        "use_denoising": False, "use_adaptive_sampling": False,
        "sample_clamp_direct": 0.0, "sample_clamp_indirect": 0.0,
        "light_sampling_threshold": 0.0, "pixel_filter_type": "BOX", "filter_width": 1.0,
    }


def open_scene(path: Path, size: int) -> bpy.types.Scene:
    """Open ``path`` (a .blend, or an .obj asset made into a scene by obj_scene.py) at size ×
    size pixels, set up to render the Combined pass to a 32-bit EXR."""
    try:
        if path.suffix.lower() == ".obj":
            scene_from_obj(path)
        else:
            bpy.ops.wm.open_mainfile(filepath=str(path.resolve()), load_ui=False)
    except (RuntimeError, ValueError) as exc:
        raise ReportError(f"cannot open {path}: {str(exc).strip()}") from None
    scene = bpy.context.scene
    if scene.camera is None:
        raise ReportError(f"scene '{scene.name}' in {path} has no active camera")
    render = scene.render
    render.resolution_x = render.resolution_y = size
    render.resolution_percentage = 100
    render.use_compositing = render.use_sequencer = False
    render.threads_mode = "AUTO"
    render.image_settings.file_format = "OPEN_EXR"
    render.image_settings.color_depth = "32"
    return scene


def read_exr(path: Path) -> np.ndarray:
    """The linear RGB of an EXR as (height, width, 3) float32, rows bottom-up."""
    image = bpy.data.images.load(str(path))
    try:
        width, height = image.size
        pixels = np.empty(width * height * image.channels, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        return pixels.reshape(height, width, image.channels)[..., :3].copy()
    finally:
        bpy.data.images.remove(image)


def render_timed(scene: bpy.types.Scene, exr: Path) -> tuple[np.ndarray, float]:
    """Render the current frame with the scene's engine: (linear RGB, wall-clock seconds)."""
    monitor.last_error = None
    start = time.perf_counter()
    try:
        bpy.ops.render.render()
    except RuntimeError as exc:  # Blender's refusal or the engine's reported error
        monitor.last_error = monitor.last_error or str(exc).strip()
    seconds = time.perf_counter() - start
    if monitor.last_error:
        raise RenderFailed(monitor.last_error)
    if monitor.cancel_requested and scene.render.engine == ENGINE_ID:
        raise ReportCancelled  # stopped part-way; Cycles cannot be, so its image is whole
    bpy.data.images["Render Result"].save_render(filepath=str(exr), scene=scene)
    return read_exr(exr), seconds


def stop_if_cancelled() -> None:
    """Raise ReportCancelled after Ctrl-C (a finished reference is cached by then)."""
    if monitor.cancel_requested:
        raise ReportCancelled


def render_cycles(scene: bpy.types.Scene, settings: dict[str, object], exr: Path
                  ) -> tuple[np.ndarray, float]:
    scene.render.engine = "CYCLES"
    for name, value in settings.items():
        setattr(scene.cycles, name, value)
    return render_timed(scene, exr)


def render_vpl(scene: bpy.types.Scene, mode: VPLMode, vpl_count: int, exr: Path
               ) -> tuple[np.ndarray, float]:
    scene.render.engine = ENGINE_ID
    for name, value in {**asdict(mode), "vpl_count": vpl_count, "auto_parameters": "off"
                        }.items():
        setattr(scene.vpl_gi, name, value)
    return render_timed(scene, exr)


def render_auto(scene: bpy.types.Scene, budget: float, exr: Path) -> tuple[np.ndarray, float]:
    """VPL GI in the automatic mode 'time' with ``budget`` seconds per frame."""
    scene.render.engine = ENGINE_ID
    scene.vpl_gi.auto_parameters, scene.vpl_gi.time_budget = "time", budget
    try:
        return render_timed(scene, exr)
    finally:
        scene.vpl_gi.auto_parameters = "off"


def file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def reference_key(blend_digest: str, size: int, settings: dict[str, object]) -> str:
    """Cache key: the .blend's bytes, resolution, Cycles settings (samples, bounces, seed, ...)
    and Blender's version."""
    text = json.dumps({"blend": blend_digest, "size": size, "cycles": settings,
                       "blender": bpy.app.version_string}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def write_atomically(path: Path, write: Callable[[BinaryIO], object]) -> None:
    """Call ``write(file)`` on a temporary file, then move it to ``path`` (no half files)."""
    unfinished = path.with_name(path.name + ".partial")
    with unfinished.open("wb") as file:
        write(file)
    unfinished.replace(path)


def reference(scene: bpy.types.Scene, settings: dict[str, object], key: str, cache_dir: Path,
              exr: Path) -> tuple[np.ndarray, float, bool]:
    """A Cycles reference from the cache, or rendered and cached: (image, seconds, cached)."""
    image_path, meta_path = cache_dir / f"{key}.npy", cache_dir / f"{key}.json"
    what = f"{settings['samples']} samples, seed {settings['seed']}"
    if image_path.is_file() and meta_path.is_file():
        print(f"reference: cached ({what})", flush=True)
        return np.load(image_path), json.loads(meta_path.read_text())["seconds"], True
    print(f"rendering reference ({what})", flush=True)
    try:
        image, seconds = render_cycles(scene, settings, exr)
    except RenderFailed as exc:
        raise ReportError(f"the Cycles reference failed: {exc}") from None
    cache_dir.mkdir(parents=True, exist_ok=True)
    write_atomically(image_path, lambda file: np.save(file, image))
    meta = json.dumps({"seconds": seconds, "settings": settings}).encode()
    write_atomically(meta_path, lambda file: file.write(meta))
    return image, seconds, False


def error_metrics(image: np.ndarray, r1: np.ndarray, r2: np.ndarray) -> dict[str, float]:
    """Every metric of ``image`` against r = (r1 + r2) / 2 (see METRICS)."""
    r = (r1 + r2) / 2
    unbiased = metrics.unbiased_squared_error(image, r1, r2)
    return {
        "relative_rmse_unbiased": math.sqrt(max(0.0, unbiased)) / float(r.mean()),
        "relative_rmse": metrics.relative_rmse(image, r),
        "rmse": metrics.rmse(image, r),
        "relative_mse": metrics.relative_mse(image, r),
        "mean_relative_energy": metrics.mean_relative_energy(image, r),
        "unbiased_squared_error": unbiased,
    }


def warm_up(scene: bpy.types.Scene, ladder: Ladder, bounces: int, exr: Path) -> None:
    """One untimed render per engine and VPL GI mode, so one-off start-up costs are not timed;
    a failure here shows again (and is recorded) in the timed render."""
    print("warming up (untimed)", flush=True)
    render_cycles(scene, cycles_settings(1, bounces, LADDER_SEED), exr)
    for mode in ladder.vpl_modes:
        with suppress(RenderFailed):
            render_vpl(scene, mode, min(ladder.vpl_counts), exr)
    if ladder.auto_budgets:  # measures the cost model on the first run on a machine
        with suppress(RenderFailed):
            render_auto(scene, min(ladder.auto_budgets), exr)


Render = Callable[[], tuple[np.ndarray, float]]


def measure(render: Render, r1: np.ndarray, r2: np.ndarray) -> dict[str, object]:
    """Run ``render()`` -> (image, seconds) and return its seconds and metrics, or its error."""
    try:
        image, seconds = render()
    except RenderFailed as exc:
        return {"error": str(exc)}
    return {"seconds": seconds, "metrics": error_metrics(image, r1, r2)}


def progress_line(index: int, total: int, entry: dict[str, object]) -> str:
    head = f"[{index:>2}/{total}] {entry['line']}, {entry['value']} {entry['parameter']}"
    if "error" in entry:
        return f"{head}: failed: {entry['error']}"
    error = entry["metrics"]["relative_rmse_unbiased"]
    return f"{head}: {entry['seconds']:.2f} s, relative RMSE {error * 100:.2f} %"


def ladder_renders(scene: bpy.types.Scene, ladder: Ladder, bounces: int, exr: Path
                   ) -> Iterator[tuple[dict[str, object], Render]]:
    """(entry without results, render()) for every render of the ladder, in order."""
    for i, samples in enumerate(ladder.cycles_samples):
        settings = cycles_settings(samples, bounces, LADDER_SEED + i)
        entry = {"engine": "CYCLES", "line": "Cycles", "parameter": "samples", "value": samples,
                 "settings": settings}
        yield entry, partial(render_cycles, scene, settings, exr)
    for mode in ladder.vpl_modes:
        for count in ladder.vpl_counts:
            entry = {"engine": ENGINE_ID, "line": mode.label, "parameter": "light paths",
                     "value": count}
            yield entry, partial(render_vpl, scene, mode, count, exr)
    for budget in ladder.auto_budgets:
        entry = {"engine": ENGINE_ID, "line": AUTO_LINE, "parameter": "s budget",
                 "value": budget}
        yield entry, partial(render_auto, scene, budget, exr)


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def gl_renderer() -> str:
    try:
        return str(shared_context().info["GL_RENDERER"])
    except GLUnavailableError as exc:
        return f"unavailable: {exc}"


def machine_info(scene: bpy.types.Scene) -> dict[str, object]:
    return {"cpu": cpu_model(), "cpu_count": os.cpu_count(), "render_threads": scene.render.threads,
            "platform": platform.platform(), "gl_renderer": gl_renderer(),
            "blender": bpy.app.version_string}


def render_references(scene: bpy.types.Scene, blend_digest: str, samples: int, bounces: int,
                      cache_dir: Path, exr: Path) -> list[tuple[np.ndarray, float, bool]]:
    """The references r1, r2: (image, seconds, cached) per seed of REFERENCE_SEEDS."""
    references = []
    for seed in REFERENCE_SEEDS:
        settings = cycles_settings(samples, bounces, seed)
        key = reference_key(blend_digest, scene.render.resolution_x, settings)
        references.append(reference(scene, settings, key, cache_dir, exr))
        stop_if_cancelled()
    return references


def render_ladder(scene: bpy.types.Scene, ladder: Ladder, bounces: int, r1: np.ndarray,
                  r2: np.ndarray, exr: Path) -> list[dict[str, object]]:
    """One entry per ladder render: engine, settings, seconds and metrics (or error)."""
    entries = []
    total = (len(ladder.cycles_samples) + len(ladder.vpl_counts) * len(ladder.vpl_modes)
             + len(ladder.auto_budgets))
    for index, (entry, render) in enumerate(ladder_renders(scene, ladder, bounces, exr), 1):
        entry.update(measure(render, r1, r2))
        stop_if_cancelled()
        stats = monitor.last_stats if entry["engine"] == ENGINE_ID else None
        if stats is not None:
            entry["stages"] = {"ran": stats.timings, "skipped": stats.skipped}
        if entry["line"] == AUTO_LINE and stats is not None:
            entry["chosen"] = [n for n in stats.notes if n.startswith("automatic parameters")]
        elif entry["engine"] == ENGINE_ID:
            entry["settings"] = asdict(scene.vpl_gi.to_settings())
        entries.append(entry)
        print(progress_line(index, total, entry), flush=True)
    return entries


def reference_summary(references: list[tuple[np.ndarray, float, bool]], samples: int,
                      cache_dir: Path) -> dict[str, object]:
    (r1, *_), (r2, *_) = references
    mean = float(((r1 + r2) / 2).mean())
    return {
        "engine": "CYCLES", "samples": samples, "seeds": list(REFERENCE_SEEDS),
        "seconds": [seconds for _, seconds, _ in references],
        "cached": [cached for *_, cached in references], "cache_dir": str(cache_dir),
        "mean": mean,
        "relative_noise": metrics.reference_noise(r1, r2) / math.sqrt(2) / mean,
        "relative_noise_meaning": "RMS noise of (r1 + r2) / 2 relative to its mean",
    }


def run(scene_path: Path, out_dir: Path, ladder: Ladder, size: int = 128,
        reference_samples: int = 4096, cache_dir: Path = DEFAULT_CACHE) -> dict[str, object]:
    """Render the report of ``scene_path``, write ``out_dir``/report.json and
    error_vs_time.png, and return the report. Raises ReportError or ReportCancelled."""
    scene = open_scene(scene_path, size)
    bounces = scene.vpl_gi.bounces
    blend_digest = file_digest(scene_path)
    with tempfile.TemporaryDirectory(prefix="vpl_gi_report_") as tmp:
        exr = Path(tmp) / "render.exr"
        warm_up(scene, ladder, bounces, exr)
        references = render_references(scene, blend_digest, reference_samples, bounces,
                                       cache_dir, exr)
        (r1, *_), (r2, *_) = references
        entries = render_ladder(scene, ladder, bounces, r1, r2, exr)
    report = {
        "scene": str(scene_path), "scene_sha256": blend_digest, "size": [size, size],
        "bounces": bounces, "ladder": asdict(ladder), "machine": machine_info(scene),
        "timing": TIMING, "metrics": METRICS,
        "reference": reference_summary(references, reference_samples, cache_dir),
        "renders": entries, "automatic": pareto_gaps(entries),
    }
    write_outputs(report, out_dir)
    return report


def pareto_gaps(renders: list[dict]) -> list[dict[str, float]]:
    """Each automatic render against the measured front of VPL GI's ladder lines: the least
    error any ladder render reached in no more time, and the least time any ladder render
    needed for no more error (None where no ladder render qualifies)."""
    ladder = [e for e in renders if "metrics" in e and e["engine"] == ENGINE_ID
              and e["line"] != AUTO_LINE]
    gaps = []
    for auto in (e for e in renders if "metrics" in e and e["line"] == AUTO_LINE):
        error = auto["metrics"]["relative_rmse_unbiased"]
        faster = [e["metrics"]["relative_rmse_unbiased"] for e in ladder
                  if e["seconds"] <= auto["seconds"]]
        better = [e["seconds"] for e in ladder
                  if e["metrics"]["relative_rmse_unbiased"] <= error]
        gaps.append({"budget": auto["value"], "seconds": auto["seconds"], "error": error,
                     "front_error_in_time": min(faster) if faster else None,
                     "front_time_for_error": min(better) if better else None})
    return gaps


def write_outputs(report: dict[str, object], out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    plot(report, out_dir / "error_vs_time.png")


def lines(renders: list[dict]) -> dict[str, list[dict]]:
    """Successful renders grouped by plot line, in ladder order."""
    grouped: dict[str, list[dict]] = {}
    for entry in renders:
        if "metrics" in entry:
            grouped.setdefault(entry["line"], []).append(entry)
    return grouped


def plot(report: dict, path: Path) -> None:
    """Noise-free relative RMSE against seconds, log-log, one line per engine/mode."""
    figure = Figure(figsize=(8, 6), dpi=110, layout="constrained")
    axes = figure.add_subplot()
    for line, entries in lines(report["renders"]).items():
        points = [(e["seconds"], e["metrics"]["relative_rmse_unbiased"], e["value"])
                  for e in entries if e["metrics"]["relative_rmse_unbiased"] > 0]
        if not points:
            continue
        x, y, _ = zip(*points, strict=True)
        axes.plot(x, y, marker="o", label=line)
        for xi, yi, label in points:
            axes.annotate(str(label), (xi, yi), textcoords="offset points", xytext=(4, 4),
                          fontsize=8)
    noise = report["reference"]["relative_noise"]
    if noise > 0:
        axes.axhline(noise, color="grey", linestyle=":", label="reference's own noise")
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.set_xlabel("render time (s, wall clock, export included)")
    axes.set_ylabel("relative RMSE (noise-free estimate)")
    width, height = report["size"]
    axes.set_title(f"{Path(report['scene']).name}, {width}×{height}, {report['bounces']} "
                   f"bounces; labels: Cycles samples, VPL GI light paths", fontsize=10)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=8)
    figure.savefig(path)


def format_table(report: dict) -> str:
    """The report as a text table: one row per render, then the reference."""
    rows = [f"{'engine / mode':<26} {'setting':>17} {'time (s)':>9} {'relRMSE*':>9} "
            f"{'relRMSE':>8} {'relMSE':>9} {'energy':>8}"]
    for e in report["renders"]:
        head = f"{e['line']:<26} {e['value']:>6} {e['parameter']:<10}"
        if "error" in e:
            rows.append(f"{head} failed: {e['error']}")
            continue
        m = e["metrics"]
        rows.append(f"{head} {e['seconds']:>9.2f} {m['relative_rmse_unbiased'] * 100:>8.2f}% "
                    f"{m['relative_rmse'] * 100:>7.2f}% {m['relative_mse']:>9.2e} "
                    f"{m['mean_relative_energy'] * 100:>+7.2f}%")
    for gap in report.get("automatic", []):
        front = gap["front_error_in_time"]
        quickest = gap["front_time_for_error"]
        rows.append(f"automatic, {gap['budget']:g} s budget: {gap['seconds']:.2f} s, "
                    f"{gap['error'] * 100:.2f} %; the ladder's best in that time: "
                    + (f"{front * 100:.2f} %" if front is not None else "none that fast")
                    + "; its quickest to that error: "
                    + (f"{quickest:.2f} s" if quickest is not None else "none that good"))
    ref = report["reference"]
    seconds = " + ".join(f"{s:.1f}" for s in ref["seconds"])
    rows.append(f"* noise-free estimate. Reference: Cycles {ref['samples']} samples × 2 (seeds "
                f"{', '.join(map(str, ref['seeds']))}), {seconds} s"
                f"{' (cached)' if all(ref['cached']) else ''}, own noise "
                f"{ref['relative_noise'] * 100:.3f} % of its mean")
    return "\n".join(rows)
