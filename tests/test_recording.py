"""Tests for maskless.recording (MCAP write/read of simulation recordings)."""

import hashlib
import json
import struct
import warnings

import numpy as np
import pytest
from camera_frames import (
    boxes_by_role,
    empty_frame,
    face_frame,
    jpeg_pixels,
    mean_abs_difference,
)
from foxglove.messages import CompressedImage, RawImage
from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.reader import make_reader
from mcap.records import Channel as McapChannel
from mcap.records import Message as McapMessage
from mcap.records import Metadata as McapMetadata
from mcap.records import Schema as McapSchema
from mcap.stream_reader import StreamReader
from mcap.writer import Writer
from mcap_protobuf.decoder import DecoderFactory
from version1_recording import write_version1_recording

from maskless.errors import RecordError
from maskless.recording import (
    COMMAND_TOPIC,
    FUSION_TOPIC,
    HEAD_HEIGHT_TOPIC,
    REFERENCE_TOPIC,
    SAFETY_TOPIC,
    Channel,
    RecordingWriter,
    TruncatedRecordingWarning,
    current_name,
    filter_estimate_topic,
    read_camera_frames,
    read_leading_metadata,
    read_recording,
    schema_for_topic,
    sensor_measurement_topic,
    write_recording,
    write_recording_batches,
)

SENSORS = ("kinect_v1", "kinect_v2")
MAGIC = b"\x89MCAP0\r\n"
OPCODE_MESSAGE = 0x05  # MCAP spec: Message record opcode

# The data fields of every topic, written out by hand from the brief (not from the module).
STATE_FIELDS = ("head_height_m", "head_velocity_m_s", "covariance")
EXPECTED_FIELDS = {
    "/reference": ("reference_head_height_m",),
    "/plant/head_height": ("head_height_m",),
    "/sensors/kinect_v1/measurement": ("distance_m", "valid"),
    "/sensors/kinect_v2/measurement": ("distance_m", "valid"),
    "/filters/kinect_v1/estimate": STATE_FIELDS,
    "/filters/kinect_v2/estimate": STATE_FIELDS,
    "/fusion/estimate": STATE_FIELDS,
    "/controller/command": ("inlet_valve_current_a", "outlet_valve_current_a"),
}


def _make_channels(seed=0, scale=1):
    """One channel per topic at different rates (ns), with values that stress float round trip."""
    rng = np.random.default_rng(seed)
    ms = 1_000_000

    def times(n, period_ns, offset_ns=0):
        return offset_ns + np.arange(n, dtype=np.int64) * period_ns

    def floats(*shape):
        # Mixed magnitudes and signs: repr round trip must hold for all of them exactly. The
        # powers of ten are parsed, not computed: the hash below, taken with numpy's vectorised
        # pow on another machine, did not reproduce here, and parsing is exact on every machine.
        exponents = rng.integers(-12, 6, size=shape)
        powers = np.vectorize(lambda k: float(f"1e{k}"))(exponents) if exponents.size else 1.0
        return rng.normal(size=shape) * powers

    n_fast, n_cam = 40 * scale, 12 * scale
    channels = [
        Channel(
            REFERENCE_TOPIC, times(n_fast, 10 * ms), {"reference_head_height_m": floats(n_fast)}
        ),
        Channel(HEAD_HEIGHT_TOPIC, times(n_fast, 10 * ms), {"head_height_m": floats(n_fast)}),
    ]
    for k, name in enumerate(SENSORS):
        # kinect_v1 at ~30 Hz, kinect_v2 at ~30 Hz with an offset so log times interleave.
        t = times(n_cam, 33 * ms, offset_ns=k * 5 * ms)
        channels.append(
            Channel(
                sensor_measurement_topic(name),
                t,
                {"distance_m": floats(n_cam), "valid": rng.random(n_cam) > 0.2},
            )
        )
        channels.append(
            Channel(
                filter_estimate_topic(name),
                t,
                {
                    "head_height_m": floats(n_cam),
                    "head_velocity_m_s": floats(n_cam),
                    "covariance": floats(n_cam, 2, 2),
                },
            )
        )
    channels.append(
        Channel(
            FUSION_TOPIC,
            times(n_fast, 10 * ms),
            {
                "head_height_m": floats(n_fast),
                "head_velocity_m_s": floats(n_fast),
                "covariance": floats(n_fast, 2, 2),
            },
        )
    )
    channels.append(
        Channel(
            COMMAND_TOPIC,
            times(n_fast, 10 * ms),
            {"inlet_valve_current_a": floats(n_fast), "outlet_valve_current_a": floats(n_fast)},
        )
    )
    return channels


def _upstream_messages(path, log_time_order=False):
    """(schema, channel, message) tuples from the plain upstream reader, in file order."""
    with open(path, "rb") as f:
        return list(make_reader(f).iter_messages(log_time_order=log_time_order))


def _message_record_ends(data):
    """Byte offsets at which each Message record ends, from the MCAP framing (opcode, u64 len)."""
    ends = []
    offset = len(MAGIC)
    while offset + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, offset)
        offset += 9 + length
        if opcode == OPCODE_MESSAGE:
            ends.append(offset)
        if opcode == 0x02:  # Footer: the magic follows
            break
    return ends


