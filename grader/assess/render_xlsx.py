"""XLSX reports (openpyxl): a sheet per section, typed cells, charts embedded as images."""

from __future__ import annotations

import io
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from openpyxl import Workbook
from openpyxl.cell.cell import Cell
from openpyxl.drawing.image import Image
from openpyxl.styles import Alignment, Font
from openpyxl.worksheet.worksheet import Worksheet

from grader.assess.exam_report import informative_heading
from grader.assess.schemas import ExamReport, SurveyReport, round6
from grader.assess.views import (
    View,
    exam_views,
    survey_comparisons,
    survey_hours,
    survey_most_useful,
    survey_summary,
)
from grader.exports.atomic import workbook_bytes
from grader.exports.cells import literal_text, xlsx_text
from grader.exports.sheets import fit_columns

_FORMATS = {"int": "0", "pct": "0.0", "num": "0.000", "p": "0.0000", "text": "@"}
_BOLD = Font(bold=True)
_TITLE = Font(bold=True, size=12)


def _is_title(cell: Cell) -> bool:
    """A view's or paragraph list's title: it overflows and does not size its column."""
    return cell.font.sz == _TITLE.sz


def _write_views(sheet: Worksheet, views: Sequence[View], start: int = 1) -> int:
    """Write the views one under another, freezing the sheet below the first one's header; return
    the next free row."""
    row = start
    for view in views:
        sheet.cell(row=row, column=1, value=xlsx_text(view.title)).font = _TITLE
        row += 1
        for col, header in enumerate(view.headers, start=1):
            cell = sheet.cell(row=row, column=col, value=xlsx_text(header))
            cell.font, cell.alignment = _BOLD, Alignment(wrap_text=True, vertical="bottom")
        row += 1
        if sheet.freeze_panes is None:
            sheet.freeze_panes = f"A{row}"
        for values in view.rows:
            for col, (value, kind) in enumerate(zip(values, view.kinds, strict=True), start=1):
                shown = round6(value) if isinstance(value, float) else xlsx_text(value)
                cell = sheet.cell(row=row, column=col, value=shown)
                cell.number_format = _FORMATS["int" if isinstance(value, int) else kind]
            row += 1
        row += 1
    return row


def _write_paragraphs(sheet: Worksheet, title: str, lines: Iterable[str], start: int, wrap: bool = True) -> int:
    """Write a titled list of sentences in column A (wrapped, or overflowing to the right)."""
    sheet.cell(row=start, column=1, value=xlsx_text(title)).font = _TITLE
    row = start + 1
    for line in lines:
        cell = sheet.cell(row=row, column=1, value=xlsx_text(line))
        cell.alignment = Alignment(wrap_text=wrap, vertical="top")
        row += 1
    return row + 1


def _image_sheet(workbook: Workbook, title: str, pngs: Sequence[bytes]) -> None:
    sheet = workbook.create_sheet(title)
    anchor_row = 1
    for png in pngs:
        picture = Image(io.BytesIO(png))
        scale = min(1.0, 900 / picture.width)
        picture.width, picture.height = picture.width * scale, picture.height * scale
        sheet.add_image(picture, f"A{anchor_row}")
        anchor_row += int(picture.height / 20) + 2


def write_survey_xlsx(report: SurveyReport, images: Mapping[str, bytes], path: Path) -> None:
    """report.xlsx: Summary first, then Comparisons, Hours, Most useful, Chart, Notes."""
    workbook = Workbook()
    summary = workbook.active
    summary.title = "Summary"
    conclusions = [c.conclusion for c in report.comparisons]
    row = _write_paragraphs(summary, "Which lab was rated highest?", conclusions, 1, wrap=False)
    _write_views(summary, survey_summary(report), row)
    sheets = [("Comparisons", survey_comparisons(report)), ("Hours", survey_hours(report)),
              ("Most useful", survey_most_useful(report))]
    for title, views in sheets:
        if views:
            _write_views(workbook.create_sheet(title), views)
    for sheet in workbook.worksheets:
        fit_columns(sheet, _is_title)
    _image_sheet(workbook, "Chart", [images[k] for k in ("likert", "hours") if k in images])
    notes = workbook.create_sheet("Notes")
    row = _write_paragraphs(notes, "What these data can and cannot show", report.limitations, 1)
    _write_paragraphs(notes, "Data notes", report.notes, row)
    notes.column_dimensions["A"].width = 120
    path.write_bytes(workbook_bytes(literal_text(workbook)))


def write_exam_xlsx(report: ExamReport, images: Mapping[str, bytes], path: Path) -> None:
    """report.xlsx for the exam question: Summary (figures), Interpretation, Chart."""
    workbook = Workbook()
    summary = workbook.active
    summary.title = "Summary"
    _write_views(summary, exam_views(report))
    fit_columns(summary, _is_title)
    text = workbook.create_sheet("Interpretation")
    row = _write_paragraphs(text, "What the comparison shows", [p.verdict for p in report.problems], 1)
    row = _write_paragraphs(text, informative_heading(report), report.why_uninformative, row)
    row = _write_paragraphs(text, "How big the next study has to be", report.next_study, row)
    _write_paragraphs(text, "Notes", report.notes, row)
    text.column_dimensions["A"].width = 140
    _image_sheet(workbook, "Chart", [images["exam"]])
    path.write_bytes(workbook_bytes(literal_text(workbook)))
