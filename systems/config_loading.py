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

from maskless.errors import ConfigError, MasklessError, MissingFileError

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


# Configs and model files are a few kB and nest 4 levels at most; these bounds refuse at once a
# file that is no config (a recording passed by mistake) or that would exhaust the composer's
# recursion, long before either costs time or memory.
MAX_YAML_BYTES = 1 << 20
MAX_YAML_DEPTH = 32


class _RefusedYaml(yaml.MarkedYAMLError):
    """Valid YAML that maskless refuses (an alias, a duplicate key, too deep a nesting)."""


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that refuses anchors and aliases, duplicate keys and deep nesting.

    Aliases are refused outright, not bounded: no config needs them, and a few lines of them (a
    "billion laughs") expand to gigabytes once the tree is walked. A repeated key would silently
    keep only its last value.
    """

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise _RefusedYaml(
                problem="anchors and aliases (&name, *name) are not accepted; write the value out",
                problem_mark=event.start_mark,
            )
        if self._depth >= MAX_YAML_DEPTH:
            raise _RefusedYaml(
                problem=f"nested deeper than {MAX_YAML_DEPTH} levels", problem_mark=event.start_mark
            )
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):
        first_lines = {}
        for key_node, _ in node.value if isinstance(node, yaml.MappingNode) else ():
            key = self.construct_object(key_node, deep=True)
            if not isinstance(key, typing.Hashable):
                continue  # SafeLoader's own check refuses it below
            if key in first_lines:
                raise _RefusedYaml(
                    problem=f"duplicate key {key!r} (first at line {first_lines[key]})",
                    problem_mark=key_node.start_mark,
                )
            first_lines[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


def read_yaml(path: Path, error: type[MasklessError] = ConfigError, loader=_StrictLoader):
    """The YAML tree of the file ``path``, read strictly (see ``_StrictLoader``).

    Raises:
        MissingFileError: ``path`` is not a file.
        error: a file too large, not UTF-8 text, malformed, or refused, in one line naming the
            file (and the line and column where known).
    """
    if not path.is_file():
        raise MissingFileError(f"file not found: {path}")
    if path.stat().st_size > MAX_YAML_BYTES:
        raise error(
            f"{path}: {path.stat().st_size} bytes; a YAML file here is at most {MAX_YAML_BYTES} "
            "(configs and model files are a few kB)"
        )
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as decode_error:
        raise error(
            f"{path}: not UTF-8 text (byte 0x{decode_error.object[decode_error.start]:02x} at "
            f"offset {decode_error.start}); save it as UTF-8"
        ) from None
    try:
        return yaml.load(text, Loader=loader)
    except yaml.YAMLError as yaml_error:
        # PyYAML's own message spans several lines; the CLI's errors are one line.
        mark = getattr(yaml_error, "problem_mark", None)
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        problem = getattr(yaml_error, "problem", None) or str(yaml_error).splitlines()[0]
        refused = isinstance(yaml_error, _RefusedYaml)
        raise error(f"{where}: {'' if refused else 'not valid YAML: '}{problem}") from None


class _TagKeepingLoader(_StrictLoader):
    """The strict loader, keeping ``!Tag`` nodes instead of refusing them."""


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
        ConfigError: the file is no UTF-8 YAML, or holds what ``read_yaml`` refuses (an alias,
            a repeated key, deep nesting), has an unknown or mistyped field, or (without
            defaults) leaves a required field unset. The message names the file and the field.
    """
    path = Path(filename)
    if not path.is_file():
        raise MissingFileError(f"config file not found: {path}")
    tree = read_yaml(path, ConfigError, _TagKeepingLoader)
    if tree is None:
        tree = {}
    checked = _checked_tree(tree, schema, defaults, str(path))
    # Here, not at the top: pydrake is slow to import, and `maskless identify` reads YAML
    # (read_yaml) without ever loading a typed config.
    from pydrake.common.yaml import yaml_load_typed

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
