"""Reading CSV / Parquet tables cell by cell with errors that name file, row and column.

Row numbers in every message are **1-based data rows** (the header is not counted); for
CSV files the message also gives the physical line where the row starts.

What a table may hold (checked here, before any cell is interpreted):

* CSV: UTF-8 text (a leading byte-order mark is ignored), no NUL bytes, every non-blank
  row with exactly as many fields as the header, every field at most
  :data:`MAX_FIELD_CHARS` characters, unique non-empty column names.
* Parquet: columns of integers, floats, booleans or text (other types are read as their
  text and rejected where a number is expected); boolean columns are never numbers.
* Memory: the parsed table is estimated from the file (CSV: its size; Parquet: its
  declared uncompressed size and row count) and refused past
  :func:`are_stats.inputs.memory_limit` before it is read.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from are_stats.inputs import Described, InputError, check_memory

__all__ = [
    "MAX_EXACT_INT",
    "MAX_FIELD_CHARS",
    "RawTable",
    "frame_table",
    "read_raw_table",
    "table_error",
]

_INT_TEXT = re.compile(r"^[+-]?[0-9]+$")
_NAN_WORDS = frozenset({"nan", "+nan", "-nan", "na", "n/a", "null", "none", "<na>"})
#: Longest CSV field accepted (characters): Python's ``csv`` default of 128 KiB.
MAX_FIELD_CHARS = csv.field_size_limit()
#: Largest integer cell accepted (2**53: integers above it are not exact in float64).
MAX_EXACT_INT = 2**53
# Bytes of memory per byte of CSV file while parsing (Python strings + object arrays).
_CSV_BYTES_PER_BYTE = 12
# Bytes of memory per Parquet cell after reading (float64 + mask, or an object pointer).
_PARQUET_BYTES_PER_CELL = 16


@dataclass(frozen=True)
class RawTable:
    """A table as read from disk, before any parsing of its cells.

    Each column is either an object array of stripped strings (CSV, or Parquet text,
    integer and boolean columns; ``""`` is an empty cell) or a float array with a null
    mask (Parquet floating-point columns). ``bools`` names the columns that were boolean
    in the file (their strings are ``"True"`` / ``"False"``): they are never read as
    numbers or identifiers.
    """

    path: Path
    kind: str
    n_rows: int
    strings: dict[str, np.ndarray]
    numbers: dict[str, tuple[np.ndarray, np.ndarray]]
    rows: np.ndarray | None = None  # original 0-based row of each row (after a subset)
    lines: np.ndarray | None = None  # physical 1-based line where each row starts (CSV)
    bools: frozenset[str] = frozenset()

    @property
    def columns(self) -> list[str]:
        return [*self.strings, *self.numbers]

    def where(self, row0: int) -> str:
        """Human position of 0-based data row ``row0``."""
        r = (row0 if self.rows is None else int(self.rows[row0])) + 1
        if self.kind != "csv":
            return f"row {r}"
        line = r + 1 if self.lines is None else int(self.lines[r - 1])
        return f"row {r} (line {line})"

    def subset(self, keep: np.ndarray) -> RawTable:
        """Rows ``keep`` (bool mask); messages still name the original rows."""
        rows = np.flatnonzero(keep) if self.rows is None else self.rows[keep]
        return RawTable(
            self.path,
            self.kind,
            int(keep.sum()),
            {c: s[keep] for c, s in self.strings.items()},
            {c: (v[keep], nl[keep]) for c, (v, nl) in self.numbers.items()},
            rows,
            self.lines,
            self.bools,
        )

    def error(self, row0: int, column: str, expected: str, got: object) -> ValueError:
        return table_error(self.path, self.where(row0), column, expected, got)

    def require(self, required: list[str], what: str) -> None:
        missing = [c for c in required if c not in self.columns]
        if missing:
            raise ValueError(
                f"{self.path}: missing column(s) {', '.join(repr(c) for c in missing)}: "
                f"expected a {what} with columns {', '.join(required)}, "
                f"got columns {', '.join(repr(c) for c in self.columns) or '(none)'}"
            )

    def _no_bools(self, column: str, expected: str) -> None:
        if column in self.bools:
            s = self.strings[column]
            hit = np.isin(s, ["True", "False"])
            i = int(np.argmax(hit)) if hit.any() else 0
            raise self.error(i, column, expected, f"a boolean ({s[i] or 'null'}, boolean column)")

    # ---- cell parsers -------------------------------------------------------------------

    def ids(self, column: str, *, allow_empty: bool = False) -> np.ndarray:
        """Identifiers as strings (numbers are formatted without a trailing .0).

        With ``allow_empty`` an empty cell is ``""``; otherwise it is an error.
        """
        expected = "a non-empty identifier" + (" or an empty cell" if allow_empty else "")
        self._no_bools(column, f"{expected} (text or integer)")
        if column in self.strings:
            out = self.strings[column]
            bad = out == ""
            if bad.any() and not allow_empty:
                i = int(np.argmax(bad))
                raise self.error(i, column, expected, "an empty cell")
            return out.astype(object)
        vals, null = self.numbers[column]
        if null.any() and not allow_empty:
            raise self.error(int(np.argmax(null)), column, expected, "an empty cell")
        bad = ~np.isfinite(vals) & ~null
        if bad.any():
            i = int(np.argmax(bad))
            raise self.error(i, column, expected, repr(float(vals[i])))
        integral = vals == np.round(vals)
        return np.array(
            [
                "" if n else str(int(v)) if ok else repr(float(v))
                for v, ok, n in zip(vals, integral, null, strict=True)
            ],
            dtype=object,
        )

    def labels(self, column: str) -> np.ndarray:
        """Free text; empty cells become ``""``."""
        if column in self.strings:
            return self.strings[column].astype(object)
        vals, null = self.numbers[column]
        return np.array(
            ["" if n else _num(v) for v, n in zip(vals, null, strict=True)], dtype=object
        )

    def class_labels(self, column: str) -> np.ndarray:
        """Class labels: free text without commas (fit files list them comma-separated)."""
        out = self.labels(column)
        comma = np.array([("," in v) for v in out], dtype=bool)
        if comma.any():
            i = int(np.argmax(comma))
            raise self.error(i, column, "a class label without commas", out[i])
        return out

    def floats(self, column: str, *, allow_empty: bool) -> tuple[np.ndarray, np.ndarray]:
        """Finite numbers; returns ``(values, empty)`` with NaN where the cell is empty."""
        self._no_bools(column, "a number")
        if column in self.strings:
            s = self.strings[column]
            empty = s == ""
            vals = pd.to_numeric(
                pd.Series(np.where(empty, "0", s), dtype=object), errors="coerce"
            ).to_numpy(dtype=float, copy=True)
            lower = np.char.lower(s.astype(str))
            nan_word = np.isin(lower, list(_NAN_WORDS))
            bad = np.isnan(vals) & ~nan_word
            if bad.any():
                i = int(np.argmax(bad))
                raise self.error(i, column, "a number", _short(s[i]))
            if nan_word.any():
                i = int(np.argmax(nan_word))
                raise self.error(
                    i,
                    column,
                    "a finite number (leave the cell empty for a missing value)",
                    f"NaN ({s[i]!r})",
                )
        else:
            vals, empty = self.numbers[column]
            vals = vals.copy()
            nan = np.isnan(vals) & ~empty
            if nan.any():
                i = int(np.argmax(nan))
                raise self.error(
                    i, column, "a finite number (leave the cell empty for a missing value)", "NaN"
                )
        inf = np.isinf(vals) & ~empty
        if inf.any():
            i = int(np.argmax(inf))
            raise self.error(i, column, "a finite number", repr(float(vals[i])))
        if not allow_empty and empty.any():
            i = int(np.argmax(empty))
            raise self.error(i, column, "a number", "an empty cell")
        vals[empty] = np.nan
        return vals, empty

    def nonneg_ints(
        self, column: str, *, allow_empty: bool, hi: int = MAX_EXACT_INT
    ) -> tuple[np.ndarray, np.ndarray]:
        """Non-negative integers up to ``hi``; returns ``(values, empty)`` with -1 where empty.

        The range is checked on the parsed number *before* the cast to int64, so a cell
        like ``1e30`` is an error, never a wrapped-around integer.
        """
        vals, empty = self.floats(column, allow_empty=allow_empty)
        if column in self.strings:
            # integer text near or above 2**53 is compared exactly, not through float64
            # (9007199254740993 parses to the float 2**53)
            s = self.strings[column]
            for i in np.flatnonzero(~empty & (np.abs(vals) >= 2.0**52)):
                text = s[i].replace("_", "")
                if _INT_TEXT.match(text) and int(text) > hi:
                    raise self.error(
                        i, column, f"a non-negative integer <= {hi}", f"{_short(s[i])} (too large)"
                    )
        neg = (vals < 0) & ~empty
        if neg.any():
            i = int(np.argmax(neg))
            raise self.error(i, column, "a non-negative integer", _num(vals[i]))
        big = (vals > hi) & ~empty
        if big.any():
            i = int(np.argmax(big))
            raise self.error(
                i, column, f"a non-negative integer <= {hi}", f"{_num(vals[i])} (too large)"
            )
        frac = (vals != np.round(vals)) & ~empty
        if frac.any():
            i = int(np.argmax(frac))
            raise self.error(i, column, "a non-negative integer", _num(vals[i]))
        out = np.where(empty, -1, vals).astype(np.int64)
        return out, empty


def frame_table(frame: object, source: str, what: str) -> RawTable:
    """A :class:`RawTable` of an in-memory DataFrame (NaN / None / NA cells are empty).

    Numeric columns become numbers, boolean columns are marked boolean (never numbers),
    everything else becomes text.
    """
    if not isinstance(frame, pd.DataFrame):
        raise InputError(
            source, "", f"a {what} as a pandas DataFrame", Described(type(frame).__name__)
        )
    names = [str(c) for c in frame.columns]
    dup = sorted({c for c in names if names.count(c) > 1})
    if dup:
        raise InputError(source, "columns", "unique column names", Described(f"{dup} repeated"))
    strings: dict[str, np.ndarray] = {}
    numbers: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    bools: set[str] = set()
    for j, c in enumerate(names):
        col = frame.iloc[:, j]
        if pd.api.types.is_bool_dtype(col):
            bools.add(c)
        if (
            pd.api.types.is_numeric_dtype(col)
            and not pd.api.types.is_bool_dtype(col)
            and not pd.api.types.is_complex_dtype(col)
        ):
            v = col.to_numpy(dtype=np.float64, na_value=np.nan)
            numbers[c] = (np.where(np.isnan(v), 0.0, v), np.isnan(v))
        else:
            cells = col.to_numpy(dtype=object)
            if any(isinstance(x, bool | np.bool_) for x in cells):
                bools.add(c)
            strings[c] = np.array(
                ["" if _is_missing(x) else str(x).strip() for x in cells],
                dtype=object,
            )
    return RawTable(Path(source), "frame", len(frame), strings, numbers, bools=frozenset(bools))


def _is_missing(x: object) -> bool:
    return x is None or x is pd.NA or x is pd.NaT or (isinstance(x, float) and math.isnan(x))


def _num(v: float) -> str:
    """``3.0 -> '3'``, ``2.5 -> '2.5'``, ``inf -> 'inf'``, ``1e30 -> '1e+30'``."""
    v = float(v)
    return repr(int(v)) if math.isfinite(v) and v == round(v) and abs(v) < 1e16 else repr(v)


def _short(text: str, limit: int = 60) -> str:
    """``repr`` of a cell, shortened so a huge cell cannot flood the message."""
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}... ({len(text)} characters)"


def table_error(
    path: Path | str, where: str, column: str, expected: str, got: object
) -> ValueError:
    """``InputError("<file>: <where>, column '<col>': expected ..., got ...")``.

    ``got`` is printed as given (callers pass a description such as ``"'abc'"``).
    """
    return InputError(path, f"{where}, column {column!r}", expected, Described(str(got)))


def _check_memory(n_bytes: int, what: str, p: Path) -> None:
    check_memory(int(n_bytes), what, str(p))


def read_raw_table(path: str | os.PathLike, what: str) -> RawTable:
    """Read a CSV (``.csv``, ``.txt``, ``.tsv``) or Parquet (``.parquet``, ``.pq``) table.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is empty, has no data rows, cannot be parsed, or would need more
        memory than :func:`are_stats.inputs.memory_limit` (``LimitError``).
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such {what} file")
    if p.is_dir():
        raise ValueError(f"{p}: expected a {what} file (CSV or Parquet), got a directory")
    if not p.is_file():
        raise ValueError(f"{p}: expected a {what} file (CSV or Parquet), got a special file")
    suffix = p.suffix.lower()
    if suffix in (".parquet", ".pq"):
        table = _read_parquet(p, what)
    elif suffix in (".csv", ".txt", ".tsv"):
        table = _read_csv(p, what, sep="\t" if suffix == ".tsv" else ",")
    else:
        raise ValueError(
            f"{p}: expected a {what} file ending in .csv, .tsv, .txt, .parquet or .pq, "
            f"got suffix {p.suffix!r}"
        )
    if table.n_rows == 0:
        raise ValueError(
            f"{p}: empty {what}: expected a header and at least one data row, got no data rows"
        )
    return table


