"""The settings schema: every field described once, text parsed by type, clear messages, and
the settings table (docs/settings.md) made from it."""

from __future__ import annotations

import struct
from dataclasses import fields

import pytest

from addon.cli import CliError, parse_overrides
from addon.core.settings import DEFAULTS, SCHEMA, SECTIONS, Settings, SettingsError, applies
from tools.settings_table import TABLE_FILE, marked_table, table


def float32(value: float) -> float:
    return struct.unpack("f", struct.pack("f", value))[0]


def test_the_settings_table_is_made_from_the_schema():
    assert marked_table(TABLE_FILE.read_text(encoding="utf-8")) == table(), \
        "docs/settings.md's table is stale: run tools/settings_table.py --write"


@pytest.mark.parametrize("name", [f.name for f in fields(Settings)])
def test_every_field_is_described_and_its_default_is_valid(name):
    meta = SCHEMA[name]
    default = getattr(DEFAULTS, name)
    assert meta.label and meta.description and meta.section in {s.id for s in SECTIONS}
    if meta.choices:
        assert default in meta.values and all(c.label and c.description for c in meta.choices)
        assert meta.low is None and meta.high is None
    elif isinstance(default, bool):
        assert meta.low is None and meta.high is None
    else:
        assert meta.low <= default <= meta.high
        assert meta.soft_high is None or meta.low < meta.soft_high <= meta.high
    conditions = getattr(meta.applies, "parts", (meta.applies,)) if meta.applies else ()
    assert all(c.name in SCHEMA and c.name != name for c in conditions)
    assert Settings.parse(name, str(default)) == default


def test_every_section_has_settings_and_parents_come_first():
    ids = [s.id for s in SECTIONS]
    assert {m.section for m in SCHEMA.values()} == set(ids)
    assert all(s.parent is None or ids.index(s.parent) < ids.index(s.id) for s in SECTIONS)


@pytest.mark.parametrize("name, text, value", [
    ("bounces", "7", 7), ("seed", " 12 ", 12), ("shadow_bias", "2.5", 2.5),
    ("time_budget", "0.01", 0.01), ("visibility", "classic", "classic"),
    ("ism_resolution", "64", 64), ("interleave", "2", 2), ("rsm_resolution", "64", 64),
    ("incremental", "true", True), ("incremental", "ON", True), ("incremental", "yes", True),
    ("incremental", "1", True), ("planner", "false", False), ("planner", "off", False),
    ("planner", "No", False), ("planner", "0", False),
])
def test_text_is_read_as_the_fields_type(name, text, value):
    parsed = Settings.parse(name, text)
    assert parsed == value and type(parsed) is type(value)


@pytest.mark.parametrize("name, text, message", [
    ("ism_resolution", "7", "ism_resolution = '7' is not one of 32, 64, 128, 256, 512"),
    ("interleave", "3", "interleave = '3' is not one of 1, 2, 4, 8"),
    ("visibility", "fast", "visibility = 'fast' is not one of ism, classic, exact"),
    ("bounces", "two", "bounces = 'two' is not a valid integer"),
    ("shadow_bias", "wide", "shadow_bias = 'wide' is not a valid number"),
    ("planner", "maybe", "planner = 'maybe' must be true or false (or 1/0, yes/no, on/off)"),
    ("seed", "-1", "seed = -1 is outside the supported range [0, 2147483647]"),
    ("time_budget", "0.0099", "time_budget = 0.0099 is outside the supported range"),
    ("clamp_distance", "nan", "clamp_distance = nan is outside the supported range [0.0, 1.0]"),
])
def test_bad_text_gets_a_message_naming_what_is_allowed(name, text, message):
    with pytest.raises(SettingsError) as error:
        Settings.parse(name, text)
    assert str(error.value).startswith(message)


def test_an_unknown_name_lists_the_settings():
    with pytest.raises(SettingsError, match="unknown setting 'bounce'") as error:
        Settings.parse("bounce", "2")
    assert all(name in str(error.value) for name in SCHEMA)


def test_an_integer_choice_out_of_its_set_is_refused_by_validate():
    with pytest.raises(SettingsError, match="interleave = 3 is not one of 1, 2, 4, 8"):
        Settings(interleave=3).validate()


def test_blenders_single_precision_floats_pass_their_own_bounds():
    """Blender stores float properties in float32: its 0.01 is 0.0099999998."""
    assert Settings(time_budget=float32(0.01), target_error=float32(0.001)).validate()
    with pytest.raises(SettingsError, match="time_budget"):
        Settings(time_budget=0.0099).validate()


def test_what_applies_follows_the_other_settings():
    values = {f.name: getattr(DEFAULTS, f.name) for f in fields(Settings)}
    assert not applies("vpl_shadow_resolution", values) and applies("ism_points", values)
    assert not applies("time_budget", values) and applies("bias_samples", values)
    values.update(bias_compensation="off")
    assert not applies("bias_samples", values)
    values.update(visibility="classic", auto_parameters="time", bias_compensation="full")
    assert applies("vpl_shadow_resolution", values) and not applies("ism_points", values)
    assert applies("time_budget", values) and applies("bias_samples", values)
    values["soft_light_ism"] = True
    assert applies("ism_points", values) and applies("bounces", values)


def test_command_line_overrides_are_typed_and_checked_together():
    assert parse_overrides(["ism_resolution=64", "interleave=2", "time_budget=0.01",
                            "soft_light_ism=yes"]) == {
        "ism_resolution": 64, "interleave": 2, "time_budget": 0.01, "soft_light_ism": True}
    with pytest.raises(CliError, match="not one of 32, 64, 128, 256, 512"):
        parse_overrides(["ism_resolution=7"])
    with pytest.raises(CliError, match="expected NAME=VALUE"):
        parse_overrides(["bounces"])
    with pytest.raises(CliError, match="unknown setting 'bounce'"):
        parse_overrides(["bounce=2"])
