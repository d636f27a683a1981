"""Automatic parameters: the cost model fit, its cache, and choices that respect the goal."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from addon.core.frame import autotune
from addon.core.frame.stages import blur_radius
from addon.core.settings import Settings, SettingsError

COST = autotune.CostModel("test GL", paths=2e-5, splat=2e-9, texels=1e-9, gather=4e-9,
                          blur=1e-8, pixels=2e-6, maps=3e-5, pool=5e-7, frame=0.02,
                          compensation=3e-7, probe=0.01, traced=3e-8, visibility_probe=0.02)
WORK = autotune.Workload(pixels=256 * 256, triangles=30_000, shadow_tiles=6,
                         vpls_per_path=2.5, bounces=4)


def test_passes_lower_the_error_models_floor_as_the_clamp_schedule_does():
    """K passes of N paths: the noise of one set of K·N paths, the floor times K^(-1/3)."""
    model = autotune.ErrorModel(floor=0.04, noise=1.0, ism={"128/8192": 0.0},
                                interleave={"4": 1.0})
    assert model.error(1024, 4, 8192, 128, passes=8) == pytest.approx(
        np.hypot(0.04 / 2, 1.0 / np.sqrt(8 * 1024)))
    assert model.error(8192, 4, 8192, 128) == pytest.approx(np.hypot(0.04, 1.0 / np.sqrt(8192)))


def test_passes_that_trace_their_visibility_add_none_of_the_maps_error():
    model = autotune.ErrorModel(floor=0.0, noise=0.0, ism={"64/1024": 0.08},
                                interleave={"4": 1.0})
    assert model.error(1024, 4, 1024, 64, passes=4) == pytest.approx(0.08)
    assert model.error(1024, 4, 1024, 64, passes=4, traced=3) == pytest.approx(0.02)


def test_the_error_model_file_is_complete_and_plausible():
    model = autotune.load_error_model()
    assert 0 < model.floor < 1 and model.noise > 0
    assert model.ism["128/8192"] == 0.0  # the default pair is the reference of the ISM term
    assert all(0 <= e < 1 for e in model.ism.values())
    assert 0 < model.maps < 1  # the maps' error in undersampled scenes (fitted on long renders)
    errors = [model.error(p, 4, 8192, 128) for p in autotune.PATHS]
    assert errors == sorted(errors, reverse=True)  # more paths, less error


@pytest.mark.parametrize("budget", [0.5, 2.0, 8.0, 30.0])
def test_a_time_budget_is_met_by_the_least_error_that_fits(budget):
    settings = replace(Settings(), auto_parameters="time", time_budget=budget)
    choice = autotune.choose(settings, WORK, COST, autotune.load_error_model())
    assert choice.seconds <= budget
    s = choice.settings
    assert s.visibility == "ism" and s.vpl_count in autotune.PATHS
    assert choice.seconds == pytest.approx(autotune.predict_seconds(
        COST, WORK, s.vpl_count, s.interleave, s.ism_points, s.ism_resolution,
        s.blur_radius if s.interleave > 1 else 0))
    model = autotune.load_error_model()
    for paths, (k, points, resolution) in [(p, o) for p in autotune.PATHS
                                           for o in model.options()]:
        blur = 0 if k == 1 else max(k, settings.blur_radius)
        if autotune.predict_seconds(COST, WORK, paths, k, points, resolution, blur) <= budget:
            assert model.error(paths, k, points, resolution) >= choice.error - 1e-12


def test_a_frame_costs_its_bias_compensation_at_its_ray_cost_and_what_it_spent_before():
    """The image's bias compensation costs its rays at the scene's measured ray cost (the ray
    probe against the calibration room's), and the seconds the frame spent before the choice
    count in its predicted time."""
    plain = replace(WORK, compensation_rays=0)
    busy = replace(WORK, compensation_rays=2, ray_cost=3.0, spent=0.25)
    args = (1024, 4, 8192, 128, 4)
    extra = autotune.predict_seconds(COST, busy, *args) - autotune.predict_seconds(COST, plain,
                                                                                  *args)
    assert extra == pytest.approx(0.25 + COST.compensation * WORK.pixels * 2 * 3.0)
    measured = replace(busy, fixed=1.5)  # a pass measured: its time replaces the model's
    assert autotune.fixed_seconds(COST, measured) == 1.5


def test_a_pass_that_traces_costs_its_pairs_at_the_visibility_ray_cost_instead_of_its_maps():
    """Tracing a pass's VPL visibility costs c_traced per gathered pixel and VPL at the
    scene's visibility ray cost (its probe of rays to VPLs against the calibration room's), in
    place of the maps (and the ISM area table, which it does not use)."""
    work = replace(WORK, visibility_cost=2.0, ray_cost=5.0)
    args = (1024, 4, 8192, 128, 4)
    vpls = 1024 * WORK.vpls_per_path
    maps = COST.pool * WORK.triangles + vpls * (COST.splat * 8192 + COST.texels * 128**2)
    rays = COST.traced * WORK.pixels * vpls / 4**2 * 2.0
    assert autotune.predict_seconds(COST, work, *args, traced=True) == pytest.approx(
        autotune.predict_seconds(COST, work, *args) - maps + rays)


def test_a_plan_prices_its_traced_passes_and_counts_the_maps_error_they_remove(monkeypatch):
    """A budget's passes from ``ray_traced_from`` on are priced as tracing: the plan fits the
    budget at its passes' sum, each pass has at least MIN_PASS_PATHS light paths, and its error
    counts the maps' error (``ErrorModel.maps`` in an undersampled scene) of the mapped passes
    only, so a dear tracing buys fewer passes; the later passes' choice with a
    ``traced_share`` fits its budget at the share's mixed time. Plans within PASSES_TIE of
    the least error go to the most passes."""
    model = replace(autotune.load_error_model(), maps=0.1)
    settings = replace(Settings(), auto_parameters="time", time_budget=40.0)
    dear = replace(COST, traced=1e-6)
    mapped = autotune.choose(settings, WORK, dear, model, split=2)
    work = replace(WORK, ray_traced_from=2, undersampled=True)
    traced = autotune.choose(settings, work, dear, model, split=2)
    assert mapped.traced_seconds == 0.0 and 2 < traced.passes < mapped.passes
    s = traced.settings
    assert s.vpl_count >= autotune.MIN_PASS_PATHS
    args = autotune.chosen_parameters(s)
    assert traced.seconds == pytest.approx(autotune.predict_seconds(dear, work, *args))
    assert traced.traced_seconds == pytest.approx(
        autotune.predict_seconds(dear, work, *args, traced=True))
    tracing = traced.passes - 2
    assert 2 * traced.seconds + tracing * traced.traced_seconds <= 40.0
    assert traced.error == pytest.approx(model.error(
        s.vpl_count, s.interleave, s.ism_points, s.ism_resolution, traced.passes, tracing,
        undersampled=True))
    assert model.error(*args[:4], 8, 6, True) < model.error(*args[:4], 8, 0, True)
    assert "s ray traced)" in traced.describe() and "ray traced" not in mapped.describe()
    later = autotune.choose(replace(settings, time_budget=4.0),
                            replace(WORK, traced_share=0.5, pass_paths=512), dear, model)
    alike = autotune.choose(replace(settings, time_budget=4.0), WORK, dear, model)
    assert 0.5 * (later.seconds + later.traced_seconds) <= 4.0 < later.traced_seconds
    assert 512 <= later.settings.vpl_count < alike.settings.vpl_count
    monkeypatch.setattr(autotune, "PASSES_TIE", 1e9)
    assert autotune.choose(settings, WORK, dear, model, split=2).passes >= mapped.passes


def test_larger_budgets_give_smaller_errors_and_targets_cost_less_when_looser():
    model = autotune.load_error_model()
    base = Settings()
    errors = [autotune.choose(replace(base, auto_parameters="time", time_budget=b), WORK, COST,
                              model).error for b in (0.3, 1, 3, 10, 30)]
    assert errors == sorted(errors, reverse=True) and errors[0] > errors[-1]
    times = [autotune.choose(replace(base, auto_parameters="error", target_error=t), WORK,
                             COST, model) for t in (0.12, 0.2, 0.4)]
    assert all(c.error <= t for c, t in zip(times, (0.12, 0.2, 0.4), strict=True))
    assert [c.seconds for c in times] == sorted((c.seconds for c in times), reverse=True)


def test_the_maps_term_leaves_single_frame_choices_and_targets_as_they_were():
    """The maps' term (undersampled scenes) compares plans of traced passes with one pass; a
    single frame's choice, whose candidates all carry it alike, does not count it, so the
    'error' mode reaches the same targets."""
    model = replace(autotune.load_error_model(), maps=0.1)
    undersampled = replace(WORK, undersampled=True)
    for mode, goal in (("error", {"target_error": 0.06}), ("time", {"time_budget": 2.0})):
        settings = replace(Settings(), auto_parameters=mode, **goal)
        assert autotune.choose(settings, undersampled, COST, model) == \
            autotune.choose(settings, WORK, COST, model)


def test_an_unreachable_target_takes_the_least_error():
    settings = replace(Settings(), auto_parameters="error", target_error=0.001)
    model = autotune.load_error_model()
    choice = autotune.choose(settings, WORK, COST, model)
    most = autotune.PATHS[-1]
    assert choice.settings.vpl_count == most
    assert choice.error == min(model.error(most, k, p, r) for k, p, r in model.options())
    assert choice.error > model.floor  # nothing gets below the floor


def test_calibration_recovers_the_coefficients_of_a_linear_machine():
    """A stand-in renderer whose stage times follow the model exactly: the fit finds them,
    the ISM atlas's allocation (half the texels' cost here) included, which only the first
    render of each setting pays, as every frame of a new process does. Its VPLs are gathered
    once per pixel, as the base settings ask, and made by camera guidance (the stage's name
    then says so; a fit of "vpl generation" alone found no cost). The ray probe's reference
    is its least disturbed measurement."""

    built = []  # the ISM area table is built by the first render only
    allocated = set()  # the settings whose ISM atlas is allocated

    def render(s: Settings) -> dict[str, float | int]:
        assert s.indirect_resolution == "pixel"  # as the base settings gather
        vpls, pixels = 2.0 * s.vpl_count, 256 * 144 * s.antialiasing**2
        gathered, k = autotune.gathered_pixels(pixels, s.interleave, s.antialiasing)
        if s.visibility == "exact":  # no maps: each gathered pair traced
            return {"vpls": vpls, "pixels": pixels, "gather_antialiasing": s.antialiasing,
                    "indirect light": (COST.gather + COST.traced) * gathered * vpls / k**2}
        table = {} if built else {"ism points": COST.pool * 4800}
        built.append(1)
        allocation = 0.0 if s in allocated else 0.5 * COST.texels * vpls * s.ism_resolution**2
        allocated.add(s)
        return {"vpls": vpls, "pixels": pixels, "triangles": 4800, "shadow_tiles": 6,
                "gather_antialiasing": s.antialiasing,
                **table,
                "vpl generation (camera-driven)": COST.paths * s.vpl_count * s.bounces,
                "ray probe": COST.probe * (1.0 + 0.1 * (len(built) - 1)),
                "visibility probe": COST.visibility_probe * (1.0 + 0.1 * (len(built) - 1)),
                "ism upload": allocation,
                "indirect light maps": COST.splat * vpls * s.ism_points
                + 0.5 * COST.texels * vpls * s.ism_resolution**2 + allocation,
                "indirect light": COST.gather * gathered * vpls / k**2,
                "blur": COST.blur * gathered * s.blur_radius if k > 1 else 0.0,
                "g-buffer": 0.5 * (COST.frame + COST.pixels * pixels),
                "bias compensation": COST.compensation * pixels * s.bias_samples,
                "supersample blur": 0.5 * (COST.frame + COST.pixels * pixels),
                "direct light maps": COST.maps * 6}

    fitted = autotune.calibrate(render, "test GL", Settings(indirect_resolution="pixel"))
    for name in ("paths", "splat", "texels", "gather", "blur", "pixels", "maps", "pool",
                 "frame", "compensation", "probe", "traced", "visibility_probe"):
        assert getattr(fitted, name) == pytest.approx(getattr(COST, name), rel=1e-6), name


def test_the_cost_model_is_cached_per_renderer(tmp_path):
    cache = tmp_path / "cost.json"
    measured = []

    def measure() -> autotune.CostModel:
        measured.append(1)
        return COST

    assert autotune.cached_cost_model(cache, "test GL", measure) == COST
    assert autotune.cached_cost_model(cache, "test GL", measure) == COST
    assert len(measured) == 1 and json.loads(cache.read_text())["renderer"] == "test GL"
    other = autotune.cached_cost_model(cache, "another GL", lambda: replace(COST,
                                                                           renderer="another GL"))
    assert other.renderer == "another GL"
    cache.write_text("{not json")
    assert autotune.cached_cost_model(cache, "test GL", measure) == COST and len(measured) == 2


def test_the_automatic_settings_are_validated():
    with pytest.raises(SettingsError, match="auto_parameters"):
        Settings(auto_parameters="fast").validate()
    with pytest.raises(SettingsError, match="time_budget"):
        Settings(time_budget=0.0).validate()


def test_a_real_automatic_frame_lands_near_its_budget(renderer, tmp_path):
    """Calibrate on this machine (the calibration scene), then render another scene with a
    time budget: the frame's time is within a factor of 2 of the prediction, and the note
    names the choice."""
    from tests.core.builders import floor_scene, light, translation
    from tests.core.test_planner import wall

    renderer.cost_cache = tmp_path / "cost.json"
    scene = floor_scene([light(autotune.LightKind.POINT, translation(0, 0, 2), power=50.0)],
                        extra=[wall(2)], size=96)
    settings = replace(Settings(antialiasing=1, interleave=1), auto_parameters="time",
                       time_budget=1.5)
    renderer.render(scene, settings)  # calibrates; compiles the chosen shaders
    assert renderer.cost_cache.is_file()
    renderer.forget_frames()  # the prediction is for a frame made afresh
    _, stats = renderer.render(scene, settings)
    note = next(n for n in stats.notes if n.startswith("automatic parameters (time)"))
    predicted = float(note.split("predicted ")[1].split(" s")[0])
    measured = sum(v for k, v in stats.timings.items() if not k.startswith("ism "))
    assert predicted <= 1.5
    chosen = note.split("points/VPL, ")[1].split("²")[0]
    levels = [k for k in stats.skipped if k.startswith("pull-push levels")]
    assert all(f"{chosen}² maps" in stats.skipped[k] for k in levels)  # planned for the choice
    if "interleave 1" not in note:
        assert "blur" not in stats.skipped and stats.timings["blur"] > 0
    assert 0.5 * predicted <= measured <= 2 * predicted + 0.2, (predicted, measured)
    assert np.isfinite(predicted)
    ray_cost = float(note.split("bias compensation rays at ")[1].split("×")[0])
    assert 0 < ray_cost < 100  # the floor's rays against the calibration room's


@pytest.mark.parametrize("vpls_per_path", [0.05, 0.5, 2.5])
def test_no_choice_is_below_the_cheapest_useful_frame(vpls_per_path):
    """Whatever the budget, the chosen paths leave MIN_VIEW_VPLS VPLs lighting the view; a
    budget below that frame says so (not ``useful``) and gets that frame."""
    work = replace(WORK, vpls_per_path=vpls_per_path)
    least = work.least_paths()
    assert least * vpls_per_path >= autotune.MIN_VIEW_VPLS
    assert least == autotune.PATHS[0] or \
        autotune.PATHS[autotune.PATHS.index(least) - 1] * vpls_per_path < autotune.MIN_VIEW_VPLS
    model = autotune.load_error_model()
    tiny = autotune.choose(replace(Settings(), auto_parameters="time", time_budget=0.01),
                           work, COST, model)
    assert tiny.settings.vpl_count >= least and not tiny.useful
    assert tiny.seconds > 0.01
    fastest = min(autotune.predict_seconds(COST, work, least, k, points, resolution,
                                           blur_radius(k, 4))
                  for k, points, resolution in model.options())
    assert tiny.seconds <= autotune.OVERRUN * fastest  # a little more time for less error
    assert tiny.error <= min(model.error(least, k, p, r) for k, p, r in model.options()
                             if autotune.predict_seconds(COST, work, least, k, p, r,
                                                         blur_radius(k, 4))
                             == fastest)
    ample = autotune.choose(replace(Settings(), auto_parameters="time", time_budget=60.0),
                            work, COST, model)
    assert ample.useful and ample.settings.vpl_count >= least and ample.seconds <= 60.0


def test_a_measured_fixed_cost_replaces_the_modelled_one():
    modelled = autotune.predict_seconds(COST, WORK, 256, 4, 1024, 64, 4)
    rest = COST.frame + COST.pixels * WORK.pixels + COST.maps * WORK.shadow_tiles
    measured = autotune.predict_seconds(COST, replace(WORK, fixed=0.25), 256, 4, 1024, 64, 4)
    assert measured == pytest.approx(modelled - rest + 0.25)


def test_a_budget_is_split_into_passes_only_where_that_costs_little_error():
    """Two passes that would both be the cheapest useful frame, the second past the budget,
    are planned as one pass of the whole budget instead; so are passes that would each repeat
    a fixed cost large enough to cost more than SPLIT_COST of the error."""
    model = autotune.load_error_model()
    fastest = min(autotune.predict_seconds(COST, WORK, WORK.least_paths(), k, p, r,
                                           blur_radius(k, 4))
                  for k, p, r in model.options())

    def planned(budget: float, split: int = 2, work=WORK) -> autotune.Choice:
        settings = replace(Settings(), auto_parameters="time", time_budget=budget)
        return autotune.choose(settings, work, COST, model, split)

    assert planned(1.9 * fastest).passes == 1
    assert planned(1.9 * fastest).seconds <= 1.9 * fastest  # for all of it
    ample = 20 * fastest
    split = planned(ample)
    assert split.passes in (2, 4, 8, 16) and split.seconds <= ample / split.passes
    s = split.settings
    together = model.error(s.vpl_count, s.interleave, s.ism_points, s.ism_resolution,
                           split.passes)
    assert together == split.error
    assert together <= autotune.SPLIT_COST * planned(ample, split=1).error
    for passes in (2, 4, 8, 16):  # within PASSES_TIE of the least error of the counts that fit
        if passes * fastest <= ample:
            other = planned(ample / passes, split=1).settings
            assert together <= autotune.PASSES_TIE * model.error(
                other.vpl_count, other.interleave, other.ism_points, other.ism_resolution,
                passes)
    assert planned(ample, split=1).passes == 1
    costly = replace(WORK, fixed=0.4 * ample)  # a pass's work not chosen: 40 % of the budget
    whole = planned(ample, work=costly)
    assert whole.passes == 1 and ample / 2 < whole.seconds <= ample
    half = planned(ample / 2, split=1, work=costly).settings
    assert whole.error < model.error(2 * half.vpl_count, half.interleave, half.ism_points,
                                     half.ism_resolution)


def test_vpls_gathered_per_pixel_are_costed_at_the_pixels_and_their_pattern():
    """With indirect light per pixel (antialiasing 3) the gather and blur run over a ninth of
    the supersamples, with the 4-pixel pattern that interleave 8 becomes there."""
    per_pixel = replace(WORK, gather_antialiasing=3)
    vpls = 512 * WORK.vpls_per_path
    saved = (COST.gather * WORK.pixels * vpls / 8**2 + COST.blur * WORK.pixels * 4) \
        - (COST.gather * WORK.pixels / 9 * vpls / 4**2 + COST.blur * WORK.pixels / 9 * 4)
    assert saved > 0
    assert autotune.chosen_seconds(COST, per_pixel, 512, 8, 1024, 64, 4) == pytest.approx(
        autotune.chosen_seconds(COST, WORK, 512, 8, 1024, 64, 4) - saved)


def test_more_budget_never_chooses_more_error():
    """Just above the cheapest useful frame's time the choice is as good as just below it
    (where it may take OVERRUN of that time), and from there on error falls with budget."""
    model = autotune.load_error_model()
    fastest = min(autotune.predict_seconds(COST, WORK, WORK.least_paths(), k, p, r,
                                           blur_radius(k, 4))
                  for k, p, r in model.options())
    errors = [autotune.choose(replace(Settings(), auto_parameters="time",
                                      time_budget=fastest * f), WORK, COST, model).error
              for f in np.linspace(0.5, 3.0, 51)]
    assert errors == sorted(errors, reverse=True)


def test_the_visibility_cost_is_measured_only_where_a_plan_could_trace():
    """autotune.may_trace: a plan reaches the switch (pass 3: four passes of a split of two)
    only where four of the cheapest passes of MIN_PASS_PATHS paths fit the budget."""
    model = autotune.load_error_model()
    work = replace(WORK, ray_traced_from=2, visibility_cost=0.0)
    settings = replace(Settings(), auto_parameters="time")
    least = min(min(c.seconds, c.traced) for c in autotune._candidates(settings, work, COST, model)
                if c.paths >= autotune.MIN_PASS_PATHS)

    def may(budget: float, split: int = 2, switch: int | None = 2) -> bool:
        return autotune.may_trace(replace(settings, time_budget=budget),
                                  replace(work, ray_traced_from=switch), COST, model, split)

    assert may(4 * least * 1.01) and not may(4 * least * 0.99)
    assert not may(100 * least, split=1)  # a single frame's choice: no plan of passes
    assert not may(100 * least, switch=None)  # maps hold the scene: nothing traces
    assert not autotune.may_trace(replace(settings, auto_parameters="error", time_budget=100),
                                  work, COST, model, 2)


@pytest.mark.parametrize("traced_share", [0.0, 0.5, 1.0])
def test_a_later_pass_is_filled_to_its_budget_between_the_ladders_rungs(traced_share):
    """autotune.fill raises the chosen light paths, short of the next of PATHS, until a pass
    (of that share traced) is predicted at its budget; a budget the choice already fills
    leaves it as it was."""
    model = autotune.load_error_model()
    work = replace(WORK, traced_share=traced_share, visibility_cost=1.0)
    settings = replace(Settings(), auto_parameters="time", interleave=8, ism_points=8192,
                       ism_resolution=128, blur_radius=4)

    def choice(paths: int) -> autotune.Choice:
        args = (paths, 8, 8192, 128, 4)
        return autotune.Choice(replace(settings, vpl_count=paths),
                               autotune.predict_seconds(COST, work, *args),
                               model.error(*args[:4]),
                               traced_seconds=autotune.predict_seconds(COST, work, *args,
                                                                       traced=True))

    def per_pass(c: autotune.Choice) -> float:
        return (1 - traced_share) * c.seconds + traced_share * c.traced_seconds

    rung = autotune.PATHS.index(1024)
    low, high = choice(1024), choice(autotune.PATHS[rung + 1])
    budget = (per_pass(low) + per_pass(high)) / 2
    filled = autotune.fill(low, work, COST, model, budget)
    assert 1024 < filled.settings.vpl_count < high.settings.vpl_count
    assert per_pass(filled) == pytest.approx(budget, rel=0.01)
    assert per_pass(filled) <= budget
    assert filled.error < low.error
    assert autotune.fill(low, work, COST, model, per_pass(low)) == low
    assert autotune.fill(low, work, COST, model, 10 * per_pass(high)).settings.vpl_count == \
        high.settings.vpl_count - 1  # the next rung would have been chosen where it fitted


def test_the_maps_term_is_fitted_from_long_renders_with_and_without_rays():
    """tools/fit_error_model.py --maps: K passes with the maps throughout against rays from
    pass s differ in RMSE² by maps² (1 − ((s − 1) / K)²), averaged over scenes in squares."""
    from tools.fit_error_model import fit_maps

    def report(passes: int, switch: int, error: float) -> dict:
        lines = [(1, 0.3), (passes, error)]
        return {"renders": [{"settings": {"passes": p, "ray_traced_from_pass": switch},
                             "metrics": {"relative_rmse_unbiased": e}} for p, e in lines]}

    rest, maps = 0.04, [0.03, 0.15]
    pairs = [(report(8, 0, np.hypot(rest, m)), report(8, 3, np.hypot(rest, m * 2 / 8)))
             for m in maps]
    assert fit_maps(pairs) == pytest.approx(np.sqrt(np.mean(np.square(maps))))
