"""Blank input files: the survey template (CSV or XLSX) and the exam-score template."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from openpyxl import Workbook
from openpyxl.styles import Font
from openpyxl.worksheet.datavalidation import DataValidation

from grader.assess.exam_io import GROUPS, REQUIRED
from grader.assess.mapping import SurveyMapping
from grader.assess.survey_io import TEMPLATE_EXTRA_COLUMNS
from grader.assess.tables import XLSX_SUFFIXES, column_letter
from grader.errors import AssessmentError
from grader.exports.atomic import workbook_bytes

_VALIDATED_ROWS = 1000


def survey_headers(mapping: SurveyMapping) -> list[str]:
    """Columns of our survey template: an optional anonymous code, then every mapped field."""
    return [*sorted(TEMPLATE_EXTRA_COLUMNS), *(f.header for f in mapping.fields("template"))]


def _check_suffix(path: Path) -> bool:
    """True for XLSX, False for CSV; anything else is an error."""
    suffix = path.suffix.lower()
    if suffix not in XLSX_SUFFIXES | {".csv"}:
        raise AssessmentError(f"{path.name}: the template must be .csv or .xlsx")
    return suffix in XLSX_SUFFIXES


def _save_csv(path: Path, header: Sequence[str]) -> None:
    try:
        with path.open("w", newline="", encoding="utf-8") as handle:
            csv.writer(handle, lineterminator="\n").writerow(header)
    except OSError as exc:
        raise AssessmentError(f"{path}: cannot write the template ({exc.strerror})") from exc


def _validate(sheet, columns: Sequence[int], choices: Sequence[str], prompt: str) -> None:
    if not columns:
        return
    rule = DataValidation(type="list", formula1='"' + ",".join(choices) + '"', allow_blank=True)
    rule.error, rule.prompt = f"Use one of: {', '.join(choices)}", prompt
    for col in columns:
        rule.add(f"{column_letter(col)}2:{column_letter(col)}{_VALIDATED_ROWS}")
    sheet.add_data_validation(rule)


def _save_xlsx(workbook: Workbook, path: Path) -> None:
    try:
        path.write_bytes(workbook_bytes(workbook))
    except OSError as exc:
        raise AssessmentError(f"{path}: cannot write the template ({exc.strerror})") from exc


def write_survey_template(path: Path, mapping: SurveyMapping) -> None:
    """Write the blank survey template (header row; XLSX adds drop-downs and a key)."""
    path = Path(path)
    header = survey_headers(mapping)
    if not _check_suffix(path):
        _save_csv(path, header)
        return
    workbook = Workbook()
    sheet = workbook.active
    sheet.title = "Responses"
    sheet.append(header)
    sheet.freeze_panes = "B2"
    fields = {f.header: f for f in mapping.fields("template")}
    kinds = [fields[h].kind if h in fields else "" for h in header]
    ratings = [str(v) for v in range(1, mapping.scale.points + 1)] + ["N/A"]
    _validate(sheet, [i for i, k in enumerate(kinds) if k in ("rating", "overall")], ratings, "Rating, or N/A")
    _validate(sheet, [i for i, k in enumerate(kinds) if k == "did_lab"], ["Yes", "No"], "Did this lab?")
    key = workbook.create_sheet("Key")
    key.append(["column", "meaning"])
    key.append(["respondent", "optional anonymous code; never shown in reports"])
    for h in header[1:]:
        key.append([h, fields[h].description])
    key.append([])
    key.append(["scale", "; ".join(f"{i} = {label}" for i, label in enumerate(mapping.scale.labels, 1))])
    for row in key.iter_rows(max_row=1):
        for cell in row:
            cell.font = Font(bold=True)
    key.column_dimensions["A"].width, key.column_dimensions["B"].width = 40, 70
    _save_xlsx(workbook, path)


def write_exam_template(path: Path) -> None:
    """Write the blank exam-score template (XLSX adds a drop-down for the group)."""
    path = Path(path)
    if not _check_suffix(path):
        _save_csv(path, REQUIRED)
        return
    workbook = Workbook()
    sheet = workbook.active
    sheet.title = "Scores"
    sheet.append(list(REQUIRED))
    _validate(sheet, [REQUIRED.index("group")], GROUPS, "Which version of the problem")
    _save_xlsx(workbook, path)
