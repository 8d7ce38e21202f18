"""Write and read the MCAP recordings of a closed-loop simulation.

Every topic of the loop's signals carries JSON messages (``message_encoding`` ``"json"``) described
by a ``"jsonschema"`` schema. ``log_time`` and ``publish_time`` are *simulated* time in integer
nanoseconds, not wall clock, so a recording of the same simulation is byte-for-byte reproducible.

A recording may also carry camera frames (``maskless.camera_images``): per camera, Foxglove's
``CompressedImage`` on ``/cameras/NAME/image`` and ``ImageAnnotations`` on
``/cameras/NAME/annotations``, protobuf messages (``message_encoding`` ``"protobuf"``) whose schemas
are the FileDescriptorSets Foxglove ships. They are merged with the JSON messages by log time, a
frame after the JSON messages of its time. ``read_recording`` passes over them;
``read_camera_frames`` reads them.

The writer takes whole columns (the arrays a Drake ``VectorLogSink`` hands back) rather than single
messages, because converting column-wise with ``ndarray.tolist()`` is far cheaper than touching
numpy scalars once per message.

Files are written *unchunked*: each message is a record of its own on disk. That costs a little
space, but a file whose writer died (or that was cut at any byte) can be read back up to its last
complete message, which a chunked file cannot promise (a whole chunk would be lost).

Topics and fields (format version 2). A field is named after the Drake output port its values come
from (``diagrams.closed_loop.export_and_log``), so a signal has one name from the diagram to the
file:

=================================  =============================================================
topic                              fields
=================================  =============================================================
``/reference``                     ``reference_head_height_m``
``/plant/head_height``             ``head_height_m``
``/sensors/NAME/measurement``      ``distance_m``, ``valid``
``/filters/NAME/estimate``         ``head_height_m``, ``head_velocity_m_s``, ``covariance``
``/fusion/estimate``               ``head_height_m``, ``head_velocity_m_s``, ``covariance``
``/controller/command``            ``inlet_valve_current_a``, ``outlet_valve_current_a``
=================================  =============================================================

An estimate comes from the ports ``estimated_state`` ([height, velocity]) and ``covariance``. Its
covariance keeps the port's name; the state is split into its two components, named after what
they estimate: the first is the plant's ``head_height_m`` (so truth and estimate compare field for
field), the second its rate, ``head_velocity_m_s``. Two scalar fields, unlike one 2-vector, can each
be read as ``TOPIC:FIELD`` (``maskless identify``) and plotted by name in an MCAP viewer.

Versions. Every schema's name carries the format version, ``maskless.Reference.v2``: the schema name
is what MCAP tools list for a channel, and a schema is written before its channel's first message,
so even a cut-off file says how to read every message it holds (a file-wide Metadata record would
say nothing per channel, and a streaming reader would have to meet it first). Version 1 (schema
names without a version, every file written before versions existed) named the fields differently:
``reference_m``, the topic ``/plant/head_position`` with ``head_position_m``, estimates'
``position_m`` and ``velocity_m_s``, and commands' ``current_a`` and ``outlet_current_a``.
``read_recording`` presents a version-1 file under the current names (``_V1_TOPICS`` and
``_V1_FIELDS`` are the one table of what changed), and refuses a version it does not know.
"""

from __future__ import annotations

import copy
import io
import json
import re
import struct
import warnings
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
from foxglove.messages import CompressedImage, ImageAnnotations
from google.protobuf.message import DecodeError
from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel as McapChannel
from mcap.records import Message as McapMessage
from mcap.records import Schema as McapSchema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, IndexType, Writer

from maskless.camera_images import (
    CameraFrame,
    annotations_message,
    annotations_topic,
    camera_of_topic,
    frame_from_messages,
    image_message,
    image_topic,
)
from maskless.errors import MissingFileError, RecordError
from maskless.sensor_names import is_sensor_name

__all__ = [
    "CAMERA_MESSAGE_ENCODING",
    "COMMAND_TOPIC",
    "FUSION_TOPIC",
    "HEAD_HEIGHT_TOPIC",
    "MESSAGE_ENCODING",
    "REFERENCE_TOPIC",
    "SCHEMA_ENCODING",
    "SCHEMA_VERSION",
    "Channel",
    "Recording",
    "TruncatedRecordingWarning",
    "current_name",
    "filter_estimate_topic",
    "read_camera_frames",
    "read_recording",
    "schema_for_topic",
    "sensor_measurement_topic",
    "write_recording",
]

