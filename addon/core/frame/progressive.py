"""Progressive final renders: passes with their own light samples and VPLs, averaged.

Pass k (from 0) renders with its own seed, its light paths continuing the sequence of the
passes before it (the user's seed's scrambled Halton sequence from the path after their last:
K passes of N paths trace one stratified set of K·N, the frame's state ``first_path``; camera
guidance draws its candidates afresh per pass), its supersamples moved by a sub-sample offset
(pass 0: none; so edges converge as in Cycles, whose samples fall anywhere in the pixel) and
the VPL clamp distance shrunk to c_k = clamp / (k + 1)^CLAMP_EXPONENT; from the setting
``ray_traced_from_pass`` on, in scenes with more triangles than an ISM has points, it traces
its VPLs' visibility (``ray_traced_from``). Both of the clamp's
errors then vanish as passes are added, at the same rate. A VPL's hot spot (distance below
c_k) peaks at 1 / c_k² over an area c_k², so pass k's squared error from hot spots grows as
1 / c_k² ∝ (k + 1)^(2a), and the average of K passes keeps Σ (k + 1)^(2a) / K² ∝ K^(2a - 1) of
it; the energy the clamp removes (what bias compensation does not restore) shrinks with the
near region's area, c_K² ∝ K^(-2a), so its square as K^(-4a). The two rates meet at
a = 1/6: mean squared error ∝ K^(-2/3), a consistent estimator. (With a = 1/2, the
schedule before, the hot spots' share stayed constant over passes: Sponza's 4 passes
measured 35.8 %, now 27.7 %; docs/how-it-works.md.) The noise of the average is estimated
from the difference of the averages of the even and of the odd passes: independent halves but
for their light paths, which are stratified together, so that the halves' errors tend to
cancel in the average and add in the difference: the estimate errs high, not low."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..scene.model import Camera, Scene
from ..settings import Settings
from ..transport.sequences import radical_inverse
from .id_passes import (
    CRYPTO_FAMILIES,
    family_of,
    family_passes,
    joined_ranks,
    merge_ranks,
    split_ranks,
)
from .result import Frame, Stats
from .scene_size import flattened_triangles
from .state import CancelCallback, ProgressCallback

UNFILTERED_PASSES = frozenset({"Depth", "Denoising Depth", "Position", "IndexOB", "IndexMA",
                               "Vector"})
"""Passes the first pass gives, whose camera has no sub-sample offset (one sample at the
pixel's centre, as Cycles writes them from a pixel's first sample); Cryptomatte's ranks are
merged (id_passes.merge_ranks); the others are averaged."""
SEED_STRIDE = 0x9E3779B1  # pass k's seed: seed + k × stride (mod 2³¹)
MIN_PASSES_FOR_NOISE = 4  # passes before the noise estimate may stop a render
CLAMP_EXPONENT = 1 / 6  # pass k's clamp distance: clamp / (k + 1)^CLAMP_EXPONENT
EXACT_PASS_COST = 2.0  # a ray-traced pass against one with ISMs: 1.6–1.9 on the sample scenes


def pass_settings(settings: Settings, index: int) -> Settings:
    """The settings of pass ``index``: its own seed and the shrunk clamp (pass 0 is
    ``settings`` itself)."""
    if index == 0:
        return settings
    return replace(settings, seed=(settings.seed + index * SEED_STRIDE) % 2**31,
                   clamp_distance=settings.clamp_distance / (index + 1) ** CLAMP_EXPONENT)


def maps_undersample(settings: Settings, triangles: int) -> bool:
    """Whether the frame reads imperfect shadow maps and its ``triangles`` outnumber each
    map's points: the maps' visibility error, which passes keep (ray_traced_from; the
    automatic mode's autotune.ErrorModel.maps)."""
    return settings.visibility == "ism" and triangles > settings.ism_points


def ray_traced_from(settings: Settings, triangles: int) -> int | None:
    """The first pass (from 0) of a final render that traces its VPLs' visibility instead of
    reading imperfect shadow maps, or None: from ``ray_traced_from_pass`` (from 1) on where
    the scene's ``triangles`` outnumber each map's points. The maps' error is the same in every
    pass, so it stays in the average: the interior's 16 passes measured 5.3 % with maps
    throughout and 4.3 % with rays from pass 3 (docs/measurements.md, *Long renders*). Where
    every triangle gets points the maps' error was the smaller: the Cornell box (34 triangles)
    measured 1.5 % and 1.7 % (rays from pass 5)."""
    if settings.ray_traced_from_pass == 0 or not maps_undersample(settings, triangles):
        return None
    return settings.ray_traced_from_pass - 1


def traces(switch: int | None, index: int) -> bool:
    """Whether pass ``index`` traces its VPLs' visibility, ``switch`` being ray_traced_from's."""
    return switch is not None and index >= switch


def traced_passes(passes: int, switch: int | None) -> int:
    """Of ``passes`` passes, those that trace their VPLs' visibility (``traces``)."""
    return 0 if switch is None else max(0, passes - switch)


def pass_camera(camera: Camera, index: int, aa: int) -> Camera:
    """The camera of pass ``index``: its projection moved by a sub-sample offset in
    [-1/2, 1/2)² supersamples, the Halton point (bases 2, 3) of the index (pass 0: the camera
    itself): 2^m passes spread over 2^m columns of the supersample."""
    if index == 0:
        return camera
    offset = [radical_inverse(index, base) - 0.5 for base in (2, 3)]
    shift = np.eye(4)
    shift[0, 3] = 2.0 * offset[0] / (camera.width * aa)  # NDC spans 2 over the image
    shift[1, 3] = 2.0 * offset[1] / (camera.height * aa)
    return replace(camera, projection_matrix=shift @ camera.projection_matrix)


@dataclass
class PassReport:
    """What a progressive render says after each pass."""

    index: int  # passes finished so far
    frame: Frame  # their average
    stats: Stats  # of the whole render so far
    noise: float | None  # estimated relative noise of the average (None: too few passes)


class Accumulator:
    """Weighted running sums of the passes' images, in float64, in two halves (even, odd
    passes), and each Cryptomatte family's ranks summed over the passes."""

    def __init__(self) -> None:
        self.count = 0
        self._halves: list[dict[str, np.ndarray]] = [{}, {}]
        self._weights = [0.0, 0.0]
        self._first: Frame | None = None
        self._ranks: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # per family

    def add(self, frame: Frame, weight: float = 1.0) -> None:
        """Add a pass's images with ``weight`` (its share of the average: the inverse of its
        variance, up to a constant)."""
        half = self._halves[self.count % 2]
        for name, image in frame.passes.items():
            if name not in UNFILTERED_PASSES and family_of(name) is None:
                image = image.astype(np.float64) * weight
                half[name] = half[name] + image if name in half else image
        for family in CRYPTO_FAMILIES:
            names = family_passes(frame.passes, family)
            if names:
                ids, weights = split_ranks([frame.passes[n] for n in names])
                if family in self._ranks:
                    kept_ids, kept = self._ranks[family]
                    ids, weights = merge_ranks(np.concatenate([kept_ids, ids], axis=-1),
                                               np.concatenate([kept, weights * weight], -1),
                                               ids.shape[-1])
                else:
                    weights = weights * weight
                self._ranks[family] = ids, weights
        self._weights[self.count % 2] += weight
        self.count += 1
        self._first = self._first or frame

    def average(self) -> Frame:
        passes = dict(self._first.passes)
        total_weight = sum(self._weights)
        for name in passes:
            if name not in UNFILTERED_PASSES and family_of(name) is None:
                total = sum(h[name] for h in self._halves if name in h)
                passes[name] = (total / total_weight).astype(np.float32)
        for family, (ids, weights) in self._ranks.items():
            images = joined_ranks(ids, weights / np.float32(total_weight))
            passes.update(zip(family_passes(passes, family), images, strict=True))
        return Frame(self._first.width, self._first.height, passes)

    def noise(self) -> float | None:
        """RMS of (even average − odd average) · √(W_even W_odd) / (W_even + W_odd), relative
        to the mean of Combined's RGB: about the noise of the average of all passes, whose
        weights are inverse variances (1/2 of the difference for equal halves; None before two
        even halves)."""
        if self.count < 2 or self.count % 2:
            return None
        even, odd = (h["Combined"][..., :3] / w for h, w in zip(self._halves, self._weights,
                                                                strict=True))
        w_even, w_odd = self._weights
        mean = float(np.mean((w_even * even + w_odd * odd) / (w_even + w_odd)))
        if mean <= 0:
            return 0.0
        share = np.sqrt(w_even * w_odd) / (w_even + w_odd)
        return float(np.sqrt(np.mean((even - odd) ** 2)) * share) / mean


def expected_pass_seconds(mapped: list[float], traced: list[float], tracing: bool,
                          predicted: float | None = None) -> float:
    """The expected time of the next pass: ``predicted`` where given (the caller's expectation
    of a pass like it), else from the times of the passes before the switch to ray-traced
    visibility (``mapped``) and after it (``traced``): the mean of the traced passes so far
    where it is ``tracing`` and one has, else the mean of the mapped passes, times
    EXACT_PASS_COST where it is ``tracing``."""
    if predicted is not None:
        return predicted
    if tracing and traced:
        return float(np.mean(traced))
    like_before = float(np.mean(mapped))
    return EXACT_PASS_COST * like_before if tracing else like_before


def merge_stats(total: Stats, one: Stats) -> None:
    """Add one pass's stats to the render's: times summed, counts and skipped stages of the
    last pass, each warning and note once."""
    for stage, seconds in one.timings.items():
        total.timings[stage] = total.timings.get(stage, 0.0) + seconds
    total.counts.update(one.counts)
    total.skipped.update(one.skipped)
    total.warnings.extend(w for w in one.warnings if w not in total.warnings)
    total.notes.extend(n for n in one.notes if n not in total.notes)


RenderPass = Callable[[Scene, Settings, int, ProgressCallback, CancelCallback],
                      tuple[Frame, Stats]]


def render_passes(render_pass: RenderPass, scene: Scene, settings: Settings,
                  progress: ProgressCallback | None = None,
                  cancelled: CancelCallback | None = None,
                  on_pass: Callable[[PassReport], None] | None = None,
                  open_ended: bool = False,
                  next_seconds: Callable[[bool], float | None] | None = None,
                  pass_weight: Callable[[int], float] | None = None
                  ) -> tuple[Frame, Stats]:
    """Render ``settings.passes`` passes (fewer when the time limit or the noise threshold is
    reached first) and return their average; ``on_pass`` sees the average after each pass.
    ``open_ended``: the time limit, not the pass count, ends the render (progress is time);
    ``next_seconds``: the expected time of the next pass, given whether it traces (None or
    absent: from the passes so far, see expected_pass_seconds); ``pass_weight``: each
    pass's weight in the average, by its index, after it rendered (absent: all alike).
    Passes from ``ray_traced_from`` on trace their VPLs' visibility. Cancelling raises
    RenderCancelled from inside the current pass."""
    report = progress or (lambda _f, _m: None)
    check = cancelled or (lambda: False)
    total, accumulator = Stats(), Accumulator()
    start = time.perf_counter()
    planned = settings.passes
    triangles = flattened_triangles(scene) if planned > 1 else 0  # one pass: no switch
    switch = ray_traced_from(settings, triangles)
    mapped: list[float] = []  # each pass's time, before the switch
    traced: list[float] = []  # and after it
    for index in range(planned):
        visibility = "exact" if traces(switch, index) else settings.visibility

        def pass_progress(fraction: float, message: str, index: int = index) -> None:
            if open_ended:
                done = (time.perf_counter() - start) / settings.time_limit
                report(min(done, 1.0), f"Pass {index + 1} | {message}")
                return
            prefix = f"Pass {index + 1}/{planned} | " if planned > 1 else ""
            report((index + fraction) / planned, prefix + message)

        began = time.perf_counter()
        frame, stats = render_pass(scene, replace(settings, visibility=visibility), index,
                                   pass_progress, check)
        accumulator.add(frame, pass_weight(index) if pass_weight is not None else 1.0)
        merge_stats(total, stats)
        noise = accumulator.noise()
        if on_pass is not None:
            on_pass(PassReport(accumulator.count, accumulator.average(), total, noise))
        elapsed = time.perf_counter() - start
        (traced if traces(switch, index) else mapped).append(
            time.perf_counter() - began)  # with the average shown
        tracing = traces(switch, accumulator.count)
        expected = expected_pass_seconds(
            mapped, traced, tracing, next_seconds(tracing) if next_seconds is not None else None)
        if settings.time_limit > 0 and elapsed + expected > settings.time_limit:
            break  # another pass would end past the limit
        if settings.noise_threshold > 0 and noise is not None \
                and accumulator.count >= MIN_PASSES_FOR_NOISE and noise <= settings.noise_threshold:
            break
    total.counts["passes"] = accumulator.count
    if planned > 1 and switch is None and settings.visibility == "ism" \
            and 0 < settings.ray_traced_from_pass <= accumulator.count:
        total.skipped[f"ray-traced visibility from pass {settings.ray_traced_from_pass}"] = (
            f"{triangles:,} triangles: each ISM's {settings.ism_points} points hold them")
    if planned > 1:
        estimate = accumulator.noise()
        of = "" if open_ended else f" of {planned}"
        noun = "pass" if accumulator.count == 1 else "passes"
        total.notes.append(f"{accumulator.count}{of} {noun} in "
                           f"{time.perf_counter() - start:.1f} s" +
                           (f", estimated noise {estimate * 100:.1f} %" if estimate is not None
                            else ""))
    if traces(switch, accumulator.count - 1):
        total.notes.append(f"passes {switch + 1}–{accumulator.count}: VPL visibility ray traced "
                           f"({settings.ism_points} ISM points for {triangles:,} triangles)")
    return accumulator.average(), total
