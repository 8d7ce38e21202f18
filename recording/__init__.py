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
complete message, which a chunked file cannot promise (a whole chunk would be lost). A writer
whose run stops early but which can still finish its file (``write_recording_batches`` when its
caller is gone) adds a ``maskless.cut`` Metadata record before the footer: the file is whole to
any MCAP reader, and ``read_recording`` reports it as truncated. What a writer says of the whole
run before it begins (a designed experiment's ``maskless.fit_split``: the parts to fit and judge a
model on) are Metadata records the file opens with, so a cut file still says it
(``read_leading_metadata``).

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
``/safety/status``                 ``state``, ``reasons``, ``beam_hold``,
                                   ``estimated_head_height_m``, ``inlet_valve_current_a``,
                                   ``outlet_valve_current_a``
``/plant/bladder_pressure``        ``gauge_pressure_pa`` (the pneumatic plant's sensor)
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
``read_recording`` presents a version-1 file under the current names (``format._V1_TOPICS``
and ``format._V1_FIELDS`` are the one table of what changed), and refuses a version it does not
know.

The package's modules: ``format`` (topics, schemas, the format version, version 1's names),
``encoding`` (channels and frames validated and encoded as message bytes, merged by log time),
``writing`` (the file, at once or batch by batch) and ``reading`` (the file read back, cut or
whole). The names below are theirs, re-exported.
"""

from maskless.lazy_exports import lazy_exports

# Public name -> the module that defines it. Imported on first use (PEP 562), so that a reader
# of the format's topic names (`maskless identify` on a CSV record) does not load mcap, the
# Foxglove schemas, protobuf and OpenCV, which only writing and reading a file need.
_EXPORTS = {
    "Channel": "maskless.recording.encoding",
    **dict.fromkeys(
        (
            "BLADDER_PRESSURE_TOPIC",
            "CAMERA_MESSAGE_ENCODING",
            "COMMAND_TOPIC",
            "FIT_SPLIT_METADATA",
            "FUSION_TOPIC",
            "HEAD_HEIGHT_TOPIC",
            "MESSAGE_ENCODING",
            "REFERENCE_TOPIC",
            "SAFETY_TOPIC",
            "SCHEMA_ENCODING",
            "SCHEMA_VERSION",
            "current_name",
            "filter_estimate_topic",
            "schema_for_topic",
            "sensor_measurement_topic",
        ),
        "maskless.recording.format",
    ),
    **dict.fromkeys(
        (
            "Recording",
            "read_camera_frames",
            "read_leading_metadata",
            "read_recording",
        ),
        "maskless.recording.reading",
    ),
    **dict.fromkeys(
        ("RecordingWriter", "write_recording", "write_recording_batches"),
        "maskless.recording.writing",
    ),
    "is_sensor_name": "maskless.sensor_names",
    "TruncatedRecordingWarning": "maskless.errors",
}

# The module's __all__ from before it became a package: every export but the batch writer, its
# writer class and the sensor-name check (imported from here by diagrams.scenario), public too but
# outside __all__ as they were.
__all__ = sorted(set(_EXPORTS) - {"RecordingWriter", "write_recording_batches", "is_sensor_name"})


__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
