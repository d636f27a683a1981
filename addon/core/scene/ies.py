"""IES light profiles (IESNA LM-63 photometric files) as Cycles reads them: parsed and
processed as its ``IESFile`` does (types B and C, mirrored to the full sphere, candela turned
into Cycles' light units by 4π / 177.83), and evaluated as its IES Texture node does (Catmull-
Rom interpolation over the file's own angles, 0 past the last vertical angle)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property

import numpy as np

CANDELA_TO_CYCLES = 0.0706650768394  # 4π / 177.83 lm/W (D65's luminous efficacy), as Cycles
TYPE_C, TYPE_B = 1, 2  # LM-63 photometric types (type A, 3, is not read)


class IesError(ValueError):
    """The text is not an IES profile Cycles can read; the message says why."""


@dataclass(frozen=True, eq=False)
class IesProfile:
    """A light's intensity over directions: ``intensity[h, v]`` at horizontal angles
    ``h_angles`` (radians, 0 to 2π, the last equal to the first) and vertical angles
    ``v_angles`` (radians from straight down, starting at 0 or π/2). Compared and hashed by
    identity, so that what is derived from one (its mean, the shaders' grid, the path
    sampler's table) is cached once for every light and frame that shares it."""

    h_angles: np.ndarray
    v_angles: np.ndarray
    intensity: np.ndarray
    edge: str = "zero"  # a spline's point past the table: "zero" (Cycles 4.x), "repeat"

    @cached_property
    def key(self) -> bytes:
        """Bytes that differ between different profiles (for caches)."""
        return self.edge.encode() + b"".join(
            a.astype(np.float32).tobytes() for a in (self.h_angles, self.v_angles, self.intensity))

    def at_angles(self, h_angle: np.ndarray, v_angle: np.ndarray) -> np.ndarray:
        """The profile at angles (radians; h in [0, 2π], v in [0, π]), as Cycles' kernel
        interpolates it: bicubic (Catmull-Rom) over the file's angles, 0 outside them. Where
        a spline's outer point lies past the table it wraps where Cycles wraps (the vertical
        angle at 0°; the horizontal, never: Cycles' float test for a full circle fails at
        360°) and reads ``self.edge`` otherwise."""
        h_angle = np.asarray(h_angle, np.float64)
        v_angle = np.asarray(v_angle, np.float64)
        h, v, table = self.h_angles, self.v_angles, self.intensity
        h_num, v_num = len(h), len(v)
        h_angle, v_angle = np.broadcast_arrays(h_angle, v_angle)
        outside = (v_angle < v[0]) | (v_angle >= v[-1]) | (h_angle < h[0]) | (h_angle >= h[-1])
        if v_num < 2 or h_num < 2:
            return np.zeros(h_angle.shape)
        h_i = np.minimum(np.searchsorted(h[1:], h_angle, side="left"), h_num - 2)
        v_i = np.minimum(np.searchsorted(v[1:], v_angle, side="left"), v_num - 2)
        h_frac = (h_angle - h[h_i]) / (h[h_i + 1] - h[h_i])
        v_frac = (v_angle - v[v_i]) / (v[v_i + 1] - v[v_i])
        wrap_h = h[0] < 1e-7 and np.float32(h[-1]) > np.float32(2 * np.pi) - np.float32(1e-7)
        wrap_v_low = v[0] < 1e-7
        wrap_v_high = np.float32(v[-1]) > np.float32(np.pi) - np.float32(1e-7)

        def vertical(row: np.ndarray) -> np.ndarray:
            at = table[row]  # (..., v_num) rows of the spline's columns
            pick = lambda k: np.take_along_axis(at, k[..., None], -1)[..., 0]  # noqa: E731
            b, c = pick(v_i), pick(v_i + 1)
            a = np.where(v_i > 0, pick(np.maximum(v_i - 1, 0)),
                         pick(np.ones_like(v_i)) if wrap_v_low else self._edge(b))
            d = np.where(v_i + 2 < v_num, pick(np.minimum(v_i + 2, v_num - 1)),
                         pick(np.full_like(v_i, v_num - 2)) if wrap_v_high else self._edge(c))
            return catmull_rom(a, b, c, d, v_frac)

        b, c = vertical(h_i), vertical(h_i + 1)
        a = np.where(h_i > 0, vertical(np.maximum(h_i - 1, 0)),
                     vertical(np.full_like(h_i, h_num - 2)) if wrap_h else self._edge(b))
        d = np.where(h_i + 2 < h_num, vertical(np.minimum(h_i + 2, h_num - 1)),
                     vertical(np.ones_like(h_i)) if wrap_h else self._edge(b))
        return np.where(outside, 0.0, np.maximum(catmull_rom(a, b, c, d, h_frac), 0.0))

    def _edge(self, inner: np.ndarray) -> np.ndarray:
        return inner if self.edge == "repeat" else np.zeros_like(inner)

    @staticmethod
    def direction(h_angle: np.ndarray, cos_v: np.ndarray) -> np.ndarray:
        """Unit directions (..., 3) in the light's frame at horizontal angles ``h_angle`` and
        vertical angles of cosine ``cos_v`` (``towards``' angles, inverted)."""
        sin_v = np.sqrt(np.maximum(0.0, 1.0 - cos_v**2))
        return np.stack([sin_v * np.sin(h_angle - np.pi), sin_v * np.cos(h_angle - np.pi),
                         -cos_v], -1)

    def towards(self, local: np.ndarray) -> np.ndarray:
        """The profile towards unit directions (n, 3) in the light's own frame (it shines
        along -Z): vertical angle acos(-z), horizontal atan2(x, y) + π, as Cycles."""
        local = np.asarray(local, np.float64)
        v_angle = np.arccos(np.clip(-local[..., 2], -1.0, 1.0))
        h_angle = np.arctan2(local[..., 0], local[..., 1]) + np.pi
        return self.at_angles(h_angle, v_angle)

    def grid(self, v_count: int, h_count: int) -> np.ndarray:
        """(h_count, v_count) float32 samples on an even grid of v in [0, π] and h in
        [0, 2π] (both ends included), for bilinear lookups on the GPU."""
        v = np.linspace(0.0, np.pi, v_count)
        h = np.linspace(0.0, 2 * np.pi, h_count)
        return self.at_angles(h[:, None], v[None, :]).astype(np.float32)

    @cached_property
    def mean(self) -> float:
        """The profile's mean over the sphere (what it multiplies a point light's flux by)."""
        n = 1 << 14
        i = np.arange(n) + 0.5
        z = 1.0 - 2.0 * i / n
        phi = np.pi * (1.0 + 5**0.5) * i
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        return float(self.towards(np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)).mean())


