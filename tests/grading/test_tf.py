"""Transfer-function diagnosis: which coefficient of the characteristic polynomial differs, and how."""

from __future__ import annotations

import pytest

from grader.grading import tf
from grader.grading.expressions import parse_expression, to_ratfunc

CL_DEN = "M*Vt*s^3 + (B*Vt + 4*beta*Kce*M)*s^2 + 4*beta*(A^2 + B*Kce)*s + 4*beta*A*Kp*Kamp*Kpot*Kq"


@pytest.mark.parametrize(("form", "text", "expected"), [
    ("char_poly", CL_DEN.replace("*Kpot", ""), ["the constant term (s^0) is missing a factor Kpot"]),
    ("char_poly", CL_DEN.replace("4*beta*A*Kp", "8*beta*A*Kp"), ["the constant term (s^0) is 2 times what it should be"]),
    ("char_poly", CL_DEN.replace(" + 4*beta*A*Kp*Kamp*Kpot*Kq", ""), ["the constant term (s^0) is missing"]),
    ("char_poly", CL_DEN.replace("(B*Vt + 4*beta*Kce*M)", "4*beta*Kce*M"), ["the s^2 coefficient is missing a term involving B"]),
    ("char_poly", CL_DEN.replace("M*Vt*s^3 + ", ""), ["your characteristic polynomial is of degree 2 in s; the loop's is of degree 3"]),
    ("closed_loop_tf", f"4*beta*A*Kp*Kamp*Kpot*Kq*Kpot/({CL_DEN})", ["the characteristic polynomial is right, but the gain has an extra factor Kpot"]),
    ("closed_loop_tf", f"4*beta*A*Kp*Kamp*Kpot*Kq/({CL_DEN.replace('4*beta*(A^2', '4*beta*Kpot*(A^2')})",
     ["the s coefficient has an extra factor Kpot"]),
])
def test_diagnosis(form: str, text: str, expected: list[str]) -> None:
    e = parse_expression(text)
    ref = tf.reference(form, "volts")
    assert not tf.equivalent(form, to_ratfunc(e), ref)
    assert tf.diagnose(form, to_ratfunc(e), ref, e.symbols, tf.reference_symbols(form, "volts")) == expected


def test_foreign_symbols_are_named() -> None:
    e = parse_expression(f"4*beta*A*Kp*Kamp*Kpot*Kq/({CL_DEN} + Ki)")
    notes = tf.diagnose("closed_loop_tf", to_ratfunc(e), tf.reference("closed_loop_tf", "volts"), e.symbols,
                        tf.reference_symbols("closed_loop_tf", "volts"))
    assert notes[0] == "it uses Ki, which do not appear in this loop"


@pytest.mark.parametrize("code", sorted(tf.TF_MISTAKES))
def test_every_mistake_form_differs_from_the_reference(code: str) -> None:
    for form in tf.TF_MISTAKES[code]:
        assert not tf.equivalent(form, tf.reference(form, "volts", code), tf.reference(form, "volts"))


def test_conventions_differ_only_by_kpot() -> None:
    volts, inches = tf.reference("closed_loop_tf", "volts"), tf.reference("closed_loop_tf", "inches")
    assert not volts == inches
    assert tf.reference_symbols("closed_loop_tf", "volts") - tf.reference_symbols("closed_loop_tf", "inches") == {"Kpot"}
