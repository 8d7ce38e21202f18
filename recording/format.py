"""The recording format's names: topics, their JSON schemas, the format version, version-1 names.

What the names mean, topic by topic and field by field, and how the versions differ, is told in
the package's docstring (``maskless.recording``); this module is that table as code.
"""

from __future__ import annotations

import copy
import re
from typing import Any

from maskless.sensor_names import is_sensor_name

MESSAGE_ENCODING = "json"
SCHEMA_ENCODING = "jsonschema"
# Camera frames are Foxglove messages, which Foxglove defines in protobuf.
CAMERA_MESSAGE_ENCODING = "protobuf"
LIBRARY = "maskless"
PROFILE = ""

# The format version every schema's name ends in (".v2"); a schema name without one is version 1.
SCHEMA_VERSION = 2
# The Metadata record a recording cut short ends with, before its footer (``RecordingWriter``).
CUT_METADATA = "maskless.cut"
# The Metadata record a designed experiment's recording opens with: the parts of it to fit and to
# judge a model on ("estimation", "validation": START:STOP as `maskless identify` takes them).
FIT_SPLIT_METADATA = "maskless.fit_split"

REFERENCE_TOPIC = "/reference"
HEAD_HEIGHT_TOPIC = "/plant/head_height"
FUSION_TOPIC = "/fusion/estimate"
COMMAND_TOPIC = "/controller/command"
SAFETY_TOPIC = "/safety/status"
BLADDER_PRESSURE_TOPIC = "/plant/bladder_pressure"

_SENSOR_TOPIC = re.compile(r"/sensors/([A-Za-z0-9_]+)/measurement")
_FILTER_TOPIC = re.compile(r"/filters/([A-Za-z0-9_]+)/estimate")
# A maskless schema name: the kind of message, then ".vN" from version 2 on.
_SCHEMA_NAME = re.compile(r"maskless\.[A-Za-z]+(?:\.v([0-9]+))?")

_NUMBER = "number"
_BOOLEAN = "boolean"
_STRING = "string"

_COVARIANCE_SCHEMA: dict[str, Any] = {
    "type": "array",
    "description": (
        "2x2 state covariance, row-major [[P_pp, P_pv], [P_vp, P_vv]]; units "
        "[[m^2, m^2/s], [m^2/s, m^2/s^2]]"
    ),
    "minItems": 2,
    "maxItems": 2,
    "items": {
        "type": "array",
        "minItems": 2,
        "maxItems": 2,
        "items": {"type": "number"},
    },
}


def _versioned(kind: str) -> str:
    """The schema name of a kind of message in this format version, e.g. maskless.Reference.v2."""
    return f"{kind}.v{SCHEMA_VERSION}"


def _object_schema(kind: str, description: str, properties: dict[str, Any]) -> dict[str, Any]:
    """Builds a closed JSON Schema object whose properties are all required."""
    return {
        "title": _versioned(kind),
        "description": description,
        "type": "object",
        "properties": properties,
        "required": list(properties),
        "additionalProperties": False,
    }


_SCHEMAS: dict[str, dict[str, Any]] = {
    "maskless.Reference": _object_schema(
        "maskless.Reference",
        "Head-height set point. Units: metres (m).",
        {"reference_head_height_m": {"type": "number", "description": "set point (m)"}},
    ),
    "maskless.HeadHeight": _object_schema(
        "maskless.HeadHeight",
        "True head height from the plant model. Units: metres (m).",
        {"head_height_m": {"type": "number", "description": "head height (m)"}},
    ),
    "maskless.DepthMeasurement": _object_schema(
        "maskless.DepthMeasurement",
        "One depth-camera distance reading. Units: metres (m); valid is unitless.",
        {
            "distance_m": {"type": "number", "description": "measured distance (m)"},
            "valid": {
                "type": "boolean",
                "description": "false when the sensor returned no usable depth",
            },
        },
    ),
    "maskless.StateEstimate": _object_schema(
        "maskless.StateEstimate",
        "Kalman-filter state estimate. Units: height m, velocity m/s, covariance SI "
        "([[m^2, m^2/s], [m^2/s, m^2/s^2]]).",
        {
            "head_height_m": {"type": "number", "description": "estimated head height (m)"},
            "head_velocity_m_s": {
                "type": "number",
                "description": "estimated head velocity (m/s)",
            },
            "covariance": _COVARIANCE_SCHEMA,
        },
    ),
    "maskless.ValveCommand": _object_schema(
        "maskless.ValveCommand",
        "Proportional-valve commands from the controller. Units: amperes (A).",
        {
            "inlet_valve_current_a": {
                "type": "number",
                "description": "inlet valve coil current (A)",
            },
            "outlet_valve_current_a": {
                "type": "number",
                "description": "outlet (vacuum) valve coil current (A)",
            },
        },
    ),
    "maskless.SafetyStatus": _object_schema(
        "maskless.SafetyStatus",
        "The safety supervisor's state at a controller tick "
        "(systems/control/safety_supervisor.py). Units: metres (m), amperes (A).",
        {
            "state": {
                "type": _STRING,
                "description": "normal, degraded (a camera excluded, the loop goes on), "
                "holding (the valves hold their currents) or venting (the bladder empties)",
            },
            "reasons": {
                "type": _STRING,
                "description": "the latched reasons, comma-separated; empty when none",
            },
            "beam_hold": {
                "type": _BOOLEAN,
                "description": "true while the beam must not be on",
            },
            "estimated_head_height_m": {
                "type": _NUMBER,
                "description": "the controller's estimate of the head height, which the beam "
                "hold judges the error by (m)",
            },
            "inlet_valve_current_a": {
                "type": _NUMBER,
                "description": "the current the inlet valve gets (A)",
            },
            "outlet_valve_current_a": {
                "type": _NUMBER,
                "description": "the current the outlet valve gets (A)",
            },
        },
    ),
    "maskless.BladderPressure": _object_schema(
        "maskless.BladderPressure",
        "The bladder's pressure sensor. Units: pascals (Pa), gauge.",
        {"gauge_pressure_pa": {"type": _NUMBER, "description": "gauge pressure (Pa)"}},
    ),
}

