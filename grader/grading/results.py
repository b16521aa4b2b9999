"""Graded results: one :class:`ItemResult` per rubric item, one :class:`SubmissionResult` per file.

Statuses (a public contract, see docs/grading.md)::

    correct        within tolerance of the key
    correct_ecf    wrong, but consistent with the student's own (wrong) upstream values
    unit_mismatch  the expected value expressed in another plausible unit
    known_mistake  matches a mistake from the rubric's catalog
    wrong_dimension  the answer's unit has the wrong physical dimension
    incorrect      none of the above
    missing        no answer
    invalid        the answer cannot be read (syntax, formula cell, NaN, rejected expression)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

Status = Literal["correct", "correct_ecf", "unit_mismatch", "known_mistake", "wrong_dimension", "incorrect",
                 "missing", "invalid"]
STATUSES: tuple[str, ...] = ("correct", "correct_ecf", "unit_mismatch", "known_mistake", "wrong_dimension",
                             "incorrect", "missing", "invalid")
#: statuses for which the student's value was read (and may feed error carried forward)
READ_STATUSES = frozenset({"correct", "correct_ecf", "unit_mismatch", "known_mistake", "incorrect"})


def round_points(x: float) -> float:
    """Points are reported to 0.01 (deterministic output)."""
    return float(round(x + 0.0, 2)) + 0.0


@dataclass(frozen=True)
class ItemResult:
    """The verdict on one answer item.

    ``value`` is the student's value in the key's (internal) unit when one was read,
    for error carried forward; ``detail`` is instructor-facing (may hold key values);
    ``feedback`` is student-facing.
    """

    item: str
    status: Status
    points: float
    max_points: float
    feedback: str
    mistake: str | None = None
    detail: Mapping[str, Any] = field(default_factory=dict)
    value: Any = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", round_points(min(max(self.points, 0.0), self.max_points)))


@dataclass(frozen=True)
class Student:
    """One student of a group, as Canvas knows them."""

    name: str
    sis_user_id: str = ""
    login_id: str = ""
    section: str = ""
    canvas_id: str = ""


@dataclass(frozen=True)
class SubmissionResult:
    """Every item's verdict for one submission; ``valid`` is False when the file could not be read."""

    submission_id: str
    source: str
    students: tuple[Student, ...]
    items: tuple[ItemResult, ...]
    valid: bool = True
    error: str | None = None
    notes: tuple[str, ...] = ()

    @property
    def score(self) -> float:
        return round_points(sum(i.points for i in self.items))

    @property
    def max_score(self) -> float:
        return round_points(sum(i.max_points for i in self.items))