def test_topic_helpers_and_schemas():
    assert sensor_measurement_topic("kinect_v1") == "/sensors/kinect_v1/measurement"
    assert filter_estimate_topic("zed_2") == "/filters/zed_2/estimate"
    assert set(EXPECTED_FIELDS) == {
        REFERENCE_TOPIC,
        HEAD_HEIGHT_TOPIC,
        FUSION_TOPIC,
        COMMAND_TOPIC,
        *(sensor_measurement_topic(s) for s in SENSORS),
        *(filter_estimate_topic(s) for s in SENSORS),
    }
    for topic, fields in EXPECTED_FIELDS.items():
        name, schema = schema_for_topic(topic)
        assert name.startswith("maskless.")
        assert schema["type"] == "object"
        assert schema["additionalProperties"] is False
        assert tuple(schema["required"]) == fields
        assert set(schema["properties"]) == set(fields)
        assert schema["description"]
    assert schema_for_topic("/sensors/new_cam/measurement")[0] == "maskless.DepthMeasurement.v2"
    assert schema_for_topic("/filters/new_cam/estimate")[0] == "maskless.StateEstimate.v2"
    with pytest.raises(ValueError, match="/no/such/topic"):
        schema_for_topic("/no/such/topic")
    with pytest.raises(ValueError, match="sensor name"):
        sensor_measurement_topic("a/b")


def test_round_trip_all_topics(tmp_path):
    channels = _make_channels()
    path = tmp_path / "run.mcap"
    write_recording(path, channels)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a complete file must not warn
        rec = read_recording(str(path))
    assert rec.truncated is False
    assert set(rec.messages) == set(EXPECTED_FIELDS)
    for ch in channels:
        assert len(rec.messages[ch.topic]) == len(ch.times_ns)
        for field, column in ch.columns.items():
            times_ns, values = rec.topic_arrays(ch.topic, field)
            assert times_ns.dtype == np.int64
            np.testing.assert_array_equal(times_ns, ch.times_ns)
            # Exact equality: JSON float repr must round-trip bit-for-bit.
            assert values.shape == column.shape
            assert values.dtype == column.dtype
            assert np.array_equal(values, column)
        # The raw payloads hold Python floats/bools, not strings or ints.
        _, payload = rec.messages[ch.topic][0]
        assert set(payload) == set(EXPECTED_FIELDS[ch.topic])


