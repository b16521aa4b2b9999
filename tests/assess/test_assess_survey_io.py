"""Survey readers: the three forms agree, and every bad file gets a clear error."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from openpyxl import Workbook

from grader.assess import build_survey_report, load_mapping, read_survey
from grader.assess.survey_io import detect_form
from grader.assess.tables import read_table
from grader.errors import AssessmentError

FIXTURES = Path(__file__).resolve().parents[2] / "submissions_fixtures" / "assessment"
MAPPING = load_mapping()
FORMS = {
    "survey_template.csv": "template",
    "survey_template.xlsx": "template",
    "survey_qualtrics.csv": "qualtrics",
    "survey_google_forms.csv": "google",
}


def _rows(name: str) -> list[list[str]]:
    with (FIXTURES / name).open(encoding="utf-8", newline="") as handle:
        return list(csv.reader(handle))


def _write(path: Path, rows: list[list[str]]) -> Path:
    with path.open("w", encoding="utf-8", newline="") as handle:
        csv.writer(handle).writerows(rows)
    return path


def _error(path: Path, mapping=MAPPING) -> str:
    with pytest.raises(AssessmentError) as info:
        read_survey(path, mapping)
    message = str(info.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize(("name", "form"), FORMS.items())
def test_forms_are_recognised(name: str, form: str) -> None:
    assert detect_form(read_table(FIXTURES / name)) == form


def test_all_forms_give_identical_figures() -> None:
    dumps = {
        name: build_survey_report(read_survey(FIXTURES / name, MAPPING), MAPPING).model_dump(
            mode="json", exclude={"form", "notes"}
        )
        for name in FORMS
    }
    reference = dumps["survey_template.csv"]
    assert reference["respondents"] == 65
    for name, dump in dumps.items():
        assert dump == reference, name


def test_missing_data_are_counted_not_neutral() -> None:
    data = read_survey(FIXTURES / "survey_template.csv", MAPPING)
    report = build_survey_report(data, MAPPING)
    for item in report.items:
        assert item.n + item.n_missing + item.n_not_done == 65
        assert sum(item.counts) == item.n
    two_tank = next(lab for lab in report.labs if lab.lab == "two_tank")
    assert (two_tank.did_no, two_tank.ratings_discarded) == (4, 5)
    assert any("5 Two-Tank ratings were left out" in note for note in report.notes)


def test_qualtrics_previews_are_left_out() -> None:
    data = read_survey(FIXTURES / "survey_qualtrics.csv", MAPPING)
    assert data.respondents == 65
    assert any("preview" in note for note in data.notes)


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("survey_bad_header.csv", ['"hydraulic_positioner.simulink"', "Hydraulic Positioner", "misspelt",
                                   '"hydraulic_positoner.simulink"']),
        ("survey_bad_value_7.csv", ["row 13", 'column V "hydraulic_pid.models"', "Hydraulic PID",
                                    '"7" is outside the scale 1-5']),
        ("survey_missing_lab.csv", ["the Two-Tank lab is missing", "none of its 6 columns", '"two_tank.did_lab"']),
        ("survey_empty.csv", ["survey_empty.csv", "the file is empty"]),
    ],
)
def test_shipped_bad_files(name: str, expected: list[str]) -> None:
    message = _error(FIXTURES / name)
    for part in expected:
        assert part in message


def test_google_error_names_spreadsheet_row_and_header(tmp_path: Path) -> None:
    rows = _rows("survey_google_forms.csv")
    col = rows[0].index("The Hydraulic PID Controller Laboratory: [was a good use of my time.]")
    rows[9][col] = "7"
    message = _error(_write(tmp_path / "google.csv", rows))
    assert "row 10," in message and "[was a good use of my time.]" in message and "Hydraulic PID" in message


def test_qualtrics_error_counts_its_three_header_rows(tmp_path: Path) -> None:
    rows = _rows("survey_qualtrics.csv")
    rows[5][rows[0].index("Q6_3")] = "Sometimes"
    message = _error(_write(tmp_path / "qualtrics.csv", rows))
    assert 'row 6, column' in message and '"Q6_3"' in message and '"Sometimes" is not a rating' in message


def test_xlsx_error_names_row_and_column(tmp_path: Path) -> None:
    rows = _rows("survey_template.csv")
    workbook = Workbook()
    for row in rows:
        workbook.active.append([int(c) if c.isdigit() else (c or None) for c in row])
    workbook.active.cell(row=20, column=3, value=9)
    workbook.save(tmp_path / "responses.xlsx")
    message = _error(tmp_path / "responses.xlsx")
    assert message.startswith(f"{tmp_path / 'responses.xlsx'}, row 20, column C") and '"9" is outside the scale' in message


def test_bad_did_lab_flag(tmp_path: Path) -> None:
    rows = _rows("survey_template.csv")
    rows[3][rows[0].index("motomatic.did_lab")] = "Perhaps"
    message = _error(_write(tmp_path / "t.csv", rows))
    assert "row 4" in message and "Motomatic / did this lab" in message and "not Yes or No" in message


def test_unknown_template_column_is_a_wrong_header(tmp_path: Path) -> None:
    rows = [[*row, "x"] for row in _rows("survey_template.csv")]
    rows[0][-1] = "comments"
    message = _error(_write(tmp_path / "t.csv", rows))
    assert 'wrong header: column AD "comments" is not a template column' in message


def test_header_of_no_known_form(tmp_path: Path) -> None:
    message = _error(_write(tmp_path / "odd.csv", [["name", "score"], ["a", "1"]]))
    assert "matches none of the survey forms" in message


def test_header_without_responses(tmp_path: Path) -> None:
    message = _error(_write(tmp_path / "t.csv", _rows("survey_template.csv")[:1]))
    assert "has a header but no responses" in message


@pytest.mark.parametrize("name", ["survey_template.csv", "survey_qualtrics.csv"])
def test_a_response_pasted_twice_is_refused_naming_both_rows(tmp_path: Path, name: str) -> None:
    """The template's respondent and Qualtrics' ResponseId identify a response: counted twice, it would weigh twice."""
    rows = _rows(name)
    col = next(i for i, h in enumerate(rows[0]) if h.strip().casefold() in ("respondent", "responseid"))
    first = 3 if name == "survey_qualtrics.csv" else 1  # after Qualtrics' three header rows
    rows.append(list(rows[first + 5]))
    message = _error(_write(tmp_path / name, rows))
    assert f"row {len(rows)}: respondent {rows[first + 5][col]!r} is also on row {first + 6}" in message


def test_a_cell_over_the_csv_field_limit_is_named_by_its_line(tmp_path: Path) -> None:
    rows = _rows("survey_template.csv")
    rows[4][-1] = "x" * 140_000  # a pasted essay: over the csv module's 131072 characters
    assert "not a valid CSV file at line 5 (field larger than field limit" in _error(_write(tmp_path / "t.csv", rows))


def test_duplicated_column(tmp_path: Path) -> None:
    rows = [[*row, row[2]] for row in _rows("survey_template.csv")]
    assert "appears more than once" in _error(_write(tmp_path / "t.csv", rows))


@pytest.mark.parametrize(
    ("name", "content", "expected"),
    [("r.json", b"{}", "unsupported file type .json"), ("r.xlsx", b"not a zip", "not a readable XLSX")],
)
def test_unreadable_files(tmp_path: Path, name: str, content: bytes, expected: str) -> None:
    (tmp_path / name).write_bytes(content)
    assert expected in _error(tmp_path / name)


@pytest.mark.parametrize(
    ("yaml_text", "expected"),
    [
        ("scale: [unclosed", "not valid YAML"),
        ("scale: {labels: [a, b]}\nstatements: []\nlabs: []\n", "statements"),
        ("scale: {labels: [a, b]}\nstatements: [{id: s, label: S, text: t}]\nlabs:\n"
         "  - {id: a, name: A, qualtrics: {items: 'Q_{x}'}}\n  - {id: b, name: B}\n", "{statement}"),
    ],
)
def test_bad_mapping_files(tmp_path: Path, yaml_text: str, expected: str) -> None:
    path = tmp_path / "map.yaml"
    path.write_text(yaml_text, encoding="utf-8")
    with pytest.raises(AssessmentError) as info:
        load_mapping(path)
    assert str(info.value).startswith("map.yaml: ") and expected in str(info.value)


def test_a_scale_labelled_no_to_yes_is_text(tmp_path: Path) -> None:
    """YAML 1.1 read No, Yes, On and Off as booleans: the mapping was refused ("Input should be a valid string")."""
    path = tmp_path / "map.yaml"
    path.write_text("scale: {labels: [No, Rather no, Unsure, Rather yes, Yes], synonyms: {Y: 5, N: 1}, missing: [Off]}\n"
                    "statements: [{id: s, label: S, text: t}]\nlabs: [{id: x, name: X}, {id: y, name: Y}]\n", encoding="utf-8")
    scale = load_mapping(path).scale
    assert scale.labels == ("No", "Rather no", "Unsure", "Rather yes", "Yes") and scale.missing == ("Off",)
    assert scale.synonyms == {"Y": 5, "N": 1}
    assert [scale.parse(a) for a in ("yes", "No", "Y", "off")] == [5, 1, 5, None]


def test_mapping_without_columns_for_the_form(tmp_path: Path) -> None:
    path = tmp_path / "map.yaml"
    path.write_text(
        "scale: {labels: [a, b, c]}\nstatements: [{id: s, label: S, text: t}]\n"
        "labs: [{id: x, name: X}, {id: y, name: Y}]\nhours: null\nmost_useful: null\n",
        encoding="utf-8",
    )
    message = _error(FIXTURES / "survey_qualtrics.csv", load_mapping(path))
    assert "gives no Qualtrics export columns for the X lab" in message


def test_column_letters() -> None:
    from grader.assess.tables import column_letter

    assert [column_letter(i) for i in (0, 25, 26, 29, 701, 702)] == ["A", "Z", "AA", "AD", "ZZ", "AAA"]


def test_fixtures_are_reproducible(tmp_path: Path) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_fixtures", FIXTURES / "make_fixtures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(tmp_path)
    written = sorted(p.name for p in tmp_path.iterdir())
    assert len(written) == 11
    for name in written:
        assert (tmp_path / name).read_bytes() == (FIXTURES / name).read_bytes(), name


def test_a_formula_cell_without_a_saved_value_is_named_not_read_as_missing(tmp_path: Path) -> None:
    """openpyxl saves no value for a formula: read as empty, it made ratings missing without a word."""
    wb = Workbook()
    for row in _rows("survey_template.csv"):
        wb.active.append(row)
    wb.active["O3"] = "=2+3"
    wb.save(tmp_path / "t.xlsx")
    assert "cell O3 holds a formula (=2+3) with no saved value" in _error(tmp_path / "t.xlsx")


def test_qualtrics_numeric_codes_read_like_its_choice_text(tmp_path: Path) -> None:
    """Qualtrics' numeric export codes a Yes/No choice 1 = Yes, 2 = No (a "2" was refused as "not Yes or No") and
    the response type as a number (1 = Survey Preview: such rows were kept as respondents, silently). The same
    answers, coded so, give the same figures as the choice-text export; a did-lab column of 1 and 0 still reads
    1 = Yes, 0 = No."""
    rows = _rows("survey_qualtrics.csv")
    status = rows[0].index("Status")
    coded = [list(r) for r in rows]
    for r in coded[3:]:
        r[:] = [{"Yes": "1", "No": "2"}.get(c, c) for c in r]
        r[status] = {"Survey Preview": "1", "IP Address": "0"}.get(r[status], r[status])
    assert any(r[status] == "1" for r in coded[3:]) and any("2" == c for r in coded[3:] for c in r)
    figures = {
        name: build_survey_report(read_survey(path, MAPPING), MAPPING).model_dump(mode="json", exclude={"form", "notes"})
        for name, path in (("text", FIXTURES / "survey_qualtrics.csv"), ("coded", _write(tmp_path / "n.csv", coded)))
    }
    assert figures["coded"] == figures["text"] and figures["coded"]["respondents"] == 65
    ones_zeros = [list(r) for r in rows]
    for r in ones_zeros[3:]:
        r[:] = [{"Yes": "1", "No": "0"}.get(c, c) for c in r]
    report = build_survey_report(read_survey(_write(tmp_path / "z.csv", ones_zeros), MAPPING), MAPPING)
    assert report.model_dump(mode="json", exclude={"form", "notes"}) == figures["text"]


def test_a_negative_alpha_gets_a_note(tmp_path: Path) -> None:
    """Two Motomatic statements answered reverse-worded (6 − rating): the lab's Cronbach's alpha falls below 0, and a
    note says what that means and how to recode; the other labs' alphas are untouched and get none."""
    rows = _rows("survey_template.csv")
    for name in ("motomatic.models", "motomatic.controllers"):
        col = rows[0].index(name)
        for r in rows[1:]:
            r[col] = str(6 - int(r[col])) if r[col].strip().isdigit() else r[col]
    report = build_survey_report(read_survey(_write(tmp_path / "rev.csv", rows), MAPPING), MAPPING)
    alpha = {a.lab: a.value for a in report.alpha}
    assert alpha["motomatic"] is not None and alpha["motomatic"] < 0 < min(v for k, v in alpha.items() if k != "motomatic")
    (note,) = [n for n in report.notes if "Cronbach's alpha" in n]
    assert note.startswith("Cronbach's alpha for Motomatic is -") and "reverse-worded" in note


def test_a_did_lab_column_mixing_0_1_and_2_is_refused_naming_the_cell(tmp_path: Path) -> None:
    """1/2 (Qualtrics) and 1/0 codings are each read; a column holding 0, 1 and 2 at once is neither, and its first
    cell that fits no coding is named."""
    rows = _rows("survey_qualtrics.csv")
    col = next(i for i, r in enumerate(zip(*rows[3:])) if set(r) >= {"Yes", "No"})
    mixed = [list(r) for r in rows]
    for r in mixed[3:]:
        r[col] = {"Yes": "1", "No": "0"}.get(r[col], r[col])
    status = rows[0].index("Status")
    row = next(k for k, r in enumerate(mixed) if k >= 3 and r[col] == "1" and r[status] != "Survey Preview")
    mixed[row][col] = "2"
    message = _error(_write(tmp_path / "mixed.csv", mixed))
    assert f"row {row + 1}" in message and '"2" is not Yes or No' in message
