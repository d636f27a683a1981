"""The automatic mode 'time' as a progressive render: passes until the time budget is spent.

Pass 0 gets the parameters of least predicted error for a share of the budget: a half, a
quarter, an eighth … whichever count of passes the error model predicts least error for (more
passes shrink the clamp's bias; fewer repeat less of the work not chosen), or all of it when
the cheapest useful frame (see autotune.MIN_VIEW_VPLS) does not fit half (two passes would
then both be that frame, and the second would not fit). Its wall time tells what the work
the automatic mode does not choose (g-buffer, direct light, bias compensation,
shadow maps, compose) really costs here, and how far the chosen work's time is from the
model's: the cost model is measured on a small room, and its stages cost more per pixel on
larger scenes (the interior at 640×360: 609 light paths predicted at 4.47 s took 5.7 s; its
indirect gather and blur took twice the model's time). The later passes get the choice made
again with those measurements for the rest of the budget, and passes run while the next one
fits (progressive.py's time limit). Passes are averaged weighted by their light paths (the VPL
noise's variance goes as 1 / paths), so a smaller later pass adds to the image instead of
diluting it. From ``ray_traced_from_pass`` on (the second pass at the earliest: the first
measures the model) passes trace their VPLs' visibility where other final renders do
(progressive.ray_traced_from): the plan and the later passes' choice price them by the cost
model's cost of a traced pair at the scene's visibility ray cost (ray_probe.py), and the
error model counts the maps' error they remove (autotune.py). The probe over-predicts them
(it traces every pair, the gather only facing ones), so the first traced pass's measured time
rescales that cost and sizes the traced passes after it: as many as fill the rest of the
budget, each at most its size (one larger pass instead measured worse on the interior's 40 s:
5.33 and 5.39 % against 4.63 %, docs/measurements.md). Later passes get the light paths that
fill their share, between the ladder's rungs (autotune.fill). A budget below the cheapest
useful frame still renders that frame, with one warning naming the time it took.

The chosen parameters depend on this machine's speed: frames of one job rendered on different
machines differ. Render farms pin the parameters instead (auto_parameters = off)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace

from ..scene.model import Scene
from ..settings import Settings
from .automatic import ChooseParameters
from .autotune import Choice
from .progressive import PassReport, RenderPass, render_passes, traced_passes
from .result import Frame, Stats
from .state import CancelCallback, ProgressCallback

BUDGET_SPLIT = 2
"""The fewest passes a budget is planned as where the cheapest useful frame fits that share of
it (autotune.choose tries twice and four times as many …, as its error model favours; measured
on the Cornell box, docs/measurements.md: 1 pass / 2 / 4 at equal budgets)."""
PLAN_HEADROOM = 0.9
"""Share of the rest of the budget the later passes are planned for: the rest is measured
before the choice is made again, and a pass predicted to fill all of it would not start, since
the choice's own time is past by then (progressive.py starts a pass only when it fits)."""
MAX_BUDGET_PASSES = 1 << 16  # the passes setting's own limit
CHOSEN_STAGES = ("vpl generation", "indirect light", "blur")
"""Stages (by name prefix) whose time the automatic mode's parameters set ("indirect light
maps" holds the ISM stages' time: "ism upload", "ism splat" and "ism pull_push" are timed
within it, and counting them too had the work not chosen measured at 0 s). The "supersample
blur" of soft direct light and bias compensation, where indirect light is gathered per pixel,
is work not chosen (timed in the "blur" stage before, it was 0.23 of the Cornell box's 0.26 s
and 0.33 of the interior's 0.35 s, which the later passes' choice took for VPL work)."""
ONCE_STAGES = ("automatic parameters", "cost model calibration", "ray tracing setup",
               "ism points")
"""Stages of pass 0 that later passes do not repeat (the BVH and the ISM area table are kept)."""
FARM_NOTE = ("the time mode adapts to this machine's speed; for the same frame on every "
             "machine (render farms) set auto_parameters off and pin the parameters")


def once_seconds(stats: Stats) -> float:
    """Seconds a render spent on the stages done once (not again in later passes)."""
    return sum(stats.timings.get(k, 0.0) for k in ONCE_STAGES)


def split_seconds(wall: float, stats: Stats) -> tuple[float, float]:
    """Seconds of one pass spent on the work the automatic mode does not choose and on the
    work it chooses (each without the stages done once)."""
    once = once_seconds(stats)
    chosen = sum(v for k, v in stats.timings.items()
                 if k.startswith(CHOSEN_STAGES) and k not in ONCE_STAGES)
    return max(0.0, wall - chosen - once), chosen


def traced_passes_after(chooser: ChooseParameters, first: Settings, wall: float, rest: float
                        ) -> Choice | None:
    """The choice for the traced passes after the first (of ``first`` settings, ``wall``
    seconds), with the visibility cost rescaled to that pass: as many as fill ``rest``
    seconds, each at most its size, where they fit (the light-path floor may not let them
    shrink), else one fewer."""
    chooser.rescale_traced(wall, first)
    again = None
    for count in (math.ceil(rest / wall), math.floor(rest / wall)):
        if count >= 1:
            again = chooser.rechoose_traced(rest / count)
            if again is None or again.traced_seconds * count <= rest:
                break
    return again