MESSAGE_ENCODING = "json"
SCHEMA_ENCODING = "jsonschema"
# Camera frames are Foxglove messages, which Foxglove defines in protobuf.
CAMERA_MESSAGE_ENCODING = "protobuf"
LIBRARY = "maskless"
PROFILE = ""

# The format version every schema's name ends in (".v2"); a schema name without one is version 1.
SCHEMA_VERSION = 2

REFERENCE_TOPIC = "/reference"
HEAD_HEIGHT_TOPIC = "/plant/head_height"
FUSION_TOPIC = "/fusion/estimate"
COMMAND_TOPIC = "/controller/command"

# The MCAP magic that opens (and closes) every file.
_MAGIC = b"\x89MCAP0\r\n"

_SENSOR_TOPIC = re.compile(r"/sensors/([A-Za-z0-9_]+)/measurement")
_FILTER_TOPIC = re.compile(r"/filters/([A-Za-z0-9_]+)/estimate")
# A maskless schema name: the kind of message, then ".vN" from version 2 on.
_SCHEMA_NAME = re.compile(r"maskless\.[A-Za-z]+(?:\.v([0-9]+))?")

_NUMBER = "number"
_BOOLEAN = "boolean"

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
}

_FIXED_TOPIC_SCHEMAS: dict[str, str] = {
    REFERENCE_TOPIC: "maskless.Reference",
    HEAD_HEIGHT_TOPIC: "maskless.HeadHeight",
    FUSION_TOPIC: "maskless.StateEstimate",
    COMMAND_TOPIC: "maskless.ValveCommand",
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


# eq=False: fields hold arrays, so field-wise == and hashing would fail.
@dataclass(frozen=True, eq=False)
class Channel:
    """The samples of one topic, as columns.

    Attributes:
        topic: Topic name, e.g. ``FUSION_TOPIC``.
        times_ns: 1-D integer array of simulated times (ns), non-decreasing; one per message.
        columns: Field name -> values. Every field is a 1-D array of length ``len(times_ns)``
            except ``"covariance"``, which is an ``(n, 2, 2)`` array. Units are those in the field
            names (m, m/s, A, ...).
    """

    topic: str
    times_ns: np.ndarray
    columns: Mapping[str, np.ndarray]


@dataclass
class Recording:
    """The messages read back from a recording.

    Attributes:
        messages: Topic -> list of ``(log_time_ns, payload)`` in file order. Topics that were
            recorded without messages map to an empty list.
        truncated: True if the file ended (or broke) before its footer, so only the messages up
            to the last complete one are present.
    """

    messages: dict[str, list[tuple[int, dict[str, Any]]]] = field(default_factory=dict)
    truncated: bool = False

    def topic_arrays(self, topic: str, field: str) -> tuple[np.ndarray, np.ndarray]:
        """Returns one field of one topic as arrays.

        Args:
            topic: Topic name.
            field: Field name, e.g. ``"head_height_m"``.

        Returns:
            ``(times_ns, values)``: ``times_ns`` is int64 (ns); ``values`` is float64 for numbers
            (in the field's unit), bool for booleans, and ``(n, 2, 2)`` float64 for
            ``"covariance"``.

        Raises:
            KeyError: If the topic is not in the recording or a message lacks the field.
        """
        if topic not in self.messages:
            raise KeyError(f"topic {topic!r} not in recording (topics: {sorted(self.messages)})")
        entries = self.messages[topic]
        times_ns = np.fromiter((t for t, _ in entries), dtype=np.int64, count=len(entries))
        try:
            raw = [payload[field] for _, payload in entries]
        except KeyError:
            raise KeyError(f"field {field!r} missing from messages on topic {topic!r}") from None
        dtype, tail_shape = _field_layout(topic, field)
        if not raw:
            return times_ns, np.empty((0, *tail_shape), dtype=dtype or np.float64)
        return times_ns, np.asarray(raw, dtype=dtype)


def _field_layout(topic: str, field: str) -> tuple[type | None, tuple[int, ...]]:
    """Returns (dtype, per-message shape) of a field; dtype None lets numpy infer it."""
    try:
        _, schema = schema_for_topic(topic)
    except ValueError:
        # A topic this version does not know: let numpy infer from the values.
        return None, ()
    prop = schema["properties"].get(field)
    if prop is None:
        return None, ()
    if prop["type"] == _BOOLEAN:
        return bool, ()
    if prop["type"] == "array":
        return np.float64, (2, 2)
    return np.float64, ()


def _prepare_channel(channel: Channel) -> tuple[np.ndarray, list[str], list[list[Any]]]:
    """Validates one channel and converts its columns to Python lists in schema field order.

    Returns:
        ``(times_ns, field_names, column_lists)``.
    """
    topic = channel.topic
    _, schema = schema_for_topic(topic)
    required = schema["required"]

    times = np.asarray(channel.times_ns)
    if times.ndim != 1:
        raise ValueError(f"topic {topic!r}: times_ns must be 1-D, got shape {times.shape}")
    if times.size and not np.issubdtype(times.dtype, np.integer):
        raise ValueError(f"topic {topic!r}: times_ns must be integer ns, got {times.dtype}")
    times = times.astype(np.int64, copy=False)
    n = times.shape[0]
    if n and times[0] < 0:
        # MCAP stores times as unsigned 64-bit integers.
        raise ValueError(f"topic {topic!r}: times_ns must be >= 0, got {int(times[0])}")
    if n > 1 and np.any(np.diff(times) < 0):
        first = int(np.argmax(np.diff(times) < 0)) + 1
        raise ValueError(
            f"topic {topic!r}: times_ns must be non-decreasing (index {first} goes back in time)"
        )

    names = set(channel.columns)
    missing = [f for f in required if f not in names]
    unknown = sorted(names - set(required))
    if missing or unknown:
        raise ValueError(
            f"topic {topic!r}: columns must be exactly {required}; "
            f"missing {missing}, unknown {unknown}"
        )

    lists: list[list[Any]] = []
    for name in required:
        kind = schema["properties"][name]["type"]
        values = np.asarray(channel.columns[name])
        expected_shape = (n, 2, 2) if kind == "array" else (n,)
        if values.shape != expected_shape:
            raise ValueError(
                f"topic {topic!r}: column {name!r} has shape {values.shape}, expected "
                f"{expected_shape} (one value per entry of times_ns)"
            )
        # astype + tolist gives Python float/bool objects in one vectorised step, the same values
        # float()/bool() would give, without per-message numpy scalar overhead.
        dtype = bool if kind == _BOOLEAN else np.float64
        lists.append(values.astype(dtype, copy=False).tolist())
    return times, list(required), lists


def _encode_payloads(topic: str, names: list[str], lists: list[list[Any]]) -> list[bytes]:
    """The compact JSON of every message of one channel.

    For finite numbers a %-template gives exactly ``json.dumps(payload, separators=(",", ":"))``
    (both write floats with ``float.__repr__``) for less (benchmarks/system_overhead.py measures
    the whole write both ways); a channel holding NaN or infinity goes through ``json.dumps``
    itself, which spells those its own way.
    """
    _, schema = schema_for_topic(topic)
    kinds = [schema["properties"][name]["type"] for name in names]
    finite = all(
        np.isfinite(np.asarray(column, dtype=float)).all()
        for column, kind in zip(lists, kinds, strict=True)
        if kind != _BOOLEAN
    )
    if not finite:
        return [
            json.dumps(dict(zip(names, row, strict=True)), separators=(",", ":")).encode()
            for row in zip(*lists, strict=True)
        ]
    parts, flat_columns = [], []
    for name, kind, column in zip(names, kinds, lists, strict=True):
        if kind == "array":  # a 2x2 matrix, row-major
            parts.append(f'"{name}":[[%r,%r],[%r,%r]]')
            flat = np.asarray(column, dtype=float).reshape(-1, 4).T.tolist()
            flat_columns.extend(flat)
        elif kind == _BOOLEAN:
            parts.append(f'"{name}":%s')
            flat_columns.append(["true" if value else "false" for value in column])
        else:
            parts.append(f'"{name}":%r')
            flat_columns.append(column)
    template = "{" + ",".join(parts) + "}"
    return [(template % row).encode() for row in zip(*flat_columns, strict=True)]


def write_recording(
    path: str | PathLike[str], channels: Sequence[Channel], frames: Sequence[CameraFrame] = ()
) -> None:
    """Writes a simulation recording as MCAP.

    All channels and frames are validated before the file is opened, so a bad input never leaves a
    partial file behind. Messages of all channels are merged in increasing log time (ties keep the
    order of ``channels``) and encoded with compact ``json.dumps``, so the same arrays always give
    the same bytes. Each frame adds its two protobuf messages (see ``maskless.camera_images``),
    merged by its time after the JSON messages of the same time; without frames the file is the
    one written before frames existed, byte for byte.

    Args:
        path: Output file; overwritten if it exists.
        channels: One ``Channel`` per topic. Each topic may appear only once; a channel with no
            samples is still registered, so its topic appears in the file.
        frames: Camera frames, each camera's in non-decreasing time. The cameras' topics are
            registered in the order their first frames come.

    Raises:
        ValueError: If a topic is unknown or repeated, a column has the wrong length or shape, the
            field names are not exactly the schema's required fields, the times are not
            non-decreasing integers (ns), or a camera's frames go back in time. The message names
            the topic and field, or the camera.
    """
    cameras = list(dict.fromkeys(frame.camera for frame in _checked_frames(frames)))
    batch = _Batch.of(channels, frames, cameras)
    with RecordingWriter(path, [channel.topic for channel in channels], cameras) as writer:
        writer._write_batch(batch)


def _checked_frames(frames: Sequence[CameraFrame]) -> Sequence[CameraFrame]:
    for i, frame in enumerate(frames):
        if not isinstance(frame, CameraFrame):
            raise ValueError(f"frames[{i}]: expected a CameraFrame, got {type(frame).__name__}")
    return frames


# Every camera's topics, in this order, with the Foxglove message each carries.
_CAMERA_TOPICS = ((image_topic, CompressedImage), (annotations_topic, ImageAnnotations))


def _camera_topics(cameras: Sequence[str]) -> list[tuple[str, Any]]:
    """The (topic, Foxglove message class) of every camera, camera by camera."""
    return [(topic(camera), kind) for camera in cameras for topic, kind in _CAMERA_TOPICS]


@dataclass
class _Batch:
    """Validated, encoded messages: every message's (time, topic, row) in log-time order.

    Topics are numbered as the writer registers them: the channels', then two per camera.
    """

    payloads: list[list[bytes]]
    times: list[int]
    channel_indices: list[int]
    rows: list[int]

    @classmethod
    def of(
        cls,
        channels: Sequence[Channel],
        frames: Sequence[CameraFrame] = (),
        cameras: Sequence[str] = (),
    ) -> _Batch:
        seen: set[str] = set()
        prepared = []
        for channel in channels:
            if channel.topic in seen:
                raise ValueError(f"topic {channel.topic!r} appears more than once in channels")
            seen.add(channel.topic)
            prepared.append(_prepare_channel(channel))
        # Encode every payload up front (column lists, no numpy scalars).
        payloads = [
            _encode_payloads(channel.topic, names, lists)
            for channel, (_, names, lists) in zip(channels, prepared, strict=True)
        ]
        frame_times, frame_payloads = _encode_frames(_checked_frames(frames), cameras)
        return cls._merged([t for t, _, _ in prepared] + frame_times, payloads + frame_payloads)

    @classmethod
    def _merged(cls, times: list[np.ndarray], payloads: list[list[bytes]]) -> _Batch:
        """Every topic's messages in log-time order, given each topic's times and payloads."""
        # A stable sort over the topics concatenated in order keeps ties in the order of the
        # topics and, within a topic, in sample order.
        empty = [np.empty(0, np.int64)]
        all_times = np.concatenate(times or empty)
        channel_index = np.concatenate(
            [np.full(t.shape[0], i, dtype=np.int64) for i, t in enumerate(times)] or empty
        )
        row_index = np.concatenate([np.arange(t.shape[0], dtype=np.int64) for t in times] or empty)
        order = np.argsort(all_times, kind="stable")
        return cls(
            payloads,
            all_times[order].tolist(),
            channel_index[order].tolist(),
            row_index[order].tolist(),
        )


def _encode_frames(
    frames: Sequence[CameraFrame], cameras: Sequence[str]
) -> tuple[list[np.ndarray], list[list[bytes]]]:
    """Each camera topic's times (ns) and encoded messages, in ``_camera_topics`` order.

    Raises:
        ValueError: If a frame's camera is not one of ``cameras``, or a camera's frames go back
            in time.
    """
    index = {camera: k for k, camera in enumerate(cameras)}
    times: list[list[int]] = [[] for _ in range(len(_CAMERA_TOPICS) * len(cameras))]
    payloads: list[list[bytes]] = [[] for _ in times]
    for frame in frames:
        if frame.camera not in index:
            raise ValueError(
                f"camera {frame.camera!r}: not one of the recording's cameras {list(cameras)}"
            )
        image = len(_CAMERA_TOPICS) * index[frame.camera]
        if times[image] and frame.time_ns < times[image][-1]:
            raise ValueError(
                f"camera {frame.camera!r}: frame times must be non-decreasing (a frame at "
                f"{frame.time_s} s follows one at {times[image][-1] / 1e9} s)"
            )
        messages = (image_message(frame), annotations_message(frame))
        for k, message in enumerate(messages, start=image):
            times[k].append(frame.time_ns)
            payloads[k].append(message.encode())
    return [np.asarray(t, dtype=np.int64) for t in times], payloads


class RecordingWriter:
    """A recording written in batches, for a run that is still going.

    Each batch holds the next samples of every topic (and the next frames of the cameras), later
    than every message before it.

    Use it as a context manager. Leaving the block normally writes the footer; leaving it on an
    error closes the file without one, so ``read_recording`` reads what was written and reports
    the recording as cut off. Messages are identical to ``write_recording``'s for the same samples
    and frames in one batch (given the cameras in the order of their first frames).
    """

    def __init__(
        self, path: str | PathLike[str], topics: Sequence[str], cameras: Sequence[str] = ()
    ):
        """Opens ``path`` (overwritten) and registers ``topics``, in order, then ``cameras``.

        Args:
            path: Output file; overwritten if it exists.
            topics: The JSON topics every batch carries a channel for, in this order.
            cameras: The cameras whose frames the batches may carry; each gets an image and an
                annotations topic (``maskless.camera_images``).

        Raises:
            ValueError: If a topic is unknown or repeated, or a camera name is invalid or
                repeated (before the file is opened).
        """
        if len(set(topics)) != len(topics):
            raise ValueError(f"topics repeat: {list(topics)}")
        if len(set(cameras)) != len(cameras):
            raise ValueError(f"cameras repeat: {list(cameras)}")
        schemas = [schema_for_topic(topic) for topic in topics]
        camera_topics = _camera_topics(cameras)  # checks the names
        self._topics = list(topics)
        self._cameras = list(cameras)
        self._messages_written = [0] * (len(topics) + len(camera_topics))
        self._last_time_ns = None
        self._stream = open(Path(path), "wb")
        self._writer = Writer(
            self._stream,
            compression=CompressionType.NONE,
            # Unchunked, so every complete message survives a crash; without chunks there is no
            # message or chunk index to write.
            use_chunking=False,
            index_types=IndexType.NONE,
            enable_data_crcs=True,
        )
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._channel_ids = []
        self._register_json_topics(topics, schemas)
        self._register_camera_topics(camera_topics)

    def _register_json_topics(self, topics, schemas) -> None:
        schema_ids: dict[str, int] = {}
        for topic, (schema_name, schema) in zip(topics, schemas, strict=True):
            if schema_name not in schema_ids:
                schema_ids[schema_name] = self._writer.register_schema(
                    name=schema_name,
                    encoding=SCHEMA_ENCODING,
                    data=json.dumps(schema, separators=(",", ":")).encode(),
                )
            self._channel_ids.append(
                self._writer.register_channel(
                    topic=topic,
                    message_encoding=MESSAGE_ENCODING,
                    schema_id=schema_ids[schema_name],
                )
            )

    def _register_camera_topics(self, camera_topics: list[tuple[str, Any]]) -> None:
        # Unchunked, each schema record lands in the file at once: before its channels' messages.
        schema_ids: dict[Any, int] = {}
        for topic, kind in camera_topics:
            if kind not in schema_ids:
                schema = kind.get_schema()  # the name, encoding and FileDescriptorSet Foxglove has
                schema_ids[kind] = self._writer.register_schema(
                    name=schema.name, encoding=schema.encoding, data=bytes(schema.data)
                )
            self._channel_ids.append(
                self._writer.register_channel(
                    topic=topic,
                    message_encoding=CAMERA_MESSAGE_ENCODING,
                    schema_id=schema_ids[kind],
                )
            )

    def write(self, channels: Sequence[Channel], frames: Sequence[CameraFrame] = ()) -> None:
        """Appends a batch: a ``Channel`` per registered topic, in order, and frames of cameras.

        Args:
            channels: One ``Channel`` per registered topic, in the registered order.
            frames: Frames of the registered cameras, each camera's in non-decreasing time.

        Raises:
            ValueError: If the topics differ from the registered ones, a channel or frame is
                invalid (as for ``write_recording``), a frame's camera is not registered, or the
                batch starts before the last message written.
        """
        topics = [channel.topic for channel in channels]
        if topics != self._topics:
            raise ValueError(f"batch topics {topics}: expected {self._topics}")
        self._write_batch(_Batch.of(channels, frames, self._cameras))

    def _write_batch(self, batch: _Batch) -> None:
        if batch.times and self._last_time_ns is not None and batch.times[0] < self._last_time_ns:
            raise ValueError(
                f"batch starts at {batch.times[0]} ns, before the last message written "
                f"({self._last_time_ns} ns)"
            )
        add_message = self._writer.add_message
        channel_ids, payloads, counts = self._channel_ids, batch.payloads, self._messages_written
        for t, c, r in zip(batch.times, batch.channel_indices, batch.rows, strict=True):
            add_message(
                channel_id=channel_ids[c],
                log_time=t,
                data=payloads[c][r],
                publish_time=t,
                # The sequence counter wraps at 2**32 (uint32 in MCAP).
                sequence=(counts[c] + r) & 0xFFFFFFFF,
            )
        for c, channel_payloads in enumerate(payloads):
            counts[c] += len(channel_payloads)
        if batch.times:
            self._last_time_ns = batch.times[-1]

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, error_type, error, traceback) -> None:
        try:
            if error_type is None:
                self._writer.finish()
        finally:
            self._stream.close()


