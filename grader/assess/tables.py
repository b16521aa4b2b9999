"""Read a CSV or XLSX file into rows of strings, with spreadsheet row numbers.

Both readers hand back the cells as text exactly as a person would read them,
so that later checks ("is this 1-5?") see what the instructor sees. Any parse
failure becomes an :class:`AssessmentError` naming the file.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

from grader.datasets.csvio import other_separator
from grader.errors import AssessmentError

CSV_SUFFIXES = frozenset({".csv", ".txt"})
XLSX_SUFFIXES = frozenset({".xlsx", ".xlsm"})


@dataclass(frozen=True)
class Table:
    """A file's cells as text; ``rows[i]`` is spreadsheet row ``i + 1``."""

    name: str
    rows: tuple[tuple[str, ...], ...]


def column_letter(index: int) -> str:
    """Spreadsheet column letter of a 0-based column index (0 -> A, 26 -> AA)."""
    letters = ""
    index += 1
    while index:
        index, rest = divmod(index - 1, 26)
        letters = chr(ord("A") + rest) + letters
    return letters


def read_table(path: Path) -> Table:
    """Read ``path`` (CSV or XLSX); raise if unreadable or empty."""
    path = Path(path)
    suffix = path.suffix.lower()
    name = str(path)
    if suffix in CSV_SUFFIXES:
        raw = _read_csv(path)
    elif suffix in XLSX_SUFFIXES:
        raw, sheet = _read_xlsx(path)
        name = name if sheet is None else f"{path} (sheet {sheet!r})"
    else:
        raise AssessmentError(f"{path}: unsupported file type {suffix or '(none)'}; use .csv or .xlsx")
    rows = _trim(raw)
    if not rows:
        raise AssessmentError(f"{name}: the file is empty")
    return Table(name=name, rows=rows)


def _read_csv(path: Path) -> list[list[str]]:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise AssessmentError(f"{path}: cannot read the file ({exc.strerror})") from exc
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("cp1252", errors="replace")
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[list[str]] = []
    try:
        rows.extend(list(row) for row in reader)
    except csv.Error as exc:  # the reader's line_num: the file line where the bad record ends
        raise AssessmentError(f"{path}: not a valid CSV file at line {reader.line_num} ({exc})") from exc
    if rows and (sep := other_separator(rows[0])) is not None:
        raise AssessmentError(f"{path}: this file uses {sep!r} as separator; save it as CSV with commas (,)")
    return rows


MAX_XLSX_BYTES = 20_000_000  # the workbook file
MAX_XLSX_UNZIPPED = 200_000_000  # what it unpacks to
MAX_ROWS = 20_000
MAX_COLS = 500


def _read_xlsx(path: Path) -> tuple[list[list[str]], str | None]:
    """The cells of the sheet to read as text, bounded (file size, unpacked size, rows and columns), and its name
    where the workbook has other sheets (else None). The sheet to read is the active one, or the only visible one:
    never a hidden sheet (an old copy kept out of sight was once read instead of the visible data)."""
    from openpyxl import load_workbook
    from openpyxl.utils.exceptions import InvalidFileException

    try:
        size = path.stat().st_size
        if size > MAX_XLSX_BYTES:
            raise AssessmentError(f"{path}: file is {size / 1e6:.1f} MB; the limit is {MAX_XLSX_BYTES / 1e6:g} MB")
        with zipfile.ZipFile(path) as archive:
            if sum(i.file_size for i in archive.infolist()) > MAX_XLSX_UNZIPPED:
                raise AssessmentError(f"{path}: workbook unpacks to more than {MAX_XLSX_UNZIPPED / 1e6:g} MB")
        workbook = load_workbook(path, read_only=True, data_only=True)
        try:
            sheet = _sheet_to_read(workbook)
            rows: list[list[str]] = []
            # one row and one column past the caps, to tell "exactly at the limit" from "beyond it"
            for n, row in enumerate(sheet.iter_rows(max_row=MAX_ROWS + 1, max_col=MAX_COLS + 1, values_only=True)):
                cells = [_cell_text(value) for value in row]
                while cells and not cells[-1]:
                    cells.pop()  # trailing empty cells (a far-away stray cell pads every row)
                if len(cells) > MAX_COLS:
                    raise AssessmentError(f"{path}: more than {MAX_COLS} columns in row {n + 1}")
                if n >= MAX_ROWS and cells:
                    raise AssessmentError(f"{path}: more than {MAX_ROWS} rows")
                rows.append(cells)
            _refuse_unsaved_formulas(path, sheet, rows)
            return rows[:MAX_ROWS], sheet.title if len(workbook.worksheets) > 1 else None
        finally:
            workbook.close()
    except (OSError, zipfile.BadZipFile, InvalidFileException, ElementTree.ParseError,
            KeyError, IndexError, TypeError, ValueError) as exc:
        raise AssessmentError(f"{path}: not a readable XLSX workbook ({exc})") from exc


#: A cell formula in a sheet's XML (``<f>…</f>``, ``<f t="shared" …>``; not a data validation's ``<formula1>``).
_FORMULA = re.compile(rb"<f[ >/]")


def _refuse_unsaved_formulas(path: Path, sheet: Any, rows: list[list[str]]) -> None:
    """A formula cell without the value its spreadsheet saved reads as empty: a missing answer, silently. Refused,
    naming the first such cell (files Excel or LibreOffice saved always hold the value; generated ones may not).
    The workbook is read a second time, with the formulas, only where a sheet's XML holds one."""
    from openpyxl import load_workbook

    with zipfile.ZipFile(path) as archive:
        if not any(_FORMULA.search(archive.read(n)) for n in archive.namelist()
                   if n.startswith("xl/worksheets/") and n.endswith(".xml")):
            return
    formulas = load_workbook(path, read_only=True, data_only=False)
    try:
        for n, row in enumerate(formulas[sheet.title].iter_rows(max_row=len(rows), max_col=MAX_COLS)):
            for j, cell in enumerate(row):
                text = cell.value
                if isinstance(text, str) and text.startswith("=") and not (j < len(rows[n]) and rows[n][j]):
                    raise AssessmentError(f"{path}: cell {cell.coordinate} holds a formula ({text[:40]}) with no saved "
                                          "value; open and save the file in Excel or LibreOffice, or paste the values")
    finally:
        formulas.close()


def _sheet_to_read(workbook: Any) -> Any:
    """The active sheet where it is visible (Excel and LibreOffice never save a hidden one active), else the first
    visible one."""
    active = workbook.active
    if active is not None and active.sheet_state == "visible":
        return active
    return next((ws for ws in workbook.worksheets if ws.sheet_state == "visible"), active)


def _cell_text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "TRUE" if value else "FALSE"
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    if isinstance(value, dt.datetime):
        return value.isoformat(sep=" ")
    return str(value)


def _trim(rows: list[list[str]]) -> tuple[tuple[str, ...], ...]:
    """Drop trailing blank rows; pad every row to the same width."""
    while rows and not any(cell.strip() for cell in rows[-1]):
        rows.pop()
    width = max((len(row) for row in rows), default=0)
    return tuple(tuple(row) + ("",) * (width - len(row)) for row in rows)