def render_budget(render_pass: RenderPass, chooser: ChooseParameters, scene: Scene,
                  settings: Settings, progress: ProgressCallback | None = None,
                  cancelled: CancelCallback | None = None,
                  on_pass: Callable[[PassReport], None] | None = None) -> tuple[Frame, Stats]:
    """Render passes within ``settings.time_budget`` seconds (see the module docstring)."""
    budget = settings.time_budget
    if settings.ray_traced_from_pass:  # the first pass measures the (mapped) model
        settings = replace(settings, ray_traced_from_pass=max(2, settings.ray_traced_from_pass))
    calibration = Stats()
    chooser.cost_model(calibration, progress or (lambda _f, _m: None))  # not in the budget
    start = time.perf_counter()
    later: Settings | None = None  # the later passes' settings
    traced: Settings | None = None  # of the traced passes after the first (chosen again)
    expected: float | None = None  # seconds of the first later pass (predicted)
    expected_traced: float | None = None  # of the next pass that traces (predicted)
    walls: list[float] = []  # of the later passes that read maps
    traced_walls: list[float] = []  # of the traced passes chosen again
    paths: list[int] = []  # light paths of each pass: its weight (noise variance ∝ 1 / paths)
    notes: list[str] = []
    later_note: list[str] = []  # the later passes' choice, noted once one of them renders
    warnings: list[str] = []

    def later_pass(scene: Scene, pass_settings: Settings, index: int,
                   progress: ProgressCallback, cancelled: CancelCallback) -> tuple[Frame, Stats]:
        nonlocal traced, expected_traced
        notes.extend(later_note)
        later_note.clear()
        tracing = pass_settings.visibility == "exact"
        these = traced if tracing and traced is not None else later
        began = time.perf_counter()
        result = render_pass(scene, replace(these, visibility=pass_settings.visibility), index,
                             progress, cancelled)
        wall = time.perf_counter() - began
        paths.append(these.vpl_count)
        if not tracing:
            walls.append(wall)
        elif traced is not None:
            traced_walls.append(wall)
        else:  # the first traced pass: its time sizes the traced passes after it
            rest = PLAN_HEADROOM * max(budget - (time.perf_counter() - start), 0.0)
            again = traced_passes_after(chooser, these, wall, rest)
            traced = these if again is None else replace(
                again.settings, auto_parameters="off", time_budget=budget)
            expected_traced = wall if again is None else again.traced_seconds
            if again is not None:
                notes.append(f"automatic parameters of the traced passes after pass {index + 1}: "
                             f"{again.describe()} (pass {index + 1} traced in {wall:.2f} s)")
        return result

    def one_pass(scene: Scene, pass_settings: Settings, index: int,
                 progress: ProgressCallback, cancelled: CancelCallback) -> tuple[Frame, Stats]:
        nonlocal later, expected, expected_traced
        if index > 0 and later is not None:
            return later_pass(scene, pass_settings, index, progress, cancelled)
        began = time.perf_counter()
        chooser.split = BUDGET_SPLIT
        try:
            frame, stats = render_pass(scene, settings, index, progress, cancelled)
        finally:
            chooser.split = 1
        wall = time.perf_counter() - began
        if chooser.last is None:  # no indirect light: every pass alike
            later = replace(settings, auto_parameters="off")
            paths.append(later.vpl_count)
            return frame, stats
        chosen = chooser.last[2]
        paths.append(chosen.settings.vpl_count)
        fixed, variable = split_seconds(wall, stats)
        rest = max(budget - (time.perf_counter() - start), 0.0)
        others = max(1, chosen.passes - 1)  # the later passes planned (one where none was)
        tracing = traced_passes(1 + others, chooser.last[1].ray_traced_from)
        again = chooser.rechoose(fixed, variable, PLAN_HEADROOM * rest / others,
                                 tracing / others)
        later = replace(again.settings if again is not None else chosen.settings,
                        auto_parameters="off", time_budget=budget)
        if again is not None:
            expected = again.seconds
            expected_traced = again.traced_seconds or None
            later_note.append(f"automatic parameters of passes 2+: {again.describe()} "
                              f"(measured {fixed:.2f} s per pass of work not chosen)")
        repeated = wall - once_seconds(stats)
        if repeated > budget and not chosen.useful:
            warnings.append(f"time budget {budget:g} s is below the cheapest useful frame of "
                            f"this scene ({chosen.settings.vpl_count} light paths, "
                            f"≈ {repeated:.1f} s here); rendered that ({FARM_NOTE})")
        elif repeated > budget:
            warnings.append(f"time budget {budget:g} s overrun: the first pass took "
                            f"{repeated:.1f} s, predicted {chosen.seconds:.1f} s (the cost "
                            f"model, measured on a small room, can be off for this scene; the "
                            f"passes after the first are sized from its measured time)")
        return frame, stats

    def next_seconds(tracing: bool) -> float | None:
        measured = traced_walls if tracing else walls
        if measured:
            return sum(measured) / len(measured)
        return expected_traced if tracing else expected

    frame, stats = render_passes(
        one_pass, scene, replace(settings, passes=MAX_BUDGET_PASSES, time_limit=budget),
        progress, cancelled, on_pass, open_ended=True, next_seconds=next_seconds,
        pass_weight=lambda index: paths[index])
    stats.timings.update(calibration.timings)
    stats.notes.extend(notes)
    stats.warnings.extend(warnings)
    return frame, stats
