"""Submission readers: JSON, YAML, XLSX (and its template); limits on untrusted files."""

from __future__ import annotations

import json
import time
import zipfile
from pathlib import Path

import pytest
from openpyxl import load_workbook

from grader.errors import SubmissionError
from grader.exports.atomic import workbook_bytes
from grader.grading.items import ITEMS
from grader.grading.submissions import InlineData, InvalidAnswer, read_submission
from grader.grading.xlsx_io import build_template

from .conftest import FIXTURES

STUDENTS = [{"name": "Ada", "sis_user_id": 1001, "login_id": "ada", "section": "L01"}]


def _write(tmp_path: Path, name: str, data: object) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def test_json_and_yaml_fixtures_read_the_same() -> None:
    a, b = read_submission(FIXTURES / "correct.json"), read_submission(FIXTURES / "correct.yaml")
    assert a.answers == b.answers and a.students == b.students
    assert a.students[0].sis_user_id == "1001" and a.station == "default"


def test_fifty_megabyte_string_is_refused_quickly(tmp_path: Path) -> None:
    path = tmp_path / "huge.json"
    with path.open("w") as f:
        f.write('{"submission_id": "huge", "students": [{"name": "A"}], "answers": {"closed_loop_tf": "')
        f.write("s+" * 25_000_000)
        f.write('s"}}')
    t0 = time.perf_counter()
    with pytest.raises(SubmissionError, match="limited to 1 MB"):
        read_submission(path)
    assert time.perf_counter() - t0 < 1.0


def test_unknown_answer_names_become_notes(tmp_path: Path) -> None:
    sub = read_submission(_write(tmp_path, "s.json", {"submission_id": "s", "students": STUDENTS, "answers": {"Kqq": 1}}))
    assert sub.notes == ("answer 'Kqq' is not an item of this lab and was ignored; did you mean 'Kq'?",)


def test_group_data_folder_must_be_next_to_the_submission(tmp_path: Path) -> None:
    (tmp_path / "mydata").mkdir()
    sub = read_submission(_write(tmp_path, "s.json", {"submission_id": "s", "students": STUDENTS, "data": "mydata"}))
    assert sub.data == (tmp_path / "mydata").resolve()
    outside = tmp_path.parent / "elsewhere"
    outside.mkdir(exist_ok=True)
    (tmp_path / "link").symlink_to(outside)
    with pytest.raises(SubmissionError, match="field data: 'link' is a link that leads out of the submission's folder"):
        read_submission(_write(tmp_path, "t.json", {"submission_id": "t", "students": STUDENTS, "data": "link"}))
    with pytest.raises(SubmissionError, match="field data: folder 'absent' not found next to the submission"):
        read_submission(_write(tmp_path, "u.json", {"submission_id": "u", "students": STUDENTS, "data": "absent"}))
    with pytest.raises(SubmissionError, match="no '..'"):
        read_submission(_write(tmp_path, "u.json", {"submission_id": "u", "students": STUDENTS, "data": "/etc"}))


@pytest.mark.parametrize(("name", "text", "message"), [
    ("a.txt", "x", "unknown submission type"),
    ("b.yaml", "a: [1, 2\n", "not valid YAML"),
    ("c.json", "[" * 100_000, "nested too deeply|not valid JSON"),
    ("c.yaml", "x: " + "[" * 100_000, "YAML nested too deeply"),  # the scanner took minutes over it
    ("d.json", '{"submission_id": "d", "students": [], "answers": {}}', "field students"),
    ("e.json", '{"submission_id": "e", "students": [{"name": "A"}], "extra": 1}', "field extra"),
    ("f.yaml", "submission_id: f\nstudents: [{name: A}]\nanswers: !!python/object:os.system {}\n", "not valid YAML"),
])
def test_malformed_files(tmp_path: Path, name: str, text: str, message: str) -> None:
    (tmp_path / name).write_text(text)
    with pytest.raises(SubmissionError, match=message):
        read_submission(tmp_path / name)


def test_template_lists_every_item_with_units_and_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "lab4.xlsx"
    path.write_bytes(workbook_bytes(build_template(list(ITEMS), station="default", gain_unit="dimensionless")))
    wb = load_workbook(path)
    assert {"info", "students", "answers", "poles", "calibration", "flow", "friction", "runs"} <= set(wb.sheetnames)
    rows = {r[0]: r for r in wb["answers"].iter_rows(min_row=2, values_only=True)}
    assert rows["Kq"][3] == "in^3/s/mA" and rows["pd_design.Kd"][3] == "s" and rows["closed_loop_tf"][3] == "(expression)"
    assert "'not reachable'" in rows["Kp_25_overshoot"][4] and "'not identifiable'" in rows["Kce"][4]
    assert "not" not in rows["Kq"][4]
    assert wb["answers"].data_validations.dataValidation
    wb["students"].append(["Ada Lovelace", "1001", "ada", "L01"])
    for r in wb["answers"].iter_rows(min_row=2):
        if r[0].value == "Kq":
            r[1].value, r[2].value = 0.0385, "in^3/s/mA"
        if r[0].value == "pd_design.Kp":
            r[1].value = 40
        if r[0].value == "Kpot":
            r[1].value = "=A1*2"
        if r[0].value == "Kce":
            r[1].value = "Not identifiable"
    wb["answers"].append(["closed_loop_poles", "not identifiable"])  # poles the data cannot give
    wb.save(path)
    sub = read_submission(path)
    assert sub.answers["Kq"] == "0.0385 in^3/s/mA" and sub.answers["pd_design"] == {"Kp": 40}
    assert isinstance(sub.answers["Kpot"], InvalidAnswer) and "formula" in sub.answers["Kpot"].reason
    assert sub.students[0].name == "Ada Lovelace" and sub.data is None
    assert sub.answers["Kce"] == "Not identifiable" and sub.answers["closed_loop_poles"] == "not identifiable"


