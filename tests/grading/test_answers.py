"""Reading answer values: quantities, poles, designs."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.grading.answers import AnswerError, Gains, parse_pole, read_design, read_poles, read_quantity, to_unit


@pytest.mark.parametrize(("text", "poles"), [
    ("-25.8+153.6j", [complex(-25.8, 153.6)]),
    ("-25.8 ± 153.6j", [complex(-25.8, 153.6), complex(-25.8, -153.6)]),
    ("-25.8 +/- 153.6i", [complex(-25.8, 153.6), complex(-25.8, -153.6)]),
    ("-25.8 + j153.6", [complex(-25.8, 153.6)]),
    ("(-11.3)", [complex(-11.3, 0)]),
    ("153j", [complex(0, 153)]),
    ("-1e1-2e0j", [complex(-10, -2)]),
    (-4, [complex(-4, 0)]),
    ([-1, 2], [complex(-1, 2)]),
    ({"re": -1, "im": -2}, [complex(-1, -2)]),
])
def test_poles(text: object, poles: list[complex]) -> None:
    assert parse_pole(text, "p") == poles


@pytest.mark.parametrize("bad", ["abc", "1e400", "--3", "3jj", True, None, "x" * 100, [1, 2, 3]])
def test_bad_poles(bad: object) -> None:
    with pytest.raises(AnswerError):
        parse_pole(bad, "p")


def test_pole_answer_forms_agree() -> None:
    a = read_poles([{"Kp": 10, "poles": ["-1 ± 2j", -3]}])
    b = read_poles({"Kp=10": [[-1, 2], [-1, -2], "-3"]})
    assert a == b and a[0][0] == Gains(10.0)


def test_pole_answer_limits() -> None:
    with pytest.raises(AnswerError, match="more than"):
        read_poles({str(k): [-1] for k in range(1, 40)})
    with pytest.raises(AnswerError, match="expected a list"):
        read_poles({"10": "-1"})


def test_hz_converts_with_two_pi_to_rad_per_second() -> None:
    assert to_unit(read_quantity("25 Hz", unit="rad/s", what="w"), "rad/s") == pytest.approx(50 * math.pi)
    assert to_unit(read_quantity("60 rpm", unit="rad/s", what="w"), "rad/s") == pytest.approx(2 * math.pi)


@pytest.mark.parametrize(("raw", "unit", "value"), [
    ("0.0385 in^3/s/mA", "in**3/s/mA", 0.0385),
    ("2.228e-5 ft**3/(s*mA)", "in**3/s/mA", 2.228e-5 * 1728),
    (0.5, "in**3/s/mA", 0.5),
    ("0.5", "in**3/s/mA", 0.5),
    ("0.08 gpm", "in**3/s", 0.08 * 231 / 60),
])
def test_quantities(raw: object, unit: str, value: float) -> None:
    assert to_unit(read_quantity(raw, unit=unit, what="x"), unit) == pytest.approx(value)


def test_wrong_dimension_is_none_not_an_error() -> None:
    assert to_unit(read_quantity("0.0385 in^3/s", unit="in**3/s/mA", what="x"), "in**3/s/mA") is None


@pytest.mark.parametrize("raw", [float("nan"), float("inf"), "nan in", [1], {"a": 1}, True, "1" * 500, "rm -rf /"])
def test_unreadable_quantities(raw: object) -> None:
    with pytest.raises(AnswerError):
        read_quantity(raw, unit="in", what="x")


def test_designs() -> None:
    pd = read_design({"Kp": 40, "Kd": "2 ms", "overshoot": "5 %"}, item="pd_design", gain_unit="dimensionless")
    assert pd.gains == Gains(40.0, 0.0, 0.002) and pd.claim == pytest.approx(0.05)
    pi = read_design({"Kp": "12 V/in", "Ki": "3 V/in/s"}, item="pi_design", gain_unit="V/in")
    assert pi.gains == Gains(12.0, 3.0, 0.0) and pi.claim is None
    for bad in ({"Kp": 40}, {"Kp": 0, "Kd": 1}, {"Kp": 40, "Kd": -1}, {"Kp": 40, "Kd": 1, "speed": 3}, "fast",
                {"Kp": 40, "Kd": "1 V"}):
        with pytest.raises(AnswerError):
            read_design(bad, item="pd_design", gain_unit="dimensionless")


@settings(max_examples=400, deadline=None)
@given(st.text(alphabet="0123456789 .+-*/^()eEinsmAVlbfpsi%µ°", min_size=1, max_size=20))
def test_any_text_is_a_quantity_or_an_answer_error(text: str) -> None:
    try:
        read_quantity(text, unit="in", what="x")
    except AnswerError:
        pass
