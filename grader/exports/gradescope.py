"""Gradescope: ``results.json`` for one submission, and the autograder zip an instructor uploads.

results.json follows Gradescope's schema: top-level ``score``, ``output``, ``visibility`` and
``tests[]`` with ``name``, ``score``, ``max_score``, ``status`` (passed/failed), ``output``,
``tags`` and ``visibility``. The autograder zip holds ``setup.sh`` and ``run_autograder`` at its
root plus the grader's source, the rubric, the reference data and the demo's example files (setup.sh
runs ``grader demo`` once to warm compiled caches); Gradescope unpacks it into ``/autograder/source``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from grader.exports.atomic import zip_bytes
from grader.exports.report_json import clean
from grader.grading.results import SubmissionResult

#: uv release that setup.sh installs to obtain a managed CPython when the image's python3 is too old.
UV_VERSION = "0.5.11"
#: Python that setup.sh provides (grader needs >= 3.11; Ubuntu 20.04 has 3.8, 22.04 has 3.10, 24.04 has 3.12).
PYTHON_VERSION = "3.12"

SETUP_SH = r"""#!/usr/bin/env bash
# Gradescope runs this once, as root, when it builds the autograder image, on any Ubuntu base image.
# grader needs Python >= 3.11: the image's python3 is used when it is recent enough (Ubuntu 24.04),
# else uv installs a managed CPython {python} (Ubuntu 20.04 has 3.8, 22.04 has 3.10).
# Paths default to Gradescope's layout; AUTOGRADER_ROOT moves them (tests run it without root).
# GRADER_SETUP_PYTHON (tests only): a Python >= 3.11 that already has grader's dependencies;
# then nothing is downloaded and the venv reuses that Python's packages.
set -euo pipefail
ROOT="${{AUTOGRADER_ROOT:-/autograder}}"
SOURCE="$ROOT/source"
VENV="$ROOT/venv"
recent() {{ "$1" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; }}

if [ -n "${{GRADER_SETUP_PYTHON:-}}" ]; then
  recent "$GRADER_SETUP_PYTHON" || {{ echo "setup.sh: $GRADER_SETUP_PYTHON is older than Python 3.11" >&2; exit 1; }}
  "$GRADER_SETUP_PYTHON" -m venv --without-pip "$VENV"
  deps="$("$GRADER_SETUP_PYTHON" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  site="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  echo "$deps" > "$site/_grader_setup_deps.pth"
  "$VENV/bin/python" -m pip install -q --no-deps --no-build-isolation --no-index --ignore-installed -e "$SOURCE"
else
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq curl ca-certificates python3 > /dev/null
  export UV_PYTHON_INSTALL_DIR=/opt/uv/python
  curl -LsSf https://astral.sh/uv/{uv}/install.sh | env UV_UNMANAGED_INSTALL=/usr/local/bin sh
  if recent python3; then PYTHON=python3; else PYTHON={python}; fi
  /usr/local/bin/uv venv --python "$PYTHON" "$VENV"
  recent "$VENV/bin/python" || {{ echo "setup.sh: no Python >= 3.11 on this image; choose the Ubuntu 24.04 base image" >&2; exit 1; }}
  /usr/local/bin/uv pip install --python "$VENV/bin/python" -e "$SOURCE"
fi
"$VENV/bin/grader" --version
if [ "${{GRADER_SETUP_WARMUP:-1}}" != 0 ]; then
  # One run of every verb, so compiled (numba) caches are warm before the first student submits.
  warm="$(mktemp -d)"
  "$VENV/bin/grader" demo -o "$warm" > /dev/null
  rm -rf "$warm"
fi
"""

RUN_AUTOGRADER = r"""#!/usr/bin/env bash
# Gradescope runs this for every submission; results go to $ROOT/results/results.json.
set -uo pipefail
ROOT="${{AUTOGRADER_ROOT:-/autograder}}"
cd "$ROOT/source"
exec "$ROOT/venv/bin/grader" gradescope --rubric rubric.yaml --feedback-convention {convention} \
  --submission-dir "$ROOT/submission" --results "$ROOT/results/results.json"
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
        ("setup.sh", SETUP_SH.format(uv=UV_VERSION, python=PYTHON_VERSION).encode(), 0o755),
        ("run_autograder", RUN_AUTOGRADER.format(convention=convention).encode(), 0o755),
        ("rubric.yaml", rubric_file.read_bytes(), 0o644),
    ]
    files = _files(repo, "grader", (".py", ".yaml", ".yml", ".json", ".html", ".j2", ".css", ".md"))
    files += [p for rel in ("pyproject.toml", "README.md") if (repo / rel).is_file() for p in [repo / rel]]
    for rel in ("rubrics", "reference_solutions/stations", "reference_solutions/datasets", "reference_solutions/keys",
                "submissions_fixtures/grading", "submissions_fixtures/assessment"):  # rubrics: the demo's default
        if (repo / rel).is_dir():
            files += _files(repo, rel)
    entries += [(p.relative_to(repo).as_posix(), p.read_bytes(), 0o644) for p in files]
    if not (repo / "README.md").is_file():
        entries.append(("README.md", b"grader autograder\n", 0o644))
    return zip_bytes(entries)
