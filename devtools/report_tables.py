"""The report's comparisons and outputs: time ratios at equal error (VPL GI against Cycles and
Cycles + OIDN, on log-log curves measured in one run), the text table, the README's Markdown
table and the error-against-time plot. No bpy: it reads report dictionaries only."""

from __future__ import annotations

from pathlib import Path

from .curves import TimeAtError, time_at_error

ERROR = "relative_rmse_unbiased"
VPL_KINDS = ("vpl", "auto")
CYCLES_LINE, OIDN_LINE = "Cycles", "Cycles + OIDN"
CYCLES_LINES = (OIDN_LINE, CYCLES_LINE)
SPEED_UP = ("speed-up at equal error: the time a Cycles line needs for a VPL GI render's error "
            "(log-log interpolation between that line's renders) ÷ the VPL GI render's time; "
            "above 1 VPL GI is faster. '<' and '>' mark bounds: the Cycles line is below that "
            "error already at its quickest render, or does not reach it by its slowest render")


def lines(renders: list[dict]) -> dict[str, list[dict]]:
    """Successful renders grouped by plot line, in ladder order."""
    grouped: dict[str, list[dict]] = {}
    for entry in renders:
        if "metrics" in entry:
            grouped.setdefault(entry["line"], []).append(entry)
    return grouped


def curve(entries: list[dict]) -> list[tuple[float, float]]:
    return [(e["seconds"], e["metrics"][ERROR]) for e in entries]


def _found(found: TimeAtError | None, ratio: TimeAtError | None) -> dict | None:
    if found is None or ratio is None:
        return None
    return {"seconds": found.seconds, "relation": found.relation, "speed_up": ratio.seconds,
            "speed_up_relation": ratio.relation}


_FLIP = {"<": ">", ">": "<", "=": "="}


def equal_error(renders: list[dict]) -> dict[str, object]:
    """For every VPL GI render, the time each Cycles line needs for its error and the speed-up
    (that time ÷ the render's); for every Cycles render, the time each VPL GI line needs for
    its error and the speed-up (the Cycles render's time ÷ that time)."""
    grouped = lines(renders)
    cycles = {name: curve(grouped[name]) for name in CYCLES_LINES if name in grouped}
    vpl_lines = {name: entries for name, entries in grouped.items()
                 if entries[0]["kind"] in VPL_KINDS}
    vpl_rows, cycles_rows = [], []
    for name, entries in vpl_lines.items():
        for e in entries:
            row = {"line": name, "parameter": e["parameter"], "value": e["value"],
                   "seconds": e["seconds"], "error": e["metrics"][ERROR]}
            for other, points in cycles.items():
                found = time_at_error(points, row["error"])
                row[other] = _found(found, found and found.ratio(e["seconds"]))
            vpl_rows.append(row)
    for other in cycles:
        for e in grouped[other]:
            row = {"line": other, "parameter": e["parameter"], "value": e["value"],
                   "seconds": e["seconds"], "error": e["metrics"][ERROR]}
            for name, entries in vpl_lines.items():
                found = time_at_error(curve(entries), row["error"])
                speed_up = found and TimeAtError(e["seconds"] / found.seconds,
                                                 _FLIP[found.relation])
                row[name] = _found(found, speed_up)
            cycles_rows.append(row)
    return {"meaning": SPEED_UP, "vpl": vpl_rows, "cycles": cycles_rows}


def seconds_text(seconds: float) -> str:
    """Three significant digits, without exponents: 0.0374, 7.69, 63.2, 1234."""
    return f"{seconds:.0f}" if seconds >= 100 else f"{seconds:.3g}"


def _time(found: dict) -> str:
    relation = "" if found["relation"] == "=" else found["relation"]
    return f"{relation}{seconds_text(found['seconds'])} s"


def _ratio(found: dict) -> str:
    relation = "" if found["speed_up_relation"] == "=" else found["speed_up_relation"]
    return f"{relation}{found['speed_up']:.2g}×"


def speed_up_text(found: dict | None) -> str:
    """'0.42× (5.1 s)': the speed-up and the other line's time; '-' where none."""
    return "-" if found is None else f"{_ratio(found)} ({_time(found)})"