def write_recording_batches(
    connection, path: str | PathLike[str], cameras: Sequence[str] = ()
) -> None:
    """Writes the batches ``connection.recv()`` returns to ``path``, until None.

    A ``background.Worker``'s serve function (``Worker(..., write_recording_batches, path,
    cameras)``). A batch is a list of channels, as for ``RecordingWriter.write``, or a pair
    ``(channels, frames)`` when it carries frames of ``cameras``; the first batch's channels name
    the topics. If the sender goes away first (EOFError), the file is left without its footer:
    cut off, and readable up to the last batch.
    """
    batch = connection.recv()
    channels, _ = _channels_and_frames(batch)
    with RecordingWriter(path, [channel.topic for channel in channels], cameras) as writer:
        while batch is not None:
            writer.write(*_channels_and_frames(batch))
            batch = connection.recv()


def _channels_and_frames(batch) -> tuple[Sequence[Channel], Sequence[CameraFrame]]:
    """A batch sent to ``write_recording_batches`` as its channels and frames."""
    # A tuple is a (channels, frames) pair; a batch of channels alone comes as a list.
    return batch if isinstance(batch, tuple) else (batch, ())


class TruncatedRecordingWarning(RuntimeWarning):
    """A recording ended or broke before its footer; only a prefix of it was read."""


