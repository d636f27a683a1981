"""The scene's VPL GI properties are the settings schema's: one per field, same defaults,
ranges and choices, read back as core Settings."""

from __future__ import annotations

import pytest

from addon.core.settings import DEFAULTS, SCHEMA


@pytest.fixture
def props(blender):
    settings = blender.context.scene.vpl_gi
    yield settings
    for name in SCHEMA:
        settings.property_unset(name)


def test_one_property_per_setting_with_the_schemas_default_and_range(props):
    rna = props.bl_rna.properties
    assert set(SCHEMA) | {"viewport_display"} == set(rna.keys()) - {"rna_type", "name"}
    for name, meta in SCHEMA.items():
        prop, default = rna[name], getattr(DEFAULTS, name)
        assert prop.name == meta.label and prop.description == meta.description, name
        if meta.choices:
            assert prop.type == "ENUM" and prop.default == str(default), name
            assert [i.identifier for i in prop.enum_items] == [str(v) for v in meta.values]
        elif isinstance(default, bool):
            assert prop.type == "BOOLEAN" and prop.default == default, name
        else:
            assert prop.type == ("INT" if isinstance(default, int) else "FLOAT"), name
            assert prop.default == pytest.approx(default, rel=1e-6), name
            assert prop.hard_min == pytest.approx(meta.low, rel=1e-6), name
            assert prop.hard_max == pytest.approx(meta.high, rel=1e-6), name


def test_the_defaults_read_back_as_the_default_settings(props):
    settings = props.to_settings()
    for name in SCHEMA:
        value, default = getattr(settings, name), getattr(DEFAULTS, name)
        assert type(value) is type(default), name
        assert value == (pytest.approx(default, rel=1e-6) if isinstance(default, float)
                         else default), name


def test_integer_choices_and_the_smallest_time_budget_go_through_blender(props):
    props.assign({"ism_resolution": 64, "interleave": 2, "rsm_resolution": 512,
                  "time_budget": 0.01, "target_error": 0.001})
    settings = props.to_settings()
    assert (settings.ism_resolution, settings.interleave, settings.rsm_resolution) == (64, 2, 512)
    assert settings.time_budget == pytest.approx(0.01) and props.interleave == "2"