def lookup_text(row: dict) -> str:
    """One Cycles render's error looked up on the VPL GI lines, as a sentence ('' if none)."""
    targets = []
    for name, found in row.items():
        if not name.startswith("VPL GI") or not found:
            continue
        seconds, ratio = seconds_text(found["seconds"]), _ratio(found)
        if found["relation"] == ">":
            targets.append(f"{name} does not reach it by its slowest render ({seconds} s; "
                           f"speed-up {ratio})")
        elif found["relation"] == "<":
            targets.append(f"{name} is below it already at its quickest render ({seconds} s; "
                           f"speed-up {ratio})")
        else:
            targets.append(f"{name} reaches it in {seconds} s (speed-up {ratio})")
    if not targets:
        return ""
    return (f"{row['line']} {_setting(row)}: {row['error'] * 100:.1f} % in "
            f"{seconds_text(row['seconds'])} s; " + "; ".join(targets) + ".")


def _setting(entry: dict) -> str:
    return f"{entry['value']} {entry['parameter']}"


def _row_key(entry: dict) -> tuple:
    return entry["line"], entry["parameter"], entry["value"]


def reference_text(report: dict) -> str:
    ref = report["reference"]
    seconds = " + ".join(f"{s:.0f}" for s in ref["seconds"])
    return (f"Reference: raw Cycles (no denoiser), {ref['samples']} samples × 2 (seeds "
            f"{', '.join(map(str, ref['seeds']))}), {seconds} s"
            f"{' (cached)' if all(ref['cached']) else ''}; own noise "
            f"{ref['relative_noise'] * 100:.2f} % of its mean, removed by the noise-free "
            f"estimate")


def widest_spread(report: dict) -> float:
    """The largest half-width of relative_rmse_unbiased_range over the renders, relative to
    the error: how far the references' noise can move an error (one standard deviation)."""
    widths = []
    for e in report["renders"]:
        m = e.get("metrics", {})
        low, high = m.get("relative_rmse_unbiased_range", (0.0, 0.0))
        if m.get(ERROR, 0) > 0:
            widths.append((high - low) / 2 / m[ERROR])
    return max(widths, default=0.0)


def scene_text(report: dict) -> str:
    """Scene, size, bounces and the VPL GI settings changed from the scene's."""
    width, height = report["size"]
    changed = ", ".join(f"{name}={value}" for name, value in report.get("overrides", {}).items())
    return (f"{Path(report['scene']).name}, {width}×{height}, {report['bounces']} diffuse "
            f"bounces; VPL GI: the scene's settings{', with ' + changed if changed else ''}")


def header(report: dict) -> str:
    return (f"{scene_text(report)}. error* = noise-free relative RMSE; energy = mean relative "
            "energy")


def format_table(report: dict) -> str:
    """The report as a text table: one row per render (VPL GI rows with their speed-up at
    equal error against each Cycles line), each Cycles render against the VPL GI lines, the
    automatic mode's renders and the reference."""
    speed_ups = {_row_key(r): r for r in report.get("equal_error", {}).get("vpl", [])}
    others = [name for name in CYCLES_LINES
              if any(e["line"] == name for e in report["renders"])]
    label = max([len(e["line"]) for e in report["renders"]] + [8])
    rows = [header(report), f"{'renderer':<{label}} {'setting':>17} {'time (s)':>9} "
            f"{'error*':>7} {'energy':>8}" + "".join(f"  {'vs ' + name:<24}" for name in others)]
    for e in report["renders"]:
        head = f"{e['line']:<{label}} {e['value']:>6} {e['parameter']:<10}"
        if "error" in e:
            rows.append(f"{head} failed: {e['error']}")
            continue
        m = e["metrics"]
        row = (f"{head} {e['seconds']:>9.2f} {m[ERROR] * 100:>6.1f}% "
               f"{m['mean_relative_energy'] * 100:>+7.1f}%")
        found = speed_ups.get(_row_key(e))
        if found is not None:
            row += "".join(f"  {speed_up_text(found.get(name)):<24}" for name in others)
        rows.append(row.rstrip())
    rows.append(f"{SPEED_UP}.")
    for row in report.get("equal_error", {}).get("cycles", []):
        text = lookup_text(row)
        if text:
            rows.append(text)
    for gap in report.get("automatic", []):
        front = gap["front_error_in_time"]
        quickest = gap["front_time_for_error"]
        rows.append(f"automatic, {gap['budget']:g} s budget: {gap['seconds']:.2f} s, "
                    f"{gap['error'] * 100:.2f} %; the ladder's best in that time: "
                    + (f"{front * 100:.2f} %" if front is not None else "none that fast")
                    + "; its quickest to that error: "
                    + (f"{quickest:.2f} s" if quickest is not None else "none that good"))
    rows.append(f"* {reference_text(report)}; it moves any error above by at most "
                f"{widest_spread(report) * 100:.1f} % of itself (one standard deviation).")
    return "\n".join(rows)


