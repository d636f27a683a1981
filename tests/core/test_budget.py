"""The automatic mode 'time' over passes: pass 0 sized from the cost model, the later passes
from pass 0's measured time, passes until the budget is spent, and one warning when the budget
is below the cheapest useful frame."""

from __future__ import annotations

import json
from dataclasses import asdict, replace

import numpy as np
import pytest

from addon.core.frame import autotune
from addon.core.frame.automatic import ChooseParameters
from addon.core.frame.budget import split_seconds, traced_passes_after
from addon.core.frame.image import SUPERSAMPLE_BLUR
from addon.core.frame.result import Stats
from addon.core.settings import Settings
from tests.core.builders import floor_scene, icosphere, light, translation
from tests.core.test_autotune import WORK
from tests.core.test_planner import wall

COST = autotune.CostModel("", paths=2e-5, splat=5e-7, texels=3e-7, gather=2e-7, blur=2.5e-7,
                          pixels=8.5e-4, maps=4e-6, pool=7e-7, traced=4e-7)
"""llvmpipe's coefficients on 2 cores, roughly, but per pixel 340 times too dear: a model that
over-predicts the work it does not choose (2 s for these 48² pixels), as on the interior."""
BASE = Settings(antialiasing=1, auto_parameters="time")


def scene():
    return floor_scene([light(autotune.LightKind.POINT, translation(0, 0, 2), power=50.0)],
                       extra=[wall(2)], size=48)


@pytest.fixture
def cached_cost(renderer, tmp_path):
    """A cost model cached for this GL renderer, so that no test calibrates."""
    cache = tmp_path / "cost.json"
    model = replace(COST, renderer=str(renderer.ctx.info["GL_RENDERER"]))
    cache.write_text(json.dumps(asdict(model)))
    previous, renderer.cost_cache = renderer.cost_cache, cache
    yield model
    renderer.cost_cache = previous


def test_a_pass_splits_into_chosen_and_fixed_work_without_the_one_off_stages():
    """The ISM stages are timed within "indirect light maps" and count once; the blur at every
    supersample (soft direct light, bias compensation) is work not chosen."""
    stats = Stats(timings={"g-buffer": 0.2, "direct light": 0.5, "vpl generation (camera-driven)":
                           0.3, "ism upload": 0.02, "ism splat": 0.06, "ism pull_push": 0.02,
                           "indirect light maps": 0.1, "indirect light": 0.4, "blur": 0.05,
                           SUPERSAMPLE_BLUR: 0.25, "automatic parameters": 0.2,
                           "ray tracing setup": 0.1, "ism points": 0.5})
    fixed, chosen = split_seconds(3.0, stats)
    assert chosen == pytest.approx(0.85) and fixed == pytest.approx(3.0 - 0.85 - 0.8)
    assert split_seconds(0.5, stats) == (0.0, pytest.approx(0.85))


def test_the_ism_stages_are_timed_within_the_indirect_light_maps(renderer):
    """What split_seconds relies on: a frame's ISM stages are part of "indirect light maps"."""
    renderer.forget_frames()
    _, stats = renderer.render(scene(), replace(BASE, auto_parameters="off"))
    nested = [v for k, v in stats.timings.items()
              if k.startswith("ism ") and k != "ism points"]
    assert nested and sum(nested) <= stats.timings["indirect light maps"]


def test_a_budget_is_spent_in_passes(renderer, cached_cost):
    renderer.forget_frames()  # the same render first: shaders compiled, ISM point pool made
    renderer.render_progressive(scene(), replace(BASE, time_budget=4.0))
    renderer.forget_frames()
    _, stats = renderer.render_progressive(scene(), replace(BASE, time_budget=4.0))
    assert stats.counts["passes"] >= 2, stats.notes
    first, later = (float(n.split("relative RMSE ")[1].split(" %")[0]) for n in stats.notes
                    if n.startswith("automatic parameters"))
    assert later < first  # the model's 2 s of fixed work were measured as far less
    spent = next(n for n in stats.notes if " passes in " in n)
    seconds = float(spent.split(" passes in ")[1].split(" s")[0])
    assert seconds <= 4.0 * 2, spent  # a pass starts only when it is expected to fit
    assert any(n.startswith("automatic parameters of passes 2+") for n in stats.notes)
    assert not stats.warnings, stats.warnings