_FIXED_TOPIC_SCHEMAS: dict[str, str] = {
    REFERENCE_TOPIC: "maskless.Reference",
    HEAD_HEIGHT_TOPIC: "maskless.HeadHeight",
    FUSION_TOPIC: "maskless.StateEstimate",
    COMMAND_TOPIC: "maskless.ValveCommand",
    SAFETY_TOPIC: "maskless.SafetyStatus",
    BLADDER_PRESSURE_TOPIC: "maskless.BladderPressure",
}

# The one table of what version 1 named otherwise: its topics (old -> current), and its fields
# (old -> current) by the current kind of message holding them, since a kind has the same fields
# on every topic it serves. Sensor measurements kept their names.
_V1_TOPICS: dict[str, str] = {"/plant/head_position": HEAD_HEIGHT_TOPIC}
_V1_FIELDS: dict[str, dict[str, str]] = {
    "maskless.Reference": {"reference_m": "reference_head_height_m"},
    "maskless.HeadHeight": {"head_position_m": "head_height_m"},
    "maskless.StateEstimate": {"position_m": "head_height_m", "velocity_m_s": "head_velocity_m_s"},
    "maskless.ValveCommand": {
        "current_a": "inlet_valve_current_a",
        "outlet_current_a": "outlet_valve_current_a",
    },
}


def sensor_measurement_topic(name: str) -> str:
    """Returns the measurement topic of a depth sensor.

    Args:
        name: Sensor name, e.g. ``"kinect_v1"`` (letters, digits and underscores only).

    Returns:
        ``"/sensors/{name}/measurement"``.

    Raises:
        ValueError: If ``name`` is empty or contains other characters.
    """
    _check_sensor_name(name)
    return f"/sensors/{name}/measurement"


def filter_estimate_topic(name: str) -> str:
    """Returns the topic of the per-sensor filter estimate.

    Args:
        name: Sensor name, e.g. ``"kinect_v1"`` (letters, digits and underscores only).

    Returns:
        ``"/filters/{name}/estimate"``.

    Raises:
        ValueError: If ``name`` is empty or contains other characters.
    """
    _check_sensor_name(name)
    return f"/filters/{name}/estimate"


def _check_sensor_name(name: str) -> None:
    if not is_sensor_name(name):
        raise ValueError(f"invalid sensor name {name!r}: use letters, digits and underscores only")


def _schema_kind_for_topic(topic: str) -> str:
    if topic in _FIXED_TOPIC_SCHEMAS:
        return _FIXED_TOPIC_SCHEMAS[topic]
    if _SENSOR_TOPIC.fullmatch(topic):
        return "maskless.DepthMeasurement"
    if _FILTER_TOPIC.fullmatch(topic):
        return "maskless.StateEstimate"
    raise ValueError(f"unknown topic {topic!r}: no schema is defined for it")


def schema_for_topic(topic: str) -> tuple[str, dict[str, Any]]:
    """Returns the schema of a topic.

    Args:
        topic: A topic such as ``REFERENCE_TOPIC`` or ``sensor_measurement_topic("kinect_v1")``.

    Returns:
        ``(schema_name, schema)``: the name carries the format version (``maskless.Reference.v2``);
        ``schema`` is a JSON Schema dict (a copy, safe to modify) whose ``description`` gives the
        units.

    Raises:
        ValueError: If the topic is unknown; the message names the topic.
    """
    kind = _schema_kind_for_topic(topic)
    return _versioned(kind), copy.deepcopy(_SCHEMAS[kind])


def _v1_renames(topic: str) -> tuple[str, dict[str, str]]:
    """The current name of a version-1 topic, and its renamed fields (version 1 -> current)."""
    topic = _V1_TOPICS.get(topic, topic)
    try:
        kind = _schema_kind_for_topic(topic)
    except ValueError:
        return topic, {}  # not a maskless topic: nothing was renamed
    return topic, _V1_FIELDS.get(kind, {})


def current_name(topic: str, field: str) -> tuple[str, str]:
    """The current name of a topic and field that may be written with version-1 names.

    Lets a name written against version-1 recordings (say ``/controller/command:current_a``) keep
    working: ``read_recording`` presents every file under the current names.

    Args:
        topic: A topic, e.g. ``"/plant/head_position"``.
        field: A field of it, e.g. ``"head_position_m"``.

    Returns:
        ``(topic, field)`` under the current names, e.g. ``("/plant/head_height",
        "head_height_m")``; current (and unknown) names come back unchanged.
    """
    topic, renames = _v1_renames(topic)
    return topic, renames.get(field, field)
