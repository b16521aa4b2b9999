"""Not-reachable items: the accepted words, the verdicts, error carried forward, key-safe feedback.

The key context is the default station's with ``Kp_25_overshoot`` marked not reachable, so
every verdict path runs without simulating a second rig (tests/identify/test_not_reachable.py
builds a rig that really has no 25 % gain).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from grader.grading.context import KeyContext
from grader.grading.ecf import student_model
from grader.grading.grade import GradeOptions, grade_submission
from grader.grading.submissions import Submission
from grader.grading.unreachable import NOT_REACHABLE_WORDS, says_not_reachable
from grader.keys import KeyEntry
from grader.model import zloop

REASON = "the identified loop peaks at 21 % overshoot below its critical gain 57.3, so no P gain gives 25 % overshoot"


@pytest.fixture(scope="module")
def kc_nr(kc: KeyContext) -> KeyContext:
    """The default key with Kp_25_overshoot not reachable."""
    old = kc.key.quantities["Kp_25_overshoot"]
    entry = KeyEntry(value=None, unit=old.unit, interval=None, method=old.method, inputs=old.inputs,
                     status="not_reachable", reason=REASON)
    key = kc.key.model_copy(update={"quantities": {**kc.key.quantities, "Kp_25_overshoot": entry}})
    return KeyContext(key=key, dataset=kc.dataset, source="station")


def _grade(kc: KeyContext, opts: GradeOptions, answers: dict[str, Any], *, reveal: bool = True) -> dict[str, Any]:
    sub = Submission("s", Path("s.json"), (), "default", answers)
    res = grade_submission(sub, kc, GradeOptions(rubric=opts.rubric, convention="volts", reveal=reveal))
    return {r.item: r for r in res.items}


@pytest.mark.parametrize("text", ["not reachable", "Not Reachable", "NOT_REACHABLE", "not-reachable", " none ",
                                  "None", "N/A", "n/a", "na", "unreachable", "not identifiable", "Not_Identifiable",
                                  "unidentifiable"])
def test_accepted_words(text: str) -> None:
    assert says_not_reachable(text)


@pytest.mark.parametrize("raw", ["0", "49.7", "not", "reachable", "no", "nan", "null", "", "none of them", 0, None, ["none"]])
def test_other_answers_are_not_the_words(raw: Any) -> None:
    assert not says_not_reachable(raw)


@given(st.text(max_size=30))
def test_only_the_documented_words_after_normalisation(text: str) -> None:
    normal = " ".join(text.replace("_", " ").replace("-", " ").lower().split())
    assert says_not_reachable(text) == (normal in NOT_REACHABLE_WORDS)


def _kce_scaled(kc: KeyContext, factor: float) -> tuple[str, float | None]:
    kce = factor * kc.value("Kce")
    return f"{kce:.6g} in^3/s/psi", zloop.gain_for_overshoot(student_model(kc, {"Kce": kce}), 0.25)


# (case, key has Kp_25?, answers, expected status of Kp_25_overshoot)
CASES = [
    ("word for a not-reachable item", False, {"Kp_25_overshoot": "not reachable"}, "correct"),
    ("other word, other case", False, {"Kp_25_overshoot": "N/A"}, "correct"),
    ("number for a not-reachable item", False, {"Kp_25_overshoot": "49.7"}, "incorrect"),
    ("word for a reachable item", True, {"Kp_25_overshoot": "none"}, "incorrect"),
    ("blank stays missing", False, {"Kp_25_overshoot": ""}, "missing"),
]


@pytest.mark.parametrize(("case", "reachable", "answers", "status"), CASES, ids=[c[0] for c in CASES])
def test_verdicts(kc: KeyContext, kc_nr: KeyContext, opts: GradeOptions, case: str, reachable: bool,
                  answers: dict[str, Any], status: str) -> None:
    r = _grade(kc if reachable else kc_nr, opts, answers)["Kp_25_overshoot"]
    assert r.status == status, r.feedback
    assert r.points == (r.max_points if status == "correct" else 0.0)


def test_not_reachable_follows_from_the_students_own_light_damping(kc: KeyContext, opts: GradeOptions) -> None:
    kce, gain = _kce_scaled(kc, 0.4)
    assert gain is None  # with this Kce the student's model has no 25 % gain
    r = _grade(kc, opts, {"Kce": kce, "Kp_25_overshoot": "not reachable"})
    assert r["Kce"].status == "incorrect"
    assert r["Kp_25_overshoot"].status == "correct_ecf" and r["Kp_25_overshoot"].mistake == "ecf"


def test_a_number_from_the_students_own_model_earns_ecf_where_the_key_has_none(kc: KeyContext, kc_nr: KeyContext,
                                                                                  opts: GradeOptions) -> None:
    kce, gain = _kce_scaled(kc, 1.3)
    assert gain is not None
    r = _grade(kc_nr, opts, {"Kce": kce, "Kp_25_overshoot": f"{gain:.4g}"})
    assert r["Kp_25_overshoot"].status == "correct_ecf"


@pytest.mark.parametrize("reveal", [True, False])
def test_feedback_on_a_number_explains_and_reveals_only_when_allowed(kc_nr: KeyContext, opts: GradeOptions,
                                                                     reveal: bool) -> None:
    text = _grade(kc_nr, opts, {"Kp_25_overshoot": "49.7"}, reveal=reveal)["Kp_25_overshoot"].feedback
    assert "not reachable" in text
    assert ("57.3" in text) == reveal and ("21 %" in text) == reveal


@pytest.mark.parametrize("reveal", [True, False])
def test_feedback_on_a_word_for_a_reachable_item(kc: KeyContext, opts: GradeOptions, reveal: bool) -> None:
    text = _grade(kc, opts, {"Kp_25_overshoot": "n/a"}, reveal=reveal)["Kp_25_overshoot"].feedback
    shown = f"{kc.value('Kp_25_overshoot'):.4g}"
    assert "incorrect" in text and (shown in text) == reveal


NI_REASON = "the instability run shows 2 cycles of oscillation above 0.002 in before it dies out, fewer than 8"
NI_ITEMS = ("omega_crit", "growth_rate", "Kp_crit", "beta_over_Vt", "Kce", "char_poly_a2", "char_poly_a1",
            "char_poly_a0_per_Kp", "beta_over_Vt_model", "Kce_model", "Kp_crit_model", "Kp_no_overshoot",
            "Kp_25_overshoot", "ramp_ess_P", "closed_loop_poles")


@pytest.fixture(scope="module")
def kc_ni(kc: KeyContext) -> KeyContext:
    """The default key as `grader key` writes it for data whose instability run does not oscillate."""
    q = {**kc.key.quantities}
    for name in NI_ITEMS:
        old = q[name]
        q[name] = KeyEntry(value=None, unit=old.unit, interval=None, method=old.method, inputs={},
                           status="not_identifiable", reason=NI_REASON)
    model = kc.key.model.model_copy(update={"beta_over_Vt": None, "Kce": None})
    return KeyContext(key=kc.key.model_copy(update={"quantities": q, "model": model}), dataset=kc.dataset, source="station")


# (answers, expected statuses) against a key whose data give no β/Vt and Kce
NI_CASES = [
    ({"Kce": "not identifiable", "Kp_crit": "N/A", "closed_loop_poles": "not identifiable"},
     {"Kce": "correct", "Kp_crit": "correct", "closed_loop_poles": "correct"}),
    ({"Kce": "7e-4 in^3/s/psi", "Kp_no_overshoot": "20", "closed_loop_poles": [{"Kp": 10, "poles": ["-50+300j", "-50-300j", "-200"]}]},
     {"Kce": "incorrect", "Kp_no_overshoot": "incorrect", "closed_loop_poles": "incorrect"}),
    # a wrong upstream value asks for the matching to be redone, which such a key cannot: graded against the key
    # (it read "this answer could not be checked: KeyError")
    ({"Kq": "0.03848 in^3/s/mA", "omega_crit": "148.4 rad/s", "Kp_crit": 58.0, "beta_over_Vt": "19060 psi/in^3",
      "Kce": "0.0008452 in^3/s/psi"}, {"beta_over_Vt": "incorrect", "Kce": "incorrect"}),
    ({"Kq": "0.05 in^3/s/mA", "Kp_no_overshoot": "20", "pd_design": {"Kp": 10, "Kd": 0.05}},
     {"Kq": "incorrect", "Kp_no_overshoot": "incorrect", "pd_design": "invalid"}),
]


@pytest.mark.parametrize(("answers", "expected"), NI_CASES)
def test_not_identifiable_items_are_graded_like_not_reachable_ones(kc_ni: KeyContext, opts: GradeOptions,
                                                                   answers: dict[str, Any], expected: dict[str, str]) -> None:
    got = _grade(kc_ni, opts, answers)
    assert {n: got[n].status for n in expected} == expected, {n: got[n].feedback for n in expected}
    if "pd_design" in expected:
        assert "cannot be checked" in got["pd_design"].feedback and "no model" in got["pd_design"].feedback
    if got["Kce"].status == "incorrect":
        assert NI_REASON in got["Kce"].feedback
