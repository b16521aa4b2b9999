"""Per-submission feedback in Markdown, for the students of a group."""

from __future__ import annotations

import re

from grader.exports.canvas import score_text
from grader.grading.results import SubmissionResult

STATUS_TEXT = {"correct": "correct", "correct_ecf": "correct (error carried forward)", "unit_mismatch": "unit mismatch",
               "known_mistake": "known mistake", "wrong_dimension": "wrong dimension", "incorrect": "incorrect",
               "missing": "missing", "invalid": "could not be read"}


def _md(text: str) -> str:
    """Student text as literal Markdown (``lbf*s/in`` must not turn italic)."""
    return re.sub(r"([\\`*_|<>\[\]#])", r"\\\1", text)


def _cell(text: str) -> str:
    return _md(text).replace("\n", " ")


def feedback_md(r: SubmissionResult, *, title: str = "") -> str:
    """The Markdown text for one submission."""
    names = ", ".join(s.name for s in r.students) or "(no students listed)"
    lines = [f"# {_md(title or 'Feedback')} — {_md(r.submission_id)}", "", f"Students: {_cell(names)}", "",
             f"**Score: {score_text(r.score)} / {score_text(r.max_score)}**", ""]
    if not r.valid:
        lines += [f"> **This submission could not be graded:** {_cell(r.error or 'unknown error')}",
                  "> Fix the file and submit again; `grader check FILE` shows the same checks.", ""]
    lines += ["| Item | Status | Points |", "|---|---|---|"]
    lines += [f"| {i.item} | {STATUS_TEXT[i.status]} | {score_text(i.points)} / {score_text(i.max_points)} |" for i in r.items]
    lines += ["", "## Details", ""]
    for i in r.items:
        lines += [f"### {i.item}: {STATUS_TEXT[i.status]} ({score_text(i.points)} / {score_text(i.max_points)})", "",
                  _md(i.feedback), ""]
    if r.notes:
        lines += ["## Notes", ""] + [f"- {_md(n)}" for n in r.notes] + [""]
    return "\n".join(lines)
