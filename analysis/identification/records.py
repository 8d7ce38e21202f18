"""Reading an identification record (CSV or a maskless MCAP), choosing its parts, detrending it.

Every error names the file and, for CSV, the line: a record with text, NaN, no values, or input and
output of different lengths is refused before any fitting starts.
"""

import contextlib
import csv
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from maskless.errors import (
    MasklessError,
    MissingFileError,
    RecordError,
)
from maskless.recording import current_name


def read_csv_signal(path: str | Path, column: str | None = None) -> np.ndarray:
    """One signal from a CSV file.

    Args:
        path: the file: one value per line, or a table whose ``column`` is chosen.
        column: a header name, or a 0-based index as text; None for one value per line.
    """
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"record not found: {path}")
    rows = _read_rows(path)
    index, first_data_line = _column_index(path, rows, column)
    values, blank_line = [], None
    for line_number, row in enumerate(rows[first_data_line - 1 :], start=first_data_line):
        if not row or all(not cell.strip() for cell in row):
            blank_line = blank_line or line_number  # allowed only at the end
            continue
        if blank_line is not None:
            raise RecordError(
                f"{path}:{blank_line}: blank line inside the record (it would shift every later "
                "sample against the other signal)"
            )
        values.append(_parse_value(path, line_number, row, index, column))
    if not values:
        raise RecordError(f"{path}: no values")
    return np.array(values)


def _read_rows(path: Path) -> list[list[str]]:
    """Every row of the CSV file ``path``; a file that is not text is a RecordError."""
    try:
        with open(path, newline="") as stream:
            return list(csv.reader(stream))
    except UnicodeDecodeError as error:
        raise RecordError(
            f"{path}: not a text file ({error.reason} at byte {error.start})"
        ) from None


def _column_index(path: Path, rows: list[list[str]], column: str | None) -> tuple[int, int]:
    """(0-based index of ``column``, 1-based line of its first value) in the CSV ``rows``.

    A header name skips the header line; an index as text, or None (one value per line), reads
    from line 1.
    """
    if column is None:
        return 0, 1
    if not rows:
        raise RecordError(f"{path}: empty file, expected a table with column {column!r}")
    header = [name.strip() for name in rows[0]]
    if column in header:
        return header.index(column), 2
    if column.isdigit():
        return int(column), 1
    raise RecordError(f"{path}: no column {column!r}; the header has {header}")