def test_upstream_reader_sees_encodings_topics_and_payloads(tmp_path):
    channels = _make_channels()
    path = tmp_path / "run.mcap"
    write_recording(path, channels)
    with open(path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        assert header.library == "maskless"
        assert header.profile == ""
    seen = {}
    for schema, channel, message in _upstream_messages(path):
        assert schema is not None
        assert schema.encoding == "jsonschema"
        assert channel.message_encoding == "json"
        assert message.publish_time == message.log_time
        assert json.loads(schema.data)["required"] == list(EXPECTED_FIELDS[channel.topic])
        seen.setdefault(channel.topic, []).append((message.log_time, json.loads(message.data)))
    assert set(seen) == set(EXPECTED_FIELDS)
    for ch in channels:
        got = seen[ch.topic]
        assert [t for t, _ in got] == ch.times_ns.tolist()
        for field, column in ch.columns.items():
            assert [p[field] for _, p in got] == column.tolist()


def test_schemas_written_once_and_messages_in_time_order(tmp_path):
    channels = _make_channels()
    path = tmp_path / "run.mcap"
    write_recording(path, channels)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    # Five kinds for eight topics: shared schemas are not duplicated.
    assert sorted(s.name for s in summary.schemas.values()) == [
        "maskless.DepthMeasurement.v2",
        "maskless.HeadHeight.v2",
        "maskless.Reference.v2",
        "maskless.StateEstimate.v2",
        "maskless.ValveCommand.v2",
    ]
    file_order = [m.log_time for _, _, m in _upstream_messages(path)]
    assert len(file_order) == sum(len(ch.times_ns) for ch in channels)
    assert all(a <= b for a, b in zip(file_order, file_order[1:], strict=False))


def test_ties_keep_channel_order(tmp_path):
    t = np.array([0, 5, 5, 9], dtype=np.int64)
    channels = [
        Channel(
            COMMAND_TOPIC,
            t,
            {
                "inlet_valve_current_a": np.array([1.0, 2.0, 3.0, 4.0]),
                "outlet_valve_current_a": np.zeros(4),
            },
        ),
        Channel(REFERENCE_TOPIC, t, {"reference_head_height_m": np.array([0.1, 0.2, 0.3, 0.4])}),
    ]
    path = tmp_path / "ties.mcap"
    write_recording(path, channels)
    got = [(m.log_time, c.topic, json.loads(m.data)) for _, c, m in _upstream_messages(path)]
    cmd, ref = COMMAND_TOPIC, REFERENCE_TOPIC
    assert got == [
        (0, cmd, {"inlet_valve_current_a": 1.0, "outlet_valve_current_a": 0.0}),
        (0, ref, {"reference_head_height_m": 0.1}),
        (5, cmd, {"inlet_valve_current_a": 2.0, "outlet_valve_current_a": 0.0}),
        (5, cmd, {"inlet_valve_current_a": 3.0, "outlet_valve_current_a": 0.0}),
        (5, ref, {"reference_head_height_m": 0.2}),
        (5, ref, {"reference_head_height_m": 0.3}),
        (9, cmd, {"inlet_valve_current_a": 4.0, "outlet_valve_current_a": 0.0}),
        (9, ref, {"reference_head_height_m": 0.4}),
    ]


def test_identical_inputs_give_identical_bytes(tmp_path):
    a, b, c = tmp_path / "a.mcap", tmp_path / "b.mcap", tmp_path / "c.mcap"
    write_recording(a, _make_channels(seed=3))
    write_recording(b, _make_channels(seed=3))
    # Column dict order must not matter either: payload keys follow the schema.
    reordered = [
        Channel(ch.topic, ch.times_ns, dict(reversed(list(ch.columns.items()))))
        for ch in _make_channels(seed=3)
    ]
    write_recording(c, reordered)
    assert a.read_bytes() == b.read_bytes() == c.read_bytes()
    assert a.read_bytes() != _write_bytes(tmp_path / "d.mcap", _make_channels(seed=4))


def _write_bytes(path, channels):
    write_recording(path, channels)
    return path.read_bytes()


def test_truncated_file_reads_exact_prefix(tmp_path):
    full_path = tmp_path / "full.mcap"
    write_recording(full_path, _make_channels())
    data = full_path.read_bytes()
    # Independent reference: the global message list from the upstream reader, in file order.
    full = [(c.topic, m.log_time, json.loads(m.data)) for _, c, m in _upstream_messages(full_path)]
    ends = _message_record_ends(data)
    assert len(ends) == len(full)

    cuts = [
        len(data) // 2,
        int(len(data) * 0.8),
        len(data) - 10,  # inside the footer: every message is intact
        ends[10],  # exactly at a record boundary, as when the writer process dies
        ends[10] - 1,  # one byte short of a complete message
        len(MAGIC) + 3,  # inside the header record
    ]
    for cut in cuts:
        cut_path = tmp_path / f"cut_{cut}.mcap"
        cut_path.write_bytes(data[:cut])
        n_complete = sum(1 for end in ends if end <= cut)
        with pytest.warns(TruncatedRecordingWarning, match=rf"cut_{cut}\.mcap.* {n_complete} "):
            rec = read_recording(cut_path)
        assert rec.truncated is True
        expected = {}
        for topic, log_time, payload in full[:n_complete]:
            expected.setdefault(topic, []).append((log_time, payload))
        got = {topic: msgs for topic, msgs in rec.messages.items() if msgs}
        assert got == expected, f"cut at byte {cut}"


SPLIT = {"maskless.fit_split": {"estimation": "0:0.8", "validation": "0.8:1"}}


def test_leading_metadata_opens_the_file_and_survives_any_cut_after_it(tmp_path):
    path = tmp_path / "split.mcap"
    write_recording(path, _make_channels(), metadata=SPLIT)
    data = path.read_bytes()
    # Independent reference: the upstream streaming reader meets it before any channel.
    with open(path, "rb") as stream:
        records = list(StreamReader(stream).records)
    first_channel = next(i for i, r in enumerate(records) if isinstance(r, McapChannel))
    (metadata,) = [(i, r) for i, r in enumerate(records) if isinstance(r, McapMetadata)]
    assert metadata[0] < first_channel
    assert {metadata[1].name: metadata[1].metadata} == SPLIT
    assert read_leading_metadata(path) == SPLIT
    # The messages are those of a file without it.
    plain = tmp_path / "plain.mcap"
    write_recording(plain, _make_channels())
    assert read_recording(path).messages == read_recording(plain).messages
    assert read_leading_metadata(plain) == {}
    ends = _message_record_ends(data)
    for cut in (ends[0], ends[0] - 1, len(data) // 3):
        cut_path = tmp_path / f"cut_{cut}.mcap"
        cut_path.write_bytes(data[:cut])
        assert read_leading_metadata(cut_path) == SPLIT, f"cut at byte {cut}"
    cut_path.write_bytes(data[: len(MAGIC) + 3])  # inside the header: nothing said yet
    assert read_leading_metadata(cut_path) == {}


@pytest.mark.parametrize(
    "metadata, message",
    [
        ({"maskless.cut": {"reason": "x"}}, "only a run cut short"),
        (
            {"maskless.fit_split": {"estimation": 0.8}},
            "expected a name and keys and values of text",
        ),
        ({"maskless.fit_split": "0:0.8"}, "expected a name and keys and values of text"),
    ],
)
def test_metadata_mcap_cannot_hold_or_that_would_lie_is_refused_before_the_file(
    tmp_path, metadata, message
):
    path = tmp_path / "refused.mcap"
    with pytest.raises(ValueError, match=message):
        write_recording(path, _make_channels(), metadata=metadata)
    assert not path.exists()


def test_file_cut_inside_magic_is_empty_and_truncated(tmp_path):
    path = tmp_path / "tiny.mcap"
    path.write_bytes(MAGIC[:5])
    with pytest.warns(TruncatedRecordingWarning, match="tiny.mcap"):
        rec = read_recording(path)
    assert rec.truncated is True
    assert rec.messages == {}


def test_wrong_column_length_raises_naming_topic(tmp_path):
    channels = _make_channels()
    bad = Channel(
        REFERENCE_TOPIC, np.arange(5, dtype=np.int64), {"reference_head_height_m": np.zeros(4)}
    )
    path = tmp_path / "bad.mcap"
    with pytest.raises(ValueError, match=r"/reference.*reference_head_height_m"):
        write_recording(path, [*channels[1:], bad])
    assert not path.exists()  # validated before anything is written


def test_wrong_covariance_shape_raises(tmp_path):
    t = np.arange(3, dtype=np.int64)
    bad = Channel(
        FUSION_TOPIC,
        t,
        {
            "head_height_m": np.zeros(3),
            "head_velocity_m_s": np.zeros(3),
            "covariance": np.zeros((3, 4)),
        },
    )
    with pytest.raises(ValueError, match=r"/fusion/estimate.*covariance"):
        write_recording(tmp_path / "bad.mcap", [bad])


def test_unknown_and_missing_fields_raise(tmp_path):
    t = np.arange(3, dtype=np.int64)
    topic = sensor_measurement_topic("kinect_v2")
    extra = Channel(topic, t, {"distance_m": np.zeros(3), "valid": np.ones(3, bool), "rgb": t})
    with pytest.raises(ValueError, match=r"/sensors/kinect_v2/measurement.*rgb"):
        write_recording(tmp_path / "bad.mcap", [extra])
    missing = Channel(topic, t, {"distance_m": np.zeros(3)})
    with pytest.raises(ValueError, match=r"/sensors/kinect_v2/measurement.*valid"):
        write_recording(tmp_path / "bad.mcap", [missing])
    with pytest.raises(ValueError, match="/unknown/topic"):
        write_recording(tmp_path / "bad.mcap", [Channel("/unknown/topic", t, {})])
    assert not (tmp_path / "bad.mcap").exists()


def test_decreasing_times_and_duplicate_topics_raise(tmp_path):
    back = Channel(
        COMMAND_TOPIC,
        np.array([0, 2, 1], dtype=np.int64),
        {"inlet_valve_current_a": np.zeros(3), "outlet_valve_current_a": np.zeros(3)},
    )
    with pytest.raises(ValueError, match=r"/controller/command.*non-decreasing"):
        write_recording(tmp_path / "bad.mcap", [back])
    ok = Channel(
        COMMAND_TOPIC,
        np.array([0, 1], dtype=np.int64),
        {"inlet_valve_current_a": np.zeros(2), "outlet_valve_current_a": np.zeros(2)},
    )
    with pytest.raises(ValueError, match=r"/controller/command.*more than once"):
        write_recording(tmp_path / "bad.mcap", [ok, ok])


def test_bad_magic_raises(tmp_path):
    path = tmp_path / "notes.mcap"
    path.write_bytes(b"this is plainly not an MCAP file\n")
    with pytest.raises(ValueError, match=r"notes\.mcap.*not an MCAP file"):
        read_recording(path)


def test_missing_file_raises(tmp_path):
    path = tmp_path / "absent.mcap"
    with pytest.raises(FileNotFoundError, match="absent.mcap"):
        read_recording(path)


def test_non_json_message_encoding_raises(tmp_path):
    path = tmp_path / "cbor.mcap"
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start()
        channel_id = writer.register_channel(COMMAND_TOPIC, "cbor", schema_id=0)
        writer.add_message(channel_id, log_time=1, data=b"\xa0", publish_time=1)
        writer.finish()
    with pytest.raises(ValueError, match=r"/controller/command.*cbor"):
        read_recording(path)


@pytest.mark.parametrize("with_nan", [False, True], ids=["finite", "nan"])
def test_payload_bytes_are_compact_json_dumps(tmp_path, with_nan):
    # The writer's fast path must produce exactly json.dumps(payload, separators=(",", ":")).
    channels = _make_channels(seed=5)
    edge = np.array([0.1, -0.0, 1e16, 5e-324, 1.7976931348623157e308, np.nan if with_nan else 2.5])
    channels[0] = Channel(
        REFERENCE_TOPIC, np.arange(edge.size, dtype=np.int64), {"reference_head_height_m": edge}
    )
    path = tmp_path / "edge.mcap"
    write_recording(path, channels)
    with open(path, "rb") as stream:
        for _, _, message in make_reader(stream).iter_messages():
            payload = json.loads(message.data)
            assert message.data == json.dumps(payload, separators=(",", ":")).encode()


def _split_at(channels, cut_ns):
    """Two batches of the same channels: samples before ``cut_ns``, then the rest."""
    batches = ([], [])
    for channel in channels:
        early = channel.times_ns < cut_ns
        for batch, keep in zip(batches, (early, ~early), strict=True):
            columns = {name: np.asarray(values)[keep] for name, values in channel.columns.items()}
            batch.append(Channel(channel.topic, channel.times_ns[keep], columns))
    return batches


def test_batches_give_the_bytes_of_one_write(tmp_path):
    channels = _make_channels(seed=3, scale=3)
    whole, batched = tmp_path / "whole.mcap", tmp_path / "batched.mcap"
    write_recording(whole, channels)
    with RecordingWriter(batched, [c.topic for c in channels]) as writer:
        for batch in _split_at(channels, 200_000_000):
            writer.write(batch)
    assert batched.read_bytes() == whole.read_bytes()


def test_a_batch_earlier_than_the_last_or_with_other_topics_is_refused(tmp_path):
    channels = _make_channels(seed=4)
    early, late = _split_at(channels, 200_000_000)
    with RecordingWriter(tmp_path / "r.mcap", [c.topic for c in channels]) as writer:
        writer.write(late)
        with pytest.raises(ValueError, match="before the last message written"):
            writer.write(early)
        with pytest.raises(ValueError, match="batch topics"):
            writer.write(late[1:])


def test_a_writer_left_on_an_error_leaves_a_cut_off_but_readable_file(tmp_path):
    channels = _make_channels(seed=5)
    first, _ = _split_at(channels, 200_000_000)
    path = tmp_path / "r.mcap"
    with pytest.raises(RuntimeError, match="simulation failed"):
        with RecordingWriter(path, [c.topic for c in channels]) as writer:
            writer.write(first)
            raise RuntimeError("simulation failed")
    with pytest.warns(TruncatedRecordingWarning):
        recording = read_recording(path)
    assert recording.truncated
    assert sum(len(m) for m in recording.messages.values()) == sum(c.times_ns.size for c in first)


def test_reading_some_topics_decodes_only_those(tmp_path):
    channels = _make_channels(seed=6)
    path = tmp_path / "r.mcap"
    write_recording(path, channels)
    whole = read_recording(path)
    some = read_recording(path, topics={FUSION_TOPIC, COMMAND_TOPIC})
    assert set(some.messages) == set(whole.messages)  # every topic is still listed
    for topic, messages in some.messages.items():
        expected = whole.messages[topic] if topic in (FUSION_TOPIC, COMMAND_TOPIC) else []
        assert messages == expected


# A version-1 file (the old names, written by the test's own writer) and what it reads as: the
# current names, both written out by hand.
_P = [[1e-6, 2e-7], [2e-7, 4e-4]]
VERSION_1_MESSAGES = [
    ("/reference", 0, {"reference_m": 0.7}),
    ("/plant/head_position", 0, {"head_position_m": 0.69}),
    ("/sensors/kinect_v1/measurement", 0, {"distance_m": 0.51, "valid": True}),
    (
        "/filters/kinect_v1/estimate",
        0,
        {"position_m": 0.68, "velocity_m_s": -0.01, "covariance": _P},
    ),
    ("/fusion/estimate", 0, {"position_m": 0.685, "velocity_m_s": -0.02, "covariance": _P}),
    ("/controller/command", 0, {"current_a": 0.12, "outlet_current_a": 0.0}),
    ("/reference", 5, {"reference_m": 0.75}),
    ("/plant/head_position", 5, {"head_position_m": 0.7}),
    ("/sensors/kinect_v1/measurement", 5, {"distance_m": 0.0, "valid": False}),
    (
        "/filters/kinect_v1/estimate",
        5,
        {"position_m": 0.69, "velocity_m_s": 0.03, "covariance": _P},
    ),
    ("/fusion/estimate", 5, {"position_m": 0.695, "velocity_m_s": 0.04, "covariance": _P}),
    ("/controller/command", 5, {"current_a": 0.13, "outlet_current_a": 0.02}),
]
VERSION_1_AS_CURRENT = {
    "/reference": [(0, {"reference_head_height_m": 0.7}), (5, {"reference_head_height_m": 0.75})],
    "/plant/head_height": [(0, {"head_height_m": 0.69}), (5, {"head_height_m": 0.7})],
    "/sensors/kinect_v1/measurement": [
        (0, {"distance_m": 0.51, "valid": True}),
        (5, {"distance_m": 0.0, "valid": False}),
    ],
    "/filters/kinect_v1/estimate": [
        (0, {"head_height_m": 0.68, "head_velocity_m_s": -0.01, "covariance": _P}),
        (5, {"head_height_m": 0.69, "head_velocity_m_s": 0.03, "covariance": _P}),
    ],
    "/fusion/estimate": [
        (0, {"head_height_m": 0.685, "head_velocity_m_s": -0.02, "covariance": _P}),
        (5, {"head_height_m": 0.695, "head_velocity_m_s": 0.04, "covariance": _P}),
    ],
    "/controller/command": [
        (0, {"inlet_valve_current_a": 0.12, "outlet_valve_current_a": 0.0}),
        (5, {"inlet_valve_current_a": 0.13, "outlet_valve_current_a": 0.02}),
    ],
}


def test_a_version_1_file_reads_under_the_current_names(tmp_path):
    path = tmp_path / "v1.mcap"
    write_version1_recording(path, VERSION_1_MESSAGES)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        recording = read_recording(path)
    assert recording.messages == VERSION_1_AS_CURRENT
    # Payload keys come in the order they were written, renamed.
    assert list(recording.messages[FUSION_TOPIC][0][1]) == list(STATE_FIELDS)
    times, height = recording.topic_arrays(HEAD_HEIGHT_TOPIC, "head_height_m")
    np.testing.assert_array_equal(times, [0, 5])
    np.testing.assert_array_equal(height, [0.69, 0.7])
    _, covariance = recording.topic_arrays(FUSION_TOPIC, "covariance")
    assert covariance.shape == (2, 2, 2)
    # Topics to decode are named as the reader presents them.
    some = read_recording(path, topics={HEAD_HEIGHT_TOPIC})
    assert some.messages[HEAD_HEIGHT_TOPIC] == VERSION_1_AS_CURRENT[HEAD_HEIGHT_TOPIC]
    assert some.messages[COMMAND_TOPIC] == []


def test_a_cut_off_version_1_file_reads_up_to_the_cut_under_the_current_names(tmp_path):
    full = tmp_path / "v1.mcap"
    write_version1_recording(full, VERSION_1_MESSAGES)
    data = full.read_bytes()
    cut = tmp_path / "v1_cut.mcap"
    cut.write_bytes(data[: _message_record_ends(data)[-1] - 1])
    with pytest.warns(TruncatedRecordingWarning, match=r"v1_cut\.mcap.* 11 "):
        recording = read_recording(cut)
    expected = {topic: list(messages) for topic, messages in VERSION_1_AS_CURRENT.items()}
    expected[COMMAND_TOPIC] = expected[COMMAND_TOPIC][:1]
    assert recording.messages == expected


def test_version_1_names_map_to_the_current_ones():
    assert current_name("/controller/command", "current_a") == (
        COMMAND_TOPIC,
        "inlet_valve_current_a",
    )
    assert current_name("/plant/head_position", "head_position_m") == (
        HEAD_HEIGHT_TOPIC,
        "head_height_m",
    )
    assert current_name("/filters/kinect_v2/estimate", "velocity_m_s") == (
        filter_estimate_topic("kinect_v2"),
        "head_velocity_m_s",
    )
    # Current, unchanged and unknown names come back as they are.
    for name in (
        (FUSION_TOPIC, "head_height_m"),
        (sensor_measurement_topic("kinect_v1"), "valid"),
        ("/no/such/topic", "current_a"),
    ):
        assert current_name(*name) == name


def test_every_schema_carries_the_format_version(tmp_path):
    path = tmp_path / "run.mcap"
    write_recording(path, _make_channels())
    with open(path, "rb") as stream:
        schemas = make_reader(stream).get_summary().schemas.values()
    assert schemas and all(schema.name.endswith(".v2") for schema in schemas)
    assert all(json.loads(schema.data)["title"] == schema.name for schema in schemas)


def _write_with_schema(path, topic, schema_name, payload):
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        schema_id = writer.register_schema(schema_name, "jsonschema", b"{}")
        channel_id = writer.register_channel(topic, "json", schema_id)
        writer.add_message(
            channel_id, log_time=1, data=json.dumps(payload).encode(), publish_time=1
        )
        writer.finish()


def test_an_unknown_format_version_is_refused_naming_file_topic_and_version(tmp_path):
    path = tmp_path / "future.mcap"
    payload = {"inlet_valve_current_a": 0.1, "outlet_valve_current_a": 0.0, "valve_id": 3}
    _write_with_schema(path, COMMAND_TOPIC, "maskless.ValveCommand.v3", payload)
    with pytest.raises(
        RecordError, match=r"future\.mcap: topic '/controller/command' .*format version 3"
    ):
        read_recording(path)


def test_a_schema_that_is_not_maskless_reads_as_it_is(tmp_path):
    path = tmp_path / "other.mcap"
    _write_with_schema(path, "/imu", "vendor.Imu", {"current_a": 1.5})
    assert read_recording(path).messages == {"/imu": [(1, {"current_a": 1.5})]}


# Camera frames: two cameras interleaved with the JSON topics, their times tying with some of them.
MS = 1_000_000


def _frames():
    frames = []
    for k in range(4):
        frames.append(face_frame("kinect_v1", time_s=k * 0.1, distance_m=0.8 + k / 100, shift=k))
        frames.append(
            empty_frame("kinect_v2", time_s=0.05 + k * 0.1)
            if k % 2
            else face_frame("kinect_v2", time_s=0.05 + k * 0.1, shift=10 + k)
        )
    return frames


def _by_camera(frames):
    cameras = {}
    for frame in frames:
        cameras.setdefault(frame.camera, []).append(frame)
    return cameras


class _JsonDecoders(McapDecoderFactory):
    def decoder_for(self, message_encoding, schema):
        return json.loads if message_encoding == "json" else None


def _decoded_messages(path):
    """(schema, channel, message, decoded) from the upstream reader and mcap_protobuf's decoder."""
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory(), _JsonDecoders()])
        return list(reader.iter_decoded_messages(log_time_order=False))


