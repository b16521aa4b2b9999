"""Read survey responses from our template, a Qualtrics export or a Google Forms export.

The form is recognised from the header: Qualtrics exports carry three header
rows (export tags, question text, ``{"ImportId": ...}``), Google Forms exports
start with a ``Timestamp`` column, anything else is read as our template. The
mapping ties columns to lab × statement; every bad cell is reported with its
spreadsheet row and column.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from grader.assess.likert import CellValueError, normalize, parse_hours, parse_yes_no
from grader.assess.mapping import FORM_NAMES, ColumnSpec, Form, SurveyMapping
from grader.assess.tables import Table, column_letter, read_table
from grader.errors import AssessmentError

T = TypeVar("T")
#: Template columns that are allowed but never read (and never reported).
TEMPLATE_EXTRA_COLUMNS = frozenset({"respondent"})
#: Qualtrics' response types left out, as choice text or as numeric codes (1 Survey Preview, 2 Survey Test, 8 Spam,
#: 9 Survey Preview Spam, 12 Imported Spam, 17 Offline Survey Preview; 0 IP Address, 4 Imported and 16 Offline are
#: responses).
_QUALTRICS_SKIP_STATUS = frozenset({"survey preview", "survey test", "spam", "preview spam", "survey preview spam",
                                    "imported spam", "offline survey preview", "1", "2", "8", "9", "12", "17"})


@dataclass(frozen=True)
class SurveyData:
    """Parsed responses, one entry per respondent in every tuple; ``None`` is missing."""

    form: Form
    respondents: int
    ratings: Mapping[tuple[str, str], tuple[int | None, ...]]
    did_lab: Mapping[str, tuple[bool | None, ...]]
    overall: Mapping[str, tuple[int | None, ...]]
    hours: tuple[float | None, ...] | None
    most_useful: tuple[str, ...] | None
    discarded: Mapping[str, int]
    notes: tuple[str, ...]


@dataclass(frozen=True)
class _Rows:
    """Data rows with their spreadsheet row numbers, and the header row."""

    table: Table
    headers: tuple[str, ...]
    records: tuple[tuple[int, tuple[str, ...]], ...]


def detect_form(table: Table) -> Form:
    """Recognise which of the three supported forms a table is."""
    rows = table.rows
    if len(rows) >= 3 and any(normalize(c).startswith('{"importid"') for c in rows[2]):
        return "qualtrics"
    if normalize(rows[0][0]) == "timestamp":
        return "google"
    return "template"


def read_survey(path: Path, mapping: SurveyMapping) -> SurveyData:
    """Read and validate a survey file against ``mapping``."""
    table = read_table(path)
    form = detect_form(table)
    rows, notes = _data_rows(table, form)
    fields = mapping.fields(form)
    index = _resolve_columns(rows, fields, form, mapping)
    if form == "template":
        _reject_unknown_template_columns(rows, fields)
    return _parse(rows, form, fields, index, mapping, notes)


def _data_rows(table: Table, form: Form) -> tuple[_Rows, list[str]]:
    header_rows = 3 if form == "qualtrics" else 1
    records = tuple(
        (number, row)
        for number, row in enumerate(table.rows[header_rows:], start=header_rows + 1)
        if any(cell.strip() for cell in row)
    )
    rows = _Rows(table=table, headers=table.rows[0], records=records)
    notes: list[str] = []
    if form == "qualtrics":
        rows, skipped = _drop_qualtrics_previews(rows)
        if skipped:
            notes.append(f"{skipped} Qualtrics preview/test/spam responses were left out.")
    if not rows.records:
        raise AssessmentError(f"{table.name}: the {FORM_NAMES[form]} has a header but no responses")
    _reject_repeated_respondents(rows)
    return rows, notes


#: Columns that identify a response: the template's ``respondent``, Qualtrics' ``ResponseId``.
RESPONDENT_COLUMNS = ("respondent", "responseid")


def _reject_repeated_respondents(rows: _Rows) -> None:
    """A response id given on two rows (a row pasted twice) would count one respondent twice: refused, naming both
    rows. Rows without an id are anonymous and may repeat."""
    for col in (i for i, h in enumerate(rows.headers) if normalize(h) in RESPONDENT_COLUMNS):
        first: dict[str, int] = {}
        for number, row in rows.records:
            rid = row[col].strip() if col < len(row) else ""
            if rid and rid in first:
                raise AssessmentError(f"{rows.table.name}: row {number}: respondent {rid[:40]!r} is also on row "
                                      f"{first[rid]}; each response once")
            first.setdefault(rid, number)


def _drop_qualtrics_previews(rows: _Rows) -> tuple[_Rows, int]:
    status = [i for i, h in enumerate(rows.headers) if normalize(h) == "status"]
    if not status:
        return rows, 0
    kept = tuple(r for r in rows.records if normalize(r[1][status[0]]) not in _QUALTRICS_SKIP_STATUS)
    return _Rows(rows.table, rows.headers, kept), len(rows.records) - len(kept)


def _resolve_columns(
    rows: _Rows, fields: Sequence[ColumnSpec], form: Form, mapping: SurveyMapping
) -> dict[str, int]:
    """Map each field's header to its column index, or raise naming what is wrong."""
    positions: dict[str, list[int]] = {}
    for i, header in enumerate(rows.headers):
        positions.setdefault(normalize(header), []).append(i)
    name = rows.table.name
    missing = [f for f in fields if normalize(f.header) not in positions]
    if len(missing) == len(fields):
        raise AssessmentError(
            f"{name}: wrong header: row 1 matches none of the survey forms (our template "
            f'from "grader survey-template", a Qualtrics export with three header rows, '
            f'or a Google Forms export starting with "Timestamp")'
        )
    if missing:
        raise AssessmentError(_missing_message(name, missing, fields, rows.headers, form, mapping))
    for f in fields:
        found = positions[normalize(f.header)]
        if len(found) > 1:
            letters = ", ".join(column_letter(i) for i in found)
            raise AssessmentError(f'{name}: column "{f.header}" appears more than once ({letters})')
    return {f.header: positions[normalize(f.header)][0] for f in fields}


