"""Reading a recording back, up to its last complete message: the JSON messages, camera frames."""

from __future__ import annotations

import io
import json
import struct
import warnings
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
from foxglove.messages import CompressedImage, ImageAnnotations
from google.protobuf.message import DecodeError
from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel as McapChannel
from mcap.records import Header as McapHeader
from mcap.records import Message as McapMessage
from mcap.records import Metadata as McapMetadata
from mcap.records import Schema as McapSchema
from mcap.stream_reader import StreamReader

from maskless.camera_images import CameraFrame, camera_of_topic, frame_from_messages, image_topic
from maskless.errors import MissingFileError, RecordError, TruncatedRecordingWarning
from maskless.recording.format import (
    _BOOLEAN,
    _SCHEMA_NAME,
    _STRING,
    CAMERA_MESSAGE_ENCODING,
    CUT_METADATA,
    MESSAGE_ENCODING,
    SCHEMA_VERSION,
    _v1_renames,
    schema_for_topic,
)

# The MCAP magic that opens (and closes) every file.
_MAGIC = b"\x89MCAP0\r\n"


@dataclass
class Recording:
    """The messages read back from a recording.

    Attributes:
        messages: Topic -> list of ``(log_time_ns, payload)`` in file order. Topics that were
            recorded without messages map to an empty list.
        truncated: True if the file ended (or broke) before its footer, so only the messages up
            to the last complete one are present, or if its run was cut short and the file
            finished with what it had (a ``*.partial.mcap`` a stopped run left).
        cut: when truncated, the sentence its ``TruncatedRecordingWarning`` said (the file, why
            and how many messages were recovered), for a report to repeat; else None.
    """

    messages: dict[str, list[tuple[int, dict[str, Any]]]] = field(default_factory=dict)
    truncated: bool = False
    cut: str | None = None

    def topic_arrays(self, topic: str, field: str) -> tuple[np.ndarray, np.ndarray]:
        """Returns one field of one topic as arrays.

        Args:
            topic: Topic name.
            field: Field name, e.g. ``"head_height_m"``.

        Returns:
            ``(times_ns, values)``: ``times_ns`` is int64 (ns); ``values`` is float64 for numbers
            (in the field's unit), bool for booleans, str for strings, and ``(n, 2, 2)``
            float64 for ``"covariance"``.

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
    if prop["type"] == _STRING:
        return str, ()
    if prop["type"] == "array":
        return np.float64, (2, 2)
    return np.float64, ()


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


def read_recording(
    path: str | PathLike[str], topics: Collection[str] | None = None, warn_if_cut: bool = True
) -> Recording:
    """Reads a recording, recovering what it can from a cut-off file.

    The file is read front to back with a streaming reader (no index or footer needed). At the
    first error after the magic bytes (a cut, or a corrupt record) reading stops, ``truncated`` is
    set and a ``TruncatedRecordingWarning`` names the file and the number of messages recovered.
    Every message returned is complete. A file whose run was cut short but which was finished
    with its footer (it holds a ``maskless.cut`` Metadata record) reads whole, and is reported
    the same way. A file shorter than the magic whose bytes match it (a
    writer that died at once) reads as an empty, truncated recording. Camera frames (protobuf
    topics) are passed over; ``read_camera_frames`` reads them.

    Args:
        path: The MCAP file.
        topics: Decode only these topics' messages (JSON decoding is most of the reading), named
            as the reader presents them (current names); the others are listed with no messages.
            All of them when None.
        warn_if_cut: warn a cut (``TruncatedRecordingWarning``); without, the caller says
            ``cut`` itself (`maskless identify`, in its report).

    Returns:
        The messages by topic, in file order, with ``log_time`` in simulated ns, under the current
        topic and field names whatever format version wrote them (see the package docstring).

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
    if records.error is not None or recording.truncated:
        recording.truncated = True
        stop = records.error or EndOfFile("its run was cut short")
        recording.cut = _cut_sentence(path, stop, f"{count} complete messages")
        if warn_if_cut:
            _warn_truncated(recording.cut)
    return recording


def read_leading_metadata(path: str | PathLike[str]) -> dict[str, dict[str, str]]:
    """The Metadata records a recording opens with (``RecordingWriter``'s ``metadata``), by name.

    Only the file's first bytes are read, up to its first schema, channel or message: what a
    writer said of the whole run before it began, which a cut-off file still holds. A recording
    written without any (or before they existed) gives an empty dict.

    Raises:
        MissingFileError, RecordError: as ``read_recording``.
    """
    path = Path(path)
    found = {}
    for record in _RecordStream(_read_mcap_bytes(path, _LEADING_BYTES)):
        if isinstance(record, McapHeader):
            continue
        if not isinstance(record, McapMetadata):
            break
        found[record.name] = dict(record.metadata)
    return found


# More than a recording's leading metadata takes: a few short strings.
_LEADING_BYTES = 1 << 16


def _read_mcap_bytes(path: Path, limit: int = -1) -> bytes:
    """The bytes of an MCAP file (its first ``limit`` when not -1), or of a prefix of one.

    Raises:
        MissingFileError: If the file does not exist.
        RecordError: If it cannot be read, or does not start as MCAP does (bad magic).
    """
    try:
        with open(path, "rb") as stream:
            data = stream.read(limit)
    except FileNotFoundError:
        raise MissingFileError(f"MCAP recording not found: {path}") from None
    except OSError as error:  # a folder, or a file that cannot be read
        raise RecordError(f"{path}: cannot read the recording ({error.strerror})") from None
    head = data[: len(_MAGIC)]
    if head != _MAGIC[: len(head)]:
        raise RecordError(f"{path} is not an MCAP file (bad magic bytes {head!r})")
    return data


def _cut_sentence(path: Path, error: Exception, recovered: str) -> str:
    """That ``path`` was read up to a cut: why, and what was recovered."""
    reason = str(error) or "file ends before its footer"
    return f"{path}: recording is truncated or corrupt ({reason}); recovered {recovered}"


def _warn_truncated(sentence: str) -> None:
    # Warn at the caller of the public reader, which calls this function.
    warnings.warn(sentence, TruncatedRecordingWarning, stacklevel=3)


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
        elif isinstance(record, McapMetadata) and record.name == CUT_METADATA:
            recording.truncated = True
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
        _warn_truncated(_cut_sentence(path, records.error, f"{count} complete camera frames"))
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