class _StrictBytesIO(io.BytesIO):
    """A BytesIO whose short reads raise ``EndOfFile``.

    The upstream stream only raises on an *empty* read; a read cut short inside a record would
    surface later as a struct or UTF-8 error from a half-read field. Raising at the cut makes every
    truncation look the same and guarantees no partial record is ever decoded.
    """

    def read(self, size: int | None = -1) -> bytes:
        data = super().read(size)
        if size is not None and size >= 0 and len(data) < size:
            raise EndOfFile()
        return data


# Errors that mean "the bytes stop making sense here": a cut, or a corrupt tail.
_READ_ERRORS = (McapError, ValueError, EOFError, struct.error)


def read_recording(path: str | PathLike[str], topics: Collection[str] | None = None) -> Recording:
    """Reads a recording, recovering what it can from a cut-off file.

    The file is read front to back with a streaming reader (no index or footer needed). At the
    first error after the magic bytes (a cut, or a corrupt record) reading stops, ``truncated`` is
    set and a ``TruncatedRecordingWarning`` names the file and the number of messages recovered.
    Every message returned is complete. A file shorter than the magic whose bytes match it (a
    writer that died at once) reads as an empty, truncated recording. Camera frames (protobuf
    topics) are passed over; ``read_camera_frames`` reads them.

    Args:
        path: The MCAP file.
        topics: Decode only these topics' messages (JSON decoding is most of the reading), named
            as the reader presents them (current names); the others are listed with no messages.
            All of them when None.

    Returns:
        The messages by topic, in file order, with ``log_time`` in simulated ns, under the current
        topic and field names whatever format version wrote them (see the module docstring).

    Raises:
        MissingFileError: If the file does not exist.
        RecordError: If the file is not MCAP (bad magic), a channel's message encoding is neither
            ``"json"`` nor ``"protobuf"``, or a schema carries a format version this reader does
            not know (the message names the file, the topic and the version).
    """
    path = Path(path)
    records = _RecordStream(_read_mcap_bytes(path))
    recording = Recording()
    count = _read_json_messages(records, path, topics, recording)
    if records.error is not None:
        recording.truncated = True
        _warn_truncated(path, records.error, f"{count} complete messages")
    return recording


