"""Hair curves as triangles: Cycles renders a curve ("3D Curves") as a round tube of the
curve's radius along a uniform Catmull-Rom spline through its points (the end points
repeated), radius interpolated along with the position. VPL GI renders the same spline as a
tube of flat sides with the round tube's normals at its edges, whose perimeter is the round
tube's: the same surface area and, averaged over directions, the same projected width
(Cauchy's formula), so a head of hair blocks and reflects as much light as Cycles'.

Six sides where an object's hair has up to ``DETAILED_SEGMENTS`` spline pieces, three
beyond (fur of a hundred thousand strands: each strand a pixel or less wide, where the
sides do not show, and half the triangles). Every point is kept: the ray tracer's boxes
around long thin triangles overlap so much that merging a strand's straight runs slows rays
down more than the fewer triangles save (docs/measurements.md, *Hair against Cycles*)."""

from __future__ import annotations

import math

import numpy as np

from .model import Mesh, empty_mesh
from .vectors import triangle_areas, unit

TUBE_SIDES = 6
THIN_SIDES = 3
DETAILED_SEGMENTS = 65536
"""The most spline pieces an object's hair is drawn with TUBE_SIDES sides (THIN_SIDES
beyond)."""

MAX_TURN = math.pi / 8
"""A spline segment is cut into pieces that each turn the curve by at most this (radians)."""
MAX_PIECES = 16


def circumradius(sides: int) -> float:
    """A tube's corner distance from the curve per unit of curve radius: its perimeter is
    then 2π × radius."""
    return math.pi / (sides * math.sin(math.pi / sides))


