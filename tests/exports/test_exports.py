"""Canvas CSV, Gradescope results.json and package, feedback Markdown, report JSON, gradebook XLSX."""

from __future__ import annotations

import csv
import io
import json
import os
import zipfile
from dataclasses import replace
from pathlib import Path

import pytest
from openpyxl import load_workbook

from grader.cli import main
from grader.exports.atomic import workbook_bytes, zip_bytes
from grader.outpaths import write_text
from grader.exports.bundle import write_outputs
from grader.exports.canvas import canvas_csv, score_text, superseded
from grader.exports.feedback_md import feedback_md
from grader.exports.gradebook_xlsx import gradebook, item_statistics
from grader.exports.gradescope import package_zip, results_json
from grader.exports.report_json import report_json
from grader.grading.commands import _warn_duplicates
from grader.grading.results import ItemResult, Student, SubmissionResult
from grader.grading.rubric import load_rubric

ROOT = Path(__file__).resolve().parents[2]
RUBRIC = load_rubric(ROOT / "rubrics" / "hydraulic_positioner.yaml")
ITEMS = (ItemResult("Kq", "unit_mismatch", 3.0, 6.0, "your Kq is 1728× the expected value | pipe", mistake="unit_slip:ft³->in³",
                    detail={"factor": 1728.0, "unit_used": "ft³", "value": float("nan")}),
         ItemResult("Kpot", "correct", 4.0, 4.0, "Kpot = 0.85 V/in: correct."))
GOOD = SubmissionResult("g-01", "g.json", (Student("Ada Lovelace", "1001", "ada", "L01", "55"), Student("Alan Turing", "1002", "at", "L01")), ITEMS)
BAD = SubmissionResult("broken", "broken.json", (), tuple(ItemResult(i.item, "invalid", 0.0, i.max_points, "not graded") for i in ITEMS),
                       valid=False, error="not valid JSON")


def test_canvas_csv() -> None:
    rows = list(csv.reader(io.StringIO(canvas_csv([GOOD, BAD], assignment="Lab 4", assignment_id="123"))))
    assert rows[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "Lab 4 (123)"]
    assert rows[1] == ["(unreadable submission broken: no student listed)", "", "", "", "", "0"]
    assert rows[2] == ["Ada Lovelace", "55", "1001", "ada", "L01", "7"] and rows[3][0] == "Alan Turing"


def test_latest_submission_by_file_time_then_score() -> None:
    twin = SubmissionResult("g-00", "g0.json", GOOD.students, ITEMS[1:])  # same students, lower score
    assert superseded([GOOD, twin], {"g-01": 1.0, "g-00": 2.0}) == {"g-01": "g-00"}
    assert superseded([GOOD, twin], {"g-01": 2.0, "g-00": 1.0}) == {"g-00": "g-01"}
    assert superseded([GOOD, twin], {}) == {"g-00": "g-01"}  # same time: the higher score
    rows = list(csv.reader(io.StringIO(canvas_csv([GOOD, twin], assignment="L", assignment_id="1",
                                                  times={"g-01": 1.0, "g-00": 2.0}))))[1:]
    assert [r[0] for r in rows] == ["Ada Lovelace", "Alan Turing"] and {r[5] for r in rows} == {score_text(twin.score)}
    other = SubmissionResult("g-02", "g2.json", (Student("ALAN TURING"),), ITEMS)  # a name only: another key
    assert superseded([GOOD, other], {}) == {}
    report = json.loads(report_json([GOOD, twin], {"g-01": "g-00"}))
    assert {s["submission_id"]: s["superseded_by"] for s in report["submissions"]} == {"g-00": None, "g-01": "g-00"}