def test_frames_are_foxglove_protobuf_messages_merged_in_log_time(tmp_path):
    channels, frames = _make_channels(), _frames()
    path = tmp_path / "run.mcap"
    write_recording(path, channels, frames)
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    schemas = {s.name: s.encoding for s in summary.schemas.values()}
    assert schemas["foxglove.CompressedImage"] == "protobuf"
    assert schemas["foxglove.ImageAnnotations"] == "protobuf"
    camera_channels = {c.topic: c.message_encoding for c in summary.channels.values()}
    for camera in ("kinect_v1", "kinect_v2"):
        assert camera_channels[f"/cameras/{camera}/image"] == "protobuf"
        assert camera_channels[f"/cameras/{camera}/annotations"] == "protobuf"

    decoded = _decoded_messages(path)
    file_times = [message.log_time for _, _, message, _ in decoded]
    assert file_times == sorted(file_times)
    images, annotations = {}, {}
    for _, channel, message, proto in decoded:
        *_, camera, kind = channel.topic.split("/")
        if kind in ("image", "annotations"):
            assert message.publish_time == message.log_time
            assert message.log_time == proto.timestamp.seconds * 10**9 + proto.timestamp.nanos
            (images if kind == "image" else annotations).setdefault(camera, []).append(
                (message.log_time, proto)
            )
    for camera, written in _by_camera(frames).items():
        assert [t for t, _ in images[camera]] == [round(f.time_s * 1e9) for f in written]
        assert [t for t, _ in annotations[camera]] == [round(f.time_s * 1e9) for f in written]
        for frame, (_, image), (_, boxes) in zip(
            written, images[camera], annotations[camera], strict=True
        ):
            assert image.frame_id == camera
            assert mean_abs_difference(jpeg_pixels(image.data), frame.rgb) < 2.0
            expected = {
                "face": [frame.face_box],
                "eye": list(frame.eye_boxes),
                "depth_region": [frame.region_box],
            }
            assert boxes_by_role(boxes) == {
                k: v for k, v in expected.items() if v not in ([None], [])
            }

    # The JSON messages are those of a file without frames, in the same order.
    plain = tmp_path / "plain.mcap"
    write_recording(plain, channels)
    json_messages = [(c.topic, m.log_time, m.data) for _, c, m in _upstream_messages(plain)]
    assert [
        (c.topic, m.log_time, m.data) for _, c, m, _ in decoded if c.message_encoding == "json"
    ] == json_messages