def _decode(p: Path, what: str, data: bytes) -> str:
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise ValueError(
            f"{p}: line {line}: expected a {what} in UTF-8 text, got byte "
            f"0x{data[err.start]:02x} at byte offset {err.start} (not UTF-8)"
        ) from None
    nul = text.find("\x00")
    if nul >= 0:
        line = text.count("\n", 0, nul) + 1
        raise ValueError(
            f"{p}: line {line}: expected a {what} in CSV text, got a NUL byte (binary data)"
        )
    return text


def _read_csv(p: Path, what: str, sep: str) -> RawTable:
    size = p.stat().st_size
    _check_memory(size * _CSV_BYTES_PER_BYTE, f"parsing the {what}", p)
    data = p.read_bytes()
    if not data.strip() or data.strip() == b"\xef\xbb\xbf":
        raise ValueError(
            f"{p}: empty file: expected a {what} with a header row and at least "
            "one data row, got no content"
        )
    text = _decode(p, what, data)
    del data
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=sep)
    records: list[list[str]] = []
    lines: list[int] = []
    header: list[str] | None = None
    start = 1
    try:
        for rec in reader:
            if header is None:
                header = [h.strip() for h in rec]
                start = reader.line_num + 1
                continue
            records.append(rec)
            lines.append(start)
            start = reader.line_num + 1
    except csv.Error as err:
        line = reader.line_num
        msg = str(err)
        if "field larger than field limit" in msg:
            raise ValueError(
                f"{p}: line {line}: expected fields of at most {MAX_FIELD_CHARS} characters, "
                "got a longer field (an unbalanced quote can also cause this)"
            ) from None
        raise ValueError(
            f"{p}: line {line}: expected a {what} in CSV format, got a parse error: {msg}"
        ) from None
    del text
    if header is None or not any(header):
        raise ValueError(f"{p}: line 1: expected a header row of column names, got an empty line")
    empty_names = [j + 1 for j, h in enumerate(header) if not h]
    if empty_names:
        raise ValueError(
            f"{p}: header: expected a non-empty name for every column, got an empty name "
            f"for field {empty_names[0]} of {len(header)} (a trailing {sep!r}?)"
        )
    dup = sorted({c for c in header if header.count(c) > 1})
    if dup:
        raise ValueError(f"{p}: header: expected unique column names, got {dup} repeated")
    k = len(header)
    cols: list[list[str]] = [[] for _ in range(k)]
    for r, rec in enumerate(records, start=1):
        fields = [f.strip() for f in rec]
        if len(fields) != k:
            if not any(fields):  # a blank line or a line of separators only: a blank row
                fields = [""] * k
            else:
                extra = ""
                if len(fields) > k:
                    extra = " (more fields than the header: an unquoted separator?)"
                raise ValueError(
                    f"{p}: row {r} (line {lines[r - 1]}): expected {k} fields "
                    f"({', '.join(header)}), got {len(fields)}{extra}"
                )
        for j in range(k):
            cols[j].append(fields[j])
    strings = {c: np.array(cols[j], dtype=object) for j, c in enumerate(header)}
    return RawTable(p, "csv", len(records), strings, {}, lines=np.asarray(lines, np.int64))


