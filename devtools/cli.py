"""Developer command line: ``python -m devtools report SCENE.blend`` measures error against
render time: VPL GI, raw Cycles and Cycles + OIDN (see report.py)."""

from __future__ import annotations

import argparse
import signal
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from addon.cli import CliError, check_output, parse_overrides, parse_resolution, run_command

if TYPE_CHECKING:
    from addon.core.settings import Value

    from . import report as report_options


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m devtools", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    add_report_parser(sub)
    return parser


def add_report_parser(sub: argparse._SubParsersAction) -> None:
    report = sub.add_parser(
        "report", help="error against render time: VPL GI, raw Cycles and Cycles + OIDN "
                       "against converged Cycles references (report.json, table.txt, "
                       "table.md, error_vs_time.png, and the table on stdout)")
    report.add_argument("scene", type=Path,
                        help="the .blend file (never modified), or an .obj asset: camera, sun "
                             "and sky are added unless it emits light")
    report.add_argument("-o", "--output", type=Path,
                        help="folder for report.json, table.txt, table.md and "
                             "error_vs_time.png (default: renders/report_SCENE)")
    size = report.add_mutually_exclusive_group()
    size.add_argument("-r", "--resolution", default="640x360",
                      help="image size WIDTHxHEIGHT (640x360)")
    size.add_argument("--size", type=int, help="a square image of this edge in pixels")
    report.add_argument("--ladder", choices=tuple(LADDER_NAMES), default="compare",
                        help="preset renders to compare: compare (what users pick instead: "
                             "Cycles + OIDN 4/16/64 spp, Cycles 4/16/64 spp, VPL GI 1024 and "
                             "4096 light paths), quick, full, ism (ISM modes), large (ISM up "
                             "to 16k paths), auto (the automatic mode at 1-16 s budgets), "
                             "test (seconds, tiny)")
    report.add_argument("--cycles-samples", metavar="N,N,...",
                        help="raw Cycles sample counts, replacing the preset's ('none': no "
                             "raw Cycles renders)")
    report.add_argument("--oidn-samples", metavar="N,N,...",
                        help="Cycles + OpenImageDenoise sample counts, replacing the preset's "
                             "('none': no denoised Cycles renders)")
    report.add_argument("--vpl-ladder", action="append", default=[], metavar="NAME=V,V,...",
                        help="a VPL GI line varying one setting, e.g. vpl_count=256,1024,4096 "
                             "or passes=1,2,4,8 (repeatable; replaces the preset's VPL GI "
                             "lines)")
    report.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a VPL GI setting for every VPL GI render, e.g. --set bounces=4 "
                             "(repeatable; names as in core/settings.py; bounces also sets "
                             "Cycles' diffuse bounces)")
    report.add_argument("--reference-samples", type=int, default=256,
                        help="Cycles samples of each of the two raw references (256; the "
                             "noise-free metric removes their noise, the table says how far "
                             "it can still move an error)")
    report.add_argument("--references-only", action="store_true",
                        help="render (or find cached) the two references, then stop")
    report.add_argument("--cache", type=Path,
                        help="folder of cached references (default: .cache/references in "
                             "the repository)")
    report.set_defaults(run=run_report)


LADDER_NAMES = ("compare", "quick", "full", "ism", "large", "auto", "test")


def sample_list(option: str, text: str) -> tuple[int, ...]:
    """'4,16,64' -> (4, 16, 64); 'none' -> ()."""
    if text.strip().lower() == "none":
        return ()
    try:
        samples = tuple(int(part) for part in text.split(","))
    except ValueError:
        raise CliError(f"{option} {text}: cannot read sample counts (use e.g. 4,16,64 or "
                       "none)") from None
    if not all(1 <= n <= 1 << 24 for n in samples):
        raise CliError(f"{option} {text}: sample counts must be in 1..{1 << 24}")
    return samples


