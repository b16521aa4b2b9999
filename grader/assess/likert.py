"""Parsing of single survey cells: Likert ratings, yes/no flags and hours.

Every parser returns ``None`` for missing data and raises :class:`CellValueError`
(a plain message, without file, row or column) for a value it will not accept;
the reader adds the location. Nothing is silently coerced: a 7 on a 1-5 scale is
an error, and "Did not do this lab", blanks and N/A are missing, never neutral.
"""

from __future__ import annotations

import math
import re

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

#: Missing-data tokens used unless a mapping file says otherwise.
DEFAULT_MISSING = ("N/A", "NA", "n/a", "Not applicable", "Did not do this lab", "-")
_YES = frozenset({"yes", "y", "true", "1", "x", "i did"})
_NO = frozenset({"no", "n", "false", "0", "did not do this lab", "i did not"})
_HOURS = re.compile(
    r"^~?\s*(?P<a>\d+(?:\.\d+)?)\s*(?:(?:-|–|to)\s*(?P<b>\d+(?:\.\d+)?))?"
    r"\s*(?:h|hr|hrs|hour|hours)?\.?$"
)
MAX_HOURS_PER_WEEK = 168.0


class CellValueError(ValueError):
    """A cell value that is not accepted; the message says why."""


def normalize(text: str) -> str:
    """Case-fold and collapse whitespace, for forgiving comparisons."""
    return " ".join(str(text).split()).casefold()


class Scale(BaseModel):
    """A Likert scale: ``labels[i]`` is the text of value ``i + 1``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    labels: tuple[str, ...] = Field(min_length=2)
    synonyms: dict[str, int] = Field(default_factory=dict)
    missing: tuple[str, ...] = DEFAULT_MISSING

    @field_validator("labels")
    @classmethod
    def _distinct_labels(cls, labels: tuple[str, ...]) -> tuple[str, ...]:
        if len({normalize(label) for label in labels}) != len(labels):
            raise ValueError("scale labels must be distinct")
        return labels

    @model_validator(mode="after")
    def _synonyms_on_scale(self) -> Scale:
        for text, value in self.synonyms.items():
            if not 1 <= value <= self.points:
                raise ValueError(f'synonym "{text}" maps to {value}, outside 1-{self.points}')
        return self

    @property
    def points(self) -> int:
        return len(self.labels)

    @property
    def midpoint(self) -> float:
        """Values below are 'disagree', above are 'agree'; equal is neutral."""
        return (self.points + 1) / 2

    def parse(self, raw: str) -> int | None:
        """Return the rating 1..points, ``None`` if missing; raise if invalid."""
        text = str(raw).strip()
        if not text or normalize(text) in {normalize(m) for m in self.missing}:
            return None
        number = _as_number(text)
        if number is not None:
            if number.is_integer() and 1 <= number <= self.points:
                return int(number)
            raise CellValueError(f'"{text}" is outside the scale 1-{self.points}')
        lookup = {normalize(label): i + 1 for i, label in enumerate(self.labels)}
        lookup.update({normalize(k): v for k, v in self.synonyms.items()})
        if normalize(text) in lookup:
            return lookup[normalize(text)]
        raise CellValueError(
            f'"{text}" is not a rating: expected 1-{self.points} or a label from '
            f'"{self.labels[0]}" to "{self.labels[-1]}"'
        )


def _as_number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def parse_yes_no(raw: str) -> bool | None:
    """A "did this lab" flag: ``True``/``False``, ``None`` when blank."""
    text = normalize(raw)
    if not text:
        return None
    if text in _YES:
        return True
    if text in _NO:
        return False
    raise CellValueError(f'"{str(raw).strip()}" is not Yes or No')


def parse_hours(raw: str) -> tuple[float | None, bool]:
    """Hours per week as ``(value, was_range)``; a range "3-4" gives its midpoint."""
    text = normalize(raw)
    if not text or text in {normalize(m) for m in DEFAULT_MISSING}:
        return None, False
    match = _HOURS.match(text)
    if match is None:
        raise CellValueError(f'"{str(raw).strip()}" is not a number of hours (e.g. 4, 3.5, 3-4)')
    low = float(match["a"])
    high = float(match["b"]) if match["b"] else low
    if high < low:
        raise CellValueError(f'"{str(raw).strip()}" is a range whose end is below its start')
    value = (low + high) / 2
    if value > MAX_HOURS_PER_WEEK:
        raise CellValueError(f'"{str(raw).strip()}" hours is more than a week holds')
    return value, match["b"] is not None
