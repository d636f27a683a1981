"""The stability suite records every case's measured value; at the end of the session the table
is written to renders/stability_table.md (the README's table is copied from it; a partial run
writes a partial table)."""

from __future__ import annotations

from pathlib import Path

import pytest

TABLE = Path(__file__).resolve().parents[2] / "renders" / "stability_table.md"


@pytest.fixture(scope="session")
def record():
    rows: list[tuple[str, str, str, str]] = []
    yield lambda case, checked, bound, measured: rows.append((case, checked, bound, measured))
    if rows:
        TABLE.parent.mkdir(exist_ok=True)
        lines = ["| case | checked | bound | measured |", "|---|---|---|---|"]
        lines += [f"| {' | '.join(row)} |" for row in sorted(rows)]
        TABLE.write_text("\n".join(lines) + "\n", encoding="utf-8")
