"""Read the embedded exam-question scores: one row per student.

Columns (any order, case and spaces ignored): student, group, problem,
item_score, item_max, total_score, total_max. Every bad cell is an error naming
its spreadsheet row and column; student ids are checked, then dropped.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from grader.assess.tables import Table, column_letter, read_table
from grader.errors import AssessmentError

TREATED = "with_lab_reference"
CONTROL = "without_lab_reference"
GROUPS = (TREATED, CONTROL)
REQUIRED = ("student", "group", "problem", "item_score", "item_max", "total_score", "total_max")
RESERVED_PROBLEM = "overall"
_NUMBERS = ("item_score", "item_max", "total_score", "total_max")


@dataclass(frozen=True)
class ExamData:
    """Validated scores, one entry per student (no student ids)."""

    group: tuple[str, ...]
    problem: tuple[str, ...]
    item_score: np.ndarray
    item_max: np.ndarray
    total_score: np.ndarray
    total_max: np.ndarray


def _key(header: str) -> str:
    return "_".join(header.replace("-", " ").split()).casefold()


def _columns(table: Table) -> dict[str, int]:
    found: dict[str, int] = {}
    for i, h in enumerate(table.rows[0]):
        if not h.strip():
            continue
        key = _key(h)
        if key in found and key in REQUIRED:
            raise AssessmentError(f'{table.name}: column "{h.strip()}" appears more than once (columns '
                                  f"{column_letter(found[key])} and {column_letter(i)})")
        found.setdefault(key, i)
    missing = [c for c in REQUIRED if c not in found]
    if missing:
        raise AssessmentError(
            f"{table.name}: wrong header: missing column(s) {', '.join(missing)}; "
            f"expected {', '.join(REQUIRED)}"
        )
    return {c: found[c] for c in REQUIRED}


def read_exam_scores(path: Path) -> ExamData:
    """Read and validate an exam-score file."""
    table = read_table(path)
    cols = _columns(table)
    records = [(n, row) for n, row in enumerate(table.rows[1:], start=2) if any(c.strip() for c in row)]
    if not records:
        raise AssessmentError(f"{table.name}: the file has a header but no students")
    parsed = [_row(table, cols, number, row) for number, row in records]
    _check_unique_students(table, cols, [(n, p[0]) for (n, _), p in zip(records, parsed, strict=True)])
    _check_item_max(table, cols, [(n, p) for (n, _), p in zip(records, parsed, strict=True)])
    groups = {p[1] for p in parsed}
    if len(groups) < 2:
        raise AssessmentError(f"{table.name}: every student is in group {groups.pop()!r}; the report compares "
                              f"the two groups, so it needs students in both {TREATED!r} and {CONTROL!r}")
    numbers = np.array([p[3:] for p in parsed], dtype=float)
    return ExamData(
        group=tuple(p[1] for p in parsed),
        problem=tuple(p[2] for p in parsed),
        item_score=numbers[:, 0],
        item_max=numbers[:, 1],
        total_score=numbers[:, 2],
        total_max=numbers[:, 3],
    )


def _fail(table: Table, number: int, col: int, message: str) -> AssessmentError:
    header = table.rows[0][col]
    return AssessmentError(f'{table.name}, row {number}, column {column_letter(col)} "{header}": {message}')


def _row(table: Table, cols: dict[str, int], number: int, row: Sequence[str]) -> tuple:
    """(student, group, problem, item_score, item_max, total_score, total_max) of one row."""
    text = {c: row[cols[c]].strip() for c in REQUIRED}
    for c in ("student", "problem"):
        if not text[c]:
            raise _fail(table, number, cols[c], f"the {c} is blank")
    if _key(text["problem"]) == RESERVED_PROBLEM:
        raise _fail(table, number, cols["problem"], f'"{RESERVED_PROBLEM}" is reserved for the pooled analysis')
    group = _key(text["group"])
    if group not in GROUPS:
        raise _fail(table, number, cols["group"], f'"{text["group"]}" is not {TREATED} or {CONTROL}')
    values = {}
    for c in _NUMBERS:
        try:
            values[c] = float(text[c])
        except ValueError:
            raise _fail(table, number, cols[c], f'"{text[c]}" is not a number') from None
        if not np.isfinite(values[c]) or values[c] < 0:
            raise _fail(table, number, cols[c], f'"{text[c]}" is not a non-negative number')
    _check_bounds(table, cols, number, values)
    return (text["student"], group, text["problem"], *(values[c] for c in _NUMBERS))


def _check_bounds(table: Table, cols: dict[str, int], number: int, v: dict[str, float]) -> None:
    if v["item_max"] == 0:
        raise _fail(table, number, cols["item_max"], "the item maximum is 0")
    if v["item_score"] > v["item_max"]:
        raise _fail(table, number, cols["item_score"],
                    f"{v['item_score']:g} is above the item maximum {v['item_max']:g}")
    if v["total_max"] <= v["item_max"]:
        raise _fail(table, number, cols["total_max"], "the test maximum must exceed the item maximum (no rest of test)")
    if v["total_score"] > v["total_max"]:
        raise _fail(table, number, cols["total_score"],
                    f"{v['total_score']:g} is above the test maximum {v['total_max']:g}")
    if v["total_score"] < v["item_score"]:
        raise _fail(table, number, cols["total_score"], "the total score is below the item score it includes")


def _check_unique_students(table: Table, cols: dict[str, int], students: list[tuple[int, str]]) -> None:
    seen: dict[str, int] = {}
    for number, student in students:
        if student in seen:
            raise _fail(table, number, cols["student"], f"this student also appears in row {seen[student]}")
        seen[student] = number


def _check_item_max(table: Table, cols: dict[str, int], rows: list[tuple[int, tuple]]) -> None:
    first: dict[str, tuple[int, float]] = {}
    for number, parsed in rows:
        problem, item_max = parsed[2], parsed[4]
        if problem not in first:
            first[problem] = (number, item_max)
        elif first[problem][1] != item_max:
            raise _fail(
                table, number, cols["item_max"],
                f"{item_max:g} differs from the maximum {first[problem][1]:g} of {problem} in row {first[problem][0]}",
            )
