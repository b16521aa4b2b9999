"""The autograder zip run as Gradescope runs it, in a simulated ``/autograder`` (no root, no network):
unzip, ``setup.sh``, place a submission, ``run_autograder``, and check ``results.json`` against
Gradescope's documented format (gradescope-autograders.readthedocs.io, "Autograder Specifications").

setup.sh's test hook GRADER_SETUP_PYTHON replaces only the step that obtains Python and the
dependencies (apt, uv, the package index) with this interpreter; the package itself is installed
from the unzipped source, and run_autograder is the script Gradescope runs.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import jsonschema
import pytest

from grader.demo import _steps
from grader.exports.gradescope import package_zip
from grader.grading.commands import DEFAULT_RUBRIC
from grader.grading.rubric import load_rubric

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "submissions_fixtures" / "grading"
FORMATS = ["text", "html", "simple_format", "md", "ansi"]
VISIBILITY = ["hidden", "after_due_date", "after_published", "visible"]
#: Gradescope's results.json: score on the top level or on every test; the documented fields only.
RESULTS_SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "anyOf": [{"required": ["score"]}, {"required": ["tests"], "properties": {"tests": {"items": {"required": ["score"]}}}}],
    "properties": {
        "score": {"type": "number"},
        "execution_time": {"type": "number"},
        "output": {"type": "string"},
        "output_format": {"enum": FORMATS},
        "test_output_format": {"enum": FORMATS},
        "test_name_format": {"enum": FORMATS},
        "visibility": {"enum": VISIBILITY},
        "stdout_visibility": {"enum": VISIBILITY},
        "extra_data": {"type": "object"},
        "leaderboard": {"type": "array"},
        "tests": {"type": "array", "items": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "score": {"type": "number"},
                "max_score": {"type": "number"},
                "status": {"enum": ["passed", "failed"]},
                "name": {"type": "string"},
                "name_format": {"enum": FORMATS},
                "number": {"type": "string"},
                "output": {"type": "string"},
                "output_format": {"enum": FORMATS},
                "tags": {"type": "array", "items": {"type": "string"}},
                "visibility": {"enum": VISIBILITY},
                "extra_data": {"type": "object"},
            },
        }},
    },
}


def _unzip(data: bytes, dest: Path) -> None:
    """Extract like Gradescope does, keeping the scripts' executable bits."""
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        for info in z.infolist():
            path = Path(z.extract(info, dest))
            mode = (info.external_attr >> 16) & 0o777
            if mode:
                path.chmod(mode)


@pytest.fixture(scope="module")
def autograder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated /autograder after Gradescope built the image from the zip."""
    root = tmp_path_factory.mktemp("gs") / "autograder"
    rubric = ROOT / "rubrics" / "hydraulic_positioner.yaml"
    _unzip(package_zip(ROOT, rubric, convention=load_rubric(rubric).feedback_convention), root / "source")
    env = {**os.environ, "AUTOGRADER_ROOT": str(root), "GRADER_SETUP_PYTHON": sys.executable, "GRADER_SETUP_WARMUP": "0"}
    setup = subprocess.run(["bash", str(root / "source" / "setup.sh")], env=env, capture_output=True, text=True,
                           timeout=300, cwd=root / "source")
    assert setup.returncode == 0, setup.stderr
    shutil.copy2(root / "source" / "run_autograder", root / "run_autograder")
    return root


def _run(root: Path, submissions: list[Path]) -> dict:
    sub, results = root / "submission", root / "results"
    for d in (sub, results):
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir()
    for f in submissions:
        shutil.copy2(f, sub / f.name)
    env = {**os.environ, "AUTOGRADER_ROOT": str(root)}
    run = subprocess.run([str(root / "run_autograder")], env=env, capture_output=True, text=True, timeout=120, cwd=root)
    assert run.returncode == 0, run.stderr
    data = json.loads((results / "results.json").read_text(encoding="utf-8"))
    jsonschema.validate(data, RESULTS_SCHEMA)
    return data


def test_setup_installs_the_grader_from_the_unzipped_source(autograder: Path) -> None:
    out = subprocess.run([str(autograder / "venv" / "bin" / "python"), "-c", "import grader; print(grader.__file__)"],
                         capture_output=True, text=True, check=True, cwd=autograder)
    assert Path(out.stdout.strip()).is_relative_to(autograder / "source")


def test_the_zip_carries_what_the_warm_up_demo_reads(autograder: Path) -> None:
    """Its inputs, and the default rubric that grade and check read when none is given (setup.sh's warm-up, under
    set -e, failed the image build without it)."""
    inputs = [Path(a) for _, argv in _steps(Path("/nonexistent-out")) for a in argv if a.startswith(str(ROOT))]
    inputs.append(ROOT / DEFAULT_RUBRIC)
    assert len(inputs) > 1
    missing = [p.relative_to(ROOT) for p in inputs if not (autograder / "source" / p.relative_to(ROOT)).exists()]
    assert not missing


@pytest.mark.parametrize(("submission", "full_marks"), [("correct.json", True), ("unit_kq_ft3.json", False)])
def test_run_autograder_writes_gradescope_results(autograder: Path, submission: str, full_marks: bool) -> None:
    data = _run(autograder, [FIXTURES / submission])
    tests = data["tests"]
    assert tests and data["score"] == pytest.approx(sum(t["score"] for t in tests))
    assert all(0 <= t["score"] <= t["max_score"] and t["status"] == ("passed" if t["score"] >= t["max_score"] else "failed")
               for t in tests)
    assert (data["score"] == pytest.approx(sum(t["max_score"] for t in tests))) is full_marks
    if not full_marks:
        assert any(t["name"] == "Kq" and t["status"] == "failed" for t in tests)
