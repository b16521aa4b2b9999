"""Messages a student or an instructor reads: plain sentences, no jargon, nothing eaten by rich."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from grader.cli import main

FIXTURES = Path(__file__).resolve().parents[2] / "submissions_fixtures" / "grading"
POLES = json.loads((FIXTURES / "correct.json").read_text())["answers"]["closed_loop_poles"]  # runs repeat Kp = 10


def _check(tmp_path: Path, capsys: pytest.CaptureFixture[str], **answers: object) -> str:
    data = json.loads((FIXTURES / "correct.json").read_text())
    data["answers"].update(answers)
    for name in [k for k in answers if answers[k] is None]:
        del data["answers"][name]
    (tmp_path / "s.json").write_text(json.dumps(data))
    assert main(["check", str(tmp_path / "s.json")]) == 0
    return " ".join(capsys.readouterr().out.replace("│", " ").split())  # the table's cells as one text


@pytest.mark.parametrize("answers, expected", [
    ({"Kpot": "0.85 V/s"}, "Kpot = 0.85 V/s: V/s is a voltage per time; Kpot needs a voltage per length (V/in)."),
    ({"Kq": "0.0385 in3/s/mA"},
     "Kq: could not read your answer: cannot read '0.0385 in3/s/mA' as a number with a unit; did you mean in^3/s/mA?"),
    ({"Kce": "0.0007475 in^3/s/psii"}, "did you mean in^3/s/psi?"),
    ({"Kq": None, "kq": "0.03851 in^3/s/mA"}, "Kq = 0.03851 in³/s/mA: correct."),
    ({"Kq": None, "kq": "0.03851 in^3/s/mA"}, "note: answer 'kq' was read as 'Kq'"),
    ({"closed_loop_poles": [{"Kp": 10, "poles": ["-1"]}, {"Kp": 10, "Ki": 5, "poles": ["x"]}]},
     "entry 2 (Kp = 10, Ki = 5, Kd = 0), pole 1: cannot read 'x' as a pole"),
    ({"closed_loop_poles": "Kp=10 -20+150j"},  # what the page sends when it cannot split the text
     "closed-loop poles: could not read your answer: cannot read 'Kp=10 -20+150j': write one gain a line, as "
     "Kp=10: -20+150j, -20-150j, -12"),
    ({"pd_design": "hello"}, "PD design: could not read your answer: cannot read 'hello': write Kp = …, Kd = …, overshoot = …"),
    ({"char_poly": "1/(s^2+"}, "characteristic polynomial: could not read your answer: cannot read it: '(' was never closed"),
    ({"char_poly": "s^3 + * 2"}, "write products with * or a space"),
    ({"char_poly": "0"}, "your characteristic polynomial is zero; the loop's is of degree 3 in s"),  # not "-inf"
    ({}, "PD design: the loop is stable on the model identified from your group's lab data"),  # the key's model
    ({"Kq": "0.03851 in³/s/mA"}, "Kq = 0.03851 in³/s/mA: correct."),  # as the reports print it
    ({"Kce": "0,0007475 in^3/s/psi"}, "contains ',', which a quantity cannot hold (a decimal comma? write 0.04)"),
    ({"closed_loop_poles": [*POLES, {"Kp": 11, "poles": ["-1", "-2", "-3"]}]},
     "closed-loop poles: correct at every gain. Poles given at 1 gain(s) that none of the lab's runs used were not "
     "graded."),  # grader check never names the lab's gains
    ({"closed_loop_poles": [*POLES, {**POLES[0], "poles": ["-1", "-2", "-3"]}]},  # a second, other set at Kp = 10
     "closed-loop poles: wrong at Kp = 10 (right at the other 4)."),
])
def test_check_feedback_is_plain(answers: dict, expected: str, tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    out = _check(tmp_path, capsys, **answers)
    assert expected in out
    assert not re.search(r"\w+Error\b|\[(mass|length|time|current)\]", out)
    assert "answer: Kq:" not in out and "answer: Kce:" not in out  # the item's name is not repeated


@pytest.mark.parametrize("doc, expected", [
    ({"submission_id": "a", "students": "bob", "answers": {}}, "s.json: field students should be a list, e.g. [a, b], not text"),
    ({"submission_id": "a b!", "students": [{"name": "x"}]},
     "s.json: field submission_id: 'a b!' must be 1-64 letters, digits, _ . - starting with a letter or digit"),
    ({"students": [{"name": "x"}], "answer": {}}, "s.json: field submission_id is required but missing "
                                                  "(and 1 more field with problems)"),
    ({"submission_id": "a", "students": [{"name": "Ada\u0001L"}]},  # would have failed the whole gradebook
     "s.json: field students.0.name: contains a control character (U+0001)"),
    ({"submission_id": "a", "students": [{"name": "\t\n"}]}, "s.json: field students.0.name: holds only blanks"),
])
def test_file_errors_are_plain(doc: dict, expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "s.json").write_text(json.dumps(doc))
    assert main(["check", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"grader check: error: {expected}") and err.count("\n") == 1
    assert "Input should" not in err and "pattern" not in err and "(+" not in err
