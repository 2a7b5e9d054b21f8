"""Reading CSV / Parquet tables cell by cell with errors that name file, row and column.

Row numbers in every message are **1-based data rows** (the header is not counted); for
CSV files the message also gives the physical line (``line = row + 1``).
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["RawTable", "read_raw_table", "table_error"]

_NAN_WORDS = frozenset({"nan", "+nan", "-nan", "na", "n/a", "null", "none", "<na>"})


@dataclass(frozen=True)
class RawTable:
    """A table as read from disk, before any parsing of its cells.

    Each column is either an object array of stripped strings (CSV, or Parquet string
    columns; ``""`` is an empty cell) or a float array with a null mask (Parquet numeric
    columns).
    """

    path: Path
    kind: str
    n_rows: int
    strings: dict[str, np.ndarray]
    numbers: dict[str, tuple[np.ndarray, np.ndarray]]
    rows: np.ndarray | None = None  # original 0-based row of each row (after a subset)

    @property
    def columns(self) -> list[str]:
        return [*self.strings, *self.numbers]

    def where(self, row0: int) -> str:
        """Human position of 0-based data row ``row0``."""
        r = (row0 if self.rows is None else int(self.rows[row0])) + 1
        return f"row {r} (line {r + 1})" if self.kind == "csv" else f"row {r}"

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

    # ---- cell parsers -------------------------------------------------------------------

    def ids(self, column: str) -> np.ndarray:
        """Non-empty identifiers as strings (numbers are formatted without a trailing .0)."""
        if column in self.strings:
            out = self.strings[column]
            bad = out == ""
            if bad.any():
                i = int(np.argmax(bad))
                raise self.error(i, column, "a non-empty identifier", "an empty cell")
            return out.astype(object)
        vals, null = self.numbers[column]
        if null.any():
            raise self.error(
                int(np.argmax(null)), column, "a non-empty identifier", "an empty cell"
            )
        if not np.isfinite(vals).all():
            i = int(np.argmax(~np.isfinite(vals)))
            raise self.error(i, column, "a non-empty identifier", repr(float(vals[i])))
        integral = vals == np.round(vals)
        return np.array(
            [str(int(v)) if ok else repr(float(v)) for v, ok in zip(vals, integral, strict=True)],
            dtype=object,
        )

    def labels(self, column: str) -> np.ndarray:
        """Free text; empty cells become ``""``."""
        if column in self.strings:
            return self.strings[column].astype(object)
        vals, null = self.numbers[column]
        return np.array(
            [
                "" if n else (str(int(v)) if v == np.round(v) else repr(float(v)))
                for v, n in zip(vals, null, strict=True)
            ],
            dtype=object,
        )

    def floats(self, column: str, *, allow_empty: bool) -> tuple[np.ndarray, np.ndarray]:
        """Finite numbers; returns ``(values, empty)`` with NaN where the cell is empty."""
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
                raise self.error(i, column, "a number", repr(s[i]))
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

    def nonneg_ints(self, column: str, *, allow_empty: bool) -> tuple[np.ndarray, np.ndarray]:
        """Non-negative integers; returns ``(values, empty)`` with -1 where empty."""
        vals, empty = self.floats(column, allow_empty=allow_empty)
        neg = (vals < 0) & ~empty
        if neg.any():
            i = int(np.argmax(neg))
            raise self.error(i, column, "a non-negative integer", _num(vals[i]))
        frac = (vals != np.round(vals)) & ~empty
        if frac.any():
            i = int(np.argmax(frac))
            raise self.error(i, column, "a non-negative integer", _num(vals[i]))
        out = np.where(empty, -1, vals).astype(np.int64)
        return out, empty


def _num(v: float) -> str:
    return repr(int(v)) if float(v) == round(float(v)) else repr(float(v))


def table_error(
    path: Path | str, where: str, column: str, expected: str, got: object
) -> ValueError:
    """``ValueError("<file>: <where>, column '<col>': expected ..., got ...")``."""
    return ValueError(f"{path}: {where}, column {column!r}: expected {expected}, got {got}")


def read_raw_table(path: str | os.PathLike, what: str) -> RawTable:
    """Read a CSV (``.csv``, ``.txt``, ``.tsv``) or Parquet (``.parquet``, ``.pq``) table.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is empty, has no data rows, or cannot be parsed.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such {what} file")
    if p.is_dir():
        raise ValueError(f"{p}: expected a {what} file (CSV or Parquet), got a directory")
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


def _read_csv(p: Path, what: str, sep: str) -> RawTable:
    if p.stat().st_size == 0 or not p.read_bytes().strip():
        raise ValueError(
            f"{p}: empty file: expected a {what} with a header row and at least "
            "one data row, got no content"
        )
    try:
        df = pd.read_csv(
            p,
            sep=sep,
            dtype=str,
            keep_default_na=False,
            na_filter=False,
            skip_blank_lines=False,
            comment=None,
        )
    except (pd.errors.ParserError, UnicodeDecodeError) as err:
        raise ValueError(
            f"{p}: expected a {what} in CSV format, got a parse error: {str(err).strip()}"
        ) from None
    with p.open(newline="", encoding="utf-8", errors="replace") as fh:
        reader = csv.reader(fh, delimiter=sep)
        header = [h.strip() for h in next(reader, [])]
        for r, rec in enumerate(reader, start=1):
            if 0 < len(rec) < len(header) and any(f.strip() for f in rec):
                raise ValueError(
                    f"{p}: row {r} (line {reader.line_num}): expected {len(header)} fields "
                    f"({', '.join(header)}), got {len(rec)}"
                )
    dup = sorted({c for c in header if header.count(c) > 1})
    if dup:
        raise ValueError(f"{p}: header: expected unique column names, got {dup} repeated")
    cols = header if len(header) == df.shape[1] else [str(c).strip() for c in df.columns]
    strings = {
        c: np.asarray(df.iloc[:, j].to_numpy(dtype=object), dtype=object)
        for j, c in enumerate(cols)
    }
    strings = {c: np.array([str(v).strip() for v in a], dtype=object) for c, a in strings.items()}
    return RawTable(p, "csv", len(df), strings, {})


def _read_parquet(p: Path, what: str) -> RawTable:
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    if p.stat().st_size == 0:
        raise ValueError(f"{p}: empty file: expected a {what} in Parquet format, got 0 bytes")
    try:
        t = pq.read_table(p)
    except (pa.ArrowInvalid, OSError) as err:
        raise ValueError(
            f"{p}: expected a {what} in Parquet format, got an unreadable file: {err}"
        ) from None
    strings: dict[str, np.ndarray] = {}
    numbers: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in t.column_names:
        col = t.column(name).combine_chunks() if t.num_rows else t.column(name)
        typ = t.schema.field(name).type
        if pa.types.is_integer(typ) or pa.types.is_floating(typ) or pa.types.is_boolean(typ):
            null = np.asarray(col.is_null().to_numpy(zero_copy_only=False), dtype=bool)
            filled = pc.fill_null(pc.cast(col, pa.float64()), 0.0)
            numbers[name] = (np.asarray(filled.to_numpy(zero_copy_only=False), float), null)
        else:
            vals = col.to_pylist()
            strings[name] = np.array(
                ["" if v is None else str(v).strip() for v in vals], dtype=object
            )
    return RawTable(p, "parquet", t.num_rows, strings, numbers)
