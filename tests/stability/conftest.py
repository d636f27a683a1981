"""The stability suite records every case's measured value; at the end of the session the table
is written to renders/stability_table.md (the README's table is copied from it; a partial run
writes a partial table).

``--full-sweep`` (or the environment variable VPL_GI_FULL_SWEEP=1) widens the parametrisations
marked ``@pytest.mark.sweep(name, default_values, full=full_values)``; the default run keeps the
small sets, fast enough for every CI run. The option is registered in tests/conftest.py, which
pytest loads at start-up for ``pytest tests`` and ``pytest tests/stability`` alike.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

TABLE = Path(__file__).resolve().parents[2] / "renders" / "stability_table.md"
FULL_SWEEP_VARIABLE = "VPL_GI_FULL_SWEEP"

Record = Callable[[str, str, str, str], None]


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "sweep(name, default, full): parametrise `name` with "
                                       "`default`, or with `full` under --full-sweep")


def is_full_sweep(config: pytest.Config) -> bool:
    """True under --full-sweep or VPL_GI_FULL_SWEEP=1."""
    return bool(config.getoption("--full-sweep", default=False)) or \
        os.environ.get(FULL_SWEEP_VARIABLE, "") not in ("", "0")


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    full = is_full_sweep(metafunc.config)
    for marker in metafunc.definition.iter_markers("sweep"):
        name, default = marker.args
        metafunc.parametrize(name, marker.kwargs["full"] if full else default)


@pytest.fixture(scope="session")
def full_sweep(request: pytest.FixtureRequest) -> bool:
    return is_full_sweep(request.config)


@pytest.fixture(scope="session")
def record() -> Iterator[Record]:
    rows: list[tuple[str, str, str, str]] = []
    yield lambda case, checked, bound, measured: rows.append((case, checked, bound, measured))
    if rows:
        TABLE.parent.mkdir(exist_ok=True)
        lines = ["| case | checked | bound | measured |", "|---|---|---|---|"]
        lines += [f"| {' | '.join(row)} |" for row in sorted(rows)]
        TABLE.write_text("\n".join(lines) + "\n", encoding="utf-8")