def test_xlsx_group_data_sheets_become_a_dataset(tmp_path: Path) -> None:
    wb = build_template(["Kq"], station="default", gain_unit="dimensionless")
    wb["students"].append(["Ada"])
    for x in range(5):
        wb["calibration"].append([x * 0.5, 4.2 + 0.85 * x * 0.5])
    path = tmp_path / "g.xlsx"
    wb.save(path)
    sub = read_submission(path)
    assert isinstance(sub.data, InlineData) and sub.data.files["calibration.csv"].startswith("position [in],voltage [V]\n")


def test_xlsx_zip_bomb_and_non_zip(tmp_path: Path) -> None:
    bomb = tmp_path / "bomb.xlsx"
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("xl/big.xml", b"0" * 45_000_000)
    with pytest.raises(SubmissionError, match="unpacks to more than"):
        read_submission(bomb)
    (tmp_path / "fake.xlsx").write_text("not a zip")
    with pytest.raises(SubmissionError, match="not an XLSX"):
        read_submission(tmp_path / "fake.xlsx")


def test_xlsx_answer_on_two_rows_is_refused_naming_both(tmp_path: Path) -> None:
    """The second row would silently replace the first (as a JSON key given twice would). The template's own row
    left blank, with the answer typed on a new row below, is no second answer."""
    wb = build_template(["Kq", "Kpot"], station="default", gain_unit="dimensionless")
    wb["students"].append(["Ada"])
    wb["answers"].append(["Kq", 0.04, "in^3/s/mA"])
    path = tmp_path / "g.xlsx"
    wb.save(path)
    assert read_submission(path).answers["Kq"] == "0.04 in^3/s/mA"
    wb["answers"].append(["Kq", 0.0385, "in^3/s/mA"])
    wb.save(path)
    with pytest.raises(SubmissionError, match=rf"^g.xlsx: sheet 'answers' row {wb['answers'].max_row}: 'Kq' is also "
                                              rf"answered on row {wb['answers'].max_row - 1}; give each answer once$"):
        read_submission(path)


def test_xlsx_answers_are_found_by_the_header_where_a_column_was_inserted_before_them(tmp_path: Path) -> None:
    """Read by position, every answer was 'missing' and nothing said why."""
    wb = build_template(["Kq", "Kpot"], station="default", gain_unit="dimensionless")
    wb["students"].append(["Ada"])
    for r in wb["answers"].iter_rows(min_row=2):
        if r[0].value == "Kq":
            r[1].value, r[2].value = 0.0385, "in^3/s/mA"
    wb["answers"].insert_cols(1)
    path = tmp_path / "g.xlsx"
    wb.save(path)
    assert read_submission(path).answers["Kq"] == "0.0385 in^3/s/mA"


def test_xlsx_info_field_misspelt_is_refused_not_ignored(tmp_path: Path) -> None:
    """Ignored, a misspelt station graded the group against the default station's key. Letter case aside, a known
    field reads; a field nowhere near one is a note."""
    wb = build_template(["Kq"], station="default", gain_unit="dimensionless")
    wb["students"].append(["Ada"])
    wb["info"].append(["notes", "late by a day"])
    path = tmp_path / "g.xlsx"
    wb.save(path)
    assert read_submission(path).notes == ("sheet 'info' row 4: field 'notes' is not read (the fields are "
                                           "submission_id, station)",)
    wb["info"]["A3"], wb["info"]["B3"] = "Station", "rig7"
    wb.save(path)
    assert read_submission(path).station == "rig7"
    wb["info"].append(["staton", "rig2"])
    wb.save(path)
    with pytest.raises(SubmissionError, match=r"^g.xlsx: sheet 'info' row 5: unknown field 'staton'; did you mean "
                                              r"'station'\?$"):
        read_submission(path)


@pytest.mark.parametrize(("value", "unit", "read"), [
    ("0.0385 in^3/s/mA", "ft^3/s/mA", "invalid"),  # glued together, it read 'in³/s/mAft³/s/mA', of a wrong dimension
    ("0.0385 in^3/s/mA", "in^3/s/mA", "0.0385 in^3/s/mA"),  # the same unit twice: given once
    (0.0385, "in^3/s/mA", "0.0385 in^3/s/mA"),
    ("3.85×10⁻²", "in^3/s/mA", "3.85×10⁻² in^3/s/mA"),  # no unit of its own: the column's
])
def test_xlsx_value_with_its_own_unit_and_a_unit_column(tmp_path: Path, value: object, unit: str, read: str) -> None:
    wb = build_template(["Kq"], station="default", gain_unit="dimensionless")
    wb["students"].append(["Ada"])
    for r in wb["answers"].iter_rows(min_row=2):
        if r[0].value == "Kq":
            r[1].value, r[2].value = value, unit
    wb.save(tmp_path / "g.xlsx")
    got = read_submission(tmp_path / "g.xlsx").answers["Kq"]
    if read == "invalid":
        assert isinstance(got, InvalidAnswer) and "carries its own unit and the unit column says 'ft^3/s/mA'" in got.reason
    else:
        assert got == read


def test_a_tab_or_line_break_in_a_name_reads_as_a_space(tmp_path: Path) -> None:
    sub = read_submission(_write(tmp_path, "s.json", {"submission_id": "s", "students": [{"name": "Ada\tLovelace\n"}]}))
    assert sub.students[0].name == "Ada Lovelace"
