"""Strict loading of YAML configuration into dataclasses, and the path of shipped assets.

Drake's ``yaml_load_typed`` already refuses unknown fields and wrong types, but its messages name
neither the file nor the dotted path of the field. This module checks the YAML tree against the
dataclass first, so a user sees ``FILE: unknown field 'kinect_v1.latency_ms' (did you mean
'latency_s'?)`` before anything runs, then lets Drake do the typed load.
"""

import dataclasses
import difflib
import math
import typing
from importlib import resources
from pathlib import Path

import yaml
from pydrake.common.yaml import yaml_load_typed

from maskless.errors import ConfigError

# A float field whose value must come from a YAML file (the shipped assets), so every published
# number is written once, in assets/, and never repeated as a Python default.
UNSET = math.nan


def asset_path(name: str) -> Path:
    """The path of a file shipped in ``maskless.assets``."""
    path = Path(str(resources.files("maskless.assets").joinpath(name)))
    if not path.is_file():
        raise FileNotFoundError(f"shipped asset '{name}' not found at {path}")
    return path


def _dataclass_of(annotation):
    """The dataclass type inside an annotation (plain or Optional[...]), else None."""
    if dataclasses.is_dataclass(annotation):
        return annotation
    for arg in typing.get_args(annotation):
        if dataclasses.is_dataclass(arg):
            return arg
    return None


def _check_known_fields(tree, schema, filename: str, prefix: str = "") -> None:
    if not isinstance(tree, dict):
        where = f"field '{prefix.rstrip('.')}'" if prefix else "the top level"
        raise ConfigError(f"{filename}: {where} must be a mapping, got {type(tree).__name__}")
    hints = typing.get_type_hints(schema)
    known = {f.name for f in dataclasses.fields(schema)}
    for key, value in tree.items():
        if key not in known:
            close = difflib.get_close_matches(str(key), sorted(known), n=1)
            hint = f" (did you mean '{prefix}{close[0]}'?)" if close else ""
            raise ConfigError(
                f"{filename}: unknown field '{prefix}{key}'{hint}; "
                f"known fields here: {', '.join(sorted(known))}"
            )
        inner = _dataclass_of(hints[key])
        if inner is not None and value is not None:
            _check_known_fields(value, inner, filename, f"{prefix}{key}.")
        else:
            _check_scalar_type(value, hints[key], filename, f"{prefix}{key}")


_EXPECTED_SCALARS = {
    float: ((int, float), "a number"),
    int: ((int,), "an integer"),
    str: ((str,), "a string"),
    bool: ((bool,), "true or false"),
}


def _check_scalar_type(value, annotation, filename: str, dotted_name: str) -> None:
    """Names the field whose YAML value has the wrong type (Drake's own message does not)."""
    if typing.get_origin(annotation) is list:
        if not isinstance(value, list):
            raise ConfigError(f"{filename}: field '{dotted_name}' = {value!r}: expected a list")
        (item_type,) = typing.get_args(annotation) or (None,)
        for index, item in enumerate(value):
            _check_scalar_type(item, item_type, filename, f"{dotted_name}[{index}]")
        return
    if annotation not in _EXPECTED_SCALARS:
        return
    accepted, description = _EXPECTED_SCALARS[annotation]
    # YAML's true/false are ints to Python; a number field must not accept them silently.
    is_bool = isinstance(value, bool) and annotation is not bool
    if is_bool or not isinstance(value, accepted):
        raise ConfigError(f"{filename}: field '{dotted_name}' = {value!r}: expected {description}")
    # .nan and .inf are valid YAML floats but no physical parameter; NaN would also read as unset.
    if annotation is float and not math.isfinite(value):
        raise ConfigError(
            f"{filename}: field '{dotted_name}' = {value!r}: expected a finite number"
        )


def find_unset_fields(config, prefix: str = "") -> list[str]:
    """Dotted names of float fields still at ``UNSET`` (NaN) anywhere in a dataclass tree."""
    unset = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        if dataclasses.is_dataclass(value):
            unset += find_unset_fields(value, f"{prefix}{field.name}.")
        elif isinstance(value, float) and math.isnan(value):
            unset.append(f"{prefix}{field.name}")
    return unset


def load_config(schema, filename: str | Path, defaults=None):
    """Loads ``filename`` into ``schema``, over ``defaults`` when given.

    Raises:
        FileNotFoundError: the file does not exist.
        ConfigError: the YAML is malformed, has an unknown or mistyped field, or (without
            defaults) leaves a required field unset. The message names the file and the field.
    """
    path = Path(filename)
    if not path.is_file():
        raise FileNotFoundError(f"config file not found: {path}")
    try:
        tree = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise ConfigError(f"{path}: not valid YAML: {error}") from error
    if tree is None:
        tree = {}
    _check_known_fields(tree, schema, str(path))
    try:
        if defaults is None:
            config = yaml_load_typed(schema=schema, data=yaml.safe_dump(tree))
        else:
            config = yaml_load_typed(schema=schema, data=yaml.safe_dump(tree), defaults=defaults)
    except (RuntimeError, ValueError, TypeError) as error:
        raise ConfigError(f"{path}: {error}") from error
    if defaults is None:
        unset = find_unset_fields(config)
        if unset:
            raise ConfigError(f"{path}: required fields not set: {', '.join(unset)}")
    return config
