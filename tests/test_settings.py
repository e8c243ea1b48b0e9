"""Settings resolution: defaults, built-in profiles, inheritance, overrides, errors."""

import msgspec
import pytest

from fgslice.errors import SettingsError
from fgslice.settings import SETTING_NAMES, Settings, builtin_profiles, describe_settings, load_settings, parse_overrides


def test_every_builtin_profile_loads_with_its_dialect():
    expected = {
        "marlin-mixing": "marlin-mixing",
        "marlin-mixing-m163": "marlin-mixing-m163",
        "toolchanger": "toolchanger",
        "foam-lwpla": "temperature",
        "foam-tpu": "temperature",
        "template-diw": "template",
        "klipper-mixing": "klipper-mixing",
        "klipper-diw": "template",
    }
    assert set(builtin_profiles()) == set(expected)
    for name, dialect in expected.items():
        s = load_settings(name)
        assert s.dialect == dialect
        assert s.profile_name == name


def test_inheritance_and_overrides():
    s = load_settings("foam-tpu", parse_overrides(["walls=3", "lookahead_mm=auto", "zipper=5"]))
    assert s.flow_model == "tpu" and s.temperature_a == 190.0  # inherited from foam-lwpla
    assert s.walls == 3 and s.zipper == 5.0
    # V_melt / (h (w - h) + pi h^2 / 4) with h = 0.2, w = 0.4
    assert s.lookahead_distance == pytest.approx(20.0 / (0.2 * 0.2 + 3.141592653589793 * 0.04 / 4))


@pytest.mark.parametrize(
    "pairs, words",
    [
        (["wals=3"], "did you mean 'walls'"),
        (["walls=-1"], "walls"),
        (["layer_height=0.5", "bead_width=0.4"], "bead_width"),
        (["strategy=3"], "strategy"),
        (["walls"], "KEY=VALUE"),
    ],
)
def test_bad_overrides_are_refused_clearly(pairs, words):
    with pytest.raises(SettingsError) as info:
        load_settings(None, parse_overrides(pairs))
    assert words in info.value.format()


def test_unknown_profile_suggests_a_builtin(tmp_path):
    with pytest.raises(SettingsError) as info:
        load_settings("toolchangr")
    assert "toolchanger" in info.value.format()
    bad = tmp_path / "bad.toml"
    bad.write_text("walls = [", encoding="utf-8")
    with pytest.raises(SettingsError) as info:
        load_settings(str(bad))
    assert "bad.toml" in info.value.format()


def test_user_profile_inherits_a_builtin(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text('inherits = "toolchanger"\n[speeds]\nprint_speed = 55\n', encoding="utf-8")
    s = load_settings(str(path))
    assert s.dialect == "toolchanger" and s.print_speed == 55 and s.profile_name == "mine"


def test_inconsistent_settings_are_named_without_dumping_every_value():
    with pytest.raises(SettingsError) as info:
        load_settings(None, parse_overrides(["layer_height=0.5"]))
    text = info.value.format()
    assert "inconsistent settings" in text and "bead_width" in text
    assert "profile_name" not in text


@pytest.mark.parametrize(
    "pair, takes",
    [
        ("walls=-1", "a whole number, at least 0, at most 100"),
        ("colors=1.5", "a whole number, at least 1, at most 1024"),
        ("bead_width=abc", "a number, above 0.05, at most 5.0"),
        ("strategy=3", "one of 1, 2"),
        ("center=maybe", "true or false"),
        ("lookahead_mm=xyz", "a number or 'auto'"),
        ("purge_tower_x=abc", "a number or none"),
    ],
)
def test_an_invalid_value_is_answered_with_what_the_setting_takes(pair, takes):
    with pytest.raises(SettingsError) as info:
        load_settings(None, parse_overrides([pair]))
    key, _, value = pair.partition("=")
    text = info.value.format()
    assert f"setting '{key}' = '{value}' is invalid (--set): it takes {takes}" in text
    assert "its default is" in text


def test_strings_of_numbers_and_booleans_become_typed_values():
    s = load_settings(None, parse_overrides(["walls=3", "bead_width=0.45", "center=false", "strategy=1",
                                             "lookahead_mm=2.5", "purge_tower_x=none"]))
    assert (s.walls, s.bead_width, s.center, s.strategy, s.lookahead_mm, s.purge_tower_x) == (3, 0.45, False, 1, 2.5, None)
    assert type(s.walls) is int and type(s.bead_width) is float


def test_settings_made_directly_are_checked_and_read_only():
    with pytest.raises(msgspec.ValidationError, match="walls"):
        Settings(walls=-1)
    with pytest.raises(ValueError, match="bead_width"):
        Settings(layer_height=0.5, bead_width=0.4)
    s = Settings(walls=4)
    with pytest.raises(AttributeError):
        s.walls = 5


def test_every_setting_is_described_with_its_default_in_order():
    described = describe_settings()
    defaults = Settings().as_dict()
    assert [name for name, _, _ in described] == list(defaults) == list(SETTING_NAMES)
    assert all(description for _, _, description in described)
    assert all(default == defaults[name] for name, default, _ in described)
