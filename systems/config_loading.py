"""Strict loading of YAML configuration into dataclasses, and the path of shipped assets.

Drake's ``yaml_load_typed`` already refuses unknown fields and wrong types, but its messages name
neither the file nor the dotted path of the field. This module checks the YAML tree against the
dataclass first, so a user sees ``FILE: unknown field 'kinect_v1.latency_ms' (did you mean
'latency_s'?)`` before anything runs, then lets Drake do the typed load.
"""

import dataclasses
import difflib
import functools
import math
import typing
from importlib import resources
from pathlib import Path

import yaml
from pydrake.common.yaml import yaml_load_typed

from maskless.errors import ConfigError, MissingFileError

# A float field whose value must come from a YAML file (the shipped assets), so every published
# number is written once, in assets/, and never repeated as a Python default.
UNSET = math.nan


def asset_path(name: str) -> Path:
    """The path of a file shipped in ``maskless.assets``."""
    path = Path(str(resources.files("maskless.assets").joinpath(name)))
    if not path.is_file():
        raise FileNotFoundError(f"shipped asset '{name}' not found at {path}")
    return path


@dataclasses.dataclass(frozen=True)
class _Tagged:
    """A YAML node written with a type tag (``!IdentifiedPlant {...}``).

    The tag picks one alternative of a ``Union`` field, as in ``yaml_load_typed``.
    """

    tag: str
    value: object


class _TagKeepingLoader(yaml.SafeLoader):
    """SafeLoader that keeps ``!Tag`` nodes instead of refusing them."""


def _construct_tagged(loader, tag_suffix, node):
    if isinstance(node, yaml.MappingNode):
        value = loader.construct_mapping(node, deep=True)
    elif isinstance(node, yaml.SequenceNode):
        value = loader.construct_sequence(node, deep=True)
    else:
        value = loader.construct_scalar(node)
    return _Tagged(tag_suffix, value)


_TagKeepingLoader.add_multi_constructor("!", _construct_tagged)


class _TagWritingDumper(yaml.SafeDumper):
    """SafeDumper that writes ``_Tagged`` nodes back with their tag."""


def _represent_tagged(dumper, tagged: _Tagged):
    if isinstance(tagged.value, dict):
        return dumper.represent_mapping(f"!{tagged.tag}", tagged.value)
    return dumper.represent_scalar(f"!{tagged.tag}", str(tagged.value))


_TagWritingDumper.add_representer(_Tagged, _represent_tagged)


def _dataclass_alternatives(annotation) -> tuple[type, ...]:
    """The dataclasses an annotation allows.

    One for a plain or Optional dataclass field, several for a Union of dataclasses (chosen in
    YAML by tag), none for anything else.
    """
    if dataclasses.is_dataclass(annotation):
        return (annotation,)
    return tuple(arg for arg in typing.get_args(annotation) if dataclasses.is_dataclass(arg))


def _checked_tree(tree, schema, default, filename: str, prefix: str = ""):
    """``tree`` checked against ``schema``, with the tag of every ``Union`` value made explicit.

    The check finds unknown fields, wrong types and unknown tags. An untagged value keeps the type
    of the default it overrides: ``yaml_load_typed`` would read it as the Union's first
    alternative and so quietly turn, say, a Kinect v2 entry into a Kinect v1.
    """
    if not isinstance(tree, dict):
        where = f"field '{prefix.rstrip('.')}'" if prefix else "the top level"
        raise ConfigError(f"{filename}: {where} must be a mapping, got {type(tree).__name__}")
    hints = typing.get_type_hints(schema)
    known = {f.name for f in dataclasses.fields(schema)}
    checked = {}
    for key, value in tree.items():
        if key not in known:
            close = difflib.get_close_matches(str(key), sorted(known), n=1)
            hint = f" (did you mean '{prefix}{close[0]}'?)" if close else ""
            raise ConfigError(
                f"{filename}: unknown field '{prefix}{key}'{hint}; "
                f"known fields here: {', '.join(sorted(known))}"
            )
        field_default = getattr(default, key, None)
        checked[key] = _checked_value(value, hints[key], field_default, filename, f"{prefix}{key}")
    return checked


