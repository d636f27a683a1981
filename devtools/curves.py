"""Error-against-time curves: the time a curve needs to reach an error, and time ratios at equal
error, interpolated on log-log axes. Pure functions (no bpy), unit-tested on synthetic curves."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from itertools import pairwise

ERROR_FLOOR = 1e-12
"""Errors at or below this (a noise-free estimate clipped at 0) count as this, for the logs."""


@dataclass(frozen=True)
class TimeAtError:
    """When a curve reaches an error. relation '=': at ``seconds`` (a measured point or
    interpolated between two); '<': already below it at its quickest point, so in less than
    ``seconds`` (that point's time); '>': not within its slowest point, so in more than
    ``seconds`` (that point's time)."""

    seconds: float
    relation: str

    def ratio(self, seconds: float) -> TimeAtError:
        """This time divided by ``seconds``, with the same relation."""
        return TimeAtError(self.seconds / seconds, self.relation)

    def text(self, unit: str = "×", digits: int = 2) -> str:
        value = f"{self.seconds:.{digits}g}" if self.seconds < 10 ** digits \
            else f"{self.seconds:.0f}"
        return f"{'' if self.relation == '=' else self.relation}{value}{unit}"


def _points(curve: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
    """(seconds, error) points with a finite positive time, sorted by time; errors floored."""
    return sorted((t, max(e, ERROR_FLOOR)) for t, e in curve
                  if math.isfinite(t) and t > 0 and math.isfinite(e))


def time_at_error(curve: Iterable[tuple[float, float]], error: float) -> TimeAtError | None:
    """The earliest time at which ``curve`` (points (seconds, error) joined by straight lines on
    log-log axes) has come down to ``error``; None for a curve without a usable point."""
    points = _points(curve)
    if not points:
        return None
    error = max(error, ERROR_FLOOR) if math.isfinite(error) else math.inf
    first_time, first_error = points[0]
    if first_error <= error:
        return TimeAtError(first_time, "=" if first_error == error else "<")
    for (t0, e0), (t1, e1) in pairwise(points):
        if e1 <= error < e0:
            fraction = (math.log(error) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return TimeAtError(math.exp(math.log(t0) + fraction * (math.log(t1) - math.log(t0))),
                               "=")
    return TimeAtError(points[-1][0], ">")


def time_ratio(curve: Iterable[tuple[float, float]], seconds: float, error: float
               ) -> TimeAtError | None:
    """The time ``curve`` needs for ``error`` divided by ``seconds`` (a render's time at that
    error): above 1, the render reached the error sooner than the curve does."""
    reached = time_at_error(curve, error)
    return None if reached is None or not seconds > 0 else reached.ratio(seconds)
