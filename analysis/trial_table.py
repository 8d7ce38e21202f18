"""A Monte Carlo's rows on disk: one CSV line per trial, appended as trials finish.

CSV rather than Parquet: a line can be appended and flushed the moment a trial ends, so a sweep
holds no rows in memory and a killed sweep loses at most the line being written, which
``read_trial_rows`` drops (and ``TrialTableWriter`` cuts off before appending). Parquet files are
written whole, a row group at a time. Floats are written with ``repr``, which reads back to the
same double, so a table compares exactly; an empty cell is None.
"""

import csv
import io
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from maskless.errors import RecordError

_TRUE, _FALSE = "true", "false"


def _cell(value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, bool):
        return _TRUE if value else _FALSE
    text = repr(value) if isinstance(value, float) else str(value)
    if "\n" in text or "\r" in text:
        # A line is a row: that is what lets a reader drop a line cut off by a kill.
        raise ValueError(f"a cell holds a line break: {text!r}")
    return text


def _value(text: str):
    if text == "":
        return None
    if text in (_TRUE, _FALSE):
        return text == _TRUE
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def format_row(row: dict, columns: Sequence[str]) -> str:
    """One CSV line (with its newline) of ``row``'s values in ``columns`` order."""
    missing = [c for c in columns if c not in row]
    if missing:
        raise ValueError(f"row lacks columns {missing}")
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow([_cell(row[c]) for c in columns])
    return buffer.getvalue()


def _header(columns: Sequence[str]) -> str:
    return format_row(dict(zip(columns, columns, strict=True)), columns)


def read_trial_rows(path: str | Path) -> tuple[list[str], list[dict]]:
    """(columns, rows) of a trial table; a last line cut off by a kill is dropped.

    Raises:
        RecordError: the file has no header, or a complete line has the wrong number of cells.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    complete = text[: text.rfind("\n") + 1]  # a line without its newline was cut off
    lines = list(csv.reader(io.StringIO(complete)))
    if not lines:
        raise RecordError(f"{path}: no header line; not a trial table")
    columns, rows = lines[0], []
    for number, cells in enumerate(lines[1:], start=2):
        if len(cells) != len(columns):
            raise RecordError(
                f"{path}:{number}: {len(cells)} cells; expected {len(columns)} ({columns[0]}, ...)"
            )
        rows.append({c: _value(cell) for c, cell in zip(columns, cells, strict=True)})
    return columns, rows


class TrialTableWriter:
    """Appends rows to a trial table, each flushed to disk as it comes.

    A new file gets the header; an existing one must have the same columns, and a cut-off last
    line is removed first. Use as a context manager.

    Args:
        path: the table's file.
        columns: its columns, in order.

    Raises:
        RecordError: an existing file has other columns.
    """

    def __init__(self, path: str | Path, columns: Sequence[str]):
        """Opens ``path`` for appending (see the class docstring)."""
        self.path, self.columns = Path(path), list(columns)
        if self.path.exists() and self.path.stat().st_size > 0:
            found, _ = read_trial_rows(self.path)
            if found != self.columns:
                raise RecordError(
                    f"{self.path}: columns {found} differ from this sweep's {self.columns}"
                )
            _cut_partial_line(self.path)
            self._file = self.path.open("a", encoding="utf-8", newline="")
        else:
            self._file = self.path.open("w", encoding="utf-8", newline="")
            self._file.write(_header(self.columns))
            self._file.flush()

    def append(self, row: dict) -> None:
        """Writes one row and flushes it to the operating system."""
        self._file.write(format_row(row, self.columns))
        self._file.flush()

    def close(self) -> None:
        """Closes the file."""
        self._file.close()

    def __enter__(self):
        """The writer itself."""
        return self

    def __exit__(self, *exc_info):
        """Closes the file."""
        self.close()


def _cut_partial_line(path: Path) -> None:
    data = path.read_bytes()
    end = data.rfind(b"\n") + 1
    if end < len(data):
        with path.open("r+b") as file:
            file.truncate(end)


def write_trial_table(path: str | Path, columns: Sequence[str], rows: Iterable[dict]) -> None:
    """Writes a whole table at once, atomically (a reader sees the old file or the new one)."""
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    with partial.open("w", encoding="utf-8", newline="") as file:
        file.write(_header(columns))
        for row in rows:
            file.write(format_row(row, columns))
    os.replace(partial, path)