def _read_parquet(p: Path, what: str) -> RawTable:
    # lazy: pyarrow.parquet adds 0.06 s CPU to `import are_stats.logs`
    import pyarrow.parquet as pq

    if p.stat().st_size == 0:
        raise ValueError(f"{p}: empty file: expected a {what} in Parquet format, got 0 bytes")
    try:
        meta = pq.ParquetFile(p).metadata
        declared = sum(meta.row_group(i).total_byte_size for i in range(meta.num_row_groups))
        _check_memory(
            max(declared, meta.num_rows * max(meta.num_columns, 1) * _PARQUET_BYTES_PER_CELL),
            f"reading the {what} ({meta.num_rows} rows x {meta.num_columns} columns)",
            p,
        )
        t = pq.read_table(p)
    except (pa.ArrowException, OSError) as err:
        raise ValueError(
            f"{p}: expected a {what} in Parquet format, got an unreadable file: {err}"
        ) from None
    strings: dict[str, np.ndarray] = {}
    numbers: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    bools: set[str] = set()
    names = [str(n) for n in t.column_names]
    dup = sorted({c for c in names if names.count(c) > 1})
    if dup:
        raise ValueError(f"{p}: schema: expected unique column names, got {dup} repeated")
    for j, name in enumerate(names):
        col = t.column(j).combine_chunks() if t.num_rows else t.column(j)
        typ = t.schema.field(j).type
        exact = pa.types.is_integer(typ) and _within_float_exact(col)
        if pa.types.is_floating(typ) or exact:
            null = np.asarray(col.is_null().to_numpy(zero_copy_only=False), dtype=bool)
            filled = pc.fill_null(pc.cast(col, pa.float64()), 0.0)
            numbers[name] = (np.asarray(filled.to_numpy(zero_copy_only=False), float), null)
        else:
            # integers past 2**53 as exact decimal text (no rounding through float64),
            # booleans and everything else as text; the RawTable parsers interpret them
            if pa.types.is_boolean(typ):
                bools.add(name)
            vals = col.to_pylist()
            strings[name] = np.array(
                ["" if v is None else str(v).strip() for v in vals], dtype=object
            )
    return RawTable(p, "parquet", t.num_rows, strings, numbers, bools=frozenset(bools))


def _within_float_exact(col: pa.Array | pa.ChunkedArray) -> bool:
    """Whether every integer of the Arrow column is exact in float64 (|v| <= 2**53)."""
    if col.null_count == len(col):
        return True
    mm = pc.min_max(col)
    return -MAX_EXACT_INT <= mm["min"].as_py() and mm["max"].as_py() <= MAX_EXACT_INT