def _read_mcap_bytes(path: Path) -> bytes:
    """The bytes of an MCAP file, or of a prefix of one.

    Raises:
        MissingFileError: If the file does not exist.
        RecordError: If it cannot be read, or does not start as MCAP does (bad magic).
    """
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise MissingFileError(f"MCAP recording not found: {path}") from None
    except OSError as error:  # a folder, or a file that cannot be read
        raise RecordError(f"{path}: cannot read the recording ({error.strerror})") from None
    head = data[: len(_MAGIC)]
    if head != _MAGIC[: len(head)]:
        raise RecordError(f"{path} is not an MCAP file (bad magic bytes {head!r})")
    return data


def _warn_truncated(path: Path, error: Exception, recovered: str) -> None:
    reason = str(error) or "file ends before its footer"
    warnings.warn(
        f"{path}: recording is truncated or corrupt ({reason}); recovered {recovered}",
        TruncatedRecordingWarning,
        # Warn at the caller of the public reader, which calls this function.
        stacklevel=3,
    )


class _RecordStream:
    """A file's records front to back, up to the first unreadable one.

    Once iterated, ``error`` is what stopped the records (a cut, or a corrupt record), or None
    when they ran to their end.
    """

    def __init__(self, data: bytes):
        self._data = data
        self.error: Exception | None = None

    def __iter__(self):
        if len(self._data) < len(_MAGIC):
            self.error = EndOfFile("file ends inside the magic bytes")
            return
        reader = StreamReader(
            _StrictBytesIO(self._data),
            validate_crcs=True,
            # No record can be longer than the file; this stops a corrupt length early.
            record_size_limit=len(self._data),
        )
        records = reader.records
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except _READ_ERRORS as exc:
                self.error = exc
                return
            yield record


