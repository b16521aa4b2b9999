"""CSV tables with ``name [unit]`` headers: read with validation, write canonically."""

from __future__ import annotations

import csv
import gc
import io
import math
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from grader.datasets.schema import TableSpec
from grader.errors import DatasetError, UnitError
from grader.units import dimension_words, parse_unit

MAX_BYTES = 20_000_000
MAX_ROWS = 1_000_000
_HEADER = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*\[(.+)\]\s*$")

Table = dict[str, NDArray[np.float64]]


def other_separator(header: list[str]) -> str | None:
    """``";"`` (or tab) when a header row read with commas is one cell holding that separator."""
    if len(header) == 1:
        return next((sep for sep in (";", "\t") if sep in header[0]), None)
    return None


def _clip(text: str, n: int = 40) -> str:
    """Echo at most ``n`` characters of untrusted text in a message."""
    return text if len(text) <= n else text[:n] + "…"


def _parse_header(path: Path, cells: list[str], spec: TableSpec) -> list[tuple[str, float, str]]:
    """(column name, scale to internal, internal unit) for each header cell."""
    out = []
    wanted = {**spec.required, **spec.optional}
    for col, cell in enumerate(cells, start=1):
        m = _HEADER.match(cell)
        if not m:
            raise DatasetError(f"{path.name}: header cell {col} {_clip(cell)!r} must look like 'name [unit]', e.g. 't [s]'")
        name, unit_text = m.group(1), m.group(2).strip()
        if name not in wanted:
            out.append((name, math.nan, ""))
            continue
        try:
            unit = parse_unit(unit_text, where=f"{path.name}: column {name!r}")
            scale = float((1 * unit).to(wanted[name]).magnitude)
        except UnitError as exc:
            raise DatasetError(str(exc)) from None
        except Exception:
            raise DatasetError(
                f"{path.name}: column {name!r} has unit [{unit_text}], which is {dimension_words(unit)}; "
                f"{name!r} needs {dimension_words(wanted[name])} (e.g. [{wanted[name]}])"
            ) from None
        out.append((name, scale, wanted[name]))
    missing = [c for c in spec.required if c not in {n for n, _, _ in out}]
    if missing:
        raise DatasetError(f"{path.name}: missing column(s) {', '.join(missing)} (header has {_clip(', '.join(cells))})")
    names = [n for n, _, _ in out]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DatasetError(f"{path.name}: column(s) {', '.join(dupes)} appear more than once")
    return out


def read_table(path: Path, spec: TableSpec) -> Table:
    """Read a CSV into internal-unit arrays; raises DatasetError naming file, row and column."""
    return read_rows(path, spec)[0]


def read_rows(path: Path, spec: TableSpec) -> tuple[Table, NDArray[np.int64]]:
    """:func:`read_table`'s arrays and each data row's line number in the file (1-based: the header's line is
    before the first; blank lines are skipped, not counted out)."""
    if path.is_symlink():
        raise DatasetError(f"{path.name}: is a symbolic link; dataset files must be regular files in the folder")
    if path.is_dir():
        raise DatasetError(f"{path.name}: is a folder, not a CSV file")
    if not path.is_file():
        raise DatasetError(f"{path.name}: file not found in {path.parent}")
    if path.stat().st_size > MAX_BYTES:
        raise DatasetError(f"{path.name}: larger than {MAX_BYTES // 1_000_000} MB")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise DatasetError(f"{path.name}: not UTF-8 text") from None
    collecting = gc.isenabled()
    gc.disable()  # a list per row and no cycles: the collector re-walked them, twice the read's time at 1M rows
    try:
        return _table(path, spec, text)
    finally:
        if collecting:
            gc.enable()


def _table(path: Path, spec: TableSpec, text: str) -> tuple[Table, NDArray[np.int64]]:
    """:func:`read_rows` on the file's ``text``."""
    rows = _records(path, text)
    if not rows:
        raise DatasetError(f"{path.name}: empty file")
    if (sep := other_separator(rows[0][1])) is not None:
        raise DatasetError(f"{path.name}: this file uses {sep!r} as separator; save it as CSV with commas (,)")
    header = _parse_header(path, rows[0][1], spec)
    body = rows[1:]
    if len(body) > MAX_ROWS:
        raise DatasetError(f"{path.name}: more than {MAX_ROWS} rows")
    if len(body) < spec.min_rows:
        raise DatasetError(f"{path.name}: {len(body)} data rows, need at least {spec.min_rows}")
    return _convert(path, header, body), np.array([line for line, _ in body], dtype=np.int64)


