"""Cross-CPU determinism: ``grader key``, ``grader grade``, ``grader exam`` and ``grader survey`` write the same
bytes whatever BLAS kernels run.

OpenBLAS picks its kernels by CPU; ``OPENBLAS_CORETYPE`` forces the kernels of an older
or newer CPU, so one machine can stand in for three. One subprocess per core type runs the four
verbs (the imports dominate their time). The exam report's workbook once held a regression's t statistic at
full precision, whose last digits differed between Prescott's kernels and Haswell's.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from grader.stations import reference_dir


def _core_types() -> tuple[str, ...]:
    """Prescott's, Nehalem's and Haswell's kernels, and SkylakeX's where the CPU has AVX-512 (forced on a CPU
    without it, OpenBLAS would run instructions the CPU lacks)."""
    cpuinfo = Path("/proc/cpuinfo")
    avx512 = cpuinfo.is_file() and "avx512f" in cpuinfo.read_text(encoding="utf-8", errors="replace")
    return ("Prescott", "Nehalem", "Haswell", *(("SkylakeX",) if avx512 else ()))


CORE_TYPES = _core_types()
FIXTURES = reference_dir().parent / "submissions_fixtures" / "grading"
#: fixtures whose items exercise ECF, known mistakes, not-reachable answers and designs (a PI design's ramp error
#: differed in its 5th digit between Prescott's kernels and SkylakeX's before the report rounded it to a millionth)
SUBMISSIONS = ("ecf_not_reachable.json", "mistake_kpot_predictions.json", "correct.json")
ASSESSMENT = reference_dir().parent / "submissions_fixtures" / "assessment"
SCRIPT = """
import sys
from grader.cli import main
out, dataset, assessment, *submissions = sys.argv[1:]
assert main(["key", dataset, "-o", out + "/key.json"]) == 0
assert main(["grade", "--workers", "1", "--no-progress", "-o", out + "/grades", *submissions]) == 0
assert main(["exam", assessment + "/exam_scores.csv", "--out", out + "/exam"]) == 0
assert main(["survey", assessment + "/survey_google_forms.csv", "--out", out + "/survey"]) == 0
"""


def _submissions(folder: Path) -> list[str]:
    paths = []
    for name in SUBMISSIONS:
        shutil.copy(FIXTURES / name, folder / name)
        paths.append(str(folder / name))
    return paths


def _outputs(core: str, out: Path, submissions: list[str]) -> dict[str, bytes]:
    out.mkdir()
    env = {**os.environ, "OPENBLAS_CORETYPE": core}
    dataset = str(reference_dir() / "datasets" / "default")
    subprocess.run([sys.executable, "-c", SCRIPT, str(out), dataset, str(ASSESSMENT), *submissions],
                   env=env, check=True, capture_output=True, timeout=300)
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def test_key_grade_and_assessment_bytes_are_the_same_under_every_blas_core_type(tmp_path: Path) -> None:
    submissions = _submissions(tmp_path)
    written = {core: _outputs(core, tmp_path / core, submissions) for core in CORE_TYPES}
    checked_in = (reference_dir() / "keys" / "default.json").read_bytes()
    first = written[CORE_TYPES[0]]
    assert {"key.json", "grades/report.json", "grades/grades.csv", "exam/report.xlsx", "survey/report.xlsx"} <= set(first)
    for core, files in written.items():
        assert files["key.json"] == checked_in, f"OPENBLAS_CORETYPE={core} wrote a key different from the checked-in one"
        assert files.keys() == first.keys()
        for name, data in files.items():
            assert data == first[name], f"OPENBLAS_CORETYPE={core} wrote a different {name}"