def catmull_rom(a, b, c, d, x):
    """Cycles' cubic_interp: the Catmull-Rom spline through a, b, c, d at x in [0, 1]
    between b and c."""
    return 0.5 * (((d + 3.0 * (b - c) - a) * x + (2.0 * a - 5.0 * b + 4.0 * c - d)) * x
                  + (c - a)) * x + b


def parse_ies(text: str) -> IesProfile:
    """The profile of an IES file's text; IesError where Cycles would not read it."""
    text = text.replace(",", " ")
    tilt = text.find("\nTILT=")
    if tilt < 0:
        raise IesError("no TILT= line")
    if text.startswith("\nTILT=INCLUDE", tilt):
        tokens = text[tilt + len("\nTILT=INCLUDE"):].split()
        try:
            tilt_count = int(float(tokens[1]))
        except (IndexError, ValueError) as error:
            raise IesError("its tilt data cannot be read") from error
        tokens = tokens[2 + 2 * tilt_count:]
    else:
        line_end = text.find("\n", tilt + 1)
        tokens = [] if line_end < 0 else text[line_end:].split()
    numbers = _Numbers(tokens)
    numbers.next()  # lamps
    numbers.next()  # lumens per lamp
    factor = numbers.next()  # candela multiplier
    v_count, h_count, kind = (int(numbers.next()) for _ in range(3))
    if kind not in (TYPE_B, TYPE_C):
        raise IesError(f"photometric type {kind} (Cycles reads types B and C)")
    if v_count < 1 or h_count < 1:
        raise IesError("no angles")
    for _ in range(4):
        numbers.next()  # units, width, length, height
    factor *= numbers.next() * numbers.next()  # ballast and ballast-lamp factors
    numbers.next()  # input watts
    v_angles = numbers.take(v_count)
    h_angles = numbers.take(h_count)
    candela = numbers.take(v_count * h_count).reshape(h_count, v_count)
    intensity = candela * (factor * CANDELA_TO_CYCLES)
    if kind == TYPE_B:
        h_angles, v_angles, intensity = _type_b(h_angles, v_angles, intensity)
    else:
        h_angles, intensity = _type_c(h_angles, v_angles, intensity)
    if not (np.isfinite(intensity).all() and np.abs(intensity).max() < 1e30):
        raise IesError("its candela values are not finite")
    if not np.all(np.diff(h_angles) > 0) or not np.all(np.diff(v_angles) > 0):
        raise IesError("its angles do not increase")
    return IesProfile(np.radians(h_angles).astype(np.float32).astype(np.float64),
                      np.radians(v_angles).astype(np.float32).astype(np.float64),
                      intensity.astype(np.float32).astype(np.float64))