def test_a_frame_at_the_time_of_json_messages_follows_them(tmp_path):
    t = np.array([0, 100 * MS], dtype=np.int64)
    reference = Channel(REFERENCE_TOPIC, t, {"reference_head_height_m": np.array([0.1, 0.2])})
    path = tmp_path / "ties.mcap"
    write_recording(path, [reference], [face_frame(time_s=0.1)])
    order = [(m.log_time, c.topic) for _, c, m in _upstream_messages(path)]
    assert order == [
        (0, REFERENCE_TOPIC),
        (100 * MS, REFERENCE_TOPIC),
        (100 * MS, "/cameras/kinect_v1/image"),
        (100 * MS, "/cameras/kinect_v1/annotations"),
    ]


def test_each_schema_is_written_before_its_channels_first_message(tmp_path):
    path = tmp_path / "run.mcap"
    write_recording(path, _make_channels(), _frames())
    first_seen = {}
    schema_of_channel, channel_of_message = {}, {}
    with open(path, "rb") as stream:
        records = list(StreamReader(stream).records)
    for index, record in enumerate(records):
        if isinstance(record, McapSchema):
            first_seen.setdefault(("schema", record.id), index)
        elif isinstance(record, McapChannel):
            first_seen.setdefault(("channel", record.id), index)
            schema_of_channel[record.id] = record.schema_id
        elif isinstance(record, McapMessage):
            channel_of_message.setdefault(record.channel_id, index)
    assert len(channel_of_message) == 12  # eight JSON topics, two per camera
    for channel_id, first_message in channel_of_message.items():
        schema = first_seen[("schema", schema_of_channel[channel_id])]
        assert schema < first_seen[("channel", channel_id)] < first_message


