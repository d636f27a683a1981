"""The denoiser: Open Image Denoise lowers the error of a noisy frame, falls back to the blur
with one warning where pyoidn is missing, never hands out NaN; the Denoising Data passes."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

from addon.core.frame import denoise
from addon.core.frame.renderer import Renderer
from addon.core.scene.model import Instance, LightKind, Material, Scene, World
from addon.core.settings import Settings
from devtools import metrics
from tests.core.builders import light, quad, top_down_camera, translation
from tests.core.test_frame_stages import lit_corner

NOISY = Settings(antialiasing=1, vpl_count=64, bounces=1, seed=3, interleave=4)


@pytest.fixture(scope="module")
def reference(renderer: Renderer) -> np.ndarray:
    """The corner with 16 times the light paths, every pixel gathering every VPL."""
    renderer.forget_frames()
    frame, _ = renderer.render(lit_corner(), Settings(antialiasing=1, vpl_count=1024, bounces=1,
                                                      seed=5, interleave=1))
    return frame.passes["Combined"]


def test_oidn_lowers_the_error_of_a_noisy_frame(renderer: Renderer, reference: np.ndarray,
                                                monkeypatch) -> None:
    pytest.importorskip("pyoidn")
    settings = replace(NOISY, denoiser="oidn")
    renderer.forget_frames()
    denoised, stats = renderer.render(lit_corner(), settings)
    assert "denoise" in stats.timings and stats.skipped.get("blur") == "denoiser = oidn"
    assert not stats.warnings, stats.warnings
    monkeypatch.setattr(denoise.Denoise, "run", lambda self, frame: None)
    renderer.forget_frames()
    raw, _ = renderer.render(lit_corner(), settings)
    raw_error = metrics.relative_rmse(raw.passes["Combined"], reference)
    denoised_error = metrics.relative_rmse(denoised.passes["Combined"], reference)
    assert denoised_error < 0.8 * raw_error, (raw_error, denoised_error)
    assert np.all(np.isfinite(denoised.passes["Combined"]))
    np.testing.assert_array_equal(denoised.passes["Combined"][..., 3],
                                  raw.passes["Combined"][..., 3])


def test_without_pyoidn_the_blur_denoises_with_one_warning(renderer: Renderer,
                                                           monkeypatch) -> None:
    renderer.forget_frames()
    blurred, _ = renderer.render(lit_corner(), NOISY)
    monkeypatch.setitem(sys.modules, "pyoidn", None)  # import pyoidn raises ImportError
    for choice in denoise.OIDN_DENOISERS:
        renderer.forget_frames()
        frame, stats = renderer.render(lit_corner(),
                                       replace(NOISY, denoiser=choice))
        warnings = [w for w in stats.warnings if "Open Image Denoise" in w]
        assert len(warnings) == 1 and len(stats.warnings) == 1, stats.warnings
        assert "blur" in warnings[0] and "denoise" not in stats.timings
        assert "blur" in stats.timings
        np.testing.assert_array_equal(frame.passes["Combined"], blurred.passes["Combined"])


def test_denoise_image_never_returns_nan() -> None:
    oidn = pytest.importorskip("pyoidn")
    rng = np.random.default_rng(0)
    color = rng.exponential(1.0, (24, 32, 3)).astype(np.float32)
    color[3, 4] = np.nan
    color[5, 6] = np.inf
    color[7, 8] = -2.0
    albedo = np.full_like(color, 0.5)
    albedo[1, 1] = np.nan
    normal = np.zeros_like(color)
    normal[..., 2] = -1.0
    normal[2, 2] = np.inf
    out = denoise.denoise_image(oidn, color, albedo, normal)
    assert out.shape == color.shape and out.dtype == np.float32
    assert np.all(np.isfinite(out)) and out.min() >= 0.0


class _Failing:
    @staticmethod
    def denoise(*_args, **_kwargs):
        raise RuntimeError("OIDN execute failed (error 5): unsupported hardware")


def test_a_failing_oidn_leaves_the_image_with_one_warning(renderer: Renderer,
                                                          monkeypatch) -> None:
    monkeypatch.setattr(denoise, "load_oidn", lambda: (_Failing, ""))
    renderer.forget_frames()
    frame, stats = renderer.render(lit_corner(), replace(NOISY, denoiser="blur_oidn"))
    assert len(stats.warnings) == 1 and "unsupported hardware" in stats.warnings[0]
    assert np.all(np.isfinite(frame.passes["Combined"]))


def _rows(mask: np.ndarray, value: tuple[float, ...]) -> np.ndarray:
    return np.broadcast_to(np.asarray(value, np.float32), (int(mask.sum()), len(value)))


def test_denoising_data_follows_cycles_conventions(renderer: Renderer) -> None:
    """Albedo = diffuse colour + emission, or the background's radiance where nothing is hit;
    normal in camera space (+Z forward); depth along the ray; both 0 on the background."""
    sky = (0.2, 0.3, 0.4)
    tile = Instance(quad(1.5, 1.5), np.eye(4), [Material("tile", (0.7, 0.5, 0.3))])
    scene = Scene([tile], [light(LightKind.POINT, translation(0, 0, 2), power=20)],
                  World(sky), top_down_camera(32))
    renderer.forget_frames()
    frame, _ = renderer.render(scene, Settings(antialiasing=2, vpl_count=16, bounces=1))
    p = frame.passes
    covered = p["Combined"][..., 3] == 1.0
    inside = (p["DiffCol"] > 0).all(axis=-1) & (np.abs(p["DiffCol"] - (0.7, 0.5, 0.3)) < 1e-6
                                                 ).all(axis=-1)
    outside = (p["DiffCol"] == 0).all(axis=-1)
    assert inside.mean() > 0.2 and outside.mean() > 0.2 and covered.all()
    albedo = p["Denoising Albedo"]
    np.testing.assert_allclose(albedo[inside], _rows(inside, (0.7, 0.5, 0.3)), atol=1e-6)
    np.testing.assert_allclose(albedo[outside], _rows(outside, sky), atol=1e-6)
    np.testing.assert_allclose(p["Denoising Normal"][inside], _rows(inside, (0, 0, -1)), atol=1e-5)
    np.testing.assert_array_equal(p["Denoising Normal"][outside], 0.0)
    np.testing.assert_allclose(p["Denoising Depth"][inside], p["Depth"][inside], atol=1e-4)
    np.testing.assert_array_equal(p["Denoising Depth"][outside], 0.0)


def test_denoising_data_is_left_out_unless_asked_for_or_needed(renderer: Renderer) -> None:
    renderer.forget_frames()
    frame, stats = renderer.render(lit_corner(), Settings(antialiasing=1, vpl_count=16, bounces=1),
                                   passes=frozenset())
    assert "denoising data" not in stats.timings
    assert "Denoising Albedo" not in frame.passes


def test_oidn_on_indirect_light_keeps_the_pass_algebra(renderer: Renderer) -> None:
    """Combined = (DiffDir + DiffInd) × DiffCol + Emit after denoising the indirect light, and
    direct light is left as it is."""
    pytest.importorskip("pyoidn")
    renderer.forget_frames()
    blurred, _ = renderer.render(lit_corner(), replace(NOISY, denoiser="blur"))
    renderer.forget_frames()
    frame, stats = renderer.render(lit_corner(), replace(NOISY, denoiser="oidn_indirect"))
    p = frame.passes
    assert "denoise" in stats.timings and not stats.warnings
    rebuilt = (p["DiffDir"] + p["DiffInd"]) * p["DiffCol"] + p["Emit"]
    np.testing.assert_allclose(p["Combined"][..., :3], rebuilt, rtol=1e-4, atol=1e-5)
    np.testing.assert_array_equal(p["DiffDir"], blurred.passes["DiffDir"])
    assert not np.array_equal(p["DiffInd"], blurred.passes["DiffInd"])
