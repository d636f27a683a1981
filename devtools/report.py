"""Error against render time, VPL GI compared with what users would pick instead
(``python -m devtools report``).

One scene, one process, one resolution (640×360 by default): Cycles (CPU, diffuse bounces only)
at a ladder of sample counts, raw and with OpenImageDenoise; VPL GI along lines that each vary
one setting (``vpl_count``, ``passes``, ...); and two independently seeded raw Cycles references
r1, r2, cached on disk. Every image's error is measured against r = (r1 + r2) / 2 (noise-free:
mean((x - r1)(x - r2))), each VPL GI render's time is compared with the time the Cycles curves
need for its error (report_tables.py), and all is written to ``report.json``, ``table.txt``,
``table.md`` and ``error_vs_time.png``. :func:`run` expects the add-on to be registered.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import tempfile
import time
from collections.abc import Callable
from contextlib import suppress
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import BinaryIO

import bpy
import numpy as np

from addon import ENGINE_ID
from addon.core.gpu.gl import GLUnavailableError, shared_context
from addon.core.scene.model import RENDERED_OBJECT_TYPES
from addon.core.settings import Value
from addon.engine import monitor, shared_renderer
from addon.export import export_material

from . import metrics
from . import report_tables as tables
from .obj_scene import scene_from_obj

DEFAULT_CACHE = Path(__file__).resolve().parents[1] / ".cache" / "references"
REFERENCE_SEEDS = (1, 2)
LADDER_SEED = 100
"""Cycles ladder renders use seeds LADDER_SEED + i, independent of the references'."""
TIMING = ("wall-clock seconds of bpy.ops.render.render(), scene export included (Cycles: sync "
          "and BVH build), writing and reading the image excluded; after one untimed warm-up "
          "render per engine and VPL GI mode (GL context, shader compilation, Cycles kernels); "
          "every VPL GI frame starts afresh, reusing nothing the warm-up or an earlier frame "
          "made (VPLs, shadow maps, BVH), as Cycles rebuilds its BVH")