def _parse_value(
    path: Path, line_number: int, row: list[str], index: int, column: str | None
) -> float:
    """The finite number in column ``index`` of the non-blank CSV ``row`` at ``line_number``.

    With ``column`` None (one value per line) a row of several columns is refused.
    """
    if column is None and len(row) > 1:
        raise RecordError(
            f"{path}:{line_number}: {len(row)} columns; choose one with --input-column or "
            "--output-column"
        )
    if index >= len(row):
        raise RecordError(f"{path}:{line_number}: has {len(row)} columns, no column {index}")
    text = row[index].strip()
    try:
        value = float(text)
    except ValueError:
        raise RecordError(f"{path}:{line_number}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise RecordError(f"{path}:{line_number}: {text!r} is not a finite number")
    return value


# Both valve currents as one two-column input, for an identification from the inlet and outlet.
VALVE_CURRENTS_FIELDS = "/controller/command:inlet_valve_current_a,outlet_valve_current_a"


def read_mcap_signals(
    path: str | Path, *topics_and_fields: str, cut_notes: list[str] | None = None
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Signals from a maskless MCAP recording, read once: (log times in ns, values) for each.

    A signal of one field has values of shape (N,); one of several fields of a topic, which share
    their log times, has one column per field, shape (N, k), in the order given (e.g.
    ``VALVE_CURRENTS_FIELDS``, the inlet's and the outlet's current).

    Args:
        path: the recording.
        topics_and_fields: each "TOPIC:FIELD", e.g. "/controller/command:inlet_valve_current_a",
            or "TOPIC:FIELD,FIELD,..." for several fields of one topic as columns; the version-1
            names (say "/controller/command:current_a") are accepted too.
        cut_notes: where given, a cut-off recording's sentence is appended to it, for a report
            to say, instead of being warned (``TruncatedRecordingWarning``) on stderr.
    """
    wanted = []
    for topic_and_field in topics_and_fields:
        topic, separator, fields = topic_and_field.rpartition(":")
        names = fields.split(",")
        if not separator or not topic or not all(names):
            raise RecordError(
                f"{path}: {topic_and_field!r} should be TOPIC:FIELD or TOPIC:FIELD,FIELD"
            )
        # The recording is read under the current names, whatever version wrote it.
        current = [current_name(topic, name) for name in names]
        wanted.append((current[0][0], [name for _, name in current]))
    # Here, not at the top: reading MCAP loads mcap, protobuf and OpenCV, which a CSV record skips.
    from maskless.recording import read_recording

    try:
        recording = read_recording(
            path, topics={topic for topic, _ in wanted}, warn_if_cut=cut_notes is None
        )
    except ValueError as error:
        raise RecordError(str(error)) from None
    if cut_notes is not None and recording.cut is not None:
        cut_notes.append(recording.cut)
    signals = []
    for topic, names in wanted:
        if topic not in recording.messages:
            raise RecordError(f"{path}: no topic {topic!r}; it has {sorted(recording.messages)}")
        columns = [_field_values(path, recording, topic, name) for name in names]
        times = columns[0][0]
        values = columns[0][1] if len(columns) == 1 else np.column_stack([v for _, v in columns])
        signals.append((times, values))
    return signals


# How far --ts may be from a recording's own sample period before it is refused.
TS_TOLERANCE = 0.01


def refuse_other_period(flag: str, ts: float, period_s: float) -> None:
    """A RecordError where ``ts`` (s, given as ``flag``) is off the recording's own period.

    Off: by more than ``TS_TOLERANCE`` of ``period_s`` (s).
    """
    if abs(period_s - ts) > TS_TOLERANCE * period_s:
        raise RecordError(f"{flag} {ts}: the recording's samples are {period_s:.6g} s apart")


def identified_before_the_cut(cut_notes: list[str]) -> tuple[str, ...]:
    """A report's warnings for the cut-off recordings ``cut_notes`` names."""
    return tuple(f"{note}: identified from what it held before the cut" for note in cut_notes)


@contextlib.contextmanager
def noting_cuts() -> Iterator[list[str]]:
    """The ``cut_notes`` for the reads in the block, added to a refusal raised in it.

    A report says its cut recordings among its warnings; a refusal has no report, so its one line
    says them instead (the CLI joins an error's notes to it).
    """
    notes: list[str] = []
    try:
        yield notes
    except MasklessError as error:
        for note in notes:
            error.add_note(note)
        raise


def named_fields(column: str) -> tuple[str, list[str]]:
    """(topic, names) of "TOPIC:A,B" (MCAP fields) or ("", names) of "A,B" (CSV columns)."""
    topic, _, names = column.rpartition(":")
    return topic, names.split(",")


def read_aligned_mcap(
    input_path: str | Path,
    input_field: str,
    output_path: str | Path,
    output_field: str,
    cut_notes: list[str] | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """(input, output (N,), sample period in s): the samples two recorded signals share.

    The input is (N,), or (N, k) for "TOPIC:FIELD,FIELD,..."; the output is one field. A recording
    holding both is read once. The period is the median step between shared log times.
    ``cut_notes``: as ``read_mcap_signals`` takes it.

    Raises:
        RecordError: an output of several fields, fewer than 2 shared samples, or a gap (a step
            more than half a period off it): a record with gaps is not one sequence.
    """
    if Path(output_path) == Path(input_path):
        (input_times, u), (output_times, y) = read_mcap_signals(
            input_path, input_field, output_field, cut_notes=cut_notes
        )
    else:
        ((input_times, u),) = read_mcap_signals(input_path, input_field, cut_notes=cut_notes)
        ((output_times, y),) = read_mcap_signals(output_path, output_field, cut_notes=cut_notes)
    if y.ndim != 1:  # "TOPIC:FIELD,FIELD" reads columns: several inputs, one output
        raise RecordError(f"{output_path}: {output_field!r}: expected one field (one output)")
    common, input_index, output_index = np.intersect1d(
        input_times, output_times, return_indices=True
    )
    if common.size < 2:
        raise RecordError(f"{input_path} and {output_path}: fewer than 2 common timestamps")
    steps_s = np.diff(common) * 1e-9
    period_s = float(np.median(steps_s))
    off = np.abs(steps_s - period_s) > 0.5 * period_s
    if np.any(off):
        gap = int(np.argmax(off))
        raise RecordError(
            f"{input_path}: {input_field} and {output_field} share no samples between "
            f"{common[gap] * 1e-9:.3f} s and {common[gap + 1] * 1e-9:.3f} s; a record with "
            "gaps cannot be identified as one sequence"
        )
    return u[input_index], y[output_index], period_s


def _field_values(path, recording, topic: str, field: str) -> tuple[np.ndarray, np.ndarray]:
    """(log times in ns, finite values) of ``topic``'s ``field`` in ``recording``."""
    messages = recording.messages[topic]
    if messages and field not in messages[0][1]:
        raise RecordError(
            f"{path}: topic {topic} has no field {field!r}; it has {sorted(messages[0][1])}"
        )
    times, values = recording.topic_arrays(topic, field)
    values = np.asarray(values, dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise RecordError(f"{path}: {topic}:{field} message {bad[0]} is not a finite number")
    return times, values


# Said of a validation part that shares samples with the estimation part.
OVERLAPPING_PARTS_WARNING = (
    "the validation part overlaps the estimation part: its figures are not a holdout and flatter "
    "the models"
)


def parts_overlap(first: slice, second: slice) -> bool:
    """Whether two parts of a record (slices with a start and a stop) share a sample."""
    return max(first.start, second.start) < min(first.stop, second.stop)


def parse_range(text: str, samples: int, what: str) -> slice:
    """A part of a record from "START:STOP": fractions (0:0.6) or sample indices (0:11782).

    Bounds that are both at most 1, or written with a decimal point, are fractions of the record.
    """
    expected = f"{what} = {text!r}: expected START:STOP, e.g. 0:0.6 or 0:11782"
    start_text, separator, stop_text = text.partition(":")
    try:
        bounds = [float(start_text), float(stop_text)]
    except ValueError:
        raise RecordError(expected) from None
    if not separator or not all(math.isfinite(b) for b in bounds):
        raise RecordError(expected)
    fractions = "." in text or max(bounds) <= 1
    start, stop = (round(b * samples) for b in bounds) if fractions else (int(b) for b in bounds)
    if not 0 <= start < stop <= samples:
        raise RecordError(
            f"{what} = {text!r}: selects samples {start}..{stop} of a record of {samples}"
        )
    return slice(start, stop)


@dataclass(frozen=True)
class Detrended:
    """A record with its offsets removed.

    Attributes:
        u, y: the detrended input and output.
        input_offset, output_offset: what was subtracted: the mean, or the trend line's value at
            the first sample (for "linear"); 0 for "none".
        input_slope, output_slope: the trend lines' slopes per sample ("linear"; else 0).
    """

    u: np.ndarray
    y: np.ndarray
    input_offset: float
    output_offset: float
    input_slope: float = 0.0
    output_slope: float = 0.0


def detrend(u: np.ndarray, y: np.ndarray, mode: str) -> Detrended:
    """Removes the record's offsets as ``mode`` says: its mean, its trend line, or nothing.

    "mean" removes the whole record's mean (the authors' preprocessing), "linear" its least-squares
    line and "none" nothing.
    """
    if mode == "none":
        return Detrended(u, y, 0.0, 0.0)
    if mode == "mean":
        return Detrended(u - u.mean(), y - y.mean(), float(u.mean()), float(y.mean()))
    if mode == "linear":
        # Imported here: this module is read before a command has chosen what it runs, and
        # scipy.signal takes most of a second to import.
        import scipy.signal

        u_detrended = scipy.signal.detrend(u, type="linear")
        y_detrended = scipy.signal.detrend(y, type="linear")
        u_trend, y_trend = u - u_detrended, y - y_detrended
        return Detrended(
            u_detrended,
            y_detrended,
            float(u_trend[0]),
            float(y_trend[0]),
            float(u_trend[1] - u_trend[0]),
            float(y_trend[1] - y_trend[0]),
        )
    raise RecordError(f"--detrend {mode!r}: expected mean, linear or none")