# sha256 of `write_recording(path, _make_channels(seed=3))` as the code before camera frames wrote
# it (commit 193882f, mcap 1.6.0; the data's powers of ten parsed, see _make_channels): without
# frames, a file must not change by a byte.
BEFORE_FRAMES_SHA256 = "e97b3b58dc54a9dc7b21d81f67c9e6c13dcab52d86ac9c06817c1d6625f1a56d"


def test_without_frames_the_bytes_are_those_written_before_frames_existed(tmp_path):
    channels = _make_channels(seed=3)
    old_call, no_frames, writer = (tmp_path / f"{n}.mcap" for n in ("old", "none", "writer"))
    write_recording(old_call, channels)
    write_recording(no_frames, channels, frames=())
    with RecordingWriter(writer, [c.topic for c in channels], cameras=()) as recording:
        recording.write(channels, frames=())
    assert old_call.read_bytes() == no_frames.read_bytes() == writer.read_bytes()
    assert hashlib.sha256(old_call.read_bytes()).hexdigest() == BEFORE_FRAMES_SHA256


def test_identical_frames_give_identical_bytes(tmp_path):
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    write_recording(a, _make_channels(seed=3), _frames())
    write_recording(b, _make_channels(seed=3), _frames())
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != _write_bytes(tmp_path / "c.mcap", _make_channels(seed=3))


