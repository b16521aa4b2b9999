"""End to end through ``grader.cli.main``: files written, contracts kept, no identifiers leak."""

from __future__ import annotations

import csv
import json
import re
import zipfile
from pathlib import Path

import pytest
from openpyxl import load_workbook

from grader.assess import build_exam_report, build_survey_report, load_mapping, read_exam_scores, read_survey
from grader.assess.templates import survey_headers
from grader.cli import main

from ..exports.test_xlsx_layout import assert_widths_fit, frozen_header

FIXTURES = Path(__file__).resolve().parents[2] / "submissions_fixtures" / "assessment"


@pytest.fixture(scope="module")
def survey_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("survey")
    assert main(["survey", str(FIXTURES / "survey_google_forms.csv"), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def exam_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("exam")
    assert main(["exam", str(FIXTURES / "exam_scores.csv"), "--out", str(out)]) == 0
    return out


def _xlsx_text(path: Path) -> str:
    workbook = load_workbook(path, read_only=True)
    return "\n".join(
        str(value) for sheet in workbook.worksheets for row in sheet.iter_rows(values_only=True)
        for value in row if value is not None
    )


def _outputs_text(out: Path) -> str:
    return "\n".join([(out / "report.json").read_text("utf-8"), (out / "report.html").read_text("utf-8"),
                      _xlsx_text(out / "report.xlsx")])


def _column(name: str, header: str, skip: int = 0) -> list[str]:
    with (FIXTURES / name).open(encoding="utf-8", newline="") as handle:
        rows = list(csv.reader(handle))
    col = rows[0].index(header)
    return [row[col] for row in rows[1 + skip:] if row[col]]


def test_survey_writes_every_output(survey_out: Path) -> None:
    names = sorted(p.name for p in survey_out.iterdir())
    assert names == ["report.html", "report.json", "report.xlsx", "survey_hours.png", "survey_ratings.png"]
    assert (survey_out / "survey_ratings.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_survey_json_contract(survey_out: Path) -> None:
    report = json.loads((survey_out / "report.json").read_text("utf-8"))
    assert len(report["items"]) == 20
    for item in report["items"]:
        assert set(item) >= {"lab", "statement", "n", "pct_disagree", "pct_neutral", "pct_agree",
                             "median", "mean", "sd"}
    assert [a["lab"] for a in report["alpha"]] == ["motomatic", "two_tank", "hydraulic_positioner", "hydraulic_pid"]
    assert all(set(a) >= {"lab", "value", "n"} for a in report["alpha"])
    for comparison in report["comparisons"]:
        assert set(comparison) >= {"statement", "friedman_chi2", "friedman_p", "kendall_w", "pairs"}
        assert len(comparison["pairs"]) == 6
        assert all(set(p) >= {"a", "b", "p_holm"} for p in comparison["pairs"])
    assert report["hours"]["n"] > 0 and report["most_useful"]["tally"]


def test_survey_json_is_deterministic(survey_out: Path) -> None:
    mapping = load_mapping()
    first = build_survey_report(read_survey(FIXTURES / "survey_google_forms.csv", mapping), mapping)
    second = build_survey_report(read_survey(FIXTURES / "survey_google_forms.csv", mapping), mapping)
    assert first.model_dump_json(indent=2) == second.model_dump_json(indent=2)
    assert (survey_out / "report.json").read_text("utf-8") == first.model_dump_json(indent=2) + "\n"


def test_html_is_self_contained(survey_out: Path, exam_out: Path) -> None:
    for out, images in ((survey_out, 2), (exam_out, 1)):
        page = (out / "report.html").read_text("utf-8")
        assert "http://" not in page and "https://" not in page and "<script" not in page
        sources = re.findall(r'src="([^"]*)"', page)
        assert len(sources) == images and all(s.startswith("data:image/png;base64,") for s in sources)


def test_charts_are_embedded_in_the_xlsx(survey_out: Path, exam_out: Path) -> None:
    for out, images in ((survey_out, 2), (exam_out, 1)):
        with zipfile.ZipFile(out / "report.xlsx") as archive:
            assert len([n for n in archive.namelist() if n.startswith("xl/media/")]) == images
        assert load_workbook(out / "report.xlsx", read_only=True).sheetnames[0] == "Summary"


def test_report_table_sheets_freeze_their_first_header_and_fit_columns(survey_out: Path, exam_out: Path) -> None:
    for path in (survey_out / "report.xlsx", exam_out / "report.xlsx"):
        wb = load_workbook(path)
        tables = [ws for ws in wb.worksheets if ws.title not in ("Chart", "Notes", "Interpretation")]
        assert len(tables) >= 1
        for ws in tables:
            assert_widths_fit(ws, frozen_header(ws))


def test_survey_reports_contain_no_student_identifiers(survey_out: Path) -> None:
    text = _outputs_text(survey_out)
    emails = _column("survey_google_forms.csv", "Email Address")
    stamps = _column("survey_google_forms.csv", "Timestamp")
    assert len(emails) == 65
    for identifier in [*emails, *stamps]:
        assert identifier not in text
    assert "@" not in text and "[e-mail removed]" in text


def test_template_and_qualtrics_identifiers_stay_out(tmp_path: Path) -> None:
    for name, header, skip in (("survey_template.csv", "respondent", 0), ("survey_qualtrics.csv", "ResponseId", 2),
                               ("survey_qualtrics.csv", "IPAddress", 2)):
        out = tmp_path / name
        mapping = load_mapping()
        report = build_survey_report(read_survey(FIXTURES / name, mapping), mapping)
        from grader.assess.render_html import survey_html

        text = report.model_dump_json() + survey_html(report, {"likert": b"", "hours": b""})
        identifiers = _column(name, header, skip)
        assert len(identifiers) >= 65, out
        assert not [i for i in identifiers if i in text]


def test_exam_outputs_and_contract(exam_out: Path) -> None:
    names = sorted(p.name for p in exam_out.iterdir())
    assert names == ["exam_scores.png", "report.html", "report.json", "report.xlsx"]
    report = json.loads((exam_out / "report.json").read_text("utf-8"))
    assert [p["problem"] for p in report["problems"]] == ["bode_tf_id", "p_controller_design", "overall"]
    assert report["why_uninformative"] and report["next_study"]
    again = build_exam_report(read_exam_scores(FIXTURES / "exam_scores.csv")).model_dump_json(indent=2) + "\n"
    assert (exam_out / "report.json").read_text("utf-8") == again


def test_exam_reports_contain_no_student_ids(exam_out: Path) -> None:
    text = _outputs_text(exam_out)
    students = _column("exam_scores.csv", "student")
    assert len(students) == 65 and not [s for s in students if s in text]


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["survey", str(FIXTURES / "survey_bad_value_7.csv")], 'row 13, column V "hydraulic_pid.models"'),
        (["survey", str(FIXTURES / "survey_empty.csv")], "the file is empty"),
        (["exam", str(FIXTURES / "exam_bad_header.csv")], "wrong header"),
        (["survey", str(FIXTURES / "does_not_exist.csv")], "cannot read the file"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, capsys, argv: list[str], expected: str) -> None:
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err and "Traceback" not in err
    assert err.startswith(f"grader {argv[0]}: error: ")


def test_survey_template_round_trip(tmp_path: Path, capsys) -> None:
    path = tmp_path / "blank.csv"
    assert main(["survey-template", "--out", str(path)]) == 0
    header = path.read_text("utf-8").strip().split(",")
    assert header == survey_headers(load_mapping())
    answers = {"respondent": "r1", "hours_per_week": "4", "most_useful": "The positioner lab"}
    row = [answers.get(h, "Yes" if h.endswith(".did_lab") else "4") for h in header]
    with path.open("a", encoding="utf-8", newline="") as handle:
        csv.writer(handle).writerow(row)
    data = read_survey(path, load_mapping())
    assert data.respondents == 1 and data.ratings[("motomatic", "simulink")] == (4,)


def test_xlsx_templates(tmp_path: Path) -> None:
    assert main(["survey-template", "--out", str(tmp_path / "s.xlsx")]) == 0
    workbook = load_workbook(tmp_path / "s.xlsx")
    assert workbook.sheetnames == ["Responses", "Key"]
    assert [c.value for c in workbook["Responses"][1]] == survey_headers(load_mapping())
    assert len(workbook["Responses"].data_validations.dataValidation) == 2
    assert main(["exam-template", "--out", str(tmp_path / "e.xlsx")]) == 0
    assert main(["exam-template", "--out", str(tmp_path / "e.csv")]) == 0
    assert (tmp_path / "e.csv").read_text("utf-8").startswith("student,group,problem,item_score")
    assert main(["exam-template", "--out", str(tmp_path / "e.txt")]) == 2


def test_custom_mapping_with_two_labs_and_seven_points(tmp_path: Path) -> None:
    mapping = tmp_path / "map.yaml"
    mapping.write_text(
        "scale: {labels: [L1, L2, L3, L4, L5, L6, L7]}\n"
        "statements: [{id: fun, label: Fun, text: was fun.}, {id: useful, label: Useful, text: was useful.}]\n"
        "labs: [{id: old, name: Old rig}, {id: new, name: New rig}]\nhours: null\nmost_useful: null\n",
        encoding="utf-8",
    )
    rows = [["respondent", "old.did_lab", "old.fun", "old.useful", "new.did_lab", "new.fun", "new.useful"]]
    rows += [[f"r{i}", "Yes", str(1 + i % 3), str(2 + i % 3), "Yes", str(5 + i % 3), "L7"] for i in range(12)]
    with (tmp_path / "r.csv").open("w", encoding="utf-8", newline="") as handle:
        csv.writer(handle).writerows(rows)
    out = tmp_path / "out"
    assert main(["survey", str(tmp_path / "r.csv"), "--out", str(out), "--mapping", str(mapping)]) == 0
    report = json.loads((out / "report.json").read_text("utf-8"))
    assert report["scale"]["neutral"] == [4] and report["hours"] is None
    assert report["comparisons"][0]["friedman_chi2"] is None  # two labs: no omnibus test
    assert report["comparisons"][0]["supported"] is True  # New rig: 12 of 12 paired students higher
    assert sorted(p.name for p in out.iterdir()) == ["report.html", "report.json", "report.xlsx", "survey_ratings.png"]


def test_every_xlsx_written_is_the_same_bytes_whenever_it_is_written(survey_out: Path, exam_out: Path,
                                                                      tmp_path: Path) -> None:
    """The reports' and the templates' workbooks carry no time of writing (openpyxl stamps the save time in the
    document properties and on every zip entry): the same input gives the same bytes on another day."""
    assert main(["survey-template", "--out", str(tmp_path / "survey.xlsx")]) == 0
    assert main(["exam-template", "--out", str(tmp_path / "exam.xlsx")]) == 0
    for path in (survey_out / "report.xlsx", exam_out / "report.xlsx", tmp_path / "survey.xlsx", tmp_path / "exam.xlsx"):
        with zipfile.ZipFile(path) as z:
            assert {i.date_time for i in z.infolist()} == {(1980, 1, 1, 0, 0, 0)}, path.name
            core = z.read("docProps/core.xml").decode()
        assert re.findall(r"<dcterms:(?:created|modified)[^>]*>([^<]*)<", core) == ["2000-01-01T00:00:00Z"] * 2, path