class _Numbers:
    def __init__(self, tokens: list[str]) -> None:
        self.tokens, self.at = tokens, 0

    def take(self, count: int) -> np.ndarray:
        return np.array([self.next() for _ in range(count)], np.float64)

    def next(self) -> float:
        if self.at >= len(self.tokens):
            raise IesError("it ends before its data does")
        token = self.tokens[self.at]
        self.at += 1
        match = re.match(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", token)
        if match is None:
            raise IesError(f"'{token[:20]}' is not a number")
        return float(match.group(0))


def _type_c(h: np.ndarray, v: np.ndarray, table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Type C (most luminaires): horizontal angles mirrored to 0-360°."""
    h, rows = list(h), list(table)
    if h[0] == 90.0:
        h = [a - 90.0 for a in h]
    if h[0] != 0.0:
        raise IesError("its horizontal angles do not start at 0° or 90°")
    if len(h) == 1:
        h, rows = [*h, 360.0], [*rows, rows[0]]
    if h[-1] == 90.0:  # one quadrant: mirrored to two here, to four below
        h += [180.0 - a for a in h[-2::-1]]
        rows += rows[-2::-1]
    if h[-1] == 180.0:
        h += [360.0 - a for a in h[-2::-1]]
        rows += rows[-2::-1]
    if h[-1] != 360.0:
        gap = 360.0 - h[-1]
        if gap not in (h[-1] - h[-2], h[1] - h[0]):
            raise IesError("its horizontal angles end short of 360°")
        h, rows = [*h, 360.0], [*rows, rows[0]]
    if not (v[0] == 0.0 or (v[0] == 90.0 and v[-1] == 180.0)):
        raise IesError("its vertical angles start at neither 0° nor 90°")
    return np.array(h), np.array(rows)


def _type_b(h: np.ndarray, v: np.ndarray, table: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Type B (floodlights): the axes swapped, each mirrored or shifted to Cycles' range."""
    h, v, table = v, h, table.T
    if h[-1] != 90.0 or v[-1] != 90.0:
        raise IesError("its type B angles do not end at 90°")
    if h[0] == 0.0:
        table = np.concatenate([table[:0:-1], table])
        h = np.concatenate([90.0 - h[:0:-1], 90.0 + h])
    elif h[0] == -90.0:
        h = h + 90.0
    h = np.append(h, 360.0)
    table = np.concatenate([table, table[:1]])
    if v[0] == 0.0:  # Cycles mirrors the values one angle off (v[-2] at -v[-1]); kept
        table = np.concatenate([table[:, -2::-1], table], axis=1)
        v = np.concatenate([90.0 - v[:0:-1], 90.0 + v])
    elif v[0] == -90.0:
        v = v + 90.0
    return h, v, table