def _read_json_messages(
    records: _RecordStream, path: Path, topics: Collection[str] | None, recording: Recording
) -> int:
    """Reads the records' JSON messages into ``recording``, up to the first unreadable record.

    Returns:
        The number of messages read (those of topics not decoded, and camera frames', included).

    Raises:
        RecordError: as ``read_recording`` does, for a channel or message it refuses.
    """
    schemas: dict[int, McapSchema] = {}
    channels: dict[int, _ReadChannel] = {}
    passed_over: set[int] = set()  # the camera frames' channels
    count = 0
    for record in records:
        if isinstance(record, McapSchema):
            schemas[record.id] = record
        elif isinstance(record, McapChannel):
            if record.message_encoding == CAMERA_MESSAGE_ENCODING:
                passed_over.add(record.id)
                continue
            channel = _read_channel(record, schemas.get(record.schema_id), path)
            channels[record.id] = channel
            recording.messages.setdefault(channel.topic, [])
        elif isinstance(record, McapMessage):
            count += 1
            if record.channel_id in passed_over:
                continue
            channel = channels.get(record.channel_id)
            if topics is None or channel is None or channel.topic in topics:
                _append_message(recording, channels, record, path)
    return count


def read_camera_frames(path: str | PathLike[str]) -> dict[str, list[CameraFrame]]:
    """Reads the camera frames of a recording, recovering what it can from a cut-off file.

    Read front to back as ``read_recording`` reads, each message decoded by ``mcap_protobuf``
    from the Foxglove schema the file holds; a frame is an image and the annotations logged at
    its time. A frame whose annotations were cut off is left out, and a cut file gives a
    ``TruncatedRecordingWarning`` naming the file and the number of frames recovered.

    Args:
        path: The MCAP file.

    Returns:
        Camera name -> its frames in file (time) order; a camera whose topics were registered but
        hold no frame maps to an empty list. Each frame's ``rgb`` is the decoded JPEG, so within
        JPEG error of the image written; its boxes, measurement and time are those written (the
        time to the nanosecond).

    Raises:
        MissingFileError: If the file does not exist.
        RecordError: If the file is not MCAP (bad magic), or a camera topic's message cannot be
            decoded (the message names the file and the topic).
    """
    path = Path(path)
    records = _RecordStream(_read_mcap_bytes(path))
    reader = _FrameReader(path)
    for record in records:
        reader.read(record)
    if records.error is not None:
        count = sum(len(camera_frames) for camera_frames in reader.frames.values())
        _warn_truncated(path, records.error, f"{count} complete camera frames")
    return reader.frames