def test_a_budgets_passes_trace_from_the_switch_priced_as_tracing(renderer, cached_cost):
    """In a scene with more triangles (a ball of 1280) than the maps' points, the time mode's
    passes from ``ray_traced_from_pass`` on trace their VPLs' visibility as other final renders
    do, and the later passes' choice prices them so (its note gives the traced pass's time)."""
    ball = autotune.Instance(icosphere(0.5, 3), translation(0.5, 0.5, 0.5),
                             [autotune.Material("ball", (0.8, 0.8, 0.8))])
    busy = scene()
    busy.instances.append(ball)
    settings = replace(BASE, time_budget=4.0, ism_points=1024, ray_traced_from_pass=2)
    renderer.forget_frames()  # the same render first: shaders compiled
    renderer.render_progressive(busy, settings)
    renderer.forget_frames()
    _, stats = renderer.render_progressive(busy, settings)
    passes = stats.counts["passes"]
    assert passes >= 2, stats.notes
    assert f"passes 2–{passes}: VPL visibility ray traced (1024 ISM points for 1,284 " \
        "triangles)" in stats.notes
    later, = (n for n in stats.notes if n.startswith("automatic parameters of passes 2+"))
    assert " s ray traced)" in later
    assert not stats.warnings, stats.warnings


def test_the_first_traced_pass_sizes_the_traced_passes_after_it(renderer, cached_cost):
    """The first traced pass's measured time rescales the visibility cost, so that the model
    predicts that pass at its time, and the traced passes after it are chosen again for their
    share of the rest: an over-predicted first traced pass gets larger passes after it, an
    under-predicted one smaller."""
    chooser = ChooseParameters(renderer.gpu, renderer.kept, renderer.render)
    chooser.cost_cache = renderer.cost_cache
    work = replace(WORK, fixed=0.5, visibility_cost=1.0, traced_share=1.0, pass_paths=1024)
    traced = replace(BASE, vpl_count=1024)
    s = autotune.chosen_parameters(traced)
    modelled = autotune.predict_seconds(cached_cost, work, *s, traced=True)
    for seconds, larger in ((0.7 * modelled, True), (1.3 * modelled, False)):
        chooser.later = (BASE, work)
        chooser.rescale_traced(seconds, traced)
        again = chooser.rechoose_traced(budget=modelled)
        assert again is not None
        _, rescaled = chooser.later
        assert autotune.predict_seconds(cached_cost, rescaled, *s, traced=True) == \
            pytest.approx(seconds)
        assert (again.settings.vpl_count > 1024) is larger, again.describe()
        assert again.traced_seconds <= modelled or again.settings.vpl_count == 1024


class FakeChooser:
    """A chooser whose traced passes take their budget, but no less than ``least`` seconds
    (the light-path floor)."""

    def __init__(self, least: float) -> None:
        self.least, self.rescaled = least, []

    def rescale_traced(self, wall: float, first: Settings) -> None:
        self.rescaled.append(wall)

    def rechoose_traced(self, budget: float) -> autotune.Choice:
        return autotune.Choice(BASE, 1.0, 0.1, traced_seconds=max(budget, self.least))


@pytest.mark.parametrize("least, each", [(5.0, 20 / 3), (7.8, 10.0), (25.0, 25.0)])
def test_the_traced_passes_after_the_first_fill_the_rest_where_they_fit(least, each):
    """After a first traced pass of 8 s with 20 s left: three passes of 6.7 s where passes may
    shrink so far, else two of 10 s; one that does not fit at all is chosen as the smallest
    (progressive.py's time limit then does not start it)."""
    chooser = FakeChooser(least)
    again = traced_passes_after(chooser, BASE, wall=8.0, rest=20.0)
    assert chooser.rescaled == [8.0]
    assert again.traced_seconds == pytest.approx(each)


