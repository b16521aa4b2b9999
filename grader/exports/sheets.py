"""XLSX layout shared by every workbook the grader writes: column widths from the content and a
frozen, wrapped header row (openpyxl; widths in characters of the default font)."""

from __future__ import annotations

from collections.abc import Callable

from openpyxl.cell.cell import Cell
from openpyxl.styles import Alignment, Font
from openpyxl.worksheet.worksheet import Worksheet

BOLD = Font(bold=True)
#: Header cells wider than this wrap onto several lines [characters].
HEADER_WIDTH = 16
#: Text longer than this overflows to the right instead of widening its column [characters].
WIDE_TEXT = 90
MIN_WIDTH = 8


def shown_width(value: object) -> int:
    """Characters a cell shows: numbers as formatted (3 decimals), text as is."""
    if isinstance(value, float):
        return len(f"{value:.3f}")
    return len(str(value))


def fit_columns(sheet: Worksheet, skip: Callable[[Cell], bool] = lambda cell: False) -> None:
    """Width of each column from its values and its (bold, capped) headers; ``skip`` cells are ignored."""
    for column in sheet.columns:
        widths = [min(shown_width(c.value), HEADER_WIDTH) if c.font.b else shown_width(c.value)
                  for c in column if c.value is not None and not skip(c)]
        longest = max((w for w in widths if w <= WIDE_TEXT), default=MIN_WIDTH)
        sheet.column_dimensions[column[0].column_letter].width = min(max(MIN_WIDTH, longest + 2), WIDE_TEXT)


def header_row(sheet: Worksheet, row: int = 1, *, freeze_column: str = "A") -> None:
    """Make ``row`` a bold, wrapped header and freeze the sheet below it (and left of ``freeze_column``)."""
    for cell in sheet[row]:
        cell.font, cell.alignment = BOLD, Alignment(wrap_text=True, vertical="bottom")
    sheet.freeze_panes = f"{freeze_column}{row + 1}"