class _FrameReader:
    """Decodes a recording's camera messages, record by record, into ``frames``."""

    def __init__(self, path: Path):
        # Imported here: protobuf decoding is needed only where frames are read back.
        from mcap_protobuf.decoder import DecoderFactory

        self.frames: dict[str, list[CameraFrame]] = {}
        self._path = path
        self._decoders = DecoderFactory()
        self._schemas: dict[int, McapSchema] = {}
        # Channel id -> (topic, camera, whether it carries images, decoder).
        self._channels: dict[int, tuple[str, str, bool, Any]] = {}
        # Camera -> its last image (log time, message), until its annotations come.
        self._images: dict[str, tuple[int, Any]] = {}

    def read(self, record) -> None:
        """Takes in the file's next record."""
        if isinstance(record, McapSchema):
            self._schemas[record.id] = record
        elif isinstance(record, McapChannel):
            self._add_channel(record)
        elif isinstance(record, McapMessage) and record.channel_id in self._channels:
            self._add_message(record)

    def _add_channel(self, channel: McapChannel) -> None:
        camera = camera_of_topic(channel.topic)
        if camera is None:
            return
        carries_images = channel.topic == image_topic(camera)
        expected = (CompressedImage if carries_images else ImageAnnotations).get_schema().name
        schema = self._schemas.get(channel.schema_id)
        if (
            channel.message_encoding != CAMERA_MESSAGE_ENCODING
            or schema is None
            or (schema.name != expected)
        ):
            raise RecordError(
                f"{self._path}: topic {channel.topic!r} carries "
                f"{channel.message_encoding!r} {schema.name if schema else 'schemaless'!r} "
                f"messages, expected {CAMERA_MESSAGE_ENCODING!r} {expected!r}"
            )
        decoder = self._decoders.decoder_for(channel.message_encoding, schema)
        self._channels[channel.id] = (channel.topic, camera, carries_images, decoder)
        self.frames.setdefault(camera, [])

    def _add_message(self, message: McapMessage) -> None:
        topic, camera, carries_images, decode = self._channels[message.channel_id]
        try:
            decoded = decode(message.data)
        except DecodeError as error:
            raise RecordError(
                f"{self._path}: topic {topic!r}: undecodable message ({error})"
            ) from None
        if carries_images:
            self._images[camera] = (message.log_time, decoded)
            return
        image = self._images.pop(camera, None)
        if image is None or image[0] != message.log_time:
            return  # annotations whose image is not in the file: no frame
        try:
            self.frames[camera].append(frame_from_messages(camera, image[1], decoded))
        except ValueError as error:
            raise RecordError(f"{self._path}: topic {topic!r}: {error}") from None


