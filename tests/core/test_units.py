"""The single registry: parsing with units, guards against hostile strings."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.errors import UnitError
from grader.units import parse_quantity, parse_unit, quantity_to_float, to_float, ureg


@pytest.mark.parametrize(
    ("text", "unit", "expected"),
    [
        ("0.0385 in^3/s/mA", "in**3/s/mA", 0.0385),
        ("2.2e-5 ft**3/(s*mA)", "in**3/s/mA", 2.2e-5 * 1728),
        ("0.5 gpm", "in**3/s", 0.5 * 231 / 60),
        ("29 lbf", "lbf", 29.0),
        ("6.895 kPa", "psi", 1.0000),
        ("1 ms", "s", 1e-3),
        (12, "V/in", 12.0),
        # powers just before a closing bracket
        ("100 lbf/(in^2)", "psi", 100.0),
        ("0.05 (lbf*s^2)/in", "lbf*s**2/in", 0.05),
        ("1 in**3/(mA*s**1)", "in**3/s/mA", 1.0),
        # as the reports and the preview print them
        ("0.0385 in³/s/mA", "in**3/s/mA", 0.0385),
        ("0.5 lbf·s/in", "lbf*s/in", 0.5),
        ("2.23×10⁻⁵ ft³/mA/s", "in**3/s/mA", 2.23e-5 * 1728),
        ("3 s⁻¹", "1/s", 3.0),
    ],
)
def test_parse_and_convert(text: str | int, unit: str, expected: float) -> None:
    assert quantity_to_float(text, unit) == pytest.approx(expected, rel=1e-3)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("", "empty"),
        ("x" * 500, "longer than"),
        ("__import__('os')", "contains \"'\", which a quantity cannot hold"),
        ("2 m**99999999", "small whole power"),
        ("1 mA**(1/3)", "small whole power"),  # a fraction in brackets: read as mA**0.333 before
        ("1" * 60 + " m", "too large"),
        ("3 blargs", "cannot read .3 blargs. as a number with a unit$"),
        ("0.0385 in3/s/mA", "did you mean in\\^3/s/mA\\?$"),
        ("2 psii", "did you mean psi\\?$"),
        ("nan m", "finite"),
        ("1 in/0", "^answers.Kq: '1 in/0' divides by zero$"),
    ],
)
def test_hostile_or_bad_quantities_raise_unit_error(text: str, words: str) -> None:
    with pytest.raises(UnitError, match=words):
        parse_quantity(text, where="answers.Kq")


def test_an_integer_too_large_for_a_float_is_a_unit_error() -> None:
    with pytest.raises(UnitError, match=r"^answers.Kq: a number too large \(401 digits\)$"):
        parse_quantity(10**400, where="answers.Kq")


def test_wrong_dimension_is_named() -> None:
    with pytest.raises(UnitError, match=r"^answers.Kq: psi is a pressure; expected a flow per current \(in³/s/mA\)$"):
        quantity_to_float("3 psi", "in**3/s/mA", where="answers.Kq")


def test_parse_unit_rejects_quantities() -> None:
    assert parse_unit("L/min") == ureg.Unit("L/min")
    with pytest.raises(UnitError, match="quantity, not a unit"):
        parse_unit("3 m")
    with pytest.raises(UnitError, match="^unit: 'in/0' divides by zero$"):
        parse_unit("in/0")


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=60))
def test_any_text_either_parses_or_raises_unit_error(text: str) -> None:
    try:
        parse_quantity(text)
    except UnitError:
        pass


@pytest.mark.parametrize("text", ["9^9^9 in^3/s/mA", "2**99**9", "99**99**99 in", "1 m**13", "10**3 m", "2 s^(9^9)"])
def test_powers_are_limited_to_units_raised_to_small_integers(text: str) -> None:
    with pytest.raises(UnitError, match="small whole power"):
        parse_quantity(text)


@pytest.mark.parametrize("text", ["0.03851 %%", "0.03851*ppm", "58 percent"])
def test_dimensionless_units_are_not_dropped(text: str) -> None:
    """A written dimensionless unit is kept (and so is a wrong dimension), unlike a bare number."""
    with pytest.raises(UnitError, match=r"is a plain number \(no unit\); expected a flow per current"):
        to_float(parse_quantity(text, default_unit="in**3/s/mA"), "in**3/s/mA")
    assert to_float(parse_quantity("0.03851", default_unit="in**3/s/mA"), "in**3/s/mA") == 0.03851
