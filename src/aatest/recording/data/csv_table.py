"""Strict, vectorised reading of the numeric CSV files of an import directory.

The format is docs/interfaces.md §3.

What is tolerated: a UTF-8 byte-order mark, CRLF or CR line ends, blank lines, ``#`` comment
lines, whitespace around cells and names, quoted header names, any column order and extra
columns (which are never parsed, so they may hold text). What is rejected, always as
:class:`~aatest.engine.errors.ImportDataError` with the file and line: an empty file or one
without data rows, a missing or duplicated column, a row with a different number of fields
than the header (a truncated last row), a cell that is not a finite number, and a time column
that is not strictly increasing.

Parsing. A plain file — an ASCII header of unquoted names, then one row of numbers per line,
no quotes, no blank or comment line — is read once, by Arrow's C++ CSV reader (``pyarrow.csv``,
one thread per file, memory-mapped, known float64 column types), and Arrow alone decides that it
is plain: it refuses anything else, and its data rows then lie on consecutive lines, so no Python
pass over the text is needed (:func:`_read_plain`). Anything else, and any file Arrow refuses,
takes the tolerant path: one ``np.loadtxt`` call over the kept lines, and only when that fails a
per-row scan (Python, error path only) finds the first offending line to report. Both paths
accept and reject the same files with the same messages.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pa_csv

from aatest.engine.errors import ImportDataError

TIME_COLUMN = "time_s"
#: bytes in the header line that send a file to the tolerant path (CR line ends, NUL, quotes)
_NOT_PLAIN = (b"\r", b"\x00", b'"')
#: bytes read to find the header line (a longer header takes the tolerant path)
_HEADER_PROBE_BYTES = 1 << 16
#: Arrow's parse block, bytes (its default; each block becomes one chunk of every column)
_BLOCK_BYTES = 1 << 20


@dataclass(frozen=True)
class CsvColumns:
    """The parsed numeric columns of one CSV file.

    Attributes
    ----------
    path
        The file, for messages.
    columns
        Column name → float64 values (only the requested columns that were present).
    header
        Every column name of the header row, in file order.
    row_lines
        1-based file line of every data row (to locate later problems).
    """

    path: Path
    columns: dict[str, np.ndarray]
    header: tuple[str, ...]
    row_lines: np.ndarray

    def __len__(self) -> int:
        return int(self.row_lines.shape[0])

    def binary(self, name: str) -> np.ndarray:
        """A 0/1 column (sync pulse, trigger) as uint8; any other value is an error."""
        values = self.columns[name]
        bad = np.flatnonzero((values != 0) & (values != 1))
        if bad.size:
            raise ImportDataError(
                self.path, f"column {name!r} must be 0 or 1, found {values[bad[0]]!r}",
                line=int(self.row_lines[bad[0]]),
            )
        return _read_only(values.astype(np.uint8))


def _split_lines(path: Path) -> list[str]:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ImportDataError(path, f"cannot read file: {exc.strerror or exc}") from exc
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ImportDataError(path, "not UTF-8 text", line=line) from exc
    if "\x00" in text:
        raise ImportDataError(path, "binary data (NUL byte) in a CSV file",
                              line=text[: text.index("\x00")].count("\n") + 1)
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def _is_content(line: str) -> bool:
    stripped = line.strip()
    return bool(stripped) and not stripped.startswith("#")


def _header(path: Path, lines: list[str]) -> tuple[int, tuple[str, ...]]:
    """Index of the header line and its column names."""
    for i, line in enumerate(lines):
        if _is_content(line):
            names = tuple(name.strip().strip('"').strip() for name in line.split(","))
            seen = set()
            for name in names:
                if not name or name in seen:
                    what = "an empty column name" if not name else f"duplicate column {name!r}"
                    raise ImportDataError(path, f"header has {what}", line=i + 1)
                seen.add(name)
            return i, names
    raise ImportDataError(path, "empty file (no header row)", line=1)


def _locate_bad_cell(
    path: Path,
    lines: list[str],
    rows: np.ndarray,
    usecols: list[int],
    header: tuple[str, ...],
    exc: ValueError,
) -> ImportDataError:
    """Error path only: the first row whose cell float() refuses, else numpy's row number."""
    for row in rows.tolist():
        cells = lines[row].split(",")
        for col in usecols:
            try:
                float(cells[col])
            except (ValueError, IndexError):
                cell = cells[col].strip() if col < len(cells) else ""
                return ImportDataError(
                    path, f"column {header[col]!r}: {cell!r} is not a number", line=row + 1
                )
    found = re.search(r"at row (\d+)", str(exc))
    if found and int(found.group(1)) < rows.size:
        return ImportDataError(path, f"unparseable number ({exc})",
                               line=int(rows[int(found.group(1))]) + 1)
    return ImportDataError(path, f"unparseable numeric data ({exc})")


