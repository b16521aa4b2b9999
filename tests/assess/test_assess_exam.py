"""Exam-score reader and report: figures, power analysis and bad files."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from grader.assess import build_exam_report, read_exam_scores
from grader.errors import AssessmentError

FIXTURES = Path(__file__).resolve().parents[2] / "submissions_fixtures" / "assessment"
HEADER = ["student", "group", "problem", "item_score", "item_max", "total_score", "total_max"]


@pytest.fixture(scope="module")
def report():
    return build_exam_report(read_exam_scores(FIXTURES / "exam_scores.csv"))


def _write(path: Path, rows: list[list[str]]) -> Path:
    with path.open("w", encoding="utf-8", newline="") as handle:
        csv.writer(handle).writerows(rows)
    return path


def _error(path: Path) -> str:
    with pytest.raises(AssessmentError) as info:
        read_exam_scores(path)
    assert "\n" not in str(info.value)
    return str(info.value)


def test_fixture_is_shaped_like_the_paper(report) -> None:
    assert report.students == 65
    names = [p.problem for p in report.problems]
    assert names == ["bode_tf_id", "p_controller_design", "overall"]
    for p in report.problems:
        treated, control = p.groups
        assert (treated.group, control.group) == ("with_lab_reference", "without_lab_reference")
        assert treated.mean < control.mean  # the lab-reference group did slightly worse ...
        assert p.welch_p > 0.05 and p.balance_p > 0.05  # ... not significantly; groups alike on the rest


def test_contract_fields(report) -> None:
    dump = report.model_dump(mode="json")
    for p in dump["problems"]:
        for key in ("problem", "groups", "welch_t", "welch_df", "welch_p", "mannwhitney_u", "mannwhitney_p",
                    "hedges_g", "hedges_g_ci", "ancova_group_p", "balance_p", "mde_80", "n_needed_d05"):
            assert key in p
        for g in p["groups"]:
            assert set(g) >= {"group", "n", "mean", "sd"}


def test_power_analysis_explains_why_it_was_uninformative(report) -> None:
    per_problem = [p for p in report.problems if p.problem != "overall"]
    assert all(0.95 < p.mde_80 < 1.1 for p in per_problem)  # ~16 per group: only d ≈ 1 is detectable
    assert all(p.n_needed_d05 == 64 for p in report.problems)
    assert all("cannot tell no effect" in p.verdict for p in report.problems)
    assert "Too few students per group" in report.why_uninformative[0]
    assert "64 students per group" in report.next_study[0]
    assert any("within students" in line for line in report.next_study)


def test_ancova_uses_the_rest_of_test_score(report) -> None:
    overall = report.problems[-1]
    assert overall.ancova_group_p is not None and overall.ancova_group_ci is not None
    assert overall.item_rest_r is not None and 0 < overall.item_rest_r < 1


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("exam_bad_header.csv", ["exam_bad_header.csv: wrong header", "item_score"]),
        ("exam_bad_score.csv", ["row 6", 'column D "item_score"', "above the item maximum"]),
    ],
)
def test_shipped_bad_files(name: str, expected: list[str]) -> None:
    message = _error(FIXTURES / name)
    for part in expected:
        assert part in message


@pytest.mark.parametrize(
    ("rows", "expected"),
    [
        ([["s1", "control", "bode_tf_id", "5", "10", "50", "100"]], 'row 2, column B "group": "control" is not'),
        ([["s1", "with_lab_reference", "bode_tf_id", "five", "10", "50", "100"]], '"five" is not a number'),
        ([["s1", "with_lab_reference", "bode_tf_id", "5", "10", "4", "100"]], "below the item score"),
        ([["s1", "with_lab_reference", "bode_tf_id", "5", "10", "50", "10"]], "must exceed the item maximum"),
        ([["s1", "with_lab_reference", "", "5", "10", "50", "100"]], "the problem is blank"),
        ([["s1", "with_lab_reference", "bode_tf_id", "5", "10", "50", "100"],
          ["s1", "without_lab_reference", "bode_tf_id", "5", "10", "50", "100"]],
         'row 3, column A "student": this student also appears in row 2'),
        ([["s1", "with_lab_reference", "bode_tf_id", "5", "10", "50", "100"],
          ["s2", "without_lab_reference", "bode_tf_id", "5", "12", "50", "100"]], "differs from the maximum 10"),
        ([], "has a header but no students"),
        ([["s1", "with_lab_reference", "Overall", "5", "10", "50", "100"]], "reserved for the pooled analysis"),
    ],
)
def test_bad_rows(tmp_path: Path, rows: list[list[str]], expected: str) -> None:
    assert expected in _error(_write(tmp_path / "scores.csv", [HEADER, *rows]))


def test_empty_exam_file(tmp_path: Path) -> None:
    (tmp_path / "scores.csv").write_bytes(b"")
    assert "scores.csv: the file is empty" in _error(tmp_path / "scores.csv")


def test_header_names_are_forgiving(tmp_path: Path) -> None:
    header = ["Student", "Group", "Problem", "Item Score", "item-max", "TOTAL SCORE", "total_max"]
    rows = [[f"s{i}", g, "p", str(i % 5), "5", str(50 + i), "100"]
            for i, g in enumerate(["with_lab_reference", "without_lab_reference"] * 4)]
    data = read_exam_scores(_write(tmp_path / "scores.csv", [header, *rows]))
    assert len(data.group) == 8
    report = build_exam_report(data)
    assert [p.problem for p in report.problems] == ["p"]


def test_tiny_groups_do_not_crash(tmp_path: Path) -> None:
    rows = [["s1", "with_lab_reference", "p", "3", "5", "60", "100"],
            ["s2", "without_lab_reference", "p", "4", "5", "70", "100"]]
    report = build_exam_report(read_exam_scores(_write(tmp_path / "s.csv", [HEADER, *rows])))
    assert report.problems[0].welch_p is None
    assert "too few students" in report.problems[0].verdict


def test_scores_without_spread_are_said_to_have_none_not_too_few_students(tmp_path: Path) -> None:
    """Every student of a group with the same score: nothing to test, and the verdict says why (not the group size)."""
    rows = [[f"s{i}", g, "p", "3", "5", "60", "100"]
            for i, g in enumerate(["with_lab_reference", "without_lab_reference"] * 6)]
    report = build_exam_report(read_exam_scores(_write(tmp_path / "s.csv", [HEADER, *rows])))
    verdict = report.problems[0].verdict
    assert report.problems[0].welch_p is None and "too few" not in verdict
    assert "within each group every student scored the same (60.0 % and 60.0 %, n = 6 and 6)" in verdict


def test_a_required_column_given_twice_is_refused_naming_both(tmp_path: Path) -> None:
    """The last copy won silently, and the error then blamed the groups."""
    rows = [[*HEADER, "group"], *([f"s{i}", g, "p", "3", "5", "60", "100", "with_lab_reference"]
                                  for i, g in enumerate(["with_lab_reference", "without_lab_reference"] * 3))]
    assert 'column "group" appears more than once (columns B and H)' in _error(_write(tmp_path / "s.csv", rows))


def test_an_xlsx_is_read_from_its_visible_sheet_not_a_hidden_first_one(tmp_path: Path) -> None:
    """A hidden old copy first in the workbook was read instead of the data (2 students, exit 0)."""
    from openpyxl import Workbook

    wb = Workbook()
    old = wb.active
    old.title, old.sheet_state = "old", "hidden"
    old.append(HEADER)
    old.append(["s1", "with_lab_reference", "p", "3", "5", "60", "100"])
    data = wb.create_sheet("scores")
    data.append(HEADER)
    for i, g in enumerate(["with_lab_reference", "without_lab_reference"] * 4):
        data.append([f"s{i}", g, "p", str(i % 5), "5", str(50 + i), "100"])
    wb.active = data
    wb.save(tmp_path / "s.xlsx")
    assert len(read_exam_scores(tmp_path / "s.xlsx").group) == 8
    data.append(["s0", "with_lab_reference", "p", "3", "5", "60", "100"])  # an error names the sheet read
    wb.save(tmp_path / "s.xlsx")
    assert _error(tmp_path / "s.xlsx").startswith(f"{tmp_path / 's.xlsx'} (sheet 'scores'), row 10")