def _records(path: Path, text: str) -> list[tuple[int, list[str]]]:
    """The file's records that are not blank, each with the line it starts on (1-based; a quoted cell may span
    lines). Strict quoting: a quote left open, or text after a closing quote, is an error naming the record."""
    reader = csv.reader(io.StringIO(text), strict=True)
    out = []
    start = 1
    try:
        for cells in reader:
            # blank lines and rows of empty cells are skipped; the first cell decides almost every row, and testing it
            # alone first reads a million rows in two thirds of the time any(...) takes
            if cells and (cells[0].strip() or "".join(cells).strip()):
                out.append((start, cells))
            start = reader.line_num + 1
    except csv.Error as exc:  # a quote left open, or a cell over the csv module's 131072 characters
        hint = "; a quote (\") opens there and is never closed" if "end of data" in str(exc) else ""
        raise DatasetError(f"{path.name}: row {start} is not readable as CSV ({exc}){hint}") from None
    return out


#: Largest magnitude of a reading in internal units (s, in, V, mA, psi, lbf, in³/s): far beyond any rig, and small
#: enough that sums of squares over a run cannot overflow.
LARGEST = 1e12


def _convert(path: Path, header: list[tuple[str, float, str]], body: list[tuple[int, list[str]]]) -> Table:
    """The (line number in the file, cells) rows as internal-unit arrays: whole columns at once (numpy reads text as
    ``float`` does), and cell by cell where that finds a fault, to name the first faulty cell."""
    n, used = len(header), [j for j, (_, scale, _) in enumerate(header) if not math.isnan(scale)]
    rows = [row for _, row in body]
    if set(map(len, rows)) <= {n}:
        columns = list(zip(*rows)) if rows else [()] * n
        out = {}
        for j in used:
            if "_" in "".join(columns[j]):  # float() reads 1_0 as 10
                break
            try:
                with np.errstate(over="ignore", invalid="ignore"):  # checked below
                    values = np.array(columns[j], dtype=np.float64) * header[j][1]
            except ValueError:
                break
            if not np.isfinite(values).all() or np.max(np.abs(values), initial=0.0) > LARGEST:
                break
            out[header[j][0]] = values
        else:
            return out
    return _convert_cells(path, header, body)


def _convert_cells(path: Path, header: list[tuple[str, float, str]], body: list[tuple[int, list[str]]]) -> Table:
    """:func:`_convert` cell by cell, raising the error that names the first faulty row and cell."""
    data = np.empty((len(body), len(header)))
    for i, (line, row) in enumerate(body):
        if len(row) != len(header):
            raise DatasetError(f"{path.name}: row {line} has {len(row)} cells, header has {len(header)}")
        for j, cell in enumerate(row):
            if math.isnan(header[j][1]):
                continue
            where = f"{path.name}: row {line}, column {header[j][0]!r}: {_clip(cell)!r}"
            try:
                value = float(cell) if "_" not in cell else math.nan  # float() reads 1_0 as 10
            except ValueError:
                value = math.nan
            if math.isnan(value) and "nan" not in cell.lower():
                raise DatasetError(f"{where} is not a number")
            if not math.isfinite(value) or not math.isfinite(value * header[j][1]):
                raise DatasetError(f"{where} is not a finite number" + (
                    f" once converted to {header[j][2]}" if math.isfinite(value) else ""))
            if abs(value * header[j][1]) > LARGEST:
                raise DatasetError(f"{where} is too large for a reading (over {LARGEST:g} {header[j][2]})")
            data[i, j] = value
    return {name: data[:, j] * scale for j, (name, scale, _) in enumerate(header) if not math.isnan(scale)}


def write_table(path: Path, columns: dict[str, tuple[str, NDArray[np.float64]]], *, digits: int = 9) -> None:
    """Write ``{name: (unit, values)}`` as a CSV with ``name [unit]`` headers."""
    names = list(columns)
    arrays = [np.asarray(columns[n][1], dtype=float) for n in names]
    lines = [",".join(f"{n} [{columns[n][0]}]" for n in names)]
    lines += [",".join(f"{v:.{digits}g}" for v in row) for row in zip(*arrays)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