def _missing_message(
    name: str,
    missing: Sequence[ColumnSpec],
    fields: Sequence[ColumnSpec],
    headers: Sequence[str],
    form: Form,
    mapping: SurveyMapping,
) -> str:
    """Name the whole lab if all its columns are gone, else the first missing column."""
    for lab in mapping.labs:
        of_lab = [f for f in fields if f.lab == lab.id]
        if of_lab and all(f in missing for f in of_lab):
            extra = len(missing) - len(of_lab)
            more = f"; {extra} other column(s) are missing too" if extra else ""
            return (
                f"{name}: the {lab.name} lab is missing: none of its {len(of_lab)} columns "
                f'(e.g. "{of_lab[0].header}") is in this {FORM_NAMES[form]}{more}'
            )
    first = missing[0]
    text = f'{name}: column "{first.header}" ({first.description}) is missing from this {FORM_NAMES[form]}'
    close = difflib.get_close_matches(first.header, [h for h in headers if h.strip()], n=1, cutoff=0.8)
    if close:
        text += f'; found "{close[0]}" - a misspelt header?'
    if len(missing) > 1:
        text += f" ({len(missing) - 1} more column(s) missing)"
    return text


def _reject_unknown_template_columns(rows: _Rows, fields: Sequence[ColumnSpec]) -> None:
    known = {normalize(f.header) for f in fields} | TEMPLATE_EXTRA_COLUMNS
    for i, header in enumerate(rows.headers):
        if header.strip() and normalize(header) not in known:
            close = difflib.get_close_matches(header, [f.header for f in fields], n=1, cutoff=0.8)
            hint = f'; did you mean "{close[0]}"?' if close else ""
            raise AssessmentError(
                f'{rows.table.name}: wrong header: column {column_letter(i)} "{header}" '
                f"is not a template column{hint}"
            )