def read_csv(path: Path, required: Sequence[str], optional: Sequence[str] = ()) -> CsvColumns:
    """Read the ``required`` and present ``optional`` numeric columns of a CSV file.

    Parameters
    ----------
    path
        The CSV file (header row, then one row per sample).
    required
        Columns that must be present; ``time_s`` must be one of them and strictly increase.
    optional
        Columns read when present.

    Raises
    ------
    ImportDataError
        The file is malformed; the message names the file, the line and the problem.
    """
    path = Path(path)
    fast = _read_plain(path, required, optional)
    if fast is not None:
        return _checked(fast)
    lines = _split_lines(path)
    header_index, header = _header(path, lines)
    wanted = _wanted(path, header, header_index, required, optional)
    rows = np.array(
        [i for i in range(header_index + 1, len(lines)) if _is_content(lines[i])], dtype=np.int64
    )
    if rows.size == 0:
        raise ImportDataError(path, "no data rows after the header", line=header_index + 1)
    _check_field_counts(path, lines, rows, len(header))
    values = _parse_numbers(path, lines, rows, header, wanted)
    columns = {name: np.ascontiguousarray(values[:, k]) for k, name in enumerate(wanted)}
    return _checked(CsvColumns(path, columns, header, rows + 1))


def _wanted(
    path: Path, header: tuple[str, ...], header_index: int, required: Sequence[str],
    optional: Sequence[str],
) -> list[str]:
    """The columns to parse: all required (else an error at the header line), present optional."""
    missing = [name for name in required if name not in header]
    if missing:
        raise ImportDataError(
            path, f"missing required column(s) {', '.join(map(repr, missing))}; "
            f"header has {', '.join(header)}", line=header_index + 1,
        )
    return list(required) + [n for n in optional if n in header and n not in required]


def _checked(table: CsvColumns) -> CsvColumns:
    """Every wanted cell finite and the time column strictly increasing, else a located error."""
    for name, values in table.columns.items():
        # a NaN or ±inf makes the sum non-finite: one pass without a temporary array; the
        # exact check (a finite sum can also overflow) runs only then
        with np.errstate(over="ignore", invalid="ignore"):
            if np.isfinite(np.add.reduce(values)):
                continue
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise ImportDataError(table.path, f"column {name!r} is not a finite number",
                                  line=int(table.row_lines[bad[0]]))
    if TIME_COLUMN in table.columns:
        _check_increasing(table)
    return table


def _plain_header(path: Path) -> tuple[str, ...] | None:
    """The header names when the file may take the Arrow path, else None.

    Only the first line is read: an ASCII header of distinct, unpadded, unquoted names ended by
    ``\n`` and followed by a data row. Everything after it is Arrow's to judge (see
    :func:`_read_plain`), so a plain file is read once, by Arrow, and never scanned in Python.
    """
    try:
        with open(path, "rb") as stream:
            head = stream.read(_HEADER_PROBE_BYTES)
    except OSError:
        return None  # the tolerant path reports it
    end = head.find(b"\n")
    if end <= 0 or head[end + 1: end + 2] in (b"", b"\n", b"\r") or head.startswith(b"#"):
        return None
    line = head[:end]
    if not line.isascii() or any(line.find(c) >= 0 for c in _NOT_PLAIN):
        return None
    names = tuple(line.decode("ascii").split(","))
    if len(set(names)) != len(names) or not all(n == n.strip() and n for n in names):
        return None
    return names


def _has_text_hazards(raw: bytes) -> bool:
    """True when a file with unparsed (text) columns holds what the tolerant path treats
    specially there: non-ASCII bytes (it checks UTF-8), NUL, or ``#`` (a comment line whose
    first column is not parsed would otherwise be read as a row)."""
    return not raw.isascii() or raw.find(b"\x00") >= 0 or raw.find(b"#") >= 0


def _read_plain(path: Path, required: Sequence[str], optional: Sequence[str]) -> CsvColumns | None:
    """The Arrow path (see the module docstring); None when the file is not plain or Arrow
    refuses it, so that the tolerant path reads it or reports the located error.

    Why one Arrow pass is enough. With quoting off and empty lines not skipped, every line
    after the header must be a row of exactly the header's field count whose parsed cells
    are numbers; a blank line, a comment line, a quoted cell, a truncated row or text in a
    number makes Arrow refuse the file. Rows therefore lie on consecutive lines (their line
    numbers are arithmetic), and no line count or byte scan is needed. Only when the header
    has columns that are not parsed (free text) is the file scanned first, for the bytes the
    tolerant path would treat differently there (:func:`_has_text_hazards`).
    """
    header = _plain_header(path)
    if header is None:
        return None
    wanted = _wanted(path, header, 0, required, optional)
    try:
        if len(wanted) < len(header):
            raw = path.read_bytes()
            if _has_text_hazards(raw):
                return None
            table = _arrow_table(pa.BufferReader(raw), header, wanted)  # zero-copy
        else:
            with pa.memory_map(str(path)) as source:  # no Python copy of the text at all
                table = _arrow_table(source, header, wanted)
    except (pa.ArrowInvalid, pa.ArrowTypeError, OSError):
        return None
    columns = {n: _read_only(_float64_values(table.column(n))) for n in wanted}
    rows = np.arange(table.num_rows, dtype=np.int64) + 2
    return CsvColumns(path, columns, header, rows)