METRICS = {
    "relative_rmse_unbiased": "sqrt(max(0, mean((x - r1)(x - r2)))) / mean(r): relative RMSE "
                              "against the converged image, free of the references' noise",
    "relative_rmse_unbiased_range": "relative_rmse_unbiased with the estimate moved by one "
                                    "standard deviation of the references' noise either way",
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
class VPLLine:
    """One VPL GI line of the plot: the setting ``parameter`` takes ``values`` in turn while
    ``fixed`` settings (name, value) hold, on top of the report's ``--set`` settings. ``name``
    labels the line (default: VPL GI and the fixed settings); lines need distinct labels."""

    parameter: str
    values: tuple[Value, ...]
    fixed: tuple[tuple[str, Value], ...] = ()
    name: str = ""

    @property
    def label(self) -> str:
        if self.name:
            return self.name
        held = ", ".join(f"{name}={value:g}" if isinstance(value, float) else f"{name}={value}"
                         for name, value in self.fixed)
        return f"VPL GI {held}" if held else "VPL GI"


@dataclass(frozen=True)
class Ladder:
    """What one report renders besides the references: raw Cycles and Cycles + OIDN at sample
    counts, VPL GI lines, and automatic-mode budgets."""

    cycles_samples: tuple[int, ...]
    vpl_lines: tuple[VPLLine, ...]
    oidn_samples: tuple[int, ...] = ()
    auto_budgets: tuple[float, ...] = ()  # seconds per frame for the automatic mode 'time'


def _mode(visibility: str, clamp: float, interleave: int = 1, counts: tuple[int, ...] = ()
          ) -> VPLLine:
    """A line of light-path counts in one visibility mode, clamp and interleaving."""
    name = f"VPL GI {visibility}, clamp {clamp:g}" + \
        (f", interleave {interleave}×" if interleave > 1 else "")
    return VPLLine("vpl_count", counts, (("visibility", visibility), ("clamp_distance", clamp),
                                         ("interleave", interleave)), name)


def _modes(counts: tuple[int, ...], *modes: tuple) -> tuple[VPLLine, ...]:
    return tuple(_mode(*mode, counts=counts) for mode in modes)


_ISM = (("ism", 0.05, 4), ("ism", 0.05), ("exact", 0.05))
_ALL = (*_ISM, ("classic", 0.05), ("exact", 0.0))
_QUICK = (16, 64, 256, 1024)
LADDERS = {
    "compare": Ladder((4, 16, 64), (VPLLine("vpl_count", (1024, 4096)),), (4, 16, 64)),
    "quick": Ladder((4, 16, 64, 256), _modes(_QUICK, *_ALL), (4, 16)),
    "full": Ladder((4, 16, 64, 256, 1024, 4096), _modes((16, 64, 256, 1024, 4096), *_ALL),
                   (4, 16, 64, 256)),
    "ism": Ladder((4, 16, 64, 256), _modes((64, 256, 1024, 4096), *_ISM), (4, 16, 64)),
    "large": Ladder((4, 16, 64, 256), _modes((1024, 4096, 16384), ("ism", 0.05, 4)),
                    (4, 16, 64)),
    "test": Ladder((4, 64), _modes((16, 256), ("classic", 0.05)), (4,), (0.5,)),
    "auto": Ladder((4, 16, 64, 256), _modes(_QUICK, *_ISM[:2]), (4, 16), (1, 2, 4, 8, 16)),
}
"""Preset ladders (``--ladder``); ``--cycles-samples``, ``--oidn-samples`` and ``--vpl-ladder``
replace their parts."""
AUTO_LINE = "VPL GI automatic (time budget)"
CYCLES_LINE, OIDN_LINE = tables.CYCLES_LINE, tables.OIDN_LINE
WARM_UP_PERCENTAGE = 25
"""Warm-up renders run at this share of the resolution: what they pay once (GL context,
shaders, Cycles kernels, the denoiser's kernels) does not depend on it."""


def cycles_settings(samples: int, bounces: int, seed: int, denoise: bool = False,
                    clear: bool = False) -> dict[str, object]:
    """Cycles set up like VPL GI: CPU, as many glossy as diffuse bounces (VPL GI's glossy lobes
    reflect its VPLs' light) without Filter Glossy (a bias of Cycles' own), no transmission,
    no adaptive sampling, clamping or light-sampling cut-off, a one-pixel box filter; no
    denoiser, or with ``denoise`` OpenImageDenoise with albedo and normal guides (Blender's
    defaults, as users render).
    With ``clear`` (a scene with clear or cutout materials, which VPL GI lets light through),
    Blender's default transparent (8) and transmission (12) bounces."""
    settings: dict[str, object] = {
        "device": "CPU", "samples": samples, "seed": seed,
        "max_bounces": bounces, "diffuse_bounces": bounces, "glossy_bounces": bounces,
        "blur_glossy": 0.0,
        "transmission_bounces": 0, "volume_bounces": 0, "transparent_max_bounces": 0,
        "use_denoising": False, "use_adaptive_sampling": False,
        "sample_clamp_direct": 0.0, "sample_clamp_indirect": 0.0,
        "light_sampling_threshold": 0.0, "pixel_filter_type": "BOX", "filter_width": 1.0,
    }
    if clear:
        settings.update(transparent_max_bounces=8, transmission_bounces=12)
    if denoise:
        settings.update(use_denoising=True, denoiser="OPENIMAGEDENOISE",
                        denoising_input_passes="RGB_ALBEDO_NORMAL",
                        denoising_prefilter="ACCURATE", denoising_quality="HIGH")
    return settings


OPTIONAL_CYCLES_SETTINGS = frozenset({"denoising_quality"})
"""Cycles settings that older Blender versions lack (left at their default there)."""


@dataclass(frozen=True)
class Options:
    """How to run one report: the image size, the ladder, VPL GI settings every VPL GI render
    gets (``--set``), and the references."""

    ladder: Ladder
    resolution: tuple[int, int] = (640, 360)
    overrides: dict[str, Value] = field(default_factory=dict)
    reference_samples: int = 256
    cache_dir: Path = DEFAULT_CACHE
    references_only: bool = False


def open_scene(path: Path, resolution: tuple[int, int]) -> bpy.types.Scene:
    """Open ``path`` (a .blend, or an .obj asset made into a scene by obj_scene.py) at
    ``resolution`` (width, height), set up to render the Combined pass to a 32-bit EXR."""
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
    render.resolution_x, render.resolution_y = resolution
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
        if name not in OPTIONAL_CYCLES_SETTINGS or hasattr(scene.cycles, name):
            setattr(scene.cycles, name, value)
    if settings.get("use_denoising"):  # the view layer's switch too (on by default)
        for view_layer in scene.view_layers:
            view_layer.cycles.use_denoising = True
    return render_timed(scene, exr)


def vpl_values(base: dict[str, Value], overrides: dict[str, Value], line: VPLLine | None = None,
               value: Value | None = None) -> dict[str, Value]:
    """The settings of one VPL GI render: the scene's (``base``), the automatic mode off, the
    report's ``--set`` settings, the line's fixed settings, then its parameter's value."""
    values = {**base, "auto_parameters": "off", **overrides}
    if line is not None:
        values.update(line.fixed)
        values[line.parameter] = value
    return values


def render_vpl(scene: bpy.types.Scene, values: dict[str, Value], exr: Path
               ) -> tuple[np.ndarray, float]:
    """A VPL GI frame started afresh, as a new process's or one after an edit: nothing is kept
    from an earlier render (VPLs, imperfect and triangle shadow maps, the ray tracer's BVH,
    the ISM point table); the GL context and compiled shaders stay, as Cycles' kernels do."""
    scene.render.engine = ENGINE_ID
    scene.vpl_gi.assign(values)
    shared_renderer().forget_frames()
    return render_timed(scene, exr)


def render_auto(scene: bpy.types.Scene, values: dict[str, Value], budget: float, exr: Path
                ) -> tuple[np.ndarray, float]:
    """VPL GI in the automatic mode 'time' with ``budget`` seconds per frame."""
    return render_vpl(scene, {**values, "auto_parameters": "time", "time_budget": budget}, exr)


def file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def reference_key(blend_digest: str, resolution: tuple[int, int], settings: dict[str, object],
                  blender_version: str) -> str:
    """Cache key: the scene file's bytes, resolution, Cycles settings (samples, seed, bounces,
    ...) and Blender's version."""
    text = json.dumps({"blend": blend_digest, "resolution": list(resolution), "cycles": settings,
                       "blender": blender_version}, sort_keys=True)
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
    meta = json.dumps({"seconds": seconds, "settings": settings,
                       "resolution": [scene.render.resolution_x, scene.render.resolution_y],
                       "blender": bpy.app.version_string}).encode()
    write_atomically(meta_path, lambda file: file.write(meta))
    return image, seconds, False


def error_metrics(image: np.ndarray, r1: np.ndarray, r2: np.ndarray) -> dict[str, float]:
    """Every metric of ``image`` against r = (r1 + r2) / 2 (see METRICS)."""
    r = (r1 + r2) / 2
    mean = float(r.mean())
    unbiased = metrics.unbiased_squared_error(image, r1, r2)
    spread = metrics.unbiased_squared_error_spread(image, r1, r2)
    return {
        "relative_rmse_unbiased": math.sqrt(max(0.0, unbiased)) / mean,
        "relative_rmse_unbiased_range": [math.sqrt(max(0.0, unbiased - spread)) / mean,
                                         math.sqrt(max(0.0, unbiased + spread)) / mean],
        "relative_rmse": metrics.relative_rmse(image, r),
        "rmse": metrics.rmse(image, r),
        "relative_mse": metrics.relative_mse(image, r),
        "mean_relative_energy": metrics.mean_relative_energy(image, r),
        "unbiased_squared_error": unbiased,
    }


@dataclass
class Job:
    """One ladder render: its report entry (without results) and how to render it."""

    entry: dict[str, object]
    render: Callable[[Path], tuple[np.ndarray, float]]
    warm_up: bool = False  # also rendered once, untimed and smaller, before any timed render


def ladder_jobs(scene: bpy.types.Scene, options: Options, bounces: int, clear: bool = False
                ) -> list[Job]:
    """Every render of the ladder, in order: raw Cycles, Cycles + OIDN, the VPL GI lines, the
    automatic mode. The first of each line is also its warm-up."""
    ladder, base = options.ladder, scene.vpl_gi.values()
    jobs = []
    for denoise, samples_list in ((False, ladder.cycles_samples), (True, ladder.oidn_samples)):
        for i, samples in enumerate(samples_list):
            settings = cycles_settings(samples, bounces, LADDER_SEED + i, denoise, clear)
            entry = {"engine": "CYCLES", "kind": "cycles_oidn" if denoise else "cycles",
                     "line": OIDN_LINE if denoise else CYCLES_LINE, "parameter": "samples",
                     "value": samples, "settings": settings}
            jobs.append(Job(entry, partial(render_cycles, scene, settings), i == 0))
    for line in ladder.vpl_lines:
        for i, value in enumerate(line.values):
            values = vpl_values(base, options.overrides, line, value)
            entry = {"engine": ENGINE_ID, "kind": "vpl", "line": line.label,
                     "parameter": line.parameter, "value": value}
            jobs.append(Job(entry, partial(render_vpl, scene, values), i == 0))
    for i, budget in enumerate(ladder.auto_budgets):
        values = vpl_values(base, options.overrides)
        entry = {"engine": ENGINE_ID, "kind": "auto", "line": AUTO_LINE, "parameter": "s budget",
                 "value": budget}
        # the warm-up measures the cost model on the first run on a machine
        jobs.append(Job(entry, partial(render_auto, scene, values, budget), i == 0))
    return jobs


def warm_up(scene: bpy.types.Scene, jobs: list[Job], exr: Path) -> None:
    """One untimed render per line at WARM_UP_PERCENTAGE of the size, so that one-off start-up
    costs are not timed; a failure here shows again (and is recorded) in the timed render."""
    print("warming up (untimed)", flush=True)
    scene.render.resolution_percentage = WARM_UP_PERCENTAGE
    try:
        for job in jobs:
            if job.warm_up:
                with suppress(RenderFailed):
                    job.render(exr)
                stop_if_cancelled()
    finally:
        scene.render.resolution_percentage = 100


def measure(job: Job, r1: np.ndarray, r2: np.ndarray, exr: Path) -> dict[str, object]:
    """Run the job's render and return its seconds and metrics, or its error."""
    try:
        image, seconds = job.render(exr)
    except RenderFailed as exc:
        return {"error": str(exc)}
    return {"seconds": seconds, "metrics": error_metrics(image, r1, r2)}


def progress_line(index: int, total: int, entry: dict[str, object]) -> str:
    head = f"[{index:>2}/{total}] {entry['line']}, {entry['parameter']} {entry['value']}"
    if "error" in entry:
        return f"{head}: failed: {entry['error']}"
    m = entry["metrics"]
    return (f"{head}: {entry['seconds']:.2f} s, relative RMSE "
            f"{m['relative_rmse_unbiased'] * 100:.2f} %, energy "
            f"{m['mean_relative_energy'] * 100:+.2f} %")


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
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {"cpu": cpu_model(), "cpu_count": os.cpu_count(), "render_threads": scene.render.threads,
            "platform": platform.platform(), "gl_renderer": gl_renderer(),
            "blender": bpy.app.version_string,
            "load_average_at_end": list(load) if load else None}


def render_references(scene: bpy.types.Scene, blend_digest: str, options: Options, bounces: int,
                      exr: Path, clear: bool = False) -> list[tuple[np.ndarray, float, bool]]:
    """The references r1, r2: (image, seconds, cached) per seed of REFERENCE_SEEDS."""
    references = []
    for seed in REFERENCE_SEEDS:
        settings = cycles_settings(options.reference_samples, bounces, seed, clear=clear)
        key = reference_key(blend_digest, options.resolution, settings, bpy.app.version_string)
        references.append(reference(scene, settings, key, options.cache_dir, exr))
        stop_if_cancelled()
    return references


def render_ladder(scene: bpy.types.Scene, jobs: list[Job], r1: np.ndarray, r2: np.ndarray,
                  exr: Path) -> list[dict[str, object]]:
    """One entry per ladder render: engine, settings, seconds and metrics (or error)."""
    entries = []
    for index, job in enumerate(jobs, 1):
        entry = {**job.entry, **measure(job, r1, r2, exr)}
        stop_if_cancelled()
        stats = monitor.last_stats if entry["engine"] == ENGINE_ID else None
        if stats is not None:
            entry["stages"] = {"ran": stats.timings, "skipped": stats.skipped}
        if entry["kind"] == "auto" and stats is not None:
            entry["chosen"] = [n for n in stats.notes if n.startswith("automatic parameters")]
        elif entry["engine"] == ENGINE_ID:
            entry["settings"] = asdict(scene.vpl_gi.to_settings())
        entries.append(entry)
        print(progress_line(index, len(jobs), entry), flush=True)
    return entries


def reference_summary(references: list[tuple[np.ndarray, float, bool]], options: Options
                      ) -> dict[str, object]:
    (r1, *_), (r2, *_) = references
    mean = float(((r1 + r2) / 2).mean())
    return {
        "engine": "CYCLES", "denoised": False, "samples": options.reference_samples,
        "seeds": list(REFERENCE_SEEDS),
        "seconds": [seconds for _, seconds, _ in references],
        "cached": [cached for *_, cached in references], "cache_dir": str(options.cache_dir),
        "mean": mean,
        "relative_noise": metrics.reference_noise(r1, r2) / math.sqrt(2) / mean,
        "relative_noise_meaning": "RMS noise of (r1 + r2) / 2 relative to its mean",
        "why": REFERENCE_WHY,
    }


REFERENCE_WHY = (
    "raw Cycles without a denoiser: a denoiser's bias would become part of the yardstick. Two "
    "independent seeds: mean((x - r1)(x - r2)) estimates the squared error against the "
    "converged image with the references' own noise removed in expectation, so they need not "
    "be noise-free, only enough that the estimate's spread from their noise (the "
    "relative_rmse_unbiased_range of each render) is small against the errors compared")


def has_clear_materials(scene: bpy.types.Scene) -> bool:
    """Whether a rendered object of ``scene`` has a material VPL GI lets light through: clear,
    or a cutout (Cycles renders either's transparency as black without transparent bounces)."""
    materials = {slot.material for obj in scene.objects if obj.type in RENDERED_OBJECT_TYPES
                 for slot in obj.material_slots if slot.material is not None}
    return any(m.is_clear or m.is_cutout for m in (export_material(m, []) for m in materials))


def run(scene_path: Path, out_dir: Path, options: Options) -> dict[str, object]:
    """Render the report of ``scene_path``, write ``out_dir``/report.json and
    error_vs_time.png, and return the report (with ``references_only``: render or load the
    references, write nothing else). Raises ReportError or ReportCancelled."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    scene = open_scene(scene_path, options.resolution)
    scene.vpl_gi.assign(options.overrides)
    bounces = scene.vpl_gi.bounces
    blend_digest = file_digest(scene_path)
    clear = has_clear_materials(scene)
    jobs = ladder_jobs(scene, options, bounces, clear)
    with tempfile.TemporaryDirectory(prefix="vpl_gi_report_") as tmp:
        exr = Path(tmp) / "render.exr"
        references = render_references(scene, blend_digest, options, bounces, exr, clear)
        report = {
            "scene": str(scene_path), "scene_sha256": blend_digest,
            "size": list(options.resolution), "bounces": bounces,
            "reference": reference_summary(references, options),
        }
        if options.references_only:
            return report
        (r1, *_), (r2, *_) = references
        warm_up(scene, jobs, exr)
        entries = render_ladder(scene, jobs, r1, r2, exr)
    report.update({
        "ladder": asdict(options.ladder), "overrides": options.overrides,
        "machine": {**machine_info(scene), "load_average_at_start": load and list(load)},
        "timing": TIMING, "metrics": METRICS,
        "renders": entries, "equal_error": tables.equal_error(entries),
        "automatic": pareto_gaps(entries),
    })
    write_outputs(report, out_dir)
    return report


def pareto_gaps(renders: list[dict]) -> list[dict[str, float]]:
    """Each automatic render against the measured front of VPL GI's ladder lines: the least
    error any ladder render reached in no more time, and the least time any ladder render
    needed for no more error (None where no ladder render qualifies)."""
    ladder = [e for e in renders if "metrics" in e and e["kind"] == "vpl"]
    gaps = []
    for auto in (e for e in renders if "metrics" in e and e["kind"] == "auto"):
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
    (out_dir / "table.txt").write_text(tables.format_table(report) + "\n")
    (out_dir / "table.md").write_text(tables.markdown_table(report) + "\n")
    tables.plot(report, out_dir / "error_vs_time.png")
