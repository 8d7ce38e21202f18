"""Typed YAML configs: values over the defaults, and errors naming the file and the field."""

import time
from dataclasses import dataclass, field

import pytest

from maskless.diagrams.scenario import load_scenario
from maskless.errors import ConfigError
from maskless.systems.config_loading import (
    MAX_YAML_DEPTH,
    UNSET,
    asset_path,
    find_unset_fields,
    load_config,
)


@dataclass
class Inner:
    gain_m: float = UNSET
    count: int = 1


@dataclass
class Outer:
    inner: Inner = field(default_factory=Inner)
    values_m: list[float] = field(default_factory=list)
    label: str = "x"


def write(tmp_path, text):
    path = tmp_path / "config.yaml"
    path.write_text(text)
    return path


def test_loads_nested_values_over_defaults(tmp_path):
    path = write(tmp_path, "inner:\n  gain_m: 0.5\nvalues_m: [1, 2]\n")
    config = load_config(Outer, path, defaults=Outer(label="kept"))
    assert config == Outer(inner=Inner(gain_m=0.5, count=1), values_m=[1.0, 2.0], label="kept")


def test_unknown_field_is_refused_naming_file_and_dotted_field(tmp_path):
    path = write(tmp_path, "inner:\n  gain_mm: 0.5\n")
    with pytest.raises(
        ConfigError,
        match=r"config\.yaml: unknown field 'inner\.gain_mm'.*"
        r"did you mean 'inner\.gain_m'",
    ):
        load_config(Outer, path, defaults=Outer())


@pytest.mark.parametrize(
    "text, field_name, expected",
    [
        ("inner:\n  gain_m: fast\n", "inner.gain_m", "a number"),
        ("inner:\n  gain_m: true\n", "inner.gain_m", "a number"),
        ("inner:\n  count: 2.5\n", "inner.count", "an integer"),
        ("values_m: 3\n", "values_m", "a list"),
        ("values_m: [1, x]\n", r"values_m\[1\]", "a number"),
        ("inner: 4\n", "inner", "a mapping"),
    ],
)
def test_mistyped_field_is_refused_naming_the_field(tmp_path, text, field_name, expected):
    path = write(tmp_path, text)
    with pytest.raises(ConfigError, match=f"'?{field_name}'?.*{expected}"):
        load_config(Outer, path, defaults=Outer())


def test_unset_required_field_is_reported(tmp_path):
    path = write(tmp_path, "label: y\n")
    with pytest.raises(ConfigError, match=r"required fields not set: inner\.gain_m"):
        load_config(Outer, path)
    assert find_unset_fields(Outer()) == ["inner.gain_m"]


def test_missing_file_and_bad_yaml(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothing.yaml"):
        load_config(Outer, tmp_path / "nothing.yaml")
    path = write(tmp_path, "inner: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(Outer, path, defaults=Outer())


def test_asset_path_names_a_missing_asset():
    assert asset_path("paper.yaml").is_file()
    with pytest.raises(FileNotFoundError, match="no_such.yaml"):
        asset_path("no_such.yaml")


@dataclass
class _Optional:
    enabled: bool = False
    size_m: float = UNSET


@dataclass
class _Holder:
    section: _Optional = field(default_factory=_Optional)


def test_a_disabled_section_needs_nothing_else_set():
    assert find_unset_fields(_Holder()) == []
    assert find_unset_fields(_Holder(_Optional(enabled=True))) == ["section.size_m"]


# --- YAML read safely: every refusal is one line naming the file (and where known, the line) ---


def refused(path, schema=Outer):
    """The one-line message of the ConfigError loading ``path`` raises."""
    with pytest.raises(ConfigError) as raised:
        load_config(schema, path, defaults=schema())
    message = str(raised.value)
    assert "\n" not in message and str(path) in message
    return message


def test_a_repeated_key_is_refused_naming_line_and_key(tmp_path):
    path = write(tmp_path, "label: a\ninner:\n  count: 2\nlabel: b\n")
    assert refused(path).endswith(":4:1: duplicate key 'label' (first at line 1)")


def test_an_alias_bomb_is_refused_at_once(tmp_path):
    # Nine levels of nine aliases each: 387 million strings once the list is walked.
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"a{i}: &a{i} [{','.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
    path = write(tmp_path, "\n".join([*lines, "values_m: *a8"]) + "\n")
    start = time.perf_counter()
    message = refused(path)
    assert time.perf_counter() - start < 0.5
    assert "anchors and aliases" in message


def test_a_file_that_is_not_utf8_is_refused(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("label: café\n".encode("latin-1"))
    assert "not UTF-8 text" in refused(path)


def test_deep_nesting_is_refused_before_the_recursion_limit(tmp_path):
    path = write(tmp_path, "values_m: " + "[" * 5000 + "]" * 5000 + "\n")
    assert f"nested deeper than {MAX_YAML_DEPTH} levels" in refused(path)


def test_tags_still_load_through_the_strict_loader(tmp_path):
    path = write(tmp_path, "cameras:\n  kinect_v1: !KinectV1Config {latency_s: 0.1}\n")
    assert load_scenario(path).cameras["kinect_v1"].latency_s == 0.1
