"""``grades.csv`` in Canvas's gradebook import format: one row per student of every submission."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable

from grader.exports.cells import csv_text
from grader.grading.results import SubmissionResult

HEADER = ("Student", "ID", "SIS User ID", "SIS Login ID", "Section")


def score_text(x: float) -> str:
    """``42.5``, ``40``: at most two decimals, no trailing zeros."""
    return f"{x:.2f}".rstrip("0").rstrip(".")


def canvas_csv(results: Iterable[SubmissionResult], *, assignment: str, assignment_id: str) -> str:
    """The CSV text; a submission without readable students still gets a row (named after its id)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow((*HEADER, csv_text(f"{assignment} ({assignment_id})")))
    for r in sorted(results, key=lambda r: r.submission_id):
        if not r.students:
            w.writerow((f"(no student listed in submission {csv_text(r.submission_id)})", "", "", "", "", score_text(r.score)))
        for s in r.students:
            w.writerow((*(csv_text(v) for v in (s.name, s.canvas_id, s.sis_user_id, s.login_id, s.section)),
                        score_text(r.score)))
    return buf.getvalue()
