"""Cell parsing: ratings, labels, missing data, yes/no flags and hours."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from grader.assess.likert import CellValueError, Scale, parse_hours, parse_yes_no
from grader.assess.mapping import load_mapping

SCALE = load_mapping().scale


@pytest.mark.parametrize(
    ("raw", "value"),
    [("1", 1), (" 5 ", 5), ("4.0", 4), ("Strongly Disagree", 1), ("strongly  disagree", 1),
     ("Neutral", 3), ("MOSTLY AGREE", 4), ("Completely Agree", 5), ("Strongly Agree", 5), ("Agree", 4)],
)
def test_ratings_and_labels(raw: str, value: int) -> None:
    assert SCALE.parse(raw) == value


@pytest.mark.parametrize("raw", ["", "   ", "N/A", "n/a", "NA", "Did not do this lab", "did not do this lab", "-"])
def test_missing_is_none_never_neutral(raw: str) -> None:
    assert SCALE.parse(raw) is None


@pytest.mark.parametrize(
    ("raw", "message"),
    [("7", '"7" is outside the scale 1-5'), ("0", "outside the scale"), ("2.5", "outside the scale"),
     ("-1", "outside the scale"), ("Maybe", '"Maybe" is not a rating'), ("nan", "is not a rating")],
)
def test_out_of_scale_values_are_errors(raw: str, message: str) -> None:
    with pytest.raises(CellValueError, match=message):
        SCALE.parse(raw)


@given(st.integers(min_value=-1000, max_value=1000))
def test_any_integer_is_itself_or_an_error(value: int) -> None:
    if 1 <= value <= 5:
        assert SCALE.parse(str(value)) == value
    else:
        with pytest.raises(CellValueError):
            SCALE.parse(str(value))


def test_configurable_labels_and_scale_length() -> None:
    seven = Scale(labels=tuple(f"L{i}" for i in range(1, 8)), missing=("skip",))
    assert seven.parse("l7") == 7 and seven.parse("6") == 6 and seven.parse("skip") is None
    assert seven.midpoint == 4
    with pytest.raises(CellValueError):
        seven.parse("N/A")  # not a missing token on this scale


def test_scale_rejects_duplicate_labels_and_bad_synonyms() -> None:
    with pytest.raises(ValueError, match="distinct"):
        Scale(labels=("a", "A"))
    with pytest.raises(ValueError, match="outside"):
        Scale(labels=("a", "b"), synonyms={"c": 3})


@pytest.mark.parametrize(("raw", "value"), [("Yes", True), ("y", True), ("No", False), ("no", False), ("", None)])
def test_yes_no(raw: str, value: bool | None) -> None:
    assert parse_yes_no(raw) is value


def test_yes_no_rejects_other_answers() -> None:
    with pytest.raises(CellValueError, match='"Perhaps" is not Yes or No'):
        parse_yes_no("Perhaps")


@pytest.mark.parametrize(
    ("raw", "value", "was_range"),
    [("4", 4.0, False), ("3.5", 3.5, False), ("3-4", 3.5, True), ("2 to 4 hours", 3.0, True),
     ("5 hrs", 5.0, False), ("~6", 6.0, False), ("", None, False), ("N/A", None, False)],
)
def test_hours(raw: str, value: float | None, was_range: bool) -> None:
    assert parse_hours(raw) == (value, was_range)


@pytest.mark.parametrize("raw", ["lots", "200", "5-3", "-2"])
def test_hours_rejects_non_numbers(raw: str) -> None:
    with pytest.raises(CellValueError):
        parse_hours(raw)