def hair_mesh(name: str, points: np.ndarray, radii: np.ndarray, offsets: np.ndarray,
              slots: np.ndarray) -> tuple[Mesh, int]:
    """The tubes of curves given by their ``points`` (P, 3), ``radii`` (P,), curve
    ``offsets`` (C + 1,) into the points, and material ``slots`` (C,); and how many curves
    were left out for points or radii that are not finite (curves of under two points, or
    of zero radius throughout, make no triangles)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    radii = np.maximum(np.asarray(radii, np.float64).reshape(-1), 0.0)
    offsets = np.asarray(offsets, np.int64)
    counts = np.diff(offsets)
    finite = np.isfinite(points).all(axis=1) & np.isfinite(radii)
    bad = np.bincount(_curve_of_each(offsets)[~finite], minlength=len(counts)) > 0
    keep = (counts >= 2) & ~bad
    if not keep.any():
        return empty_mesh(name), int(bad.sum())
    kept_points = np.repeat(keep, counts)
    offsets = np.concatenate([[0], np.cumsum(counts[keep])])
    control = np.concatenate([points[kept_points], radii[kept_points, None]], axis=1)
    samples, sample_offsets = spline_samples(control, offsets)
    pieces = len(samples) - (len(sample_offsets) - 1)
    mesh = tube(name, samples[:, :3], samples[:, 3], sample_offsets,
                np.asarray(slots, np.int32)[keep],
                TUBE_SIDES if pieces <= DETAILED_SEGMENTS else THIN_SIDES)
    return mesh, int(bad.sum())


def spline_samples(control: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points along each curve's uniform Catmull-Rom spline through its ``control`` points
    (P, 4: position and radius), the end points repeated: every control point, and between
    two of them as many more as the curve's turn needs (``MAX_TURN``); with the samples'
    curve offsets."""
    curve = _curve_of_each(offsets)
    last = offsets[1:][curve] - 1
    first = offsets[:-1][curve]
    starts = np.flatnonzero(np.arange(len(control)) < last)  # each segment's first point
    segment_curve = curve[starts]
    before = np.maximum(starts - 1, first[starts])
    after = np.minimum(starts + 2, last[starts])
    p0, p1, p2, p3 = (control[i] for i in (before, starts, starts + 1, after))
    turn = _angle(p2[:, :3] - p0[:, :3], p3[:, :3] - p1[:, :3])
    pieces = np.clip(np.ceil(turn / MAX_TURN), 1, MAX_PIECES).astype(np.int64)
    segment = np.repeat(np.arange(len(starts)), pieces)
    step = np.arange(len(segment)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    t = (step / pieces[segment])[:, None]
    a, b, c, d = p0[segment], p1[segment], p2[segment], p3[segment]
    inner = 0.5 * (2 * b + (c - a) * t + (2 * a - 5 * b + 4 * c - d) * t ** 2
                   + (3 * (b - c) + d - a) * t ** 3)
    per_curve = np.bincount(segment_curve, weights=pieces, minlength=len(offsets) - 1)
    sample_offsets = np.concatenate([[0], np.cumsum(per_curve.astype(np.int64) + 1)])
    samples = np.empty((sample_offsets[-1], control.shape[1]))
    ends = sample_offsets[1:] - 1
    samples[ends] = control[offsets[1:] - 1]
    samples[np.delete(np.arange(len(samples)), ends)] = inner
    return samples, sample_offsets


def _curve_of_each(offsets: np.ndarray) -> np.ndarray:
    """The curve each point (or sample) belongs to, from the curves' ``offsets``."""
    return np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The angle between rows of ``u`` and ``v`` (0 where either is zero)."""
    cosine = np.einsum("ij,ij->i", unit(u), unit(v))
    zero = ~(np.abs(u).sum(axis=1) > 0) | ~(np.abs(v).sum(axis=1) > 0)
    return np.where(zero, 0.0, np.arccos(np.clip(cosine, -1.0, 1.0)))


def tube(name: str, centres: np.ndarray, radii: np.ndarray, offsets: np.ndarray,
         slots: np.ndarray, sides: int = TUBE_SIDES) -> Mesh:
    """Tubes of ``sides`` sides around each curve's ``centres`` (offsets as in hair_mesh),
    each ring turned along the curve by parallel transport (no twist), with the round
    tube's normals at the corners; triangles of zero area (at tips of radius 0) left
    out."""
    tangents = _tangents(centres, offsets)
    normals, binormals = _frames(tangents, offsets)
    angle = (np.arange(sides) + 0.5) * (2 * np.pi / sides)
    around = np.cos(angle)[None, :, None] * normals[:, None] \
        + np.sin(angle)[None, :, None] * binormals[:, None]  # (S, sides, 3)
    corners = centres[:, None] + (circumradius(sides) * radii)[:, None, None] * around
    curve = _curve_of_each(offsets)
    ring = np.flatnonzero(np.arange(len(centres)) < offsets[1:][curve] - 1)
    side = np.arange(sides)
    here = ring[:, None] * sides + side[None]
    turned = ring[:, None] * sides + (side[None] + 1) % sides
    lower = np.stack([here, turned, turned + sides], axis=-1)
    upper = np.stack([here, turned + sides, here + sides], axis=-1)
    triangles = np.stack([lower, upper], axis=2).reshape(-1, 3)
    triangle_slots = np.repeat(slots[curve[ring]], 2 * sides)
    positions = corners.reshape(-1, 3)
    keep = triangle_areas(positions[triangles]) > 0
    index = triangles[keep].ravel().astype(np.int32)
    return Mesh(name, positions.astype(np.float32), around.reshape(-1, 3).astype(np.float32),
                triangle_slots[keep].astype(np.int32), None, index, index)


def _tangents(centres: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Unit tangents at each sample: its neighbours' difference within its curve."""
    curve = _curve_of_each(offsets)
    index = np.arange(len(centres))
    ahead = np.minimum(index + 1, offsets[1:][curve] - 1)
    behind = np.maximum(index - 1, offsets[:-1][curve])
    return unit(centres[ahead] - centres[behind])


def _frames(tangents: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A normal and binormal at each sample, perpendicular to its tangent, carried along
    each curve by parallel transport (all curves at once, a step per sample)."""
    counts = np.diff(offsets)
    normals = np.zeros_like(tangents)
    previous = _perpendicular(tangents[offsets[:-1]])
    for step in range(int(counts.max())):
        live = np.flatnonzero(counts > step)
        index = offsets[:-1][live] + step
        t = tangents[index]
        carried = previous[live] - np.einsum("ij,ij->i", previous[live], t)[:, None] * t
        length = np.linalg.norm(carried, axis=1)
        fresh = _perpendicular(t)
        carried = np.where((length > 1e-6)[:, None], carried / np.maximum(length, 1e-12)[:, None],
                           fresh)
        previous[live] = carried
        normals[index] = carried
    return normals, np.cross(tangents, normals)


def _perpendicular(vectors: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit row (any, for a zero row)."""
    axis = np.where((np.abs(vectors[:, 0]) < 0.9)[:, None], [[1.0, 0.0, 0.0]],
                    [[0.0, 1.0, 0.0]])
    return unit(np.cross(vectors, axis))


def particle_radii(strands: np.ndarray, root: float, tip: float, shape: float,
                   close_tip: bool) -> np.ndarray:
    """The radius at each key of hair particles' ``strands`` (n, keys, 3), as Cycles gives
    it: from ``root`` to ``tip`` along the strand's length, bent by ``shape`` in [-1, 1]
    (below 0 thicker, above thinner towards the tip), 0 at the last key with
    ``close_tip``."""
    steps = np.linalg.norm(np.diff(strands, axis=1), axis=2)
    along = np.concatenate([np.zeros((len(strands), 1)), np.cumsum(steps, axis=1)], axis=1)
    total = along[:, -1:]
    time = np.divide(along, total, out=np.zeros_like(along), where=total > 0)
    exponent = 1.0 + shape if shape < 0 else 1.0 / max(1.0 - shape, 1e-6)
    radii = (1.0 - time) ** exponent * (root - tip) + tip
    if close_tip:
        radii[:, -1] = 0.0
    return radii