def test_a_later_submission_that_could_not_be_graded_never_replaces_one_that_was() -> None:
    """A second file under the same submission_id is invalid (score 0): picked as the latest, it zeroed the students'
    grade in grades.csv."""
    again = SubmissionResult("g-01~2", "g_v2.json", GOOD.students, tuple(ItemResult(i.item, "invalid", 0.0, i.max_points,
                                                                                        "not graded") for i in ITEMS),
                             valid=False, error="duplicate submission_id 'g-01' (also in g.json)")
    assert superseded([GOOD, again], {"g-01": 1.0, "g-01~2": 2.0}) == {"g-01~2": "g-01"}
    rows = list(csv.reader(io.StringIO(canvas_csv([GOOD, again], assignment="L", assignment_id="1",
                                                  times={"g-01": 1.0, "g-01~2": 2.0}))))[1:]
    assert [(r[0], r[5]) for r in rows] == [("Ada Lovelace", score_text(GOOD.score)), ("Alan Turing", score_text(GOOD.score))]
    third = SubmissionResult("g-01~3", "g_v3.json", GOOD.students, again.items, valid=False, error="x")
    assert superseded([again, third], {"g-01~2": 2.0, "g-01~3": 3.0}) == {"g-01~2": "g-01~3"}  # none graded: latest


def test_one_row_per_student_whichever_of_their_ids_a_submission_gives() -> None:
    """Listed twice in one submission, or with the Canvas id in one and only the SIS id in a later one: one row,
    from the later submission (two rows with one SIS id would make Canvas's import ambiguous)."""
    ada = GOOD.students[0]
    twice = SubmissionResult("g-03", "g3.json", (ada, ada), ITEMS)
    later = SubmissionResult("g-04", "g4.json", (Student("Ada L.", ada.sis_user_id),), ITEMS[1:])
    rows = list(csv.reader(io.StringIO(canvas_csv([twice, later], assignment="L", assignment_id="1",
                                                  times={"g-03": 1.0, "g-04": 2.0}))))[1:]
    assert rows == [["Ada L.", "", "1001", "", "", score_text(later.score)]]
    assert superseded([twice, later], {"g-03": 1.0, "g-04": 2.0}) == {"g-03": "g-04"}
    assert len(list(csv.reader(io.StringIO(canvas_csv([twice], assignment="L", assignment_id="1"))))) == 2


def test_gradescope_results_schema() -> None:
    data = json.loads(results_json(GOOD))
    assert data["score"] == 7.0 and {"tests", "output", "visibility"} <= set(data)
    for t in data["tests"]:
        assert set(t) == {"name", "score", "max_score", "status", "output", "tags", "visibility"}
        assert t["status"] in ("passed", "failed") and isinstance(t["tags"], list)
    assert data["tests"][0]["tags"] == ["unit_mismatch", "unit_slip:ft³->in³"]
    assert "could not be graded: not valid JSON" in json.loads(results_json(BAD))["output"]


def test_report_json_schema_and_clean_numbers() -> None:
    data = json.loads(report_json([GOOD, BAD]))
    assert [s["submission_id"] for s in data["submissions"]] == ["broken", "g-01"]
    sub = data["submissions"][1]
    assert set(sub) == {"submission_id", "score", "max_score", "valid", "error", "superseded_by", "items"}
    assert set(sub["items"][0]) == {"item", "status", "points", "max_points", "mistake", "detail", "feedback"}
    assert sub["items"][0]["detail"] == {"factor": 1728.0, "unit_used": "ft³", "value": None}


def test_feedback_markdown_escapes_and_explains_invalid() -> None:
    md = feedback_md(GOOD, title="Lab 4")
    assert md.startswith("# Lab 4 — g-01\n") and "**Score: 7 / 10**" in md and "\\| pipe" in md
    assert "unit\\_slip" not in md and "| Kq | unit mismatch | 3 / 6 |" in md
    assert "could not be graded:** not valid JSON" in feedback_md(BAD)


def test_gradebook_statistics() -> None:
    rows = item_statistics([GOOD, BAD], ["Kq", "Kpot"])
    assert rows[0][:4] == ["Kq", 6.0, 1.5, 25.0] and rows[0][-1] == "unit_slip:ft³->in³ (1)"
    wb = load_workbook(io.BytesIO(workbook_bytes(gradebook([GOOD, BAD], ["Kq", "Kpot"]))))
    assert wb.sheetnames == ["grades", "item statistics", "mistakes"]
    grades = list(wb["grades"].iter_rows(values_only=True))
    assert grades[0][:8] == ("submission_id", "students", "SIS user ids", "sections", "valid", "score", "max_score", "Kq")
    assert grades[2][0] == "g-01" and grades[2][7] == 3.0


