"""A CSV file's text, row by row, for the readers of campaigns and of ring lists: bytes -> UTF-8
text -> rows with their line numbers -> numeric columns, each problem one InputError naming the
file, the 1-based line (the header is line 1) and the column.

Method: docs/methods/campaign_csv.md.
"""

from __future__ import annotations

import csv
import io as _io
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ph_explorer.errors import InputError


def read_bytes(path: Path) -> bytes:
    name = str(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError("no such file", file=name) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a CSV file", file=name) from None
    except OSError as error:
        raise InputError(f"cannot read the file ({error.strerror})", file=name) from None
    if not raw.strip():
        raise InputError("empty file: no header and no rows", file=name, row=1)
    return raw


def decoded_text(raw: bytes, name: str) -> str:
    """The file's text, or an InputError when it is not UTF-8 CSV text."""
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise InputError("not a UTF-8 CSV text file (UTF-16 text: save it as UTF-8 CSV)", file=name, row=1)
    if b"\x00" in raw:
        line = raw[: raw.index(b"\x00")].count(b"\n") + 1
        raise InputError("not a CSV text file (binary data: NUL byte)", file=name, row=line)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = raw[: error.start].count(b"\n") + 1
        raise InputError(f"not a UTF-8 CSV text file (undecodable byte 0x{raw[error.start]:02x})", file=name, row=line) from None


def _is_blank(record: list[str]) -> bool:
    return len(record) <= 1 and not (record and record[0].strip())


def parse_rows(text: str, name: str) -> tuple[list[str], int, list[list[str]], NDArray[np.int64]]:
    """Header, its line, the data rows and their 1-based line numbers; blank lines are skipped."""
    reader = csv.reader(_io.StringIO(text, newline=""), strict=True)
    if '"' not in text:
        # Fast path: without quotes every record is one physical line, so record i is line i + 1.
        try:
            records = list(reader)
        except csv.Error as error:
            raise InputError(f"not valid CSV text ({error})", file=name, row=reader.line_num) from None
        filled = [i for i, r in enumerate(records) if not _is_blank(r)]
        if not filled:
            raise InputError("empty file: no header and no rows", file=name, row=1)
        header_index = filled[0]
        return (
            [cell.strip() for cell in records[header_index]],
            header_index + 1,
            [records[i] for i in filled[1:]],
            np.asarray(filled[1:], dtype=np.int64) + 1,
        )
    # Quoted fields may span lines: ask the reader where each record ends.
    header: list[str] | None = None
    header_line = 1
    rows: list[list[str]] = []
    lines: list[int] = []
    last_end = 0  # line where the previous record ended: a broken record starts on the next one
    try:
        for record in reader:
            last_end = reader.line_num
            if _is_blank(record):
                continue
            if header is None:
                header = [cell.strip() for cell in record]
                header_line = reader.line_num
                continue
            rows.append(record)
            lines.append(reader.line_num)
    except csv.Error as error:
        raise InputError(f"not valid CSV text ({error})", file=name, row=last_end + 1) from None
    if header is None:
        raise InputError("empty file: no header and no rows", file=name, row=1)
    return header, header_line, rows, np.asarray(lines, dtype=np.int64)


def numeric_columns(header: list[str], rows: list[list[str]], lines: NDArray[np.int64], name: str) -> dict[str, NDArray[np.float64]]:
    """Every column as floats, after checking that each row has as many fields as the header."""
    width = len(header)
    lengths = np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows))
    ragged = lengths != width
    if ragged.any():
        i = int(np.argmax(ragged))
        column = header[lengths[i]] if lengths[i] < width else None
        raise InputError(f"{lengths[i]} fields where the header has {width}", file=name, row=int(lines[i]), column=column)
    return {col: numeric_column([r[j] for r in rows], col, lines, name) for j, col in enumerate(header)}


def numeric_column(cells: list[str], column: str, lines: NDArray[np.int64], name: str) -> NDArray[np.float64]:
    """The column as floats; an InputError at the first non-numeric, NaN or infinite value."""
    try:
        values = np.fromiter(map(float, cells), dtype=float, count=len(cells))
    except ValueError:
        # Only on the error path: find the offending cell.
        for cell, line in zip(cells, lines):
            try:
                float(cell)
            except ValueError:
                shown = cell if len(cell) <= 40 else cell[:37] + "..."
                raise InputError(f"not a number: {shown!r}", file=name, row=int(line), column=column) from None
        raise InputError("not a number", file=name, column=column) from None  # pragma: no cover
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"value {cells[i].strip()!r} is not finite", file=name, row=int(lines[i]), column=column)
    return values
