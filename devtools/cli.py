"""Developer command line: ``python -m devtools report SCENE.blend`` measures error against
render time, VPL GI and Cycles (see report.py)."""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from addon.cli import CliError, check_output, run_command


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m devtools", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    add_report_parser(sub)
    return parser


def add_report_parser(sub: argparse._SubParsersAction) -> None:
    report = sub.add_parser(
        "report", help="error against render time: VPL GI and Cycles against a converged "
                       "Cycles reference (report.json, error_vs_time.png, a table)")
    report.add_argument("scene", type=Path,
                        help="the .blend file (never modified), or an .obj asset: camera, sun "
                             "and sky are added unless it emits light")
    report.add_argument("-o", "--output", type=Path,
                        help="folder for report.json and error_vs_time.png "
                             "(default: renders/report_SCENE)")
    report.add_argument("--size", type=int, default=128, help="image edge in pixels (128)")
    report.add_argument("--ladder", choices=("quick", "full", "ism", "large", "auto", "test"),
                        default="quick",
                        help="renders to compare: quick (minutes), full (tens of minutes "
                             "at 128 px), ism (ISM modes only), large (ISM up to 16k paths, "
                             "for big scenes), auto (the automatic mode at 1-16 s budgets "
                             "against ISM ladders), test (seconds, tiny)")
    report.add_argument("--reference-samples", type=int, default=4096,
                        help="Cycles samples of each of the two references (4096)")
    report.add_argument("--cache", type=Path,
                        help="folder of cached references (default: .cache/references in "
                             "the repository)")
    report.set_defaults(run=run_report)


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv)


def check_report_args(args: argparse.Namespace) -> Path:
    """Check the report's input before Blender starts; return the output folder."""
    if not args.scene.is_file():
        raise CliError(f"scene file not found: {args.scene}")
    if args.scene.suffix.lower() not in (".blend", ".obj"):
        raise CliError(f"not a .blend or .obj file: {args.scene}")
    if not 1 <= args.size <= 8192:
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

    from addon import register, unregister
    from addon.engine import monitor

    from . import report

    def request_cancel(_signum, _frame) -> None:
        monitor.cancel_requested = True

    register()
    previous_handler = signal.signal(signal.SIGINT, request_cancel)
    try:
        result = report.run(args.scene, out_dir, report.LADDERS[args.ladder], args.size,
                            args.reference_samples, args.cache or report.DEFAULT_CACHE)
    except report.ReportError as exc:
        raise CliError(str(exc)) from None
    except report.ReportCancelled:
        print("cancelled: no report written", file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGINT, previous_handler)
        unregister()
    print(report.format_table(result))
    print(f"Saved {out_dir / 'report.json'} and {out_dir / 'error_vs_time.png'}")
    return 1 if any("error" in entry for entry in result["renders"]) else 0
