"""Regression tests for hostile assessment inputs and outputs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from openpyxl import load_workbook

from grader.assess import (
    build_exam_report,
    build_survey_report,
    load_mapping,
    read_exam_scores,
    read_survey,
)
from grader.assess.render_xlsx import write_exam_xlsx, write_survey_xlsx

FIXTURES = Path(__file__).resolve().parents[2] / "submissions_fixtures" / "assessment"
HOSTILE = ["=HYPERLINK(\"http://x\",\"y\")", "+1+1", "-2+3", "@SUM(A1)", "\t=1", "\r=1"]


def _cells(path: Path) -> list[tuple[object, str]]:
    wb = load_workbook(path)
    return [(c.value, c.data_type) for ws in wb.worksheets for row in ws.iter_rows() for c in row if c.value is not None]


@pytest.mark.parametrize("kind", ["survey", "exam"])
def test_report_xlsx_writes_formula_like_text_as_text(tmp_path: Path, kind: str) -> None:
    if kind == "survey":
        mapping = load_mapping()
        report = build_survey_report(read_survey(FIXTURES / "survey_google_forms.csv", mapping), mapping)
        write_survey_xlsx(report.model_copy(update={"notes": HOSTILE}), {}, tmp_path / "report.xlsx")
    else:
        report = build_exam_report(read_exam_scores(FIXTURES / "exam_scores.csv"))
        write_exam_xlsx(report.model_copy(update={"notes": HOSTILE}), {"exam": _png()}, tmp_path / "report.xlsx")
    cells = _cells(tmp_path / "report.xlsx")
    assert not [c for c in cells if c[1] == "f"]
    for text in HOSTILE:
        assert (text.replace("\r", "\n") if text.startswith("\r") else text, "s") in cells or (text, "s") in cells
    assert any(isinstance(v, (int, float)) and t == "n" for v, t in cells)  # numbers stay numbers


def _png() -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 4)).save(buf, format="PNG")
    return buf.getvalue()


def _xlsx(path: Path, cells: dict[str, object]) -> Path:
    from openpyxl import Workbook

    wb = Workbook()
    ws = wb.active
    ws.append(["a", "b"])
    ws.append(["1", "2"])
    for ref, value in cells.items():
        ws[ref] = value
    wb.save(path)
    return path


@pytest.mark.parametrize(("cells", "caps", "error"), [
    ({"XFD1048576": "x"}, {}, None),  # a stray far-away cell: read the real data, nothing else
    ({"F1": "c"}, {"MAX_COLS": 5}, "more than 5 columns"),
    ({"A3": "x", "A4": "x", "A5": "x", "A6": "late"}, {"MAX_ROWS": 5}, "more than 5 rows"),
    ({}, {"MAX_XLSX_BYTES": 100}, "file is .* the limit is"),
])
def test_xlsx_tables_are_bounded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, cells: dict[str, object],
                                 caps: dict[str, int], error: str | None) -> None:
    from grader.assess import tables
    from grader.errors import AssessmentError

    for name, value in caps.items():
        monkeypatch.setattr(tables, name, value)
    path = _xlsx(tmp_path / "t.xlsx", cells)
    if error is None:
        assert tables.read_table(path).rows == (("a", "b"), ("1", "2"))
    else:
        with pytest.raises(AssessmentError, match=rf"^{re.escape(str(tmp_path))}/t\.xlsx: {error}"):
            tables.read_table(path)


def test_control_characters_in_free_text_are_shown_not_fatal(tmp_path: Path) -> None:
    """XML cannot hold C0 controls (openpyxl refused the cell, and the whole workbook with it): shown as U+FFFD."""
    mapping = load_mapping()
    report = build_survey_report(read_survey(FIXTURES / "survey_google_forms.csv", mapping), mapping)
    write_survey_xlsx(report.model_copy(update={"notes": ["bad\x01\x02text", "nul\x00"]}), {}, tmp_path / "report.xlsx")
    values = [v for v, _ in _cells(tmp_path / "report.xlsx")]
    assert "bad\ufffd\ufffdtext" in values and "nul\ufffd" in values
