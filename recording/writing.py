"""Writing a recording: at once (``write_recording``) or batch by batch while a run goes on."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from os import PathLike
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, IndexType, Writer

from maskless.camera_images import CameraFrame
from maskless.recording.encoding import Channel, _Batch, _camera_topics, _checked_frames
from maskless.recording.format import (
    CAMERA_MESSAGE_ENCODING,
    CUT_METADATA,
    LIBRARY,
    MESSAGE_ENCODING,
    PROFILE,
    SCHEMA_ENCODING,
    schema_for_topic,
)


def write_recording(
    path: str | PathLike[str],
    channels: Sequence[Channel],
    frames: Sequence[CameraFrame] = (),
    metadata: Mapping[str, Mapping[str, str]] | None = None,
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
        metadata: Metadata records the file opens with, name -> {key: value} (strings), as
            ``RecordingWriter`` writes them; none when None.

    Raises:
        ValueError: If a topic is unknown or repeated, a column has the wrong length or shape, the
            field names are not exactly the schema's required fields, the times are not
            non-decreasing integers (ns), or a camera's frames go back in time. The message names
            the topic and field, or the camera; or a metadata record is not strings.
    """
    cameras = list(dict.fromkeys(frame.camera for frame in _checked_frames(frames)))
    batch = _Batch.of(channels, frames, cameras)
    topics = [channel.topic for channel in channels]
    with RecordingWriter(path, topics, cameras, metadata) as writer:
        writer._write_batch(batch)


class RecordingWriter:
    """A recording written in batches, for a run that is still going.

    Each batch holds the next samples of every topic (and the next frames of the cameras), later
    than every message before it.

    Use it as a context manager. Leaving the block normally writes the footer; leaving it on an
    error closes the file without one, so ``read_recording`` reads what was written and reports
    the recording as cut off. A run that ends early but can still finish its file calls
    ``mark_cut`` first: the file is whole (any MCAP reader reads it) and says it was cut. Messages
    are identical to ``write_recording``'s for the same samples and frames in one batch (given the
    cameras in the order of their first frames).
    """

    def __init__(
        self,
        path: str | PathLike[str],
        topics: Sequence[str],
        cameras: Sequence[str] = (),
        metadata: Mapping[str, Mapping[str, str]] | None = None,
    ):
        """Opens ``path`` (overwritten): ``metadata``, then ``topics`` in order, then ``cameras``.

        Args:
            path: Output file; overwritten if it exists.
            topics: The JSON topics every batch carries a channel for, in this order.
            cameras: The cameras whose frames the batches may carry; each gets an image and an
                annotations topic (``maskless.camera_images``).
            metadata: Metadata records, name -> {key: value} (strings), written first so that a
                file cut anywhere after them still says them (``read_leading_metadata``).

        Raises:
            ValueError: If a topic is unknown or repeated, a camera name is invalid or repeated,
                or a metadata record is not strings or is named ``maskless.cut`` (before the
                file is opened).
        """
        metadata = _checked_metadata(metadata or {})
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
        for name, values in metadata.items():
            self._writer.add_metadata(name, values)
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

    def mark_cut(self, reason: str) -> None:
        """Records that the run ended early, for ``reason``, after the messages written so far.

        ``read_recording`` reports such a file as truncated, like one cut before its footer.
        """
        last = "none" if self._last_time_ns is None else str(self._last_time_ns)
        self._writer.add_metadata(CUT_METADATA, {"reason": reason, "last_log_time_ns": last})

    def __enter__(self) -> RecordingWriter:
        """Returns the writer itself."""
        return self

    def __exit__(self, error_type, error, traceback) -> None:
        """Writes the footer unless the block raised, then closes the file."""
        try:
            if error_type is None:
                self._writer.finish()
        finally:
            self._stream.close()


def _checked_metadata(metadata: Mapping[str, Mapping[str, str]]) -> dict[str, dict[str, str]]:
    """``metadata`` as plain dicts, refused by name where MCAP cannot hold it or it would lie."""
    checked = {}
    for name, values in metadata.items():
        if name == CUT_METADATA:
            raise ValueError(f"metadata {name!r}: only a run cut short is marked so (mark_cut)")
        if not (
            isinstance(name, str)
            and isinstance(values, Mapping)
            and all(
                isinstance(key, str) and isinstance(value, str) for key, value in values.items()
            )
        ):
            raise ValueError(f"metadata {name!r}: expected a name and keys and values of text")
        checked[name] = dict(values)
    return checked


def write_recording_batches(
    connection, path: str | PathLike[str], cameras: Sequence[str] = ()
) -> None:
    """Writes the batches ``connection.recv()`` returns to ``path``, until None.

    A ``background.Worker``'s serve function (``Worker(..., write_recording_batches, path,
    cameras)``). A batch is a list of channels, as for ``RecordingWriter.write``, or a pair
    ``(channels, frames)`` when it carries frames of ``cameras``; the first batch's channels name
    the topics. If the sender goes away or stops first (EOFError), the batches received are
    finished as a whole file marked as cut (``RecordingWriter.mark_cut``); before the first one,
    no file is written.
    """
    batch = connection.recv()
    channels, _ = _channels_and_frames(batch)
    with RecordingWriter(path, [channel.topic for channel in channels], cameras) as writer:
        while batch is not None:
            writer.write(*_channels_and_frames(batch))
            try:
                batch = connection.recv()
            except EOFError:
                writer.mark_cut("the run ended before its last batch")
                return


def _channels_and_frames(batch) -> tuple[Sequence[Channel], Sequence[CameraFrame]]:
    """A batch sent to ``write_recording_batches`` as its channels and frames."""
    # A tuple is a (channels, frames) pair; a batch of channels alone comes as a list.
    return batch if isinstance(batch, tuple) else (batch, ())
