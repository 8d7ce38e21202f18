"""The trial table: exact round trips, rows appended and flushed, a cut-off line survived."""

import math

import pytest

from maskless.analysis.trial_table import (
    TrialTableWriter,
    format_row,
    read_trial_rows,
    write_trial_table,
)
from maskless.errors import RecordError

COLUMNS = ["trial", "controller", "p95_mm", "settled", "error"]
ROWS = [
    {"trial": 0, "controller": "a", "p95_mm": 0.1 + 0.2, "settled": True, "error": None},
    {"trial": 1, "controller": "b,c", "p95_mm": None, "settled": False, "error": 'Bad: "x"'},
    {"trial": 2, "controller": "a", "p95_mm": 1e-300, "settled": None, "error": None},
]


def test_rows_read_back_exactly(tmp_path):
    path = tmp_path / "t.csv"
    with TrialTableWriter(path, COLUMNS) as writer:
        for row in ROWS:
            writer.append(row)
    columns, rows = read_trial_rows(path)
    assert columns == COLUMNS
    assert rows == ROWS  # 0.1 + 0.2 is not 0.3: repr keeps every bit


def test_nan_is_written_as_an_empty_cell():
    assert format_row({"a": math.nan, "b": 1}, ["a", "b"]) == ",1\n"


def test_each_row_is_on_disk_before_the_next_is_written(tmp_path):
    path = tmp_path / "t.csv"
    with TrialTableWriter(path, COLUMNS) as writer:
        writer.append(ROWS[0])
        assert read_trial_rows(path)[1] == ROWS[:1]


def test_a_line_cut_off_by_a_kill_is_dropped_and_then_overwritten(tmp_path):
    path = tmp_path / "t.csv"
    write_trial_table(path, COLUMNS, ROWS[:2])
    with path.open("a") as file:
        file.write("2,a,0.5")  # killed mid-line
    assert read_trial_rows(path)[1] == ROWS[:2]
    with TrialTableWriter(path, COLUMNS) as writer:
        writer.append(ROWS[2])
    assert read_trial_rows(path)[1] == ROWS


def test_another_sweeps_columns_are_refused(tmp_path):
    path = tmp_path / "t.csv"
    write_trial_table(path, ["trial", "other"], [])
    with pytest.raises(RecordError, match="differ from this sweep's"):
        TrialTableWriter(path, COLUMNS)


def test_a_complete_line_with_missing_cells_is_named(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("trial,controller\n0,a\n1\n")
    with pytest.raises(RecordError, match=r"t.csv:3: 1 cells; expected 2"):
        read_trial_rows(path)


def test_a_file_without_a_header_is_refused(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("")
    with pytest.raises(RecordError, match="no header"):
        read_trial_rows(path)


def test_a_row_missing_a_column_is_a_bug_named():
    with pytest.raises(ValueError, match="lacks columns"):
        format_row({"trial": 0}, COLUMNS)


def test_a_line_break_in_a_cell_is_refused_because_a_line_is_a_row():
    with pytest.raises(ValueError, match="line break"):
        format_row({"trial": 0, "error": "a\nb"}, ["trial", "error"])
