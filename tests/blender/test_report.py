"""The error-against-time report, run as a developer would: ``python -m devtools report`` in a
subprocess, twice on the Cornell box at 16×16 pixels with the tiny 'test' ladder."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
CORNELL = REPO / "sample_scenes" / "cornell_box.blend"
METRICS = {"relative_rmse_unbiased", "relative_rmse", "rmse", "relative_mse",
           "mean_relative_energy", "unbiased_squared_error"}


def run_report(out: Path, cache: Path) -> tuple[subprocess.CompletedProcess, float]:
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "devtools", "report", str(CORNELL), "-o", str(out), "--size", "16",
         "--ladder", "test", "--reference-samples", "4096", "--cache", str(cache)],
        cwd=REPO, capture_output=True, text=True, timeout=180,
        env={**os.environ, "XDG_CACHE_HOME": str(cache / "user")})  # the cost model's cache
    return result, time.perf_counter() - start


def numbers(value: object) -> list[float]:
    """Every int/float inside a JSON value."""
    if isinstance(value, dict):
        return [n for v in value.values() for n in numbers(v)]
    if isinstance(value, list):
        return [n for v in value for n in numbers(v)]
    return [float(value)] if isinstance(value, int | float) else []


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """The report run twice with one reference cache: (first, second) as (result, seconds)."""
    tmp = tmp_path_factory.mktemp("report")
    first = run_report(tmp / "first", tmp / "cache")
    second = run_report(tmp / "second", tmp / "cache")
    return tmp, first, second


def test_report_has_every_field_and_finite_numbers(two_runs):
    tmp, (result, _), _ = two_runs
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    report = json.loads((tmp / "first" / "report.json").read_text())
    assert {"cpu", "cpu_count", "gl_renderer", "blender"} <= report["machine"].keys()
    assert {"samples", "seconds", "relative_noise"} <= report["reference"].keys()
    assert report["size"] == [16, 16] and "wall-clock" in report["timing"]
    engines = {entry["engine"] for entry in report["renders"]}
    assert engines == {"CYCLES", "VPL_GI"}
    for entry in report["renders"]:
        assert "error" not in entry, entry
        assert entry["seconds"] > 0 and entry["metrics"].keys() >= METRICS
        assert entry.get("settings") or entry["chosen"][0].startswith("automatic parameters")
        if entry["engine"] == "VPL_GI":  # the planner's account of the frame
            assert entry["stages"]["ran"]["g-buffer"] > 0
            assert entry["stages"]["skipped"]["world light"] == "black world"
    (auto,) = report["automatic"]
    assert auto["budget"] == 0.5 and auto["seconds"] > 0 and 0 < auto["error"] < 10
    assert "automatic, 0.5 s budget" in result.stdout
    assert all(math.isfinite(n) for n in numbers(report))
    assert (tmp / "first" / "error_vs_time.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "relRMSE" in result.stdout  # the table


def test_error_falls_with_more_samples_and_light_paths(two_runs):
    tmp, *_ = two_runs
    report = json.loads((tmp / "first" / "report.json").read_text())
    for engine in ("CYCLES", "VPL_GI"):
        errors = [e["metrics"]["relative_rmse_unbiased"] for e in report["renders"]
                  if e["engine"] == engine and "settings" in e]
        assert errors == sorted(errors, reverse=True) and errors[0] > errors[-1], engine
    cycles = [e for e in report["renders"] if e["engine"] == "CYCLES"]
    assert [e["value"] for e in cycles] == [4, 64]
    assert cycles[-1]["metrics"]["relative_rmse_unbiased"] < \
        0.5 * cycles[0]["metrics"]["relative_rmse_unbiased"]  # ~1/4 expected


def test_second_run_uses_cached_references_and_is_faster(two_runs):
    tmp, (first, first_seconds), (second, second_seconds) = two_runs
    assert first.returncode == 0 and second.returncode == 0, second.stderr[-3000:]
    assert "rendering reference" in first.stdout and "reference: cached" not in first.stdout
    assert second.stdout.count("reference: cached") == 2
    assert "rendering reference" not in second.stdout
    report = json.loads((tmp / "second" / "report.json").read_text())
    assert report["reference"]["cached"] == [True, True]
    assert second_seconds < first_seconds


@pytest.mark.parametrize("args, message", [
    (["missing.blend"], "scene file not found"),
    ([str(CORNELL), "--size", "0"], "size 0"),
])
def test_bad_input_is_one_clear_line_and_exit_code_2(args, message):
    result = subprocess.run([sys.executable, "-m", "devtools", "report", *args], cwd=REPO,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert lines[-1].startswith("error: ") and message in lines[-1]
