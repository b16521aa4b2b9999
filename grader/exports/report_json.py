"""``report.json``: every item of every submission, for instructors and scripts."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from typing import Any

from grader.grading.results import SubmissionResult
from grader.precision import round_sig


def clean(obj: Any) -> Any:
    """JSON-safe, deterministic: floats at :mod:`grader.precision` (6 significant digits, the same
    bytes on every CPU), non-finite to null, mappings sorted."""
    if isinstance(obj, bool) or obj is None or isinstance(obj, (int, str)):
        return obj
    if isinstance(obj, float) or hasattr(obj, "__float__") and not isinstance(obj, complex):
        x = float(obj)
        return round_sig(x) if math.isfinite(x) else None
    if isinstance(obj, complex):
        return [clean(obj.real), clean(obj.imag)]
    if isinstance(obj, Mapping):
        return {str(k): clean(v) for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [clean(v) for v in (sorted(obj, key=str) if isinstance(obj, (set, frozenset)) else obj)]
    return str(obj)


def submission_dict(r: SubmissionResult, superseded_by: str | None = None) -> dict[str, Any]:
    return {
        "submission_id": r.submission_id, "score": r.score, "max_score": r.max_score, "valid": r.valid, "error": r.error,
        "superseded_by": superseded_by,
        "items": [{"item": i.item, "status": i.status, "points": i.points, "max_points": i.max_points,
                   "mistake": i.mistake, "detail": clean(i.detail), "feedback": i.feedback} for i in r.items],
    }


def report_json(results: Iterable[SubmissionResult], superseded: Mapping[str, str] | None = None) -> str:
    """The report text (submissions sorted by id, two-space indent, trailing newline); ``superseded``
    maps a submission id to the later submission that grades its students (grades.csv's rule)."""
    gone = superseded or {}
    subs = [submission_dict(r, gone.get(r.submission_id)) for r in sorted(results, key=lambda r: r.submission_id)]
    return json.dumps({"submissions": subs}, indent=2, ensure_ascii=False, allow_nan=False) + "\n"