def _checked_value(value, annotation, default, filename: str, dotted_name: str):
    """One field's YAML value checked against its annotation (see ``_checked_tree``)."""
    if typing.get_origin(annotation) is dict and isinstance(value, dict):
        _, value_type = typing.get_args(annotation)
        defaults = default if isinstance(default, dict) else {}
        return {
            key: _checked_value(
                item, value_type, defaults.get(key), filename, f"{dotted_name}.{key}"
            )
            for key, item in value.items()
        }
    alternatives = _dataclass_alternatives(annotation)
    if not alternatives or value is None:
        if isinstance(value, _Tagged):
            raise ConfigError(
                f"{filename}: field '{dotted_name}' has the tag !{value.tag}, but takes no tag"
            )
        _check_scalar_type(value, annotation, filename, dotted_name)
        return value
    if len(alternatives) == 1 and not isinstance(value, _Tagged):
        return _checked_tree(value, alternatives[0], default, filename, f"{dotted_name}.")
    by_tag = {alternative.__name__: alternative for alternative in alternatives}
    tags = ", ".join(f"!{name}" for name in by_tag)
    if len(alternatives) > 1 and not isinstance(value, _Tagged | dict):
        raise ConfigError(
            f"{filename}: field '{dotted_name}' = {value!r}: expected a mapping tagged with one "
            f"of {tags}"
        )
    if isinstance(value, _Tagged):
        tag, value = value.tag, value.value
        if tag not in by_tag:
            raise ConfigError(
                f"{filename}: field '{dotted_name}' has the tag !{tag}; expected one of {tags}"
            )
    else:
        tag = type(default).__name__ if type(default) in alternatives else alternatives[0].__name__
    if value is None or value == "":  # a bare tag, "!PneumaticPlant", has no fields to set
        value = {}
    same_type_default = default if type(default) is by_tag[tag] else None
    tree = _checked_tree(value, by_tag[tag], same_type_default, filename, f"{dotted_name}.")
    return _Tagged(tag, tree) if len(alternatives) > 1 else tree


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


def check_override(schema, field_name: str, value, source: str) -> None:
    """Refuses a value set in Python (not YAML) whose type the field of ``schema`` cannot hold.

    Numbers, strings, booleans and lists are checked as a YAML value would be; a dataclass field
    (or a Union of them) takes an instance of one of its dataclasses.

    Raises:
        ConfigError: naming ``source``, the field and what was expected.
    """
    annotation = typing.get_type_hints(schema)[field_name]
    if typing.get_origin(annotation) is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{source}: field '{field_name}' = {value!r}: expected a mapping")
        annotation = typing.get_args(annotation)[1]
        for key, item in value.items():
            _check_override_value(annotation, f"{field_name}.{key}", item, source)
        return
    _check_override_value(annotation, field_name, value, source)


def _check_override_value(annotation, field_name: str, value, source: str) -> None:
    alternatives = _dataclass_alternatives(annotation)
    if alternatives and not isinstance(value, alternatives):
        names = ", ".join(alternative.__name__ for alternative in alternatives)
        raise ConfigError(f"{source}: field '{field_name}' = {value!r}: expected one of {names}")
    _check_scalar_type(value, annotation, source, field_name)


def find_unset_fields(config, prefix: str = "") -> list[str]:
    """Dotted names of float fields still at ``UNSET`` (NaN) anywhere in a dataclass tree.

    Mapping values are included. A section whose ``enabled`` field is False needs nothing else set
    (a camera that is not rendered needs no rendering settings).
    """
    unset = []
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        items = value.items() if isinstance(value, dict) else [(None, value)]
        for key, item in items:
            name = f"{prefix}{field.name}" + ("" if key is None else f".{key}")
            if dataclasses.is_dataclass(item):
                if getattr(item, "enabled", True) is not False:
                    unset += find_unset_fields(item, f"{name}.")
            elif isinstance(item, float) and math.isnan(item):
                unset.append(name)
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
        raise MissingFileError(f"config file not found: {path}")
    try:
        tree = yaml.load(path.read_text(), Loader=_TagKeepingLoader)
    except yaml.YAMLError as error:
        # PyYAML's own message spans several lines; the CLI's errors are one line.
        mark = getattr(error, "problem_mark", None)
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise ConfigError(f"{where}: not valid YAML: {problem}") from None
    if tree is None:
        tree = {}
    checked = _checked_tree(tree, schema, defaults, str(path))
    data = yaml.dump(checked, Dumper=_TagWritingDumper)
    try:
        if defaults is None:
            config = yaml_load_typed(schema=schema, data=data)
        else:
            config = yaml_load_typed(schema=schema, data=data, defaults=defaults)
    except (RuntimeError, ValueError, TypeError) as error:
        raise ConfigError(f"{path}: {error}") from error
    if defaults is None:
        unset = find_unset_fields(config)
        if unset:
            raise ConfigError(f"{path}: required fields not set: {', '.join(unset)}")
    return config


def refuse_out_of_range(prefix: str, config, checks) -> None:
    """Raises ConfigError naming ``{prefix}.FIELD``, its value and what was expected.

    ``checks`` is (in range, field name, what was expected) per field, in order; the first not in
    range is refused. A field name may be dotted (``rendering.color_scale``). A generator of
    checks is evaluated lazily, so a check may rely on those before it having passed.
    """
    for in_range, field_name, expected in checks:
        if not in_range:
            value = functools.reduce(getattr, field_name.split("."), config)
            dotted = f"{prefix}.{field_name}" if prefix else field_name
            raise ConfigError(f"{dotted} = {value}: expected {expected}")
