"""Tests for maskless.recording (MCAP write/read of simulation recordings)."""

import json
import struct
import warnings

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from version1_recording import write_version1_recording

from maskless.errors import RecordError
from maskless.recording import (
    COMMAND_TOPIC,
    FUSION_TOPIC,
    HEAD_HEIGHT_TOPIC,
    REFERENCE_TOPIC,
    Channel,
    RecordingWriter,
    TruncatedRecordingWarning,
    current_name,
    filter_estimate_topic,
    read_recording,
    schema_for_topic,
    sensor_measurement_topic,
    write_recording,
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
        # Mixed magnitudes and signs: repr round trip must hold for all of them exactly.
        return rng.normal(size=shape) * 10.0 ** rng.integers(-12, 6, size=shape)

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
