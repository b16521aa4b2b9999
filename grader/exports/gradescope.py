"""Gradescope: ``results.json`` for one submission, and the autograder zip an instructor uploads.

results.json follows Gradescope's schema: top-level ``score``, ``output``, ``visibility`` and
``tests[]`` with ``name``, ``score``, ``max_score``, ``status`` (passed/failed), ``output``,
``tags`` and ``visibility``. The autograder zip holds ``setup.sh`` and ``run_autograder`` at its
root plus the grader's source, the rubric and the reference data; Gradescope unpacks it into
``/autograder/source``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from grader.exports.atomic import zip_bytes
from grader.exports.report_json import clean
from grader.grading.results import SubmissionResult

SETUP_SH = """#!/usr/bin/env bash
# Gradescope runs this once when building the autograder image.
set -euo pipefail
apt-get update -qq && apt-get install -y -qq python3 python3-pip python3-venv > /dev/null
python3 -m venv /autograder/venv
/autograder/venv/bin/pip install -q -e /autograder/source
"""

RUN_AUTOGRADER = """#!/usr/bin/env bash
# Gradescope runs this for every submission; results go to /autograder/results/results.json.
set -uo pipefail
cd /autograder/source
exec /autograder/venv/bin/grader gradescope --rubric rubric.yaml --feedback-convention {convention}
"""


def results_json(r: SubmissionResult) -> str:
    """Gradescope's results.json text for one graded submission."""
    tests = [{"name": i.item, "score": i.points, "max_score": i.max_points,
              "status": "passed" if i.points >= i.max_points else "failed", "output": i.feedback,
              "tags": [t for t in (i.status, i.mistake) if t], "visibility": "visible"} for i in r.items]
    output = "" if r.valid else f"This submission could not be graded: {r.error}"
    if r.notes:
        output = "\n".join([output, *r.notes]).strip()
    data: dict[str, Any] = {"score": r.score, "output": output, "visibility": "visible",
                            "stdout_visibility": "hidden", "tests": tests}
    return json.dumps(clean(data), indent=2, ensure_ascii=False) + "\n"


def _files(root: Path, rel: str, suffixes: tuple[str, ...] | None = None) -> list[Path]:
    base = root / rel
    if base.is_file():
        return [base]
    return sorted(p for p in base.rglob("*") if p.is_file() and "__pycache__" not in p.parts
                  and (suffixes is None or p.suffix in suffixes))


def package_zip(repo: Path, rubric_file: Path, *, convention: str) -> bytes:
    """The autograder zip (deterministic): scripts, rubric, grader source and reference data."""
    entries: list[tuple[str, bytes, int]] = [
        ("setup.sh", SETUP_SH.encode(), 0o755),
        ("run_autograder", RUN_AUTOGRADER.format(convention=convention).encode(), 0o755),
        ("rubric.yaml", rubric_file.read_bytes(), 0o644),
    ]
    files = _files(repo, "grader", (".py", ".yaml", ".yml", ".json", ".html", ".j2", ".css", ".md"))
    files += [p for rel in ("pyproject.toml", "README.md") if (repo / rel).is_file() for p in [repo / rel]]
    for rel in ("reference_solutions/stations", "reference_solutions/datasets", "reference_solutions/keys"):
        if (repo / rel).is_dir():
            files += _files(repo, rel)
    entries += [(p.relative_to(repo).as_posix(), p.read_bytes(), 0o644) for p in files]
    if not (repo / "README.md").is_file():
        entries.append(("README.md", b"grader autograder\n", 0o644))
    return zip_bytes(entries)
