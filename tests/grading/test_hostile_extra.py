"""Regression tests for hostile submissions: one failing item never sinks the others."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grader.grading import checks
from grader.grading.grade import GradeOptions, grade_submission
from grader.grading.submissions import read_submission

from .conftest import FIXTURES


def _with_answer(tmp_path: Path, item: str, value: object) -> Path:
    data = json.loads((FIXTURES / "correct.json").read_text())
    data["answers"][item] = value
    path = tmp_path / "sub.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize(("item", "value", "reason"), [
    ("closed_loop_tf", "9" * 309, "out of range"),
    ("closed_loop_tf", "(s-s)**0", "0**0 is undefined"),
    ("closed_loop_tf", "s**" + "9" * 400, "out of range"),
])
def test_bad_expression_invalidates_only_its_item(tmp_path: Path, kc, opts: GradeOptions, item: str, value: str,
                                                  reason: str) -> None:
    result = grade_submission(read_submission(_with_answer(tmp_path, item, value)), kc, opts)
    assert result.valid
    bad = [i for i in result.items if i.status != "correct"]
    assert [(i.item, i.status) for i in bad] == [(item, "invalid")]
    assert reason in bad[0].feedback and "Traceback" not in bad[0].feedback


@pytest.mark.parametrize("exc", [OverflowError("x"), ValueError("secret"), ArithmeticError("y"), KeyError("k")])
def test_unexpected_exception_in_a_check_is_contained(monkeypatch: pytest.MonkeyPatch, kc, opts: GradeOptions,
                                                      exc: Exception) -> None:
    from grader.grading import grade

    def boom(*args: object, **kwargs: object) -> None:
        raise exc

    monkeypatch.setattr(grade, "check_quantity", boom)
    checks.tf_verdict.cache_clear()
    monkeypatch.setattr(checks, "to_ratfunc", boom)
    try:
        result = grade_submission(read_submission(FIXTURES / "correct.json"), kc, opts)
    finally:
        checks.tf_verdict.cache_clear()
    assert result.valid
    kinds = {i.item: i for i in result.items}
    for name in ("closed_loop_tf", "Kq"):
        assert kinds[name].status == "invalid"
        assert kinds[name].feedback.endswith(f"this answer could not be checked: {type(exc).__name__}.")
        assert "secret" not in kinds[name].feedback
    assert kinds["closed_loop_poles"].status == "correct"


def _rezip(src: Path, dst: Path, sheet: str, edit) -> Path:  # type: ignore[no-untyped-def]
    import zipfile

    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info.filename)
            zout.writestr(info, edit(data) if info.filename == sheet else data)
    return dst


_LOL = b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY l0 "lol">' + b"".join(
    b'<!ENTITY l%d "%s">' % (i, b"".join(b"&l%d;" % (i - 1) for _ in range(10))) for i in range(1, 10)) + b"]>"


@pytest.mark.parametrize(("label", "edit"), [
    ("billion laughs", lambda d: _LOL + d.replace(b"<sheetPr>", b"<sheetPr>&l9;", 1)),
    ("undefined entity", lambda d: d.replace(b"<sheetPr>", b"<sheetPr>&nope;", 1)),
    ("truncated xml", lambda d: d[: len(d) // 2]),
])
def test_malformed_xlsx_is_a_submission_error(tmp_path: Path, label: str, edit) -> None:  # type: ignore[no-untyped-def]
    from grader.errors import SubmissionError

    bad = _rezip(FIXTURES / "correct.xlsx", tmp_path / "bad.xlsx", "xl/worksheets/sheet1.xml", edit)
    with pytest.raises(SubmissionError, match=r"^bad\.xlsx: "):
        read_submission(bad)


def test_xlsx_row_limit_error_names_the_file(tmp_path: Path) -> None:
    from openpyxl import load_workbook

    from grader.errors import SubmissionError

    wb = load_workbook(FIXTURES / "correct.xlsx")
    for r in range(60):
        wb["info"].append([None, f"extra{r}"])  # rows without a field name: skipped, but counted
    wb.save(tmp_path / "long.xlsx")
    with pytest.raises(SubmissionError, match=r"^long\.xlsx: sheet 'info': more than 50 rows"):
        read_submission(tmp_path / "long.xlsx")


@pytest.mark.parametrize(("suffix", "text"), [
    (".json", '{"submission_id": "a", "answers": {"Kq": ' + "9" * 5000 + "}}"),
    (".yaml", "submission_id: a\nanswers:\n  Kq: " + "9" * 5000 + "\n"),
])
def test_huge_integer_literal_is_a_submission_error(tmp_path: Path, suffix: str, text: str) -> None:
    from grader.errors import SubmissionError

    path = tmp_path / f"big{suffix}"
    path.write_text(text)
    with pytest.raises(SubmissionError, match=r"^big\.(json|yaml): .*number is too long"):
        read_submission(path)


_INJECT = ["=HYPERLINK(\"http://x\",\"y\")", "+1+1", "-2+3", "@SUM(A1)", "\t=1", "\r=1"]


@pytest.mark.parametrize("text", _INJECT)
def test_exports_write_formula_like_text_literally(text: str) -> None:
    import csv
    import io

    from openpyxl import load_workbook

    from grader.exports.atomic import workbook_bytes
    from grader.exports.canvas import canvas_csv
    from grader.exports.gradebook_xlsx import gradebook
    from grader.grading.results import ItemResult, Student, SubmissionResult

    items = (ItemResult("Kq", "incorrect", 0.0, 6.0, "x", mistake=text),)
    r = SubmissionResult("g-01", "g.json", (Student(text, "1", text, "L01", text),), items, valid=False, error=text)
    wb = load_workbook(io.BytesIO(workbook_bytes(gradebook([r], ["Kq"]))))
    cells = [(c.value, c.data_type) for ws in wb.worksheets for row in ws.iter_rows() for c in row if c.value is not None]
    assert not [c for c in cells if c[1] == "f"]
    assert any(v == text.replace("\r", "\n") or v == text for v, t in cells if t == "s")
    assert (6, "n") in cells  # numbers stay numbers
    rows = list(csv.reader(io.StringIO(canvas_csv([r], assignment=text, assignment_id="7"))))
    shown = "'" + text.replace("\r", "\n")
    assert rows[0][-1] == shown + " (7)" and rows[1][0] == shown
    assert not any(f.startswith(("=", "+", "-", "@", "\t", "\r")) for row in rows for f in row)


def test_cell_sanitiser_leaves_numbers_alone() -> None:
    from openpyxl import Workbook

    from grader.exports.cells import csv_text, literal_text

    assert [csv_text(v) for v in (-3, -2.5, 0, "-1", "ok", "=1")] == [-3, -2.5, 0, "'-1", "ok", "'=1"]
    wb = Workbook()
    wb.active.append([-3, -2.5, "=1+1", "-x"])
    literal_text(wb)
    assert [(c.value, c.data_type) for c in wb.active[1]] == [(-3, "n"), (-2.5, "n"), ("=1+1", "s"), ("-x", "s")]


_CP = "s^3 + (B/M + 4*beta*Kce/Vt)*s^2 + 4*beta*(A^2 + B*Kce)/(M*Vt)*s + {c} = 0"


@pytest.mark.parametrize(("item", "value"), [
    ("char_poly", _CP.format(c="4*beta*A/(M*Vt)")),  # constant term missing Kp·Kamp·Kpot·Kq
    ("char_poly", _CP.format(c="4*beta*A*Kp*Kamp*Kpot*Kq*Kd/(M*Vt)")),  # an extra factor
    ("char_poly", "s^3 + (B/M)*s^2 + 4*beta*(A^2 + B*Kce)/(M*Vt)*s + 4*beta*A*Kp*Kamp*Kpot*Kq/(M*Vt) = 0"),  # missing term
    ("char_poly", "s^3 + (B/M + 4*beta*Kce/Vt)*s^2 + 2*beta*(A^2 + B*Kce)/(M*Vt)*s + 4*beta*A*Kp*Kamp*Kpot*Kq/(M*Vt) = 0"),
])
def test_check_feedback_does_not_reveal_the_model_structure(tmp_path: Path, kc, opts: GradeOptions, item: str,
                                                            value: str) -> None:
    import re
    from dataclasses import replace

    from grader.grading import tf

    sub = read_submission(_with_answer(tmp_path, item, value))
    hidden = {i.item: i for i in grade_submission(sub, kc, replace(opts, reveal=False)).items}[item]
    shown = {i.item: i for i in grade_submission(sub, kc, opts).items}[item]
    assert hidden.status == shown.status == "incorrect"
    words = set(re.findall(r"[A-Za-z_]\w*", hidden.feedback + " " + " ".join(hidden.detail.get("differences", []))))
    assert not words & (set(tf._SYM) - {"s"}), hidden.feedback
    assert "differs from the model's" in hidden.feedback
    assert shown.feedback != hidden.feedback and ("missing" in shown.feedback or "extra" in shown.feedback)  # instructors


@pytest.mark.parametrize(("sid", "ok"), [
    ("ok-1", True), ("a..b", True), ("9lives", True), ("x" * 64, True),
    (".hidden", False), ("-rf", False), ("_x", False), ("..", False), ("abc\n", False), ("x" * 65, False), ("a/b", False),
])
def test_submission_id_rule(tmp_path: Path, sid: str, ok: bool) -> None:
    from grader.errors import SubmissionError
    from grader.grading.submissions import safe_id

    assert safe_id(sid) is ok
    data = json.loads((FIXTURES / "correct.json").read_text())
    data["submission_id"] = sid
    (tmp_path / "s.json").write_text(json.dumps(data))
    if ok:
        assert read_submission(tmp_path / "s.json").submission_id == sid
    else:
        with pytest.raises(SubmissionError, match="submission_id"):
            read_submission(tmp_path / "s.json")


@pytest.mark.parametrize(("name", "expected"), [("-rf.json", "rf"), ("..x.json", "x"), ("___.json", "submission")])
def test_fallback_id_starts_with_a_letter_or_digit(name: str, expected: str) -> None:
    from grader.grading.submissions import fallback_id

    assert fallback_id(Path(name)) == expected


def test_ids_differing_only_in_case_get_distinct_outputs(tmp_path: Path, rubric) -> None:
    """On a case-insensitive disk 'Ab' and 'ab' would be one file: the second becomes an invalid,
    renamed result saying why, and nothing is overwritten or dropped."""
    import json

    from grader.grading.grade import GradeOptions
    from grader.grading.pipeline import read_all

    base = json.loads((Path(__file__).resolve().parents[2] / "submissions_fixtures/grading/correct.json").read_text())
    paths = []
    for name, sid in (("one.json", "Ab"), ("two.json", "ab"), ("three.json", "cd")):
        (tmp_path / name).write_text(json.dumps({**base, "submission_id": sid}))
        paths.append(tmp_path / name)
    subs = read_all(paths, GradeOptions(rubric=rubric, convention=rubric.feedback_convention, reveal=True))
    ids = [s.submission_id for s in subs]
    assert len({i.casefold() for i in ids}) == 3 and ids[0] == "Ab" and ids[1] == "ab~2"
    assert "duplicate submission_id" in subs[1].error
