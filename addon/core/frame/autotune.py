"""Automatic parameters: VPL count, points per VPL, ISM resolution, interleaving and blur chosen
for a time budget per frame or a target error, from a cost model measured on this machine
(:func:`calibrate`, cached on disk) and an error model fitted on the error-against-time
reports (``error_model.json``, written by ``tools/fit_error_model.py``).

Cost of a frame, per stage (seconds; P supersampled pixels, V VPLs, K the interleave):
    VPL generation  c_paths · paths · bounces
    ISMs            c_splat · V · points + c_texels · V · resolution²
    ISM area table  c_pool · triangles, when the table of triangle areas must be built
    indirect light  c_gather · P · V / K²  (P and K of the pixels the VPLs are gathered at)
                    + c_traced · P · V / K² · visibility ray cost, instead of the ISMs, in a
                    pass that traces its VPLs' visibility (a time budget's passes from
                    ``ray_traced_from_pass`` on, progressive.py)
    blur            c_blur · P · radius (K > 1)
    the rest        c_frame + c_pixels · P + c_maps · shadow-map tiles  (not chosen here:
                    PIXEL_STAGES, the direct light's shadow maps)
                    + c_compensation · P · rays · ray cost  (bias compensation, whose short
                    rays cost what the scene's ray probe measures against the calibration
                    room's)
    (replaced by ``Workload.fixed``, their time measured in a pass, when it is known)
    plus what the pass spent before the choice (``Workload.spent``)
Error (relative RMSE against a converged image):
    sqrt(floor² + noise² / paths + ism(points, resolution)² + maps²)
(maps: in scenes with more triangles than an ISM has points; over K passes, of which T trace:
noise² / (K · paths), floor · K^(-1/3), and the last two terms times (K - T) / K)
No choice has fewer light paths than the cheapest useful one: MIN_VIEW_VPLS VPLs lighting
the view (fewer leave the image dark and blotchy whatever the budget).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from itertools import product
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..scene.model import Camera, Instance, Light, LightKind, Material, Mesh, Scene
from ..settings import Settings
from .progressive import traced_passes
from .stages import blur_radius, pixel_interleave

COST_MODEL_VERSION = 15  # 15: c_traced scaled by a probe of rays to VPLs (the short rays'
# probe overstated them 1.3-1.6 times); 14: the cost of ray-traced VPL visibility; 13:
# measured with numpy's BLAS on one thread (blas_threads.py:
# a spinning BLAS thread slowed the ray probe by up to 60 % in streaks); 12: bias
# compensation by the scene's ray cost, VPL generation under each of its stage names (none
# was fitted: the calibration's is camera-driven); 11: the
# g-buffer's GPU time in its own stage (it was counted in the direct light's maps, the next
# stage that waited for the GPU); 10: measured at 256×144 as frames gather, with a frame's atlas
ERROR_MODEL_FILE = Path(__file__).with_name("error_model.json")
PATHS = tuple(round(16 * 2 ** (k / 4)) for k in range(41))
"""Light-path counts the automatic mode considers: 16 to 16384 in steps of 2^(1/4) (19 %)."""
MIN_VIEW_VPLS = 64
"""VPLs lighting the view of the cheapest useful frame (the interior at 384² with 3 of them was
51 % dark and 79 % off; see docs/measurements.md)."""
OVERRUN = 1.1
"""Below or just above the cheapest useful frame's time, the choice is the least predicted error
among the candidates within this factor of the fastest (the least light paths; better ISMs cost
little)."""
FLOOR_EXPONENT = 1 / 3
"""The error model's floor falls as passes^(-FLOOR_EXPONENT): the clamp schedule's bias's mean
squared error goes as passes^(-2/3) (progressive.CLAMP_EXPONENT = 1/6)."""
SPLIT_COST = 1.1
"""A time budget is split into passes (the first measures what the cost model predicts, the
later ones are sized from it) only while the passes' predicted error is within this factor of
one pass's over the whole budget: each pass repeats the work not chosen (on the Cornell box
about 1.9 s of a 4.7 s budget: two passes measured 6.7 % in 2.7 s, one pass 3.7 % in 5.4 s)."""
MIN_PASS_PATHS = 1024
"""The fewest light paths a pass of a time budget's several gets (the default frame's): the
error model's noise, fitted across scenes, under-predicts scenes few paths reach (Sponza's 40 s
as 8 passes of 256 paths was predicted at 4.5 % and measured 19.0 %; of 1024, 12.2 %)."""
PASSES_TIE = 1.05
"""Among plans predicted within this factor of the least error, the one of most passes: on the
Cornell box's 40 s budget 8 passes of 1722 paths and 4 of 4096 were predicted within 2 % of
each other and measured 1.65 % and 2.55-2.62 % (passes shrink the clamp's bias faster than the
error model's floor says)."""
ONE_PASS_SHARE = 0.9
"""A time budget planned as one pass is chosen for this share of it: nothing measured corrects
that pass's prediction (on the Cornell box 1448 light paths predicted at 4.68 s took 5.5 s)."""
PIXEL_STAGES = ("g-buffer", "direct light", "shadow hints", "upsample", "supersample blur",
                "thin surfaces", "compose")
"""The stages whose time grows with the supersamples (from a cost per frame) and that the choice
does not set, but for bias compensation (COMPENSATION_STAGE)."""
COMPENSATION_STAGE = "bias compensation"
"""The stage of a short ray per supersample, whose cost per ray differs between scenes as the ray
probe's does (ray_probe.py)."""


@dataclass(frozen=True)
class CostModel:
    """Seconds per unit of work of each stage, measured by :func:`calibrate`."""

    renderer: str  # the GL renderer it was measured with
    paths: float  # per light path and bounce
    splat: float  # per VPL and point
    texels: float  # per VPL and ISM texel
    gather: float  # per pixel and VPL gathered
    blur: float  # per pixel and blur radius
    pixels: float  # per pixel: PIXEL_STAGES
    maps: float  # per shadow-map tile
    pool: float  # per triangle of the ISM area table (the points are drawn on the GPU)
    frame: float = 0.0  # per frame: PIXEL_STAGES' cost whatever the pixels (draws, passes)
    compensation: float = 0.0  # per bias compensation ray (one per supersample by default)
    probe: float = 0.0  # seconds of the ray probe in the calibration room
    traced: float = 0.0  # per pixel and VPL gathered, of tracing their visibility (at the
    # calibration room's ray cost)
    visibility_probe: float = 0.0  # seconds of the visibility probe in the calibration room
    version: int = COST_MODEL_VERSION


@dataclass(frozen=True)
class ErrorModel:
    """Relative RMSE against a converged image, as fitted on the reports."""

    floor: float  # what more VPLs do not remove (clamp, visibility, the scene's own bias)
    noise: float  # relative RMSE × sqrt(light paths)
    ism: dict[str, float]  # "resolution/points" -> ISM visibility error against exact
    interleave: dict[str, float]  # K -> factor on the noise term (with its blur)
    maps: float = 0.0  # the default maps' visibility error in scenes with more triangles than
    # an ISM has points, which passes do not remove (ray-traced passes do)

    def error(self, paths: int, interleave: int, points: int, resolution: int,
              passes: int = 1, traced: int = 0, undersampled: bool = False) -> float:
        """The error of ``passes`` passes of ``paths`` light paths each: their noise as one
        set's of all their paths, and the floor shrinking as passes^(-1/3), as the passes'
        clamp schedule makes its bias (progressive.py); the maps' error (with ``maps`` where
        the scene is ``undersampled``) is the mapped passes' share of it: ``traced`` of them
        trace their VPLs' visibility."""
        noise = self.noise * self.interleave[str(interleave)] / math.sqrt(paths * passes)
        maps = math.hypot(self.ism[f"{resolution}/{points}"],
                          self.maps if undersampled else 0.0) * (passes - traced) / passes
        floor = self.floor * passes ** -FLOOR_EXPONENT
        return math.sqrt(floor**2 + noise**2 + maps**2)

    def options(self) -> list[tuple[int, int, int]]:
        """(interleave, points, resolution) triples the model has measurements for."""
        pairs = [tuple(int(v) for v in key.split("/")) for key in self.ism]
        return [(int(k), points, resolution) for k in self.interleave
                for resolution, points in pairs]


@dataclass(frozen=True)
class Workload:
    """What the chosen parameters scale with, for one frame of one scene."""

    pixels: int  # supersampled
    triangles: int
    shadow_tiles: int  # of the direct light's shadow maps
    vpls_per_path: float  # VPLs that can light the view per light path
    bounces: int
    area_table: bool = False  # the ISM area table of these triangles is built already
    gathered_per_path: float | None = None  # VPLs gathered per light path, when camera
    # guidance keeps more of them in view than the paths leave there (None: vpls_per_path)
    gather_antialiasing: int = 1  # supersamples per pixel edge the VPLs are gathered once for
    # (indirect light per pixel: the antialiasing), else 1
    fixed: float | None = None  # measured seconds of the work not chosen here (None: modelled)
    scale: float = 1.0  # measured / modelled seconds of the chosen work (the machine's load)
    # (applied to the ISM area table's modelled time too)
    compensation_rays: int = 0  # per supersample, of bias compensation from the image
    ray_cost: float = 1.0  # the scene's ray probe / the calibration room's (cost.probe)
    visibility_cost: float = 1.0  # the scene's visibility probe / the calibration room's
    spent: float = 0.0  # seconds the frame spent before the choice (counted in its time)
    ray_traced_from: int | None = None  # the first of a time budget's passes (from 0) that
    # traces its VPLs' visibility (progressive.ray_traced_from), None: none does
    traced_share: float = 0.0  # share of the passes chosen for that trace (the later passes)
    undersampled: bool = False  # more triangles than an ISM has points (ErrorModel.maps)
    pass_paths: int = 0  # the fewest light paths a pass of several is chosen with (0: any)

    def least_paths(self) -> int:
        """Light paths of the cheapest useful frame: the fewest of PATHS that leave
        MIN_VIEW_VPLS VPLs lighting the view."""
        needed = MIN_VIEW_VPLS / max(self.vpls_per_path, 1e-9)
        return next((p for p in PATHS if p >= needed), PATHS[-1])

@dataclass(frozen=True)
class Choice:
    """Parameters the automatic mode chose, with the time and error it predicts."""

    settings: Settings
    seconds: float
    error: float  # of all the passes planned
    useful: bool = True  # False: the goal needs less than the cheapest useful frame
    passes: int = 1  # passes the time budget is planned as (the choice is for one share)
    traced_seconds: float = 0.0  # predicted for a pass that traces its VPLs' visibility,
    # where some of the passes chosen for do (0: none)

    def describe(self) -> str:
        s = self.settings
        traced = f" ({self.traced_seconds:.2f} s ray traced)" if self.traced_seconds else ""
        plan = (f" a pass{traced}, {self.passes} passes planned," if self.passes > 1
                else f" a pass{traced}," if traced else "")
        return (f"{s.vpl_count} paths, {s.ism_points} points/VPL, {s.ism_resolution}² ISMs, "
                f"interleave {s.interleave}, blur {s.blur_radius}: predicted "
                f"{self.seconds:.2f} s{plan} relative RMSE {self.error * 100:.1f} %")


def chosen_parameters(settings: Settings) -> tuple[int, int, int, int, int]:
    """The settings the automatic mode chooses, in :func:`predict_seconds`' order: light
    paths, interleave, ISM points, ISM resolution and blur radius."""
    return (settings.vpl_count, settings.interleave, settings.ism_points,
            settings.ism_resolution, settings.blur_radius)


def predict_seconds(cost: CostModel, work: Workload, paths: int, interleave: int, points: int,
                    resolution: int, blur_radius: int, traced: bool = False) -> float:
    """Predicted wall time of one frame with these parameters (``traced``: tracing its VPLs'
    visibility instead of rendering their ISMs)."""
    pool = 0.0 if work.area_table or traced else cost.pool * work.triangles
    return (work.scale * (pool + chosen_seconds(cost, work, paths, interleave, points,
                                                resolution, blur_radius, traced))
            + fixed_seconds(cost, work) + work.spent)


def fixed_seconds(cost: CostModel, work: Workload) -> float:
    """Predicted (or measured) seconds of the work the choice does not set."""
    if work.fixed is not None:
        return work.fixed
    compensation = cost.compensation * work.pixels * work.compensation_rays * work.ray_cost
    return cost.frame + cost.pixels * work.pixels + cost.maps * work.shadow_tiles + compensation


def chosen_seconds(cost: CostModel, work: Workload, paths: int, interleave: int, points: int,
                   resolution: int, blur_radius: int, traced: bool = False) -> float:
    """Predicted seconds of the stages these parameters set (not the ISM area table)."""
    vpls = paths * (work.gathered_per_path or work.vpls_per_path)
    pixels, k = gathered_pixels(work.pixels, interleave, work.gather_antialiasing)
    pairs = pixels * vpls / k**2
    visibility = (cost.traced * pairs * work.visibility_cost if traced
                  else cost.splat * vpls * points + cost.texels * vpls * resolution**2)
    return (cost.paths * paths * max(1, work.bounces) + visibility + cost.gather * pairs
            + (cost.blur * pixels * blur_radius if k > 1 else 0.0))


def gathered_pixels(supersamples: float, interleave: int, antialiasing: int
                    ) -> tuple[float, int]:
    """The pixels the VPLs are gathered at and their interleave pattern's edge: every
    supersample with ``interleave``, or once per pixel (``antialiasing`` > 1: indirect light
    per pixel) with stages.pixel_interleave."""
    return supersamples / antialiasing**2, pixel_interleave(interleave, antialiasing)


class Candidate(NamedTuple):
    """One choice of parameters with what the models predict for it."""

    seconds: float  # of a pass with imperfect shadow maps
    error: float  # of one pass
    paths: int
    interleave: int
    points: int
    resolution: int
    blur: int
    traced: float  # seconds of a pass that traces its VPLs' visibility instead

    def per_pass(self, traced_share: float) -> float:
        """Mean seconds a pass where ``traced_share`` of the passes trace their visibility."""
        return (1.0 - traced_share) * self.seconds + traced_share * self.traced


def choose(settings: Settings, work: Workload, cost: CostModel, errors: ErrorModel,
           split: int = 1) -> Choice:
    """The parameters of least predicted error within ``settings.time_budget`` seconds
    (mode 'time'), or of least predicted time within ``settings.target_error`` (mode
    'error'). Never fewer light paths than the cheapest useful frame's; when nothing meets the
    goal, the closest candidate, marked not ``useful`` when the budget is below that frame.
    ``split``: the fewest passes the time mode would share the budget among (1: none); it
    tries split, 2 × split, 4 × split … passes while the cheapest useful frame fits a share,
    and the choice is for one share of the count whose passes' predicted error is least, where
    that is within SPLIT_COST of one pass's over the whole budget, else for ONE_PASS_SHARE of
    it, as ``Choice.passes`` says; among plans within PASSES_TIE of the least error, the one of
    most passes. A plan's passes have at least MIN_PASS_PATHS light paths each; those from
    ``work.ray_traced_from`` on are priced as tracing their VPLs' visibility and add none of the
    maps' error (which the plans are compared with one pass by; a single frame's choice, with
    every candidate's maps alike, leaves it out, so that the 'error' mode's targets stay
    reachable). With ``work.traced_share`` that share of the passes is priced so (the later
    passes' choice, whose passes have at least ``work.pass_paths``)."""
    candidates = _candidates(settings, work, cost, errors)
    several = [c for c in candidates if c.paths >= MIN_PASS_PATHS] or candidates
    if work.pass_paths:
        candidates = [c for c in candidates if c.paths >= work.pass_paths] or candidates
    share = work.traced_share
    budget, passes = settings.time_budget, 1
    if settings.auto_parameters == "time":
        best = _least_error(candidates, ONE_PASS_SHARE * budget if split > 1 else budget, share)
        plans = []
        count = split
        while split > 1:
            traced = traced_passes(count, work.ray_traced_from)
            if min(c.per_pass(traced / count) for c in several) > budget / count:
                break  # the cheapest useful passes do not fit
            one = _least_error(several, budget / count, traced / count)
            plans.append((errors.error(one.paths, one.interleave, one.points, one.resolution,
                                       count, traced, work.undersampled), count, one))
            count *= 2
        least = min(plans)[0] if plans else math.inf
        one_pass = errors.error(best.paths, best.interleave, best.points, best.resolution,
                                undersampled=work.undersampled)  # with the maps' term
        if least <= SPLIT_COST * one_pass:
            error, passes, best = max((p for p in plans if p[0] <= PASSES_TIE * least),
                                      key=lambda p: p[1])
            best = best._replace(error=error)  # the error of all the passes
            share = traced_passes(passes, work.ray_traced_from) / passes
            budget /= passes
    else:
        fitting = [c for c in candidates if c.error <= settings.target_error]
        best = min(fitting) if fitting else min(candidates, key=lambda c: (c.error, c.seconds))
    chosen = replace(settings, vpl_count=best.paths, interleave=best.interleave,
                     ism_points=best.points, ism_resolution=best.resolution,
                     blur_radius=max(1, best.blur or settings.blur_radius), visibility="ism")
    return Choice(chosen, best.seconds, best.error,
                  useful=settings.auto_parameters != "time" or best.per_pass(share) <= budget,
                  passes=passes, traced_seconds=best.traced if share > 0 else 0.0)


def may_trace(settings: Settings, work: Workload, cost: CostModel, errors: ErrorModel,
              split: int) -> bool:
    """Whether a time budget's plan of ``split``, 2 × ``split`` … passes could reach
    ``work.ray_traced_from`` (see :func:`choose`): its passes of MIN_PASS_PATHS light paths fit
    at the least of a mapped pass's seconds and a traced pass's without its rays. Where not,
    the visibility cost is not needed."""
    if work.ray_traced_from is None or split <= 1 or settings.auto_parameters != "time":
        return False
    count = split
    while count <= work.ray_traced_from:
        count *= 2
    least = min((min(c.seconds, c.traced) for c in
                 _candidates(settings, replace(work, visibility_cost=0.0), cost, errors)
                 if c.paths >= MIN_PASS_PATHS), default=math.inf)
    return count * least <= settings.time_budget


def fill(choice: Choice, work: Workload, cost: CostModel, errors: ErrorModel,
         budget: float) -> Choice:
    """``choice`` with its light paths raised, short of the next of PATHS, so that a pass (of
    ``work.traced_share`` traced) is predicted at ``budget`` seconds: a time budget's later
    passes, sized from measured times, would otherwise leave up to the ladder's step (19 %)
    of each unused."""
    s = choice.settings
    _, *kept = chosen_parameters(s)  # all but the light paths

    def candidate(paths: int) -> Candidate:
        return _candidate(work, cost, errors, paths, *kept)

    now = candidate(s.vpl_count).per_pass(work.traced_share)
    slope = (candidate(2 * s.vpl_count).per_pass(work.traced_share) - now) / s.vpl_count
    rung = next((p for p in PATHS if p > s.vpl_count), s.vpl_count + 1)
    paths = min(s.vpl_count + int((budget - now) / slope), rung - 1) if slope > 0 else 0
    if paths <= s.vpl_count:
        return choice
    filled = candidate(paths)
    return replace(choice, settings=replace(s, vpl_count=paths), seconds=filled.seconds,
                   error=filled.error,
                   traced_seconds=filled.traced if choice.traced_seconds else 0.0)


def _least_error(candidates: list[Candidate], budget: float,
                 traced_share: float = 0.0) -> Candidate:
    """The candidate of least predicted error within ``budget`` seconds a pass (where
    ``traced_share`` of the passes trace), or within OVERRUN of the cheapest useful frame's
    where that is more (so that a budget just above that frame does not get a worse choice
    than one just below it)."""
    limit = max(budget, OVERRUN * min(c.per_pass(traced_share) for c in candidates))
    return min((c for c in candidates if c.per_pass(traced_share) <= limit),
               key=lambda c: (c.error, c.per_pass(traced_share)))


def _candidates(settings: Settings, work: Workload, cost: CostModel, errors: ErrorModel
                ) -> list[Candidate]:
    """Every choice with at least the cheapest useful frame's light paths."""
    candidates = []
    least = work.least_paths()
    for paths, (k, points, resolution) in product([p for p in PATHS if p >= least],
                                                  errors.options()):
        candidates.append(_candidate(work, cost, errors, paths, k, points, resolution,
                                     blur_radius(k, settings.blur_radius)))
    return candidates


def _candidate(work: Workload, cost: CostModel, errors: ErrorModel, paths: int, k: int,
               points: int, resolution: int, blur: int) -> Candidate:
    """One choice with its predicted seconds (mapped and traced) and error (of one pass)."""
    return Candidate(predict_seconds(cost, work, paths, k, points, resolution, blur),
                     errors.error(paths, k, points, resolution), paths, k, points, resolution,
                     blur, predict_seconds(cost, work, paths, k, points, resolution, blur,
                                           traced=True))


# -- the error model ---------------------------------------------------------------------------

def load_error_model(path: Path = ERROR_MODEL_FILE) -> ErrorModel:
    data = json.loads(path.read_text())
    return ErrorModel(data["floor"], data["noise"], data["ism"], data["interleave"],
                      data.get("maps", 0.0))


# -- the cost model ----------------------------------------------------------------------------

Render = Callable[[Settings], dict[str, float | int]]
"""Renders the calibration scene with the given settings and returns its stage timings
(seconds), counts (``vpls``, ``pixels``, ``triangles``, ``shadow_tiles``), the supersamples per
pixel edge its VPLs were gathered once for (``gather_antialiasing``) and the seconds of the ray
probes on it (``ray probe``, ``visibility probe``)."""

CALIBRATION = (  # (paths, interleave, points, resolution, antialiasing): spread so each term
    # is separable (the two supersampled pixel counts part the pixel stages' cost per frame
    # from their cost per pixel); the last with an atlas as large as a frame's: the gather's
    # cost per VPL and pixel grows with it (the room at 640×360: 1.04 times the cost fitted
    # without it for 569 VPLs of 64² maps, 1.71 times for 2276 of 128²)
    (64, 1, 1024, 64, 1), (256, 4, 4096, 128, 2), (128, 2, 1024, 256, 1), (512, 8, 2048, 64, 2),
    (1024, 8, 1024, 128, 3),
)
TRACED_CALIBRATION = (256, 4, 1024, 64, 1)
"""The calibration frame that traces its VPLs' visibility (the gather's cost per traced pair
beyond the mapped gather's)."""


def _through_origin(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Non-negative least-squares coefficients of y ≈ x @ c (columns of x scaled first)."""
    from scipy.optimize import nnls

    scale = np.maximum(np.abs(x).max(axis=0), 1e-30)
    coefficients, _ = nnls(x / scale, y)
    return coefficients / scale


def calibrate(render: Render, renderer_name: str, base: Settings) -> CostModel:
    """Measure the cost model: render the calibration scene at the CALIBRATION settings, each
    twice (the first compiles shaders and builds tables), and fit each stage's coefficients to
    the second render's seconds, with the first's ISM atlas allocation; the ray probe's
    reference is the least of its measurements. The VPLs are gathered
    where ``base`` gathers them (indirect light per pixel or per supersample). Last, the
    TRACED_CALIBRATION frame traces its VPLs' visibility: what its gather takes beyond the
    mapped gather's cost is the cost of tracing."""
    rows, probes, visibility_probes = [], [], []

    def settings_of(paths: int, k: int, points: int, resolution: int, aa: int,
                    visibility: str = "ism") -> Settings:
        return replace(base, vpl_count=paths, interleave=k, ism_points=points,
                       ism_resolution=resolution, antialiasing=aa, visibility=visibility,
                       auto_parameters="off")

    for row in CALIBRATION:
        settings = settings_of(*row)
        first = render(settings)  # builds the ISM area table (if new), compiles shaders
        again = render(settings)
        probes += [m["ray probe"] for m in (first, again) if "ray probe" in m]
        visibility_probes += [m["visibility probe"] for m in (first, again)
                              if "visibility probe" in m]
        # a frame allocates its ISM atlas, as the first render did, where the second found it
        # made (a new process pays it every frame: about 0.3-1 s for 1500-2500 VPLs of 128²
        # maps on llvmpipe, the textures' fresh pages)
        maps = (again.get("indirect light maps", 0.0) - again.get("ism upload", 0.0)
                + first.get("ism upload", 0.0))
        rows.append((settings, {**again, "ism points": first.get("ism points"),
                                "indirect light maps": maps}))

    def column(f) -> np.ndarray:
        return np.array([f(s, m) for s, m in rows], dtype=np.float64)

    vpls, pixels = column(lambda s, m: m["vpls"]), column(lambda s, m: m["pixels"])
    splat, texels = _through_origin(
        np.stack([vpls * column(lambda s, m: s.ism_points),
                  vpls * column(lambda s, m: s.ism_resolution**2)], axis=1),
        column(lambda s, m: m.get("indirect light maps", 0.0)))
    (paths,) = _through_origin(column(lambda s, m: s.vpl_count * s.bounces)[:, None],
                               column(lambda s, m: sum(v for k, v in m.items()
                                                       if k.startswith("vpl generation"))))
    gathered = [gathered_pixels(m["pixels"], s.interleave, m["gather_antialiasing"])
                for s, m in rows]  # (pixels, pattern edge) the VPLs are gathered at
    at, edge = (np.array(v, np.float64) for v in zip(*gathered, strict=True))
    (gather,) = _through_origin((at * vpls / edge**2)[:, None],
                                column(lambda s, m: m.get("indirect light", 0.0)))
    blurred = (edge > 1) * at * column(lambda s, m: s.blur_radius)
    (blur,) = _through_origin(blurred[:, None], column(lambda s, m: m.get("blur", 0.0)))
    # the rows with supersamples (antialiasing 1 runs no upsample, supersample blur or shadow
    # hints: fitted with them, the three sample scenes' pixel stages at 640×360, antialiasing
    # 3, were predicted at 1.25-1.73 s in three calibrations, where they took 1.06-1.23 s;
    # without them 0.95-0.98 s in two)
    supersampled = column(lambda s, m: s.antialiasing) > 1
    frame, pixel = _through_origin(
        np.stack([np.ones_like(pixels), pixels], axis=1)[supersampled],
        column(lambda s, m: sum(m.get(k, 0.0) for k in PIXEL_STAGES))[supersampled])
    (compensation,) = _through_origin((pixels * column(lambda s, m: s.bias_samples))[:, None],
                                      column(lambda s, m: m.get(COMPENSATION_STAGE, 0.0)))
    probe = float(min(probes, default=0.0))  # the least disturbed
    (maps,) = _through_origin(column(lambda s, m: m["shadow_tiles"])[:, None],
                              column(lambda s, m: m.get("direct light maps", 0.0)))
    built = [m for _, m in rows if m["ism points"] is not None]  # the table is built once
    pool = (sum(m["ism points"] for m in built) / sum(m["triangles"] for m in built)
            if built else 0.0)
    traced_settings = settings_of(*TRACED_CALIBRATION, visibility="exact")
    render(traced_settings)  # compiles the tracing gather
    traced_row = render(traced_settings)
    at, edge = gathered_pixels(traced_row["pixels"], traced_settings.interleave,
                               traced_row["gather_antialiasing"])
    pairs = at * traced_row["vpls"] / edge**2
    traced = max(0.0, traced_row.get("indirect light", 0.0) / pairs - gather) if pairs else 0.0
    return CostModel(renderer_name, float(paths), float(splat), float(texels), float(gather),
                     float(blur), float(pixel), float(maps), float(pool), float(frame),
                     float(compensation), probe, float(traced),
                     float(min(visibility_probes, default=0.0)))


def cached_cost_model(cache: Path | None, renderer_name: str,
                      measure: Callable[[], CostModel]) -> CostModel:
    """The cost model cached in ``cache`` for this GL renderer, measured (and cached) when
    there is none; an unreadable cache is measured again."""
    if cache is not None and cache.is_file():
        try:
            data = json.loads(cache.read_text())
            model = CostModel(**data)
            if model.renderer == renderer_name and model.version == COST_MODEL_VERSION:
                return model
        except (ValueError, TypeError):
            pass
    model = measure()
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        cache.write_text(json.dumps(asdict(model), indent=2) + "\n")
    return model


def default_cost_cache() -> Path:
    """Where the measured cost model is kept: the user's cache directory."""
    import os

    root = os.environ.get("XDG_CACHE_HOME") or os.environ.get("LOCALAPPDATA")
    return (Path(root) if root else Path.home() / ".cache") / "vpl_gi" / "cost_model.json"


def calibration_scene() -> Scene:
    """A closed 4 × 4 × 3 m room of 4800 triangles with a box in it, lit by a point light (ray
    traced) and an area light (its samples shadow mapped), seen at 256×144 pixels (a model
    fitted at 128² put its pixel stages at 640×360 at 0.6-0.9 of their time): the scene the
    cost model is measured on."""
    faces = []
    n = 20
    g = np.linspace(0.0, 1.0, n + 1)
    a, b = np.meshgrid(g[:-1], g[:-1], indexing="ij")
    quads = np.stack([np.stack([a, b], -1), np.stack([a + 1 / n, b], -1),
                      np.stack([a + 1 / n, b + 1 / n], -1), np.stack([a, b + 1 / n], -1)],
                     axis=2).reshape(-1, 4, 2)
    lo, hi = np.array([-2.0, -2.0, 0.0]), np.array([2.0, 2.0, 3.0])
    for axis, side in product(range(3), (0, 1)):
        u, v = [i for i in range(3) if i != axis]
        corners = np.zeros((len(quads), 4, 3))
        corners[..., axis] = (lo, hi)[side][axis]
        corners[..., u] = lo[u] + quads[..., 0] * (hi[u] - lo[u])
        corners[..., v] = lo[v] + quads[..., 1] * (hi[v] - lo[v])
        if (axis == 1) != bool(side):  # wind so normals face into the room
            corners = corners[:, ::-1]
        faces.append(corners[:, [0, 1, 2, 0, 2, 3]].reshape(-1, 3))
    positions = np.concatenate(faces).astype(np.float32)
    e1 = positions[1::3] - positions[0::3]
    e2 = positions[2::3] - positions[0::3]
    normal = np.cross(e1, e2)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    room = Mesh("calibration room", positions, np.repeat(normal, 3, axis=0),
                np.zeros(len(positions) // 3, np.int32))
    box = np.eye(4)
    box[:3, :3] *= 0.3
    box[:3, 3] = (0.5, 0.3, 1.0)
    light, panel = np.eye(4), np.eye(4)
    light[:3, 3] = (-0.8, -0.5, 2.4)
    panel[:3, 3] = (0.8, 0.5, 2.9)  # under the ceiling, facing down (-z)
    near, far = 0.05, 50.0
    width, height = 256, 144
    projection = np.array([[1.2 * height / width, 0, 0, 0], [0, 1.2, 0, 0],
                           [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
                           [0, 0, -1, 0]])
    view = np.eye(4)
    view[:3, 3] = (0.0, -1.9, -1.5)  # the camera at (0, -1.5, 1.9)
    view[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # look along +y
    materials = [Material("walls", (0.7, 0.6, 0.5))]
    return Scene([Instance(room, np.eye(4), materials), Instance(room, box, materials)],
                 [Light("calibration", LightKind.POINT, light, power=200.0),
                  Light("calibration panel", LightKind.AREA, panel, power=100.0, size_x=0.5)],
                 camera=Camera(view, projection, width, height))
