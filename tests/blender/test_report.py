"""The error-against-time report, run as a developer would: ``python -m devtools report`` in a
subprocess, twice on the Cornell box at 16×16 pixels with the tiny 'test' ladder, and with VPL GI
lines over any setting at a non-square size; the speed-up at equal error (curves.py,
report_tables.py) and the reference cache key on synthetic input."""

from __future__ import annotations

import importlib
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from devtools import report_tables
from devtools.curves import TimeAtError, time_at_error, time_ratio
from tests.core.test_tools import NEEDS_BLENDER

REPO = Path(__file__).resolve().parents[2]
CORNELL = REPO / "sample_scenes" / "cornell_box.blend"
METRICS = {"relative_rmse_unbiased", "relative_rmse_unbiased_range", "relative_rmse", "rmse",
           "relative_mse", "mean_relative_energy", "unbiased_squared_error"}


def run_report(out: Path, cache: Path, *options: str, timeout: float = 180
               ) -> tuple[subprocess.CompletedProcess, float]:
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "devtools", "report", str(CORNELL), "-o", str(out),
         "--cache", str(cache), *(options or ("--size", "16", "--ladder", "test",
                                              "--reference-samples", "4096"))],
        cwd=REPO, capture_output=True, text=True, timeout=timeout,
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
    kinds = [entry["kind"] for entry in report["renders"]]
    assert kinds == ["cycles", "cycles", "cycles_oidn", "vpl", "vpl", "auto"]
    oidn = report["renders"][2]
    assert oidn["line"] == "Cycles + OIDN" and oidn["settings"]["use_denoising"]
    assert oidn["settings"]["denoising_input_passes"] == "RGB_ALBEDO_NORMAL"
    assert not report["reference"]["denoised"] and "no denoiser" in result.stdout
    for entry in report["renders"]:
        assert "error" not in entry, entry
        assert entry["seconds"] > 0 and entry["metrics"].keys() >= METRICS
        assert entry.get("settings") or entry["chosen"][0].startswith("automatic parameters")
        if entry["engine"] == "VPL_GI":  # the planner's account of the frame
            assert entry["stages"]["ran"]["g-buffer"] > 0
            assert entry["stages"]["skipped"]["world light"] == "black world"
        if entry["kind"] == "vpl":  # made afresh, nothing kept from the warm-up's frame
            assert not {"vpl generation", "ism", "ism points", "shadow maps",
                        "ray tracing setup"} & entry["stages"]["skipped"].keys()
            assert entry["stages"]["ran"]["ray tracing setup"] > 0
    (auto,) = report["automatic"]
    assert auto["budget"] == 0.5 and auto["seconds"] > 0 and 0 < auto["error"] < 10
    assert "automatic, 0.5 s budget" in result.stdout
    assert all(math.isfinite(n) for n in numbers(report))
    assert (tmp / "first" / "error_vs_time.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "error*" in result.stdout and "vs Cycles + OIDN" in result.stdout  # the table
    assert (tmp / "first" / "table.txt").read_text().startswith("cornell_box.blend, 16×16")
    speed_ups = report["equal_error"]["vpl"]
    assert len(speed_ups) == 3  # two ladder renders, one automatic
    for row in speed_ups:
        for line in ("Cycles", "Cycles + OIDN"):
            assert row[line]["relation"] in "=<>" and row[line]["speed_up"] > 0


def test_error_falls_with_more_samples_and_light_paths(two_runs):
    tmp, *_ = two_runs
    report = json.loads((tmp / "first" / "report.json").read_text())
    for kind in ("cycles", "vpl"):
        errors = [e["metrics"]["relative_rmse_unbiased"] for e in report["renders"]
                  if e["kind"] == kind]
        assert errors == sorted(errors, reverse=True) and errors[0] > errors[-1], kind
    cycles = [e for e in report["renders"] if e["kind"] == "cycles"]
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


def test_vpl_lines_over_any_setting_at_a_non_square_size(tmp_path):
    """--references-only fills the cache for 24×16; then two VPL GI lines (vpl_count, and
    antialiasing) with a --set setting, raw Cycles and Cycles + OIDN ladders of one's choice."""
    size = ("--resolution", "24x16", "--reference-samples", "1024", "--set", "light_samples=4")
    first, _ = run_report(tmp_path / "out", tmp_path / "cache", *size, "--references-only")
    assert first.returncode == 0, first.stderr[-3000:]
    assert first.stdout.count("rendering reference (1024 samples") == 2
    assert "Reference: raw Cycles (no denoiser), 1024 samples × 2" in first.stdout
    assert not (tmp_path / "out" / "report.json").exists()
    result, _ = run_report(tmp_path / "out", tmp_path / "cache", *size,
                           "--vpl-ladder", "vpl_count=16,64", "--vpl-ladder", "antialiasing=1,2",
                           "--cycles-samples", "2,8", "--oidn-samples", "1,4")
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert result.stdout.count("reference: cached") == 2
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["size"] == [24, 16] and report["overrides"] == {"light_samples": 4}
    rows = [(e["line"], e["parameter"], e["value"]) for e in report["renders"]]
    assert rows == [("Cycles", "samples", 2), ("Cycles", "samples", 8),
                    ("Cycles + OIDN", "samples", 1), ("Cycles + OIDN", "samples", 4),
                    ("VPL GI, vpl_count", "vpl_count", 16), ("VPL GI, vpl_count", "vpl_count", 64),
                    ("VPL GI, antialiasing", "antialiasing", 1),
                    ("VPL GI, antialiasing", "antialiasing", 2)]
    for entry in report["renders"][4:]:
        assert entry["settings"][entry["parameter"]] == entry["value"]
        assert entry["settings"]["light_samples"] == 4
        assert entry["settings"]["auto_parameters"] == "off"
    assert [r["value"] for r in report["equal_error"]["vpl"]] == [16, 64, 1, 2]
    assert {r["line"] for r in report["equal_error"]["cycles"]} == {"Cycles", "Cycles + OIDN"}
    assert "VPL GI, antialiasing" in report["equal_error"]["cycles"][0]
    markdown = (tmp_path / "out" / "table.md").read_text().splitlines()
    assert markdown[0].startswith("| renderer | setting | time | error | energy |")
    assert len(markdown) == 2 + len(rows)


@pytest.mark.parametrize("args, message", [
    (["missing.blend"], "scene file not found"),
    ([str(CORNELL), "--size", "0"], "size 0"),
    ([str(CORNELL), "--resolution", "640x0"], "resolution 640x0"),
    ([str(CORNELL), "--resolution", "wide"], "cannot read resolution"),
    ([str(CORNELL), "--vpl-ladder", "no_such_setting=1,2"], "unknown setting 'no_such_setting'"),
    ([str(CORNELL), "--vpl-ladder", "vpl_count=0,16"], "vpl_count = 0 is outside"),
    ([str(CORNELL), "--vpl-ladder", "vpl_count"], "expected NAME=VALUE,VALUE"),
    ([str(CORNELL), "--set", "vpl_count=64", "--vpl-ladder", "vpl_count=16"], "--set fixes"),
    ([str(CORNELL), "--oidn-samples", "4,many"], "--oidn-samples 4,many"),
    ([str(CORNELL), "--cycles-samples", "0"], "must be in 1.."),
])
def test_bad_input_is_one_clear_line_and_exit_code_2(args, message):
    result = subprocess.run([sys.executable, "-m", "devtools", "report", *args], cwd=REPO,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert lines[-1].startswith("error: ") and message in lines[-1]


def power_law(exponent: float, *times: float) -> list[tuple[float, float]]:
    return [(t, t ** exponent) for t in times]


def test_time_at_error_interpolates_on_log_log_axes():
    curve = power_law(-0.5, 1, 4, 16, 64)  # error 1, 0.5, 0.25, 0.125: Monte Carlo's slope
    assert time_at_error(curve, 0.5) == TimeAtError(4, "=")  # a measured point
    found = time_at_error(curve, 0.3)  # between 4 s and 16 s: exact for a power law
    assert found.relation == "=" and math.isclose(found.seconds, 0.3 ** -2)
    assert time_at_error(list(reversed(curve)), 0.3) == found  # order does not matter
    assert math.isclose(time_ratio(curve, 2.0, 0.3).seconds, 0.3 ** -2 / 2)


def test_curves_that_do_not_reach_an_error_give_bounds():
    curve = power_law(-0.5, 1, 4, 16)  # from 100 % at 1 s to 25 % at 16 s
    assert time_at_error(curve, 2.0) == TimeAtError(1, "<")  # below it at its first point
    assert time_at_error(curve, 0.1) == TimeAtError(16, ">")  # never reaches it
    assert time_ratio(curve, 4.0, 0.1) == TimeAtError(4.0, ">")
    assert time_ratio(curve, 4.0, 2.0) == TimeAtError(0.25, "<")
    assert time_at_error([(2.0, 0.3)], 0.3) == TimeAtError(2.0, "=")  # one point
    assert time_at_error([], 0.3) is None and time_ratio(curve, 0.0, 0.3) is None
    assert time_at_error([(0.0, 0.5), (math.nan, 0.1)], 0.3) is None  # no usable point


def test_the_first_crossing_counts_on_a_curve_that_rises_again():
    curve = [(1, 0.4), (2, 0.2), (4, 0.3), (8, 0.1)]  # a plateau that wobbles
    found = time_at_error(curve, 0.25)
    assert found.relation == "=" and 1 < found.seconds < 2
    assert time_at_error(curve, 0.15).seconds > 4  # the dip at 2 s never went that low
    assert time_at_error([(1, 0.3), (2, 0.0)], 0.1).relation == "="  # error 0 (clipped)
    assert time_at_error(curve, 0.0) == TimeAtError(8, ">")


def entry(kind: str, line: str, value: int, seconds: float, error: float) -> dict:
    return {"kind": kind, "line": line, "parameter": "p", "value": value, "seconds": seconds,
            "metrics": {"relative_rmse_unbiased": error, "mean_relative_energy": 0.0}}


def test_equal_error_compares_each_vpl_render_with_each_cycles_line():
    renders = [entry("cycles", "Cycles", 16, 10, 0.6), entry("cycles", "Cycles", 64, 40, 0.3),
               entry("cycles_oidn", "Cycles + OIDN", 4, 3, 0.2),
               entry("cycles_oidn", "Cycles + OIDN", 16, 12, 0.1),
               entry("vpl", "VPL GI", 1024, 10, 0.4), entry("vpl", "VPL GI", 4096, 20, 0.35),
               {"kind": "vpl", "line": "VPL GI", "parameter": "p", "value": 8, "error": "x"}]
    result = report_tables.equal_error(renders)
    first, second = result["vpl"]
    assert first["Cycles + OIDN"] == {"seconds": 3, "relation": "<", "speed_up": 0.3,
                                      "speed_up_relation": "<"}
    expected = 10 * 4 ** (math.log(0.4 / 0.6) / math.log(0.3 / 0.6))  # log-log between 16, 64
    assert math.isclose(first["Cycles"]["seconds"], expected)
    assert math.isclose(first["Cycles"]["speed_up"], expected / 10)
    assert second["Cycles"]["relation"] == "="
    oidn_16 = next(r for r in result["cycles"] if r["value"] == 16 and r["line"] != "Cycles")
    assert oidn_16["VPL GI"] == {"seconds": 20, "relation": ">", "speed_up": 0.6,
                                 "speed_up_relation": "<"}  # VPL GI never gets to 10 %
    cycles_16 = next(r for r in result["cycles"] if r["value"] == 16 and r["line"] == "Cycles")
    assert cycles_16["VPL GI"]["relation"] == "<"  # VPL GI is below 60 % at once
    assert report_tables.speed_up_text(oidn_16["VPL GI"]) == "<0.6× (>20 s)"


def test_readme_block_is_replaced_between_markers():
    text = "intro\n<!-- begin -->\nold\ntable\n<!-- end -->\nrest\n"
    new = report_tables.replace_block(text, "<!-- begin -->", "<!-- end -->", "| new |\n")
    assert new == "intro\n<!-- begin -->\n| new |\n<!-- end -->\nrest\n"
    with pytest.raises(ValueError, match="markers"):
        report_tables.replace_block("no markers", "<!-- begin -->", "<!-- end -->", "x")


def test_reference_cache_key_names_scene_size_samples_seed_and_blender():
    from devtools.report import cycles_settings, reference_key

    settings = cycles_settings(256, 4, 1)
    key = reference_key("abc", (640, 360), settings, "4.5.1")
    assert key == reference_key("abc", (640, 360), dict(settings), "4.5.1")
    others = [reference_key("abd", (640, 360), settings, "4.5.1"),
              reference_key("abc", (360, 640), settings, "4.5.1"),
              reference_key("abc", (640, 360), cycles_settings(512, 4, 1), "4.5.1"),
              reference_key("abc", (640, 360), cycles_settings(256, 4, 2), "4.5.1"),
              reference_key("abc", (640, 360), cycles_settings(256, 3, 1), "4.5.1"),
              reference_key("abc", (640, 360), settings, "5.3.0")]
    assert len({key, *others}) == 1 + len(others)
    assert not settings["use_denoising"]  # references are raw Cycles


def test_markdown_section_has_the_table_the_lookups_and_the_reference():
    renders = [entry("cycles", "Cycles", 16, 10, 0.6), entry("cycles", "Cycles", 64, 40, 0.3),
               entry("cycles_oidn", "Cycles + OIDN", 4, 3, 0.2),
               entry("vpl", "VPL GI", 1024, 10, 0.4)]
    report = {"scene": "x/interior.blend", "size": [640, 360], "bounces": 4,
              "overrides": {"bounces": 4}, "renders": renders,
              "equal_error": report_tables.equal_error(renders),
              "machine": {"cpu_count": 2, "load_average_at_start": [3.0, 2.0, 1.0]},
              "reference": {"samples": 128, "seeds": [1, 2], "seconds": [600.0, 610.0],
                            "cached": [False, False], "relative_noise": 0.05}}
    text = report_tables.markdown_section(report)
    assert text.startswith("**interior.blend, 640×360, 4 diffuse bounces; VPL GI: the scene's "
                           "settings, with bounces=4.** 2 CPU cores, load average 3.0")
    assert "| VPL GI | 1024 p | 10 s | 40.0 % | +0.0 % | <0.3× (<3 s) | 2.2× (22.5 s) |" in text
    assert ("- Cycles + OIDN 4 p: 20.0 % in 3 s; VPL GI does not reach it by its slowest render "
            "(10 s; speed-up <0.3×).") in text
    assert "raw Cycles (no denoiser), 128 samples × 2 (seeds 1, 2), 600 + 610 s" in text


@pytest.mark.parametrize("name", sorted(NEEDS_BLENDER))
def test_the_tools_that_need_blender_import_and_have_a_main(name):
    assert callable(getattr(importlib.import_module(f"tools.{name}"), "main", None))