class _Connection:
    """What a worker's serve function reads: the batches sent, then None."""

    def __init__(self, batches):
        self._batches = iter([*batches, None])

    def recv(self):
        return next(self._batches)


def test_batches_of_frames_give_the_bytes_of_one_write(tmp_path):
    channels, frames = _make_channels(seed=3), _frames()
    whole = tmp_path / "whole.mcap"
    write_recording(whole, channels, frames)
    cut_s = 0.2
    early_frames = [f for f in frames if f.time_s < cut_s]
    late_frames = [f for f in frames if f.time_s >= cut_s]
    early, late = _split_at(channels, round(cut_s * 1e9))
    cameras = ["kinect_v1", "kinect_v2"]  # in the order of their first frames
    batched = tmp_path / "batched.mcap"
    with RecordingWriter(batched, [c.topic for c in channels], cameras) as writer:
        writer.write(early, early_frames)
        writer.write(late, late_frames)
    assert batched.read_bytes() == whole.read_bytes()
    # The worker takes (channels, frames) pairs.
    served = tmp_path / "served.mcap"
    write_recording_batches(
        _Connection([(early, early_frames), (late, late_frames)]), served, cameras
    )
    assert served.read_bytes() == whole.read_bytes()


def test_the_worker_takes_lists_of_channels_and_pairs_alike(tmp_path):
    channels = _make_channels(seed=3)
    whole = tmp_path / "whole.mcap"
    write_recording(whole, channels)
    early, late = _split_at(channels, 200 * MS)
    for batches in ([early, late], [(early, ()), late], [early, (late, [])]):
        served = tmp_path / "served.mcap"
        write_recording_batches(_Connection(batches), served)
        assert served.read_bytes() == whole.read_bytes()


def test_reading_a_recording_with_frames_passes_over_them(tmp_path):
    channels = _make_channels(seed=7)
    plain, with_frames = tmp_path / "plain.mcap", tmp_path / "frames.mcap"
    write_recording(plain, channels)
    write_recording(with_frames, channels, _frames())
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing to warn about on a whole file
        recording = read_recording(with_frames)
    assert recording.truncated is False
    assert recording.messages == read_recording(plain).messages


def _assert_same_frames(got, written):
    """``got`` reads back as ``written``: boxes, measurement and time, pixels within JPEG error."""
    assert len(got) == len(written)
    for back, frame in zip(got, written, strict=True):
        assert (back.camera, back.time_ns) == (frame.camera, frame.time_ns)  # to the ns
        assert (back.face_box, back.eye_boxes, back.region_box) == (
            frame.face_box,
            frame.eye_boxes,
            frame.region_box,
        )
        assert back.valid == frame.valid
        np.testing.assert_equal(back.distance_m, frame.distance_m)
        assert mean_abs_difference(back.rgb, frame.rgb) < 2.0


def test_camera_frames_read_back_as_written(tmp_path):
    frames = _frames()
    path = tmp_path / "run.mcap"
    write_recording(path, _make_channels(), frames)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = read_camera_frames(path)
    assert list(got) == ["kinect_v1", "kinect_v2"]
    for camera, written in _by_camera(frames).items():
        _assert_same_frames(got[camera], written)


def test_cameras_without_frames_read_back_empty_and_files_without_cameras_as_none(tmp_path):
    path = tmp_path / "quiet.mcap"
    channels = _make_channels()
    with RecordingWriter(path, [c.topic for c in channels], cameras=["kinect_v1"]) as writer:
        writer.write(channels)
    assert read_camera_frames(path) == {"kinect_v1": []}
    write_recording(path, channels)
    assert read_camera_frames(path) == {}
    with pytest.raises(FileNotFoundError, match="absent.mcap"):
        read_camera_frames(tmp_path / "absent.mcap")


def test_a_cut_file_gives_the_frames_before_the_cut(tmp_path):
    frames = _frames()
    full_path = tmp_path / "full.mcap"
    write_recording(full_path, _make_channels(), frames)
    data = full_path.read_bytes()
    # Independent reference: the upstream reader's topics in file order, with the MCAP framing's
    # record ends. A frame is whole once its annotations message (after its image) is.
    messages = [(c.topic, m.log_time) for _, c, m in _upstream_messages(full_path)]
    ends = _message_record_ends(data)
    assert len(ends) == len(messages)
    by_time = {(f.camera, f.time_ns): f for f in frames}
    # Each frame, in file order, with the end of its annotations.
    file_frames = [
        (by_time[(topic.split("/")[2], t)], end)
        for (topic, t), end in zip(messages, ends, strict=True)
        if topic.endswith("/annotations")
    ]
    annotation_ends = [end for _, end in file_frames]
    image_ends = [end for (t, _), end in zip(messages, ends, strict=True) if t.endswith("/image")]
    cuts = [
        len(data) // 3,
        len(data) // 2,
        len(data) - 10,  # inside the footer: every frame is whole
        annotation_ends[3],  # at a record boundary, just after a frame
        annotation_ends[3] - 1,  # one byte short of that frame's annotations
        image_ends[5] + 5,  # after an image whose annotations are lost
        len(MAGIC) + 3,  # inside the header record
    ]
    for cut in cuts:
        cut_path = tmp_path / f"cut_{cut}.mcap"
        cut_path.write_bytes(data[:cut])
        whole = [frame for frame, end in file_frames if end <= cut]
        with pytest.warns(TruncatedRecordingWarning, match=rf"cut_{cut}\.mcap.* {len(whole)} "):
            got = read_camera_frames(cut_path)
        for camera, written in _by_camera(whole).items():
            _assert_same_frames(got[camera], written)
        assert sum(len(v) for v in got.values()) == len(whole), f"cut at byte {cut}"


