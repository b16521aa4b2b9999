"""Every workbook a person opens has its header row frozen and its columns sized to their content."""

from __future__ import annotations

import io

from openpyxl import load_workbook
from openpyxl.utils.cell import coordinate_from_string
from openpyxl.worksheet.worksheet import Worksheet

from grader.exports.atomic import workbook_bytes
from grader.exports.gradebook_xlsx import gradebook
from grader.exports.sheets import HEADER_WIDTH, WIDE_TEXT

from .test_exports import BAD, GOOD


def frozen_header(ws: Worksheet) -> int:
    """The row just above the frozen pane, asserting it is a bold header row."""
    assert ws.freeze_panes is not None, f"sheet {ws.title!r} has no frozen header"
    header = coordinate_from_string(ws.freeze_panes)[1] - 1
    cells = [c for c in ws[header] if c.value is not None]
    assert cells and all(c.font.b for c in cells), f"sheet {ws.title!r}: row {header} is not a header"
    return header


def assert_widths_fit(ws: Worksheet, header: int) -> None:
    """Each used column is as wide as its widest short value, and header text wraps past the cap."""
    for column in ws.iter_cols(min_row=header, max_row=ws.max_row):
        values = [c for c in column if c.value is not None and not (c.font.sz or 11) > 11]
        if not values:
            continue
        width = ws.column_dimensions[column[0].column_letter].width
        body = [len(f"{c.value:.3f}") if isinstance(c.value, float) else len(str(c.value))
                for c in values if c.row > header and not c.font.b]
        assert width >= min(max(body, default=0), WIDE_TEXT), (ws.title, column[0].column_letter)
        title = ws.cell(row=header, column=column[0].column)
        if title.value is not None and len(str(title.value)) > HEADER_WIDTH:
            assert title.alignment.wrap_text


def test_gradebook_sheets_freeze_the_header_and_fit_their_columns() -> None:
    wb = load_workbook(io.BytesIO(workbook_bytes(gradebook([GOOD, BAD], ["Kq", "Kpot"]))))
    for ws in wb.worksheets:
        assert frozen_header(ws) == 1
        assert_widths_fit(ws, 1)
    assert wb["grades"].freeze_panes == "B2"  # the submission id stays in view too
    assert wb["grades"].column_dimensions["B"].width >= len("Ada Lovelace; Alan Turing")
