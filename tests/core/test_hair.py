"""Hair curves as tubes: the spline through the points as Cycles draws it, a tube whose area
is the round tube's (2π × radius × length) without twist, outward normals, a material slot
per curve, and curves with points that are not finite left out and counted."""

from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core.scene.hair import (
    DETAILED_SEGMENTS,
    THIN_SIDES,
    TUBE_SIDES,
    circumradius,
    hair_mesh,
    spline_samples,
)
from addon.core.scene.vectors import triangle_areas


def _areas(mesh) -> np.ndarray:
    return triangle_areas(mesh.corner_positions())


def _one(points: np.ndarray, radius: float = 0.01):
    return hair_mesh("h", points, np.full(len(points), radius), np.array([0, len(points)]),
                     np.zeros(1, np.int32))[0]


def test_a_straight_strand_is_a_tube_of_the_round_tubes_area_with_outward_normals():
    mesh = _one(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.3], [0.0, 0.0, 0.6]]))
    assert mesh.triangle_count == 2 * 2 * TUBE_SIDES  # straight: a piece between points
    assert _areas(mesh).sum() == pytest.approx(2 * math.pi * 0.01 * 0.6, rel=1e-5)
    assert np.linalg.norm(mesh.positions[:, :2], axis=1) == pytest.approx(
        np.full(len(mesh.positions), circumradius(TUBE_SIDES) * 0.01), rel=1e-5)
    corners = mesh.corner_positions().reshape(-1, 3, 3)
    facing = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    outward = mesh.corner_normals().reshape(-1, 3, 3).mean(axis=1)
    assert (np.einsum("ij,ij->i", facing, outward) > 0).all()


def test_a_helix_keeps_its_area_without_twisting():
    turns = np.linspace(0.0, 6 * math.pi, 200)
    helix = np.stack([np.cos(turns), np.sin(turns), 0.1 * turns], axis=1)
    mesh = _one(helix)
    length = np.linalg.norm(np.diff(helix, axis=0), axis=1).sum()
    assert _areas(mesh).sum() == pytest.approx(2 * math.pi * 0.01 * length, rel=2e-3)
    # no twist: each side's quads stay rectangles (a twisted ring turns them into skew ones)
    areas = _areas(mesh)
    assert areas.min() > 0.9 * np.median(areas)


def test_the_spline_passes_through_the_points_as_cycles_draws_it():
    """Uniform Catmull-Rom with the end points repeated: measured on a Cycles render of the
    three-point strand (-1, 0, -1), (0, 0, 0.6), (1, 0, -1), where it crosses x = -0.5 at
    z = 0.025 ± 0.005 (0.019 here; a polyline: -0.2)."""
    control = np.array([[-1.0, 0.0, -1.0, 0.01], [0.0, 0.0, 0.6, 0.01], [1.0, 0.0, -1.0, 0.01]])
    samples, offsets = spline_samples(control, np.array([0, 3]))
    assert offsets.tolist() == [0, len(samples)] and len(samples) > 3
    t = np.linspace(0.0, 1.0, 20001)[:, None]
    p = control[[0, 0, 1, 2, 2]]
    curve = np.concatenate([_catmull_rom(*p[i:i + 4], t) for i in range(2)])
    distances = np.linalg.norm(samples[:, None, :3] - curve[None, :, :3], axis=2).min(axis=1)
    assert distances.max() < 1e-3  # every sample on the spline, the control points too
    left = curve[curve[:, 0] < 0]
    assert np.interp(-0.5, left[:, 0], left[:, 2]) == pytest.approx(0.025, abs=0.01)


def _catmull_rom(p0, p1, p2, p3, t):
    """The uniform Catmull-Rom segment from p1 to p2 at parameters ``t`` (n, 1)."""
    return 0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                  + (3 * p1 - 3 * p2 + p3 - p0) * t ** 3)


def test_material_slots_bad_curves_and_tips():
    points = np.array([[0, 0, 0], [0, 0, 1],  # slot 0
                       [1, 0, 0], [np.nan, 0, 1],  # NaN: left out, counted
                       [2, 0, 0],  # one point: no triangles, not counted
                       [3, 0, 0], [3, 0, 1]], np.float64)  # slot 3, zero radius at the tip
    radii = np.array([0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.0])
    mesh, dropped = hair_mesh("h", points, radii, np.array([0, 2, 4, 5, 7, 7]),
                              np.array([0, 1, 2, 3, 4]))
    assert dropped == 1
    assert sorted(set(mesh.material_slots.tolist())) == [0, 3]
    assert (_areas(mesh) > 0).all()  # the tip's zero-area triangles are left out
    assert np.isfinite(mesh.positions).all()
    empty, dropped = hair_mesh("h", np.zeros((0, 3)), np.zeros(0), np.array([0]),
                               np.zeros(0, np.int32))
    assert empty.triangle_count == 0 and dropped == 0


def test_fur_of_many_strands_gets_three_sided_tubes():
    count = DETAILED_SEGMENTS // 2 + 1  # two pieces each: just over the detailed limit
    roots = np.stack([np.arange(count, dtype=float), np.zeros(count), np.zeros(count)], 1)
    bend = np.array([[0.0, 0.0, 0.0], [0.0, 0.03, 0.3], [0.0, 0.0, 0.6]])
    points = (roots[:, None] + bend[None]).reshape(-1, 3)
    mesh, _ = hair_mesh("fur", points, np.full(len(points), 0.01),
                        np.arange(0, len(points) + 1, 3), np.zeros(count, np.int32))
    assert mesh.triangle_count == count * 2 * 2 * THIN_SIDES
    assert _areas(mesh).sum() == pytest.approx(
        _areas(_one(bend)).sum() * count, rel=0.02)  # the same area as six sides