@dataclass(frozen=True)
class _ReadChannel:
    """How the reader presents one channel: current topic name, message encoding, field names.

    The field names map each version-1 name to its current name; empty when nothing was renamed.
    """

    topic: str
    message_encoding: str
    renames: Mapping[str, str]


def _read_channel(channel: McapChannel, schema: McapSchema | None, path: Path) -> _ReadChannel:
    """Presents a channel under the current names, given the schema its file declared for it.

    Raises:
        RecordError: If the schema carries a format version this reader does not know.
    """
    version = _format_version(schema)
    if version == 1:
        topic, renames = _v1_renames(channel.topic)
    elif version is None or version == SCHEMA_VERSION:
        topic, renames = channel.topic, {}
    else:
        raise RecordError(
            f"{path}: topic {channel.topic!r} has schema {schema.name!r}, format version "
            f"{version}; this maskless reads versions 1 to {SCHEMA_VERSION}"
        )
    return _ReadChannel(topic, channel.message_encoding, renames)


def _format_version(schema: McapSchema | None) -> int | None:
    """The format version a schema's name carries (1 without ".vN").

    None for no schema or one that is not maskless's, whose messages are read as they are.
    """
    match = None if schema is None else _SCHEMA_NAME.fullmatch(schema.name)
    if match is None:
        return None
    return 1 if match[1] is None else int(match[1])


def _append_message(
    recording: Recording,
    channels: Mapping[int, _ReadChannel],
    message: McapMessage,
    path: Path,
) -> None:
    """Decodes one message and appends it to its topic's list, under the current field names."""
    channel = channels.get(message.channel_id)
    if channel is None:
        raise RecordError(f"{path}: message refers to unknown channel id {message.channel_id}")
    if channel.message_encoding != MESSAGE_ENCODING:
        raise RecordError(
            f"{path}: topic {channel.topic!r} has message encoding "
            f"{channel.message_encoding!r}, expected {MESSAGE_ENCODING!r}"
        )
    payload = json.loads(message.data)
    if channel.renames:
        payload = {channel.renames.get(name, name): value for name, value in payload.items()}
    recording.messages[channel.topic].append((message.log_time, payload))
