"""Implicit products (``4 beta Kq A``, ``4beta``, ``2(s+1)``, ``Kp Kamp``): a tokenizer, never eval."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.errors import ExpressionError
from grader.grading.expressions import implicit_products, parse_expression, to_ratfunc
from grader.grading.submissions import read_submission
from grader.model.symbolic import COURSE_SYMBOLS

SAME = [
    ("4 beta Kq A", "4*beta*Kq*A"),
    ("4beta", "4*beta"),
    ("2(s+1)", "2*(s+1)"),
    ("Kp Kamp", "Kp*Kamp"),
    ("(s+1)(s+2)", "(s+1)*(s+2)"),
    ("Kp(s + 1)", "Kp*(s + 1)"),
    ("K_p K_amp", "Kp*Kamp"),
    ("1.5e-3s", "0.0015*s"),
    ("2s^2 + 3s + 1", "2*s**2 + 3*s + 1"),
    ("1/2s", "s/2"),  # the documented ambiguity: an implicit product binds like '*'
    ("4 β A Kp Kamp Kpot Kq / (M Vt s^3 + 4β A^2 s)", "4*beta*A*Kp*Kamp*Kpot*Kq/(M*Vt*s**3 + 4*beta*A**2*s)"),
]


@pytest.mark.parametrize(("implicit", "explicit"), SAME)
def test_implicit_equals_explicit(implicit: str, explicit: str) -> None:
    assert to_ratfunc(parse_expression(implicit)) == to_ratfunc(parse_expression(explicit))


def test_kpot_is_one_symbol() -> None:
    assert parse_expression("Kpot").symbols == {"Kpot"}
    assert parse_expression("Kp Kpot").symbols == {"Kp", "Kpot"}
    with pytest.raises(ExpressionError, match="unknown symbol 'KpKamp'"):
        parse_expression("KpKamp")  # names are read whole: no guessing how to split them


@pytest.mark.parametrize(("text", "reason"), [
    ("exp(s)", "function calls"),  # a name that is not a course symbol before '(' stays a (refused) call
    ("__import__('os').system('ls')", "function calls"),
    ("s if Kp else 1", "not allowed"),  # keywords are never operands
    ("2 3", "write products with * or a space"),  # two numbers side by side are not a product
    ("s 2", "write products with * or a space"),
])
def test_still_refused(text: str, reason: str) -> None:
    with pytest.raises(ExpressionError, match=reason.replace("*", r"\*")):
        parse_expression(text)


_ATOMS = st.sampled_from([*COURSE_SYMBOLS, "2", "0.5", "3e2", "(s+1)", "(Kp+2)"])


@settings(max_examples=150, deadline=None)
@given(st.lists(_ATOMS, min_size=1, max_size=6), st.lists(st.sampled_from([" ", "  ", ""]), min_size=6, max_size=6))
def test_products_read_as_products(atoms: list[str], gaps: list[str]) -> None:
    # a number after anything needs '*' (two numbers side by side are refused); a name after a name
    # needs a space (else they read as one name); anything else may touch or be spaced
    text = atoms[0]
    for gap, a, b in zip(gaps, atoms, atoms[1:]):
        if b[0].isdigit():
            gap = "*"
        elif a[0].isalpha() and b[0].isalpha():
            gap = gap or " "
        text += gap + b
    assert to_ratfunc(parse_expression(text)) == to_ratfunc(parse_expression("*".join(atoms)))


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet=st.sampled_from(list("s Kpamb4.2()+-*/^_eβ'\"x")), max_size=40))
def test_tokenizer_only_inserts_stars_and_is_idempotent(text: str) -> None:
    out = implicit_products(text)
    assert out.replace("*", "") == text.replace("*", "")
    assert implicit_products(out) == out


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=60))
def test_any_text_is_read_or_refused_with_a_reason(text: str) -> None:
    try:
        parse_expression(text)
    except ExpressionError as exc:
        assert str(exc) and "\n" not in str(exc)


def test_files_accept_the_same_syntax(tmp_path: Path) -> None:
    doc = {"submission_id": "g1", "students": [{"name": "A"}],
           "answers": {"open_loop_tf": "4 beta A Kp Kamp Kpot Kq / (s(M Vt s^2 + 4beta A^2))"}}
    path = tmp_path / "g1.json"
    path.write_text(json.dumps(doc))
    raw = read_submission(path).answers["open_loop_tf"]
    explicit = "4*beta*A*Kp*Kamp*Kpot*Kq/(s*(M*Vt*s**2 + 4*beta*A**2))"
    assert to_ratfunc(parse_expression(raw)) == to_ratfunc(parse_expression(explicit))
