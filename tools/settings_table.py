"""The settings table of docs/settings.md, made from the settings schema (addon/core/settings.py).

    .venv/bin/python tools/settings_table.py           # print the markdown table
    .venv/bin/python tools/settings_table.py --write   # replace the table in docs/settings.md
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from addon.core.settings import DEFAULTS, SCHEMA, SECTIONS, Meta, Value  # noqa: E402

TABLE_FILE = REPO / "docs" / "settings.md"
START, END = "<!-- settings-table:start -->", "<!-- settings-table:end -->"
_UNITS = {"TIME_ABSOLUTE": " s"}


def _value(value: Value) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _allowed(meta: Meta) -> str:
    if meta.int_choices:
        return ", ".join(str(v) for v in meta.values)
    if meta.choices:
        return ", ".join(f"`{v}`" for v in meta.values)
    if meta.low is None or meta.high is None:
        return "on, off"
    return f"{_value(meta.low)} – {_value(meta.high)}"


def _description(meta: Meta) -> str:
    named = [] if meta.int_choices else [f"`{c.value}`: {c.description}" for c in meta.choices]
    return "; ".join([meta.description, *named]).replace("|", "\\|")


def table() -> str:
    """The markdown table of every setting, section by section."""
    rows = ["| setting | default | range / choices | applies when | description |",
            "|---|---|---|---|---|"]
    for section in SECTIONS:
        for name, meta in SCHEMA.items():
            if meta.section == section.id:
                default = _value(getattr(DEFAULTS, name)) + _UNITS.get(meta.unit, "")
                applies = str(meta.applies) if meta.applies else ""
                rows.append(f"| {name} | {default} | {_allowed(meta)} | {applies} | "
                            f"{_description(meta)} |")
    return "\n".join(rows)


def marked_table(text: str) -> str:
    """The table between the settings-table markers of docs/settings.md."""
    return text.split(START, 1)[1].split(END, 1)[0].strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true",
                        help="replace the table in docs/settings.md")
    if not parser.parse_args().write:
        print(table())
        return
    head, rest = TABLE_FILE.read_text(encoding="utf-8").split(START, 1)
    tail = rest.split(END, 1)[1]
    TABLE_FILE.write_text(f"{head}{START}\n{table()}\n{END}{tail}", encoding="utf-8")


if __name__ == "__main__":
    main()
