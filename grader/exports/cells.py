"""Spreadsheet-injection guard for every text cell the grader writes (XLSX and CSV).

Text that starts with ``= + - @`` TAB or CR can be run as a formula by a spreadsheet
(OWASP "CSV injection"). Only ``str`` values are touched: numbers stay numbers.
"""

from __future__ import annotations

from typing import Any

from openpyxl import Workbook

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


def literal_text(wb: Workbook) -> Workbook:
    """Make every risky text cell of ``wb`` a plain string cell (never a formula); returns ``wb``."""
    for ws in wb.worksheets:
        for row in ws.iter_rows():
            for cell in row:
                if risky(cell.value):
                    cell.data_type = "s"
    return wb
