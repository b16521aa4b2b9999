"""Spreadsheet-injection guard for every text cell the grader writes (XLSX and CSV).

Text that starts with ``= + - @`` TAB or CR can be run as a formula by a spreadsheet
(OWASP "CSV injection"). XLSX (XML 1.0) cannot hold the other C0 control characters at all
(openpyxl refuses the cell): :func:`xlsx_text` shows each as U+FFFD. Only ``str`` values are
touched: numbers stay numbers.
"""

from __future__ import annotations

from typing import Any

from openpyxl import Workbook
from openpyxl.cell.cell import ILLEGAL_CHARACTERS_RE

FORMULA_LEADS = ("=", "+", "-", "@", "\t", "\r")


def risky(value: Any) -> bool:
    """True for text a spreadsheet could read as a formula."""
    return isinstance(value, str) and value.startswith(FORMULA_LEADS)


def csv_text(value: Any) -> Any:
    """A CSV field: risky text gets a leading ``'`` (OWASP); a bare CR becomes LF so the csv
    module (line terminator ``\n``) quotes the field instead of splitting the row; non-text unchanged."""
    if not isinstance(value, str):
        return value
    text = "'" + value if risky(value) else value
    return text.replace("\r\n", "\n").replace("\r", "\n")


def xlsx_text(value: Any) -> Any:
    """An XLSX cell value: control characters XML cannot hold (C0 but TAB, LF, CR) shown as U+FFFD, so that a
    student's or respondent's stray control character is visible in the sheet instead of failing the whole
    workbook; non-text unchanged."""
    return ILLEGAL_CHARACTERS_RE.sub("\ufffd", value) if isinstance(value, str) else value


def literal_text(wb: Workbook) -> Workbook:
    """Make every risky text cell of ``wb`` a plain string cell (never a formula); returns ``wb``."""
    for ws in wb.worksheets:
        for row in ws.iter_rows():
            for cell in row:
                if risky(cell.value):
                    cell.data_type = "s"
    return wb