def test_bad_frames_are_refused_naming_the_camera_before_the_file_is_written(tmp_path):
    path = tmp_path / "bad.mcap"
    back_in_time = [face_frame(time_s=0.2), face_frame(time_s=0.1)]
    with pytest.raises(ValueError, match="camera 'kinect_v1': frame times must be non-decreasing"):
        write_recording(path, [], back_in_time)
    with pytest.raises(ValueError, match=r"frames\[1\]: expected a CameraFrame, got dict"):
        write_recording(path, [], [face_frame(), {"camera": "kinect_v1"}])
    assert not path.exists()
    channels = _make_channels()
    with RecordingWriter(path, [c.topic for c in channels], cameras=["kinect_v1"]) as writer:
        with pytest.raises(ValueError, match=r"camera 'zed': not one of the recording's cameras"):
            writer.write(channels, [face_frame("zed")])
    for cameras, match in ((["kinect_v1", "kinect_v1"], "cameras repeat"), (["a b"], "'a b'")):
        with pytest.raises(ValueError, match=match):
            RecordingWriter(tmp_path / "other.mcap", [], cameras)
    assert not (tmp_path / "other.mcap").exists()


def _write_camera_topic(path, topic, message_class, data):
    schema = message_class.get_schema()
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        schema_id = writer.register_schema(schema.name, schema.encoding, bytes(schema.data))
        channel_id = writer.register_channel(topic, "protobuf", schema_id)
        writer.add_message(channel_id, log_time=1, data=data, publish_time=1)
        writer.finish()


def test_a_camera_topic_of_another_schema_or_undecodable_is_refused_naming_file_and_topic(
    tmp_path,
):
    raw = tmp_path / "raw.mcap"
    _write_camera_topic(raw, "/cameras/kinect_v1/image", RawImage, RawImage(width=1).encode())
    with pytest.raises(
        RecordError, match=r"raw\.mcap: topic '/cameras/kinect_v1/image' .*foxglove.RawImage"
    ):
        read_camera_frames(raw)
    assert read_recording(raw).messages == {}  # the JSON reader passes over it
    broken = tmp_path / "broken.mcap"
    _write_camera_topic(broken, "/cameras/kinect_v1/image", CompressedImage, b"\xff")
    with pytest.raises(RecordError, match=r"broken\.mcap: topic '/cameras/kinect_v1/image'"):
        read_camera_frames(broken)


class _CutConnection(_Connection):
    """A worker's connection whose caller goes away after the batches: EOFError, not None."""

    def recv(self):
        batch = super().recv()
        if batch is None:
            raise EOFError("the caller is gone")
        return batch


def test_a_worker_whose_caller_goes_away_finishes_the_file_marked_as_cut(tmp_path):
    channels = _make_channels(seed=3)
    early, _ = _split_at(channels, 200 * MS)
    path = tmp_path / "cut.mcap"
    write_recording_batches(_CutConnection([early]), path)
    # Whole to the standard reader (summary and footer), holding the batches received.
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None
        assert sum(1 for _ in reader.iter_messages()) == sum(c.times_ns.size for c in early)
    with pytest.warns(TruncatedRecordingWarning, match="its run was cut short"):
        recording = read_recording(path)
    assert recording.truncated
    assert sum(len(m) for m in recording.messages.values()) == sum(c.times_ns.size for c in early)


def safety_channel(states, reasons):
    t = np.arange(len(states), dtype=np.int64)
    return Channel(
        SAFETY_TOPIC,
        t,
        {
            "state": np.array(states, dtype=object),
            "reasons": np.array(reasons, dtype=object),
            "beam_hold": np.array([True, False][: len(states)] + [True] * (len(states) - 2)),
            "estimated_head_height_m": np.zeros(len(states)),
            "inlet_valve_current_a": np.zeros(len(states)),
            "outlet_valve_current_a": np.zeros(len(states)),
        },
    )


def test_string_fields_round_trip_as_json_strings(tmp_path):
    # A quote, a backslash and a non-ASCII character survive, in both encoding paths (the NaN in
    # the second file sends it through json.dumps).
    reasons = ["", 'a "quoted", \\ reason', "détection"]
    path = tmp_path / "safety.mcap"
    write_recording(path, [safety_channel(["normal", "degraded", "holding"], reasons)])
    _, read = read_recording(path).topic_arrays(SAFETY_TOPIC, "reasons")
    assert list(read) == reasons
    channel = safety_channel(["normal", "degraded", "holding"], reasons)
    channel.columns["estimated_head_height_m"][1] = np.nan
    write_recording(tmp_path / "nan.mcap", [channel])
    _, states = read_recording(tmp_path / "nan.mcap").topic_arrays(SAFETY_TOPIC, "state")
    assert list(states) == ["normal", "degraded", "holding"]


def test_a_string_field_given_numbers_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"/safety/status.*'state' must hold strings"):
        write_recording(tmp_path / "bad.mcap", [safety_channel([1.0, 2.0, 3.0], ["", "", ""])])
