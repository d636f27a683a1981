"""The Principled BSDF's sheen (core/scene/sheen.py): the table measured on Cycles, its
layering over the other layers, and its place in a material's specular row."""

from __future__ import annotations

import json

import numpy as np
import pytest

from addon.core.scene import principled, sheen


def test_the_table_reads_back_cycles_measurements_at_its_nodes():
    measured = np.asarray(json.loads(sheen.TABLE.read_text())["albedo"])
    nodes = np.linspace(0.0, 1.0, sheen.SIZE)
    for i in (0, 5, 8, 16):
        assert sheen.albedo(nodes[i], nodes) == pytest.approx(measured[i], abs=1e-9)
    # halfway between nodes: the mean of the four around it (bilinear, as the shader)
    half = 0.5 / (sheen.SIZE - 1)
    assert sheen.albedo(nodes[8] + half, np.array([nodes[3] + half]))[0] == pytest.approx(
        measured[8:10, 3:5].mean())


def test_rougher_sheens_reflect_more_and_most_at_grazing_views():
    """As Cycles' microfiber sheen: a velvet of roughness 1 reflects about a third of
    light seen head-on, a smooth one almost nothing but at grazing angles."""
    mu = np.linspace(0.0, 1.0, 11)
    smooth, default, rough = (sheen.albedo(r, mu) for r in (0.1, 0.5, 1.0))
    assert np.all(np.diff(default) < 0) and np.all(np.diff(rough) < 0)
    assert np.all(rough >= default) and np.all(default >= smooth)
    assert smooth[-1] < 1e-3 < smooth[0]
    assert 0.3 < rough[-1] < 0.4 and default[-1] < 0.05


def test_the_lobe_tables_are_finite_transforms():
    """The measured transform M⁻¹ = (a x + b z, a y, z): a > 0 everywhere (a cosine lobe),
    b leaning towards the view's side."""
    t = sheen.table()
    a, b = t[sheen.SIZE:2 * sheen.SIZE], t[2 * sheen.SIZE:]
    assert np.isfinite(t).all() and a.min() > 0.0
    assert b.max() <= 1e-3 and b.min() > -0.5


def test_a_sheen_dims_the_layers_below_by_its_largest_channel():
    layer = sheen.Sheen((1.0, 0.5, 0.2), 0.8)
    mu = np.array([0.1, 0.5, 1.0])
    reflected, keep = sheen.layer(layer, mu)
    assert reflected[:, 1] == pytest.approx(0.5 * reflected[:, 0])
    assert keep == pytest.approx(1.0 - reflected[:, 0])
    none, keep_all = sheen.layer(sheen.NO_SHEEN, mu)
    assert not none.any() and keep_all == pytest.approx(1.0)


def test_a_white_material_under_a_grey_sheen_reflects_all_light():
    """Cycles' furnace: a white diffuse base (no specular) under a sheen of weight 1 reflects
    everything, the sheen taking its albedo and the base the rest."""
    row = principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1),
                                  sheen=sheen.Sheen((1.0, 1.0, 1.0), 0.5))
    assert row[7] == 1.0  # the sheen alone makes the row layered
    assert principled.path_albedo(np.ones((1, 3)), row)[0] == pytest.approx(np.ones(3))
    black = principled.path_albedo(np.zeros((1, 3)), row)[0]
    mu = (np.arange(20000) + 0.5) / 20000
    average = (sheen.albedo(0.5, mu) * 2 * mu).mean()
    assert black == pytest.approx(np.full(3, average), rel=2e-3)  # 8 quadrature nodes


def test_the_row_keeps_the_sheen_and_clamps_bad_values():
    layer = sheen.Sheen((0.8, 0.4, 0.2), 0.3)
    row = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1), sheen=layer)
    def flat(s: sheen.Sheen) -> list[float]:
        return [*s.color, s.roughness]

    assert flat(principled.sheen_of(row)) == pytest.approx(flat(layer))
    assert flat(principled.specular_parameters(row)[-1]) == pytest.approx(flat(layer))
    odd = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1),
                                  sheen=sheen.Sheen((-1.0, np.nan, 2.0), 7.0))
    assert flat(principled.sheen_of(odd)) == pytest.approx([0.0, 0.0, 2.0, 1.0])
    assert not principled.specular_row(0.5, 0.0, 1.5, 0.0, (1, 1, 1)).any()


def test_a_sheen_dims_the_light_its_emission_casts_where_it_says_so():
    """Blender 5.x dims the light a glowing surface casts under its sheen by the sheen's
    keep averaged over cosine-weighted directions; 4.x only what the camera sees."""
    layer = sheen.Sheen((1.0, 1.0, 1.0), 1.0, dims_cast_light=True)
    mu = (np.arange(4000) + 0.5) / 4000
    expected = (sheen.layer(layer, mu)[1] * 2 * mu).mean()
    through = principled.emission_below_layers(principled.NO_COAT, layer)
    assert through == pytest.approx(np.full(3, expected), rel=2e-3)
    assert 0.4 < expected < 0.7
    assert principled.emission_below_layers(
        principled.NO_COAT, layer._replace(dims_cast_light=False)) == pytest.approx(np.ones(3))
    row = principled.specular_row(0.5, 0.0, 1.5, 0.5, (1, 1, 1), sheen=layer)
    assert principled.sheen_of(row).dims_cast_light and principled.sheen_of(row).layered
