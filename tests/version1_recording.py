"""Version-1 recordings, written the old way as an independent reference.

The schemas, topics and field names of every maskless file written before the format carried a
version, spelled out here rather than taken from maskless.recording.
"""

import json
import re

from mcap.writer import CompressionType, IndexType, Writer

# Schema name (no version) -> its fields, in the order the old writer wrote them.
V1_FIELDS = {
    "maskless.Reference": ("reference_m",),
    "maskless.HeadPosition": ("head_position_m",),
    "maskless.DepthMeasurement": ("distance_m", "valid"),
    "maskless.StateEstimate": ("position_m", "velocity_m_s", "covariance"),
    "maskless.ValveCommand": ("current_a", "outlet_current_a"),
}
V1_TOPICS = {
    "/reference": "maskless.Reference",
    "/plant/head_position": "maskless.HeadPosition",
    "/fusion/estimate": "maskless.StateEstimate",
    "/controller/command": "maskless.ValveCommand",
}
_TYPES = {"valid": "boolean", "covariance": "array"}


def _schema_name(topic):
    if topic in V1_TOPICS:
        return V1_TOPICS[topic]
    if re.fullmatch(r"/sensors/\w+/measurement", topic):
        return "maskless.DepthMeasurement"
    assert re.fullmatch(r"/filters/\w+/estimate", topic), topic
    return "maskless.StateEstimate"


def _schema(name):
    fields = V1_FIELDS[name]
    return {
        "title": name,
        "type": "object",
        "properties": {field: {"type": _TYPES.get(field, "number")} for field in fields},
        "required": list(fields),
        "additionalProperties": False,
    }


def write_version1_recording(path, messages):
    """Writes ``messages``, (topic, log time in ns, payload) in file order, as version 1 did.

    As the version-1 writer did: unchunked, a schema named without a version per kind of message,
    compact JSON.
    """
    with open(path, "wb") as stream:
        writer = Writer(
            stream,
            compression=CompressionType.NONE,
            use_chunking=False,
            index_types=IndexType.NONE,
            enable_data_crcs=True,
        )
        writer.start(profile="", library="maskless")
        schema_ids, channel_ids, sequences = {}, {}, {}
        for topic, log_time, payload in messages:
            name = _schema_name(topic)
            assert tuple(payload) == V1_FIELDS[name], (topic, payload)
            if name not in schema_ids:
                data = json.dumps(_schema(name), separators=(",", ":")).encode()
                schema_ids[name] = writer.register_schema(name, "jsonschema", data)
            if topic not in channel_ids:
                channel_ids[topic] = writer.register_channel(topic, "json", schema_ids[name])
            sequences[topic] = sequences.get(topic, -1) + 1
            writer.add_message(
                channel_ids[topic],
                log_time=log_time,
                data=json.dumps(payload, separators=(",", ":")).encode(),
                publish_time=log_time,
                sequence=sequences[topic],
            )
        writer.finish()