def test_a_budget_below_the_cheapest_useful_frame_renders_that_and_says_so(renderer,
                                                                          cached_cost):
    renderer.forget_frames()
    frame, stats = renderer.render_progressive(scene(), replace(BASE, time_budget=0.01))
    assert stats.counts["passes"] == 1
    assert not [n for n in stats.notes if "passes 2+" in n]  # no later pass rendered
    chosen = stats.counts["auto_vpl_count"]
    warning, = [w for w in stats.warnings if "below the cheapest useful frame" in w]
    assert f"({chosen} light paths" in warning and "auto_parameters off" in warning
    indirect = frame.passes["DiffInd"]
    assert float(indirect.mean()) > 0  # not a dark image


def test_a_budget_without_indirect_light_renders_alike_passes(renderer, cached_cost):
    """With no indirect light nothing is chosen: the passes use the settings as set, alike."""
    renderer.forget_frames()
    frame, stats = renderer.render_progressive(scene(), replace(BASE, bounces=0,
                                                                time_budget=1.5))
    assert stats.counts["passes"] >= 2, stats.notes
    assert not [n for n in stats.notes if n.startswith("automatic parameters")]
    assert not stats.warnings
    combined = frame.passes["Combined"]
    assert np.isfinite(combined).all() and float(combined[..., :3].mean()) > 0


def test_a_first_pass_past_its_predicted_time_says_so(renderer, tmp_path):
    """A cost model that under-predicts (here a thousandth of llvmpipe's costs) lets the first
    pass overrun a budget it was predicted to fit: one warning names both times."""
    cheap = replace(COST, renderer=str(renderer.ctx.info["GL_RENDERER"]), paths=0.0,
                    splat=5e-10, texels=3e-10, gather=2e-10, blur=2.5e-10, pixels=1e-9,
                    maps=4e-9, pool=0.0)
    cache = tmp_path / "cost.json"
    cache.write_text(json.dumps(asdict(cheap)))
    previous, renderer.cost_cache = renderer.cost_cache, cache
    try:
        renderer.forget_frames()
        _, stats = renderer.render_progressive(scene(), replace(BASE, time_budget=0.02))
    finally:
        renderer.cost_cache = previous
    warning, = [w for w in stats.warnings if "overrun" in w]
    assert "time budget 0.02 s overrun: the first pass took" in warning
    assert not [w for w in stats.warnings if "cheapest useful frame" in w]


def test_a_budget_render_reads_the_model_files_once(renderer, cached_cost, monkeypatch):
    """The cost-model cache and the error model are read at most once per render (the choice,
    the later passes' choice and the budget each need them), and again only when the file
    changes."""
    reads: list[str] = []
    read_text = autotune.Path.read_text

    def counted(path, *args, **kwargs):
        reads.append(path.name)
        return read_text(path, *args, **kwargs)

    monkeypatch.setattr(autotune.Path, "read_text", counted)
    models = {renderer.cost_cache.name, autotune.ERROR_MODEL_FILE.name}
    renderer.forget_frames()
    renderer.render_progressive(scene(), replace(BASE, time_budget=0.01))
    first = [name for name in reads if name in models]
    assert first.count(renderer.cost_cache.name) == 1  # a new cache file
    assert first.count(autotune.ERROR_MODEL_FILE.name) <= 1  # read by an earlier test maybe
    reads.clear()
    renderer.forget_frames()
    renderer.render_progressive(scene(), replace(BASE, time_budget=0.01))
    assert not [name for name in reads if name in models]
    renderer.cost_cache.write_text(json.dumps(asdict(replace(cached_cost, pixels=1e-3))))
    renderer.render_progressive(scene(), replace(BASE, time_budget=0.01))
    assert [name for name in reads if name in models] == [renderer.cost_cache.name]
