"""CSV and MCAP records, part ranges and detrending, with errors naming the file, line and flag."""

import numpy as np
import pytest
from version1_recording import write_version1_recording

from maskless.analysis.identification.records import (
    VALVE_CURRENTS_FIELDS,
    detrend,
    identified_before_the_cut,
    noting_cuts,
    parse_range,
    read_aligned_mcap,
    read_csv_signal,
    read_mcap_signals,
)
from maskless.errors import RecordError, TruncatedRecordingWarning
from maskless.recording import Channel, write_recording


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_one_value_per_line_with_trailing_blank_line(tmp_path):
    path = write(tmp_path, "u.csv", "1.5\n2\n-3e-1\n\n")
    np.testing.assert_array_equal(read_csv_signal(path), [1.5, 2.0, -0.3])


def test_column_by_header_name_and_by_index(tmp_path):
    path = write(tmp_path, "t.csv", "time,current_ma\n0,80\n0.048,81\n")
    np.testing.assert_array_equal(read_csv_signal(path, "current_ma"), [80.0, 81.0])
    path = write(tmp_path, "n.csv", "0,80\n0.048,81\n")
    np.testing.assert_array_equal(read_csv_signal(path, "1"), [80.0, 81.0])


@pytest.mark.parametrize(
    "text, message",
    [
        ("1\n2\nabc\n", r"u\.csv:3: 'abc' is not a number"),
        ("1\nnan\n", r"u\.csv:2: 'nan' is not a finite number"),
        ("", r"u\.csv: no values"),
        ("\n\n", r"u\.csv: no values"),
    ],
)
def test_bad_records_name_file_and_line(tmp_path, text, message):
    path = write(tmp_path, "u.csv", text)
    with pytest.raises(RecordError, match=message):
        read_csv_signal(path)


def test_unknown_column_and_missing_file(tmp_path):
    path = write(tmp_path, "t.csv", "time,current_ma\n0,80\n")
    with pytest.raises(RecordError, match="no column 'current_a'"):
        read_csv_signal(path, "current_a")
    with pytest.raises(FileNotFoundError, match="nothing.csv"):
        read_csv_signal(tmp_path / "nothing.csv")


@pytest.mark.parametrize(
    "text, expected",
    [
        ("0:0.6", slice(0, 11782)),
        ("0.6:1", slice(11782, 19637)),
        ("0:11782", slice(0, 11782)),
        ("100:200", slice(100, 200)),
    ],
)
def test_ranges_take_fractions_or_indices(text, expected):
    assert parse_range(text, 19637, "--estimation") == expected


@pytest.mark.parametrize("text", ["0.6", "a:b", "0:30000", "0.5:0.2"])
def test_bad_ranges_are_refused_naming_the_flag(text):
    with pytest.raises(RecordError, match="--validation"):
        parse_range(text, 19637, "--validation")


def test_detrend_modes():
    t = np.arange(100.0)
    u, y = 2 + 0.5 * t, 10 - 0.1 * t
    mean = detrend(u, y, "mean")
    assert mean.input_offset == pytest.approx(u.mean()) and abs(mean.y.mean()) < 1e-12
    linear = detrend(u, y, "linear")
    np.testing.assert_allclose(linear.u, 0, atol=1e-9)
    assert linear.input_offset == pytest.approx(2.0) and linear.output_offset == pytest.approx(10.0)
    assert detrend(u, y, "none").u is u
    with pytest.raises(RecordError, match="--detrend"):
        detrend(u, y, "quadratic")


def _command_recording(path, inlet, outlet):
    times_ns = np.arange(inlet.size, dtype=np.int64) * 48_000_000
    channel = Channel(
        "/controller/command",
        times_ns,
        {"inlet_valve_current_a": inlet, "outlet_valve_current_a": outlet},
    )
    write_recording(path, [channel])
    return times_ns


def test_both_valve_currents_read_as_two_columns_of_one_signal(tmp_path):
    rng = np.random.default_rng(0)
    inlet, outlet = rng.uniform(0, 0.165, 50), rng.uniform(0, 0.165, 50)
    path = tmp_path / "two.mcap"
    times_ns = _command_recording(path, inlet, outlet)
    (times, currents), (_, inlet_only) = read_mcap_signals(
        path, VALVE_CURRENTS_FIELDS, "/controller/command:inlet_valve_current_a"
    )
    np.testing.assert_array_equal(times, times_ns)
    assert currents.shape == (50, 2)
    np.testing.assert_array_equal(currents, np.column_stack([inlet, outlet]))
    # The single-field call is as before: one 1-D signal.
    assert inlet_only.shape == (50,)
    np.testing.assert_array_equal(inlet_only, inlet)


