"""Camera-driven VPLs: the same VPL count spent on what the camera sees, unbiased."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings
from addon.core.transport.guidance import MIN_ACCEPTANCE, acceptance
from devtools import metrics
from tests.core.builders import floor_scene, light, quad, rotation_x, translation

BASE = Settings(antialiasing=1, bounces=1, vpl_count=256, visibility="exact", interleave=1,
                clamp_distance=0.02)


def mostly_wasted_scene():
    """A lit wall beside the floor the camera sees, and a second light that only lights the
    back of a far wall turned away from everything: most VPLs light nothing in view."""
    near_wall = Instance(quad(5, 2), translation(0, 4, 2) @ rotation_x(np.pi / 2),
                         [Material("near", (0.8, 0.3, 0.3))])
    far_wall = Instance(quad(5, 5), translation(0, -30, 5) @ rotation_x(np.pi / 2),
                        [Material("far", (0.8, 0.8, 0.8))])
    lights = [light(LightKind.POINT, translation(0, 2, 1), power=100),
              light(LightKind.POINT, translation(0, -33, 5), power=300)]
    return floor_scene(lights, extra=[near_wall, far_wall], size=24)


def test_guided_vpls_light_the_view_with_less_error_and_the_same_energy(renderer) -> None:
    reference, _ = renderer.render_progressive(
        mostly_wasted_scene(), replace(BASE, vpl_guidance="off", vpl_count=2048, passes=16))
    truth = reference.passes["DiffInd"]
    error, energy, stats = {}, {}, {}
    for guidance in ("off", "camera"):
        frame, stats[guidance] = renderer.render_progressive(
            mostly_wasted_scene(), replace(BASE, vpl_guidance=guidance, passes=4))
        image = frame.passes["DiffInd"]
        error[guidance] = metrics.relative_rmse(image, truth)
        energy[guidance] = metrics.mean_relative_energy(image, truth)
    guided = stats["camera"].counts
    assert guided["vpls_in_view_pct"] >= 70 > guided["candidates_in_view_pct"] + 40, guided
    assert error["camera"] < 0.75 * error["off"], error
    assert abs(energy["camera"]) < 0.05, energy


def test_acceptance_spends_the_budget_on_contribution() -> None:
    contribution = np.r_[np.zeros(900), np.linspace(1, 2, 100)]
    chance = acceptance(contribution, 120.0)  # at most 100 + 0.05 × 900 = 145 are possible
    assert abs(chance.sum() - 120) < 0.01
    assert np.all(chance[:900] == MIN_ACCEPTANCE) and np.all(chance[900:] > MIN_ACCEPTANCE)
    assert np.all(np.diff(chance[900:]) >= 0)  # more contribution, more chance
    assert np.all(acceptance(contribution, 2000.0) == 1.0)  # fewer candidates than wanted


def test_the_decision_costs_a_small_probe_not_a_round_of_candidates(renderer, monkeypatch):
    """Whether guidance pays is decided from DECISION_PATHS light paths: where most VPLs light
    the view the frame traces only those and its plain paths (no FIRST_ROUND × vpl_count round),
    and where few do the guided rounds follow."""
    from addon.core.frame import vpl_stage

    traced: list[int] = []
    plain = vpl_stage.generate_vpls

    def counting(scene, geometry, settings, *args):
        traced.append(settings.vpl_count)
        return plain(scene, geometry, settings, *args)

    monkeypatch.setattr(vpl_stage, "generate_vpls", counting)
    from tests.core.test_progressive import closed_sphere

    settings = replace(BASE, vpl_count=512)
    renderer.forget_frames()
    _, stats = renderer.render(closed_sphere(), settings)  # every VPL lights the view
    assert "vpl guidance" in stats.skipped
    assert traced == [vpl_stage.DECISION_PATHS, 512]
    traced.clear()
    renderer.forget_frames()
    _, stats = renderer.render(mostly_wasted_scene(), settings)
    assert "vpl guidance" not in stats.skipped and stats.counts["vpls_in_view_pct"] >= 50
    assert traced[:2] == [vpl_stage.DECISION_PATHS, vpl_stage.FIRST_ROUND * 512]
