"""Write every output of a graded batch into one folder (each file atomically)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from grader.exports.atomic import workbook_bytes
from grader.exports.canvas import canvas_csv, superseded
from grader.exports.feedback_md import feedback_md
from grader.exports.gradebook_xlsx import gradebook
from grader.exports.gradescope import results_json
from grader.exports.report_json import report_json
from grader.grading.results import SubmissionResult
from grader.grading.rubric import Rubric
from grader.outpaths import write_bytes, write_text


def write_outputs(results: Sequence[SubmissionResult], out: Path, rubric: Rubric, *, assignment: str,
                  assignment_id: str) -> list[Path]:
    """grades.csv, results/<id>.json, feedback/<id>.md, report.json, gradebook.xlsx; stale per-submission
    files of an earlier run in results/ and feedback/ are removed. Returns the files written."""
    out.mkdir(parents=True, exist_ok=True)
    times = source_times(results)
    written = [write_text(out / "grades.csv", canvas_csv(results, assignment=assignment, assignment_id=assignment_id,
                                                         times=times))]
    for folder, suffix, render in (("results", ".json", results_json),
                                   ("feedback", ".md", lambda r: feedback_md(r, title=rubric.title))):
        keep = set()
        for r in results:  # ids are unique even up to letter case (grading.pipeline.read_all)
            path = write_text(out / folder / f"{r.submission_id}{suffix}", render(r))
            keep.add(path.name)
            written.append(path)
        for stale in (out / folder).glob(f"*{suffix}"):
            if stale.name not in keep:
                stale.unlink()
    written.append(write_text(out / "report.json", report_json(results, superseded(results, times))))
    written.append(write_bytes(out / "gradebook.xlsx", workbook_bytes(gradebook(results, list(rubric.items)))))
    return written


def source_times(results: Sequence[SubmissionResult]) -> dict[str, float]:
    """Submission id -> modification time (s) of its file; grades.csv grades each student's latest."""
    times = {}
    for r in results:
        try:
            times[r.submission_id] = os.stat(r.source).st_mtime
        except OSError:
            times[r.submission_id] = 0.0
    return times
