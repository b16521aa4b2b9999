"""``grades.csv`` in Canvas's gradebook import format: one row per student (their latest submission)."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Iterable, Mapping

from grader.exports.cells import csv_text
from grader.grading.results import Student, SubmissionResult

HEADER = ("Student", "ID", "SIS User ID", "SIS Login ID", "Section")


def score_text(x: float) -> str:
    """``42.5``, ``40``: at most two decimals, no trailing zeros."""
    return f"{x:.2f}".rstrip("0").rstrip(".")


def _identifiers(s: Student) -> list[str]:
    """A student record's Canvas id, SIS user id and login (any case); its name only where it has none of them."""
    ids = [f"{k}:{v.strip().casefold()}" for k, v in (("id", s.canvas_id), ("sis", s.sis_user_id), ("login", s.login_id))
           if v.strip()]
    return ids or [f"name:{s.name.strip().casefold()}"]


def people(results: Iterable[SubmissionResult]) -> Callable[[Student], str]:
    """Who each student of ``results`` is: records that share a Canvas id, SIS user id or login are one person
    (one record may give the Canvas id and another only the SIS id); a record with none of them is known by its
    name, any case. Returns a key for each student record."""
    parent: dict[str, str] = {}

    def find(x: str) -> str:
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for r in results:
        for s in r.students:
            first, *rest = _identifiers(s)
            for other in rest:
                parent[find(other)] = find(first)
    return lambda s: find(_identifiers(s)[0])


def latest(results: Iterable[SubmissionResult], times: Mapping[str, float]) -> tuple[dict[str, SubmissionResult],
                                                                                      Callable[[Student], str]]:
    """Each student's graded submission (by the key :func:`people` gives, returned with it).

    The rule (docs/reference/report-files.md): a student's grade comes from their latest
    submission by file time (``times``: submission id -> modification time in seconds) among those
    that could be graded (one that could not, such as a second file under the same submission id,
    only where none could); equal times go to the higher score, then to the later submission id."""
    results = list(results)
    key = people(results)
    rank = lambda r: (r.valid, times.get(r.submission_id, 0.0), r.score, r.submission_id)  # noqa: E731
    out: dict[str, SubmissionResult] = {}
    for r in results:
        for s in r.students:
            k = key(s)
            if k not in out or rank(r) > rank(out[k]):
                out[k] = r
    return out, key


def superseded(results: Iterable[SubmissionResult], times: Mapping[str, float]) -> dict[str, str]:
    """``{submission_id: the later submission that replaces it}`` for submissions sharing a student."""
    results = list(results)
    chosen, key = latest(results, times)
    out = {}
    for r in results:
        newer = sorted({chosen[key(s)].submission_id for s in r.students} - {r.submission_id})
        if newer:
            out[r.submission_id] = newer[0]
    return out


def canvas_csv(results: Iterable[SubmissionResult], *, assignment: str, assignment_id: str,
               times: Mapping[str, float] | None = None) -> str:
    """The CSV text: one row per student, from their latest submission (:func:`latest`).
    A submission without readable students still gets a row, named so an instructor sees why."""
    results = sorted(results, key=lambda r: r.submission_id)
    chosen, key = latest(results, times or {})
    written: set[str] = set()  # a student listed twice (in one submission, or by two of their ids): one row
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow((*HEADER, csv_text(f"{assignment} ({assignment_id})")))
    for r in results:
        if not r.students:
            what = "unreadable submission" if not r.valid else "submission"
            w.writerow((f"({what} {csv_text(r.submission_id)}: no student listed)", "", "", "", "", score_text(r.score)))
        for s in r.students:
            if chosen[key(s)] is r and key(s) not in written:
                written.add(key(s))
                w.writerow((*(csv_text(v) for v in (s.name, s.canvas_id, s.sis_user_id, s.login_id, s.section)),
                            score_text(r.score)))
    return buf.getvalue()
