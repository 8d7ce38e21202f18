"""A recording's messages before they reach the file: channels and frames, validated and encoded.

Pure: arrays and frames in, every message's bytes out, merged in log-time order (a ``_Batch``);
``maskless.recording.writing`` puts the batches in the file.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from foxglove.messages import CompressedImage, ImageAnnotations

from maskless.camera_images import (
    CameraFrame,
    annotations_message,
    annotations_topic,
    image_message,
    image_topic,
)
from maskless.recording.format import _BOOLEAN, _STRING, schema_for_topic


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
        if kind == _STRING:
            strings = values.tolist()
            if not all(isinstance(value, str) for value in strings):
                raise ValueError(f"topic {topic!r}: column {name!r} must hold strings")
            lists.append(strings)
            continue
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
        if kind not in (_BOOLEAN, _STRING)
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
        elif kind == _STRING:
            parts.append(f'"{name}":%s')
            flat_columns.append([json.dumps(value) for value in column])
        elif kind == _BOOLEAN:
            parts.append(f'"{name}":%s')
            flat_columns.append(["true" if value else "false" for value in column])
        else:
            parts.append(f'"{name}":%r')
            flat_columns.append(column)
    template = "{" + ",".join(parts) + "}"
    return [(template % row).encode() for row in zip(*flat_columns, strict=True)]


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