def markdown_table(report: dict) -> str:
    """The report as the README's Markdown table: renderer, setting, time, error, energy and
    the speed-ups of VPL GI rows at equal error."""
    speed_ups = {_row_key(r): r for r in report.get("equal_error", {}).get("vpl", [])}
    others = [name for name in CYCLES_LINES
              if any(e["line"] == name for e in report["renders"])]
    rows = ["| renderer | setting | time | error | energy | "
            + " | ".join(f"speed-up vs {name}" for name in others) + " |",
            "|---|---|---|---|---|" + "---|" * len(others)]
    for e in report["renders"]:
        if "metrics" not in e:
            rows.append(f"| {e['line']} | {_setting(e)} | failed | | |" + " |" * len(others))
            continue
        m = e["metrics"]
        found = speed_ups.get(_row_key(e)) or {}
        cells = [speed_up_text(found[name]) if found.get(name) else "" for name in others]
        rows.append(f"| {e['line']} | {_setting(e)} | {seconds_text(e['seconds'])} s | "
                    f"{m[ERROR] * 100:.1f} % | {m['mean_relative_energy'] * 100:+.1f} % | "
                    + " | ".join(cells) + " |")
    return "\n".join(rows)


def markdown_section(report: dict) -> str:
    """One scene's part of the README: a heading line (scene, size, bounces, VPL GI settings,
    machine), the table, each Cycles + OIDN render's error against the VPL GI lines, and the
    reference."""
    machine = report.get("machine", {})
    load = machine.get("load_average_at_start")
    parts = [f"**{scene_text(report)}.** {machine.get('cpu_count', '?')} CPU "
             f"cores{f', load average {load[0]:.1f} at the start' if load else ''}.", "",
             markdown_table(report), ""]
    for row in report.get("equal_error", {}).get("cycles", []):
        if row["line"] != CYCLES_LINES[0]:
            continue
        text = lookup_text(row)
        if text:
            parts.append(f"- {text}")
    parts += ["", f"{reference_text(report)}; it moves any error above by at most "
                  f"{widest_spread(report) * 100:.1f} % of itself (one standard deviation)."]
    return "\n".join(parts)


def replace_block(text: str, begin: str, end: str, body: str) -> str:
    """``text`` with what lies between the lines ``begin`` and ``end`` replaced by ``body``;
    ValueError if the markers are missing or out of order."""
    start, stop = text.find(begin), text.find(end)
    if start < 0 or stop < start:
        raise ValueError(f"markers not found in order: {begin!r} ... {end!r}")
    return text[:start + len(begin)] + "\n" + body.strip("\n") + "\n" + text[stop:]


def plot(report: dict, path: Path) -> None:
    """Noise-free relative RMSE against seconds, log-log, one line per engine/mode."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 6), dpi=110, layout="constrained")
    axes = figure.add_subplot()
    for line, entries in lines(report["renders"]).items():
        points = [(e["seconds"], e["metrics"][ERROR], e["value"])
                  for e in entries if e["metrics"][ERROR] > 0]
        if not points:
            continue
        x, y, _ = zip(*points, strict=True)
        axes.plot(x, y, marker="o", label=f"{line} ({entries[0]['parameter']})")
        for xi, yi, label in points:
            axes.annotate(str(label), (xi, yi), textcoords="offset points", xytext=(4, 4),
                          fontsize=8)
    noise = report["reference"]["relative_noise"]
    if noise > 0:
        axes.axhline(noise, color="grey", linestyle=":", label="reference's own noise")
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.set_xlabel("render time (s, wall clock, export included)")
    axes.set_ylabel("relative RMSE (noise-free estimate)")
    width, height = report["size"]
    axes.set_title(f"{Path(report['scene']).name}, {width}×{height}, {report['bounces']} "
                   "bounces; labels: the setting each line varies", fontsize=10)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=8)
    figure.savefig(path)
