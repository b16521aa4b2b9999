"""The key-safe self-check shared by ``grader check`` and the web server (``grader serve``).

Both call :func:`self_check`, so a student sees the same statuses and feedback on the
command line, on the page and through the JSON API. Feedback never reveals the key
(``reveal=False``); without lab data for the submission's station only the prelab
items are checked, with a note saying so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from grader.errors import GraderError
from grader.grading.context import KeyContext
from grader.grading.grade import GradeOptions, RigLookup, grade_submission
from grader.grading.results import SubmissionResult
from grader.grading.submissions import Submission

KeyResolver = Callable[[Submission], KeyContext]


def no_key_note(exc: GraderError) -> str:
    """The note given when a submission has no key to be checked against."""
    return f"no lab data to check against ({exc}); checking the prelab items only"


def self_check(sub: Submission, resolve: KeyResolver, opts: GradeOptions, *,
               rig: RigLookup | None = None) -> SubmissionResult:
    """Grade ``sub`` for its students: statuses and key-safe feedback (``opts.reveal`` must be False).

    ``rig`` holds known rig verdicts of designs; a dict is also filled with the ones computed here.
    """
    if opts.reveal:
        raise ValueError("a self-check never reveals the key (reveal=False)")
    try:
        kc: KeyContext | None = resolve(sub)
    except GraderError as exc:
        result = grade_submission(sub, None, opts)
        return replace(result, notes=(no_key_note(exc), *result.notes))
    return grade_submission(sub, kc, opts, rig=rig)