def test_two_columns_under_version1_names(tmp_path):
    path = str(tmp_path / "v1.mcap")
    messages = [
        ("/controller/command", 48_000_000 * k, {"current_a": 0.1 + k, "outlet_current_a": -k})
        for k in range(5)
    ]
    write_version1_recording(path, messages)
    ((_, currents),) = read_mcap_signals(path, "/controller/command:current_a,outlet_current_a")
    np.testing.assert_array_equal(currents, [[0.1 + k, -k] for k in range(5)])


@pytest.mark.parametrize(
    "spec, message",
    [
        (
            "/controller/command:inlet_valve_current_a,",
            "should be TOPIC:FIELD or TOPIC:FIELD,FIELD",
        ),
        ("/controller/command:inlet_valve_current_a,coil_a", "has no field 'coil_a'"),
        ("/nothing:a,b", "no topic '/nothing'"),
    ],
)
def test_bad_multi_field_specs_are_refused(tmp_path, spec, message):
    path = tmp_path / "two.mcap"
    _command_recording(path, np.zeros(3), np.zeros(3))
    with pytest.raises(RecordError, match=message):
        read_mcap_signals(path, spec)


def _height_recording(path, times_ns, heights):
    columns = {
        "head_height_m": heights,
        "head_velocity_m_s": np.zeros(heights.size),
        "covariance": np.tile(np.eye(2), (heights.size, 1, 1)),
    }
    channel = Channel("/fusion/estimate", times_ns, columns)
    write_recording(path, [channel])


def test_aligned_signals_keep_the_shared_samples_and_their_period(tmp_path):
    rng = np.random.default_rng(1)
    inlet, outlet = rng.uniform(0, 0.165, 40), rng.uniform(0, 0.165, 40)
    currents_path, height_path = tmp_path / "u.mcap", tmp_path / "y.mcap"
    times_ns = _command_recording(currents_path, inlet, outlet)
    # The output starts three samples late: only the 37 shared log times are kept, in step.
    heights = rng.uniform(0.1, 0.2, 37)
    _height_recording(height_path, times_ns[3:], heights)
    u, y, period_s = read_aligned_mcap(
        currents_path, VALVE_CURRENTS_FIELDS, height_path, "/fusion/estimate:head_height_m"
    )
    np.testing.assert_array_equal(u, np.column_stack([inlet, outlet])[3:])
    np.testing.assert_array_equal(y, heights)
    assert period_s == pytest.approx(0.048)


def test_aligned_signals_with_a_gap_are_refused_naming_where(tmp_path):
    currents_path, height_path = tmp_path / "u.mcap", tmp_path / "y.mcap"
    times_ns = _command_recording(currents_path, np.zeros(40), np.zeros(40))
    # Ten output samples missing in the middle: the shared samples are not one sequence.
    kept = np.r_[0:15, 25:40]
    _height_recording(height_path, times_ns[kept], np.zeros(kept.size))
    with pytest.raises(RecordError, match=r"share no samples between 0\.672 s and 1\.200 s"):
        read_aligned_mcap(
            currents_path, VALVE_CURRENTS_FIELDS, height_path, "/fusion/estimate:head_height_m"
        )
    with pytest.raises(RecordError, match="expected one field"):
        read_aligned_mcap(
            currents_path,
            "/controller/command:inlet_valve_current_a",
            currents_path,
            VALVE_CURRENTS_FIELDS,
        )


def test_a_cut_recording_read_for_a_report_is_noted_not_warned(tmp_path):
    rng = np.random.default_rng(2)
    whole, cut = tmp_path / "u.mcap", tmp_path / "cut.mcap"
    _command_recording(whole, rng.uniform(0, 0.165, 40), rng.uniform(0, 0.165, 40))
    cut.write_bytes(whole.read_bytes()[:-200])
    # Read plainly, the cut is warned; given a list for the notes, it is noted there instead
    # (the suite turns an unexpected warning into an error).
    with pytest.warns(TruncatedRecordingWarning):
        read_mcap_signals(cut, VALVE_CURRENTS_FIELDS)
    notes = []
    ((_, currents),) = read_mcap_signals(cut, VALVE_CURRENTS_FIELDS, cut_notes=notes)
    (note,) = notes
    assert note.startswith(f"{cut}: recording is truncated or corrupt") and currents.shape[1] == 2
    assert identified_before_the_cut(notes) == (
        f"{note}: identified from what it held before the cut",
    )
    read_mcap_signals(whole, VALVE_CURRENTS_FIELDS, cut_notes=notes)
    assert len(notes) == 1  # a whole file adds none


def test_a_refusal_carries_the_notes_and_other_errors_pass_as_they_are():
    with pytest.raises(RecordError) as refused, noting_cuts() as notes:
        notes.append("run.mcap: cut")
        raise RecordError("too short")
    assert refused.value.__notes__ == ["run.mcap: cut"]
    with pytest.raises(KeyError) as other, noting_cuts() as notes:
        notes.append("run.mcap: cut")
        raise KeyError("a bug")
    assert not hasattr(other.value, "__notes__")