def _column(rows: _Rows, col: int, spec: ColumnSpec, parse: Callable[[str], T]) -> tuple[T, ...]:
    """Parse one column, turning a bad cell into an error naming row and column."""
    out: list[T] = []
    for number, row in rows.records:
        try:
            out.append(parse(row[col]))
        except CellValueError as exc:
            raise AssessmentError(
                f'{rows.table.name}, row {number}, column {column_letter(col)} "{spec.header}" '
                f"({spec.description}): {exc}"
            ) from None
    return tuple(out)


def _parse(
    rows: _Rows,
    form: Form,
    fields: Sequence[ColumnSpec],
    index: Mapping[str, int],
    mapping: SurveyMapping,
    notes: list[str],
) -> SurveyData:
    parsed: dict[str, tuple[Any, ...]] = {
        f.header: _column(rows, index[f.header], f, _parser(f, mapping, rows, index[f.header])) for f in fields
    }
    by_kind = {kind: [f for f in fields if f.kind == kind] for kind in ("did_lab", "rating", "overall")}
    did = {f.lab: parsed[f.header] for f in by_kind["did_lab"] if f.lab}
    ratings, discarded = _apply_did_lab(
        {(f.lab, f.statement): parsed[f.header] for f in by_kind["rating"] if f.lab and f.statement},
        did,
    )
    hours = _single(fields, parsed, "hours")
    if hours is not None:
        ranges = sum(was_range for _, was_range in hours)
        if ranges:
            notes.append(f"{ranges} hours answers were ranges; their midpoints were used.")
    most_useful = _single(fields, parsed, "most_useful")
    return SurveyData(
        form=form,
        respondents=len(rows.records),
        ratings=ratings,
        did_lab=did,
        overall={f.statement: parsed[f.header] for f in by_kind["overall"] if f.statement},
        hours=None if hours is None else tuple(value for value, _ in hours),
        most_useful=None if most_useful is None else tuple(text.strip() for text in most_useful),
        discarded=discarded,
        notes=tuple(notes),
    )


#: Qualtrics' numeric export codes a Yes/No choice 1 = Yes, 2 = No.
_QUALTRICS_YES_NO = {"1": "yes", "2": "no"}


def _did_lab_parser(rows: _Rows, col: int) -> Callable[[str], bool | None]:
    """:func:`parse_yes_no`, or, where the column's answers are the codes 1 and 2 and no other (Qualtrics'
    numeric export of a Yes/No choice), 1 = Yes and 2 = No. A column of 1 and 0 reads as Yes and No either way."""
    codes = {normalize(row[col]) for _, row in rows.records} - {""}
    if "2" in codes and codes <= set(_QUALTRICS_YES_NO):
        return lambda raw: parse_yes_no(_QUALTRICS_YES_NO.get(normalize(raw), raw))
    return parse_yes_no


def _parser(spec: ColumnSpec, mapping: SurveyMapping, rows: _Rows, col: int) -> Callable[[str], Any]:
    parsers: dict[str, Callable[[str], Any]] = {
        "rating": mapping.scale.parse,
        "overall": mapping.scale.parse,
        "did_lab": _did_lab_parser(rows, col),
        "hours": parse_hours,
        "most_useful": str,
    }
    return parsers[spec.kind]


def _single(fields: Sequence[ColumnSpec], parsed: Mapping[str, tuple], kind: str) -> tuple | None:
    found = [f for f in fields if f.kind == kind]
    return parsed[found[0].header] if found else None


def _apply_did_lab(
    ratings: dict[tuple[str, str], tuple[int | None, ...]],
    did: Mapping[str, tuple[bool | None, ...]],
) -> tuple[dict[tuple[str, str], tuple[int | None, ...]], dict[str, int]]:
    """Blank out ratings of students who said they did not do the lab; count them."""
    discarded: dict[str, int] = {lab: 0 for lab in did}
    out: dict[tuple[str, str], tuple[int | None, ...]] = {}
    for (lab, statement), values in ratings.items():
        flags = did.get(lab)
        if flags is None:
            out[(lab, statement)] = values
            continue
        discarded[lab] += sum(v is not None and f is False for v, f in zip(values, flags, strict=True))
        out[(lab, statement)] = tuple(None if f is False else v for v, f in zip(values, flags, strict=True))
    return out, discarded