def parse_vpl_ladder(text: str, overrides: dict[str, Value]) -> tuple[str, tuple[Value, ...]]:
    """'vpl_count=256,1024' -> ('vpl_count', (256, 1024)), each value read and checked by the
    settings schema (together with the --set settings)."""
    from addon.core.settings import Settings, SettingsError

    name, sep, values = text.partition("=")
    name = name.strip()
    if not sep or not values.strip():
        raise CliError(f"--vpl-ladder {text}: expected NAME=VALUE,VALUE,..., e.g. "
                       "vpl_count=256,1024,4096")
    if name in overrides:
        raise CliError(f"--vpl-ladder {name} varies a setting that --set fixes")
    try:
        parsed = tuple(Settings.parse(name, part) for part in values.split(","))
        for value in parsed:
            replace(Settings(), **{**overrides, name: value}).validate()
    except SettingsError as exc:
        raise CliError(f"--vpl-ladder {text}: {exc}") from None
    return name, parsed


def vpl_line_label(index: int, name: str, ladders: list[tuple[str, tuple]]) -> str:
    """'VPL GI' for a single line; 'VPL GI, NAME' (numbered if NAME repeats) among several."""
    if len(ladders) == 1:
        return "VPL GI"
    names = [n for n, _ in ladders]
    repeat = f" {names[:index].count(name) + 1}" if names.count(name) > 1 else ""
    return f"VPL GI, {name}{repeat}"


def build_options(args: argparse.Namespace) -> report_options.Options:
    """The report's Options from the command line (everything checked before Blender starts
    rendering)."""
    resolution = (args.size, args.size) if args.size is not None else \
        parse_resolution(args.resolution)
    overrides = parse_overrides(args.set)
    vpl_ladders = [parse_vpl_ladder(text, overrides) for text in args.vpl_ladder]
    cycles_samples, oidn_samples = (
        None if text is None else sample_list(option, text)
        for option, text in (("--cycles-samples", args.cycles_samples),
                             ("--oidn-samples", args.oidn_samples)))

    from . import report  # imports bpy: after the checks, so that bad input fails at once

    ladder = report.LADDERS[args.ladder]
    if vpl_ladders:
        ladder = replace(ladder, vpl_lines=tuple(
            report.VPLLine(name, values, name=vpl_line_label(i, name, vpl_ladders))
            for i, (name, values) in enumerate(vpl_ladders)))
    if cycles_samples is not None:
        ladder = replace(ladder, cycles_samples=cycles_samples)
    if oidn_samples is not None:
        ladder = replace(ladder, oidn_samples=oidn_samples)
    return report.Options(ladder, resolution, overrides, args.reference_samples,
                          args.cache or report.DEFAULT_CACHE, args.references_only)


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv)


def check_report_args(args: argparse.Namespace) -> Path:
    """Check the report's input before Blender starts; return the output folder."""
    if not args.scene.is_file():
        raise CliError(f"scene file not found: {args.scene}")
    if args.scene.suffix.lower() not in (".blend", ".obj"):
        raise CliError(f"not a .blend or .obj file: {args.scene}")
    if args.size is not None and not 1 <= args.size <= 8192:
        raise CliError(f"size {args.size} is outside 1..8192")
    if not 1 <= args.reference_samples <= 1 << 24:
        raise CliError(f"reference samples {args.reference_samples} is outside 1..{1 << 24}")
    out_dir = args.output or Path("renders") / f"report_{args.scene.stem}"
    check_output(out_dir / "report.json", args.scene)
    return out_dir


def run_report(args: argparse.Namespace) -> int:
    """Render the error-against-time report (see report.py); exit code 1 if a render failed,
    130 on Ctrl-C (after the current render; no report written)."""
    out_dir = check_report_args(args)
    options = build_options(args)

    from addon import register, unregister
    from addon.engine import monitor

    from . import report, report_tables

    def request_cancel(_signum, _frame) -> None:
        monitor.cancel_requested = True

    register()
    previous_handler = signal.signal(signal.SIGINT, request_cancel)
    try:
        result = report.run(args.scene, out_dir, options)
    except report.ReportError as exc:
        raise CliError(str(exc)) from None
    except report.ReportCancelled:
        print("cancelled: no report written", file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGINT, previous_handler)
        unregister()
    if options.references_only:
        print(report_tables.reference_text(result))
        return 0
    print(report_tables.format_table(result))
    print(f"Saved {out_dir / 'report.json'}, table.txt, table.md and error_vs_time.png there")
    return 1 if any("error" in entry for entry in result["renders"]) else 0
