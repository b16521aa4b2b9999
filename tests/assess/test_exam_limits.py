"""Exam files too small to compare: a clear error (one group) or a stated limitation (a few students)."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from grader.cli import main

SCORES = Path(__file__).resolve().parents[2] / "submissions_fixtures" / "assessment" / "exam_scores.csv"


def test_one_group_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = SCORES.read_text().splitlines()
    (tmp_path / "one.csv").write_text("\n".join([lines[0], *(x for x in lines[1:] if ",with_lab_reference," in x)]))
    assert main(["exam", str(tmp_path / "one.csv"), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"grader exam: error: {tmp_path / 'one.csv'}: every student is in group 'with_lab_reference'")
    assert "without_lab_reference" in err and err.count("\n") == 1


@pytest.mark.parametrize("students", [4, 5, 6])
def test_tiny_exam_states_its_limits_without_warnings(students: int, tmp_path: Path) -> None:
    (tmp_path / "tiny.csv").write_text("\n".join(SCORES.read_text().splitlines()[: students + 1]) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["exam", str(tmp_path / "tiny.csv"), "-o", str(tmp_path / "out")]) == 0
    html = (tmp_path / "out" / "report.html").read_text()
    assert "too few students" in html.lower() or "limitation" in html.lower()