def _arrow_table(source: pa.NativeFile, header: tuple[str, ...], wanted: list[str]) -> pa.Table:
    """Arrow's strict parse of the data rows: the ``wanted`` columns as float64.

    ``column_types`` skips type inference; quoting off and ``ignore_empty_lines=False`` make
    Arrow refuse anything that is not one row per line (see :func:`_read_plain`).
    """
    return pa_csv.read_csv(
        source,  # type: ignore[arg-type]  # the stubs omit NativeFile
        # malloc, whose large blocks go back to the system when freed: the default pool
        # (mimalloc) keeps ≈ 25 MB of freed parse buffers resident after a 45 MB import
        memory_pool=pa.system_memory_pool(),
        # one thread per file: files are read two at a time (importer), and on a busy
        # 2-core machine Arrow's block threads cost more CPU than they save wall time
        read_options=pa_csv.ReadOptions(column_names=list(header), skip_rows=1,
                                        use_threads=False, block_size=_BLOCK_BYTES),
        parse_options=pa_csv.ParseOptions(quote_char=False, newlines_in_values=False,
                                          ignore_empty_lines=False),
        convert_options=pa_csv.ConvertOptions(
            include_columns=wanted, column_types={n: pa.float64() for n in wanted},
            strings_can_be_null=False, quoted_strings_can_be_null=False, null_values=[]),
    )


def _float64_values(column: pa.ChunkedArray[Any]) -> np.ndarray:
    """One float64 column of Arrow's parse as a NumPy array that owns its memory.

    The chunks' value buffers are copied straight into one array (Arrow's own
    ``to_numpy`` imports pandas, ≈ 50 MB resident and half a second, for nothing), and the
    array owns its memory, so the parsed table is released as soon as the file is read.
    The columns are non-null by construction (``null_values=[]``, ``*_can_be_null=False``).
    """
    out = np.empty(len(column), dtype=np.float64)
    start = 0
    for chunk in column.chunks:
        size, values = len(chunk), chunk.buffers()[1]
        if size:
            assert values is not None  # a non-empty float64 chunk has a value buffer
            out[start:start + size] = np.frombuffer(memoryview(values), dtype=np.float64,
                                                    count=size, offset=8 * chunk.offset)
        start += size
    return out


def _read_only(values: np.ndarray) -> np.ndarray:
    """Mark a freshly parsed column read-only, so a SampledLog keeps it without a copy."""
    values.flags.writeable = False
    return values


def _parse_numbers(
    path: Path, lines: list[str], rows: np.ndarray, header: tuple[str, ...], wanted: list[str]
) -> np.ndarray:
    """One vectorised parse of the wanted columns; (rows, columns) finite float64 values."""
    usecols = [header.index(name) for name in wanted]
    try:
        values = np.loadtxt([lines[i] for i in rows.tolist()], delimiter=",", usecols=usecols,
                            ndmin=2, comments=None, dtype=np.float64)
    except ValueError as exc:
        raise _locate_bad_cell(path, lines, rows, usecols, header, exc) from exc
    return values


def _check_field_counts(path: Path, lines: list[str], rows: np.ndarray, n_fields: int) -> None:
    counts = np.fromiter((lines[i].count(",") + 1 for i in rows.tolist()), np.int64, rows.size)
    bad = np.flatnonzero(counts != n_fields)
    if bad.size:
        first = int(bad[0])
        hint = " (truncated row?)" if counts[first] < n_fields else ""
        raise ImportDataError(
            path, f"row has {counts[first]} fields, the header has {n_fields}{hint}",
            line=int(rows[first]) + 1,
        )


def _check_increasing(table: CsvColumns) -> None:
    steps = np.diff(table.columns[TIME_COLUMN])
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise ImportDataError(
            table.path, f"{TIME_COLUMN} does not increase "
            f"({table.columns[TIME_COLUMN][k]!r} after {table.columns[TIME_COLUMN][k - 1]!r})",
            line=int(table.row_lines[k]),
        )