def test_files_are_deterministic_and_atomic(tmp_path: Path) -> None:
    assert workbook_bytes(gradebook([GOOD], ["Kq"])) == workbook_bytes(gradebook([GOOD], ["Kq"]))
    assert zip_bytes([("a", b"1", 0o644)]) == zip_bytes([("a", b"1", 0o644)])
    write_text(tmp_path / "x.txt", "hello")
    assert [p.name for p in tmp_path.iterdir()] == ["x.txt"]


def test_bundle_removes_stale_files(tmp_path: Path) -> None:
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "old.json").write_text("{}")
    written = write_outputs([GOOD, BAD], tmp_path, RUBRIC, assignment="Lab 4", assignment_id="1")
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["broken.json", "g-01.json"]
    assert len(written) == 7


def test_gradescope_package(tmp_path: Path) -> None:
    data = package_zip(ROOT, ROOT / "rubrics" / "hydraulic_positioner.yaml", convention="inches")
    assert data == package_zip(ROOT, ROOT / "rubrics" / "hydraulic_positioner.yaml", convention="inches")
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        names = z.namelist()
        assert names[:3] == ["setup.sh", "run_autograder", "rubric.yaml"]
        assert (z.getinfo("run_autograder").external_attr >> 16) & 0o111
        assert "--feedback-convention inches" in z.read("run_autograder").decode()
        assert "grader/grading/pipeline.py" in names and "pyproject.toml" in names
        assert "reference_solutions/stations/default.yaml" in names
        assert not any("__pycache__" in n for n in names)
    assert main(["gradescope-package", "-o", str(tmp_path / "a.zip")]) == 0


@pytest.mark.parametrize(("files", "score_zero", "message"), [
    ([], True, "no submission file"),
    (["a.json", "b.json"], True, "2 submission files"),
    (["garbage.json"], True, "not valid JSON"),
    (["answers.txt"], True, "found no submission file (only answers.txt); upload exactly one"),
    (["lab4/garbage.json", "__MACOSX/lab4/._garbage.json"], True, "not valid JSON"),  # a zip upload: graded inside
    (["lab4/a.json", "lab4/b.yaml"], True, "2 submission files (lab4/a.json, lab4/b.yaml)"),
])
def test_gradescope_verb_paths(tmp_path: Path, files: list[str], score_zero: bool, message: str) -> None:
    sub = tmp_path / "submission"
    sub.mkdir()
    for f in files:
        (sub / f).parent.mkdir(parents=True, exist_ok=True)
        (sub / f).write_text("{ not json")
    out = tmp_path / "results" / "results.json"
    assert main(["gradescope", "--submission-dir", str(sub), "--results", str(out)]) == 0
    data = json.loads(out.read_text())
    assert (data["score"] == 0) is score_zero and message in data["output"]


def test_the_warning_says_which_students_a_partly_superseded_submission_keeps(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A later submission listing only Ada replaces g-01 for her alone: the warning says Alan is still graded on
    g-01 (it said "g-01 -> g-02", as if the whole group had moved). A whole group moving keeps the short form."""
    first, later = tmp_path / "g.json", tmp_path / "h.json"
    for f, t in ((first, 1_000_000), (later, 2_000_000)):
        f.write_text("{}")
        os.utime(f, (t, t))
    old = replace(GOOD, source=str(first))
    ada = SubmissionResult("g-02", str(later), GOOD.students[:1], ITEMS)
    _warn_duplicates([old, ada])
    err = " ".join(capsys.readouterr().err.split())
    assert "g-01: Ada Lovelace -> g-02; Alan Turing still graded on it" in err and "g-01 -> g-02" not in err
    _warn_duplicates([old, replace(ada, students=GOOD.students)])
    assert "g-01 -> g-02" in " ".join(capsys.readouterr().err.split())
