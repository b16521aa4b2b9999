"""The output-path policy (grader/outpaths.py), verb by verb, and the CLI's lazy start-up.

Every verb that writes is run against each bad output path. The inputs named are missing on
purpose: the error must be about the output path, which proves the path is checked before
any work starts. Every case must give one line on stderr, exit code 2, no traceback
(an exception escaping ``main`` fails the test) and no stray temporary file.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from grader.cli import main
from grader.stations import reference_dir

ROOT = Path(__file__).resolve().parents[2]
Argv = Callable[[Path, str], list[str]]

#: verb -> argv given (tmp folder, output path); the inputs are missing on purpose.
FILE_VERBS: dict[str, Argv] = {
    "key": lambda t, o: ["key", str(t / "no_dataset"), "-o", o],
    "template": lambda t, o: ["template", "-o", o, "--rubric", str(t / "no_rubric.yaml")],
    "gradescope-package": lambda t, o: ["gradescope-package", "-o", o, "--rubric", str(t / "no_rubric.yaml")],
    "gradescope": lambda t, o: ["gradescope", "--submission-dir", str(t / "none"), "--results", o,
                                "--rubric", str(t / "no_rubric.yaml")],
    "survey-template": lambda t, o: ["survey-template", "-o", o, "--mapping", str(t / "no_mapping.yaml")],
    "exam-template": lambda t, o: ["exam-template", "-o", o],
}
FOLDER_VERBS: dict[str, Argv] = {
    "grade": lambda t, o: ["grade", str(t / "no_submission.json"), "-o", o, "--no-progress"],
    "diagnose": lambda t, o: ["diagnose", str(t / "no_dataset"), "-o", o],
    "demo": lambda t, o: ["demo", "-o", o],
    "simulate": lambda t, o: ["simulate", "--station", str(t / "no_station.yaml"), "-o", o],
    "bench-gap": lambda t, o: ["bench-gap", "--n", "1", "--workdir", o],
    "survey": lambda t, o: ["survey", str(t / "no_responses.csv"), "-o", o],
    "exam": lambda t, o: ["exam", str(t / "no_scores.csv"), "-o", o],
}


def _unwritable(tmp: Path) -> str:
    """A folder path that cannot be created or written, also for root (sysfs refuses new entries)."""
    if os.geteuid() == 0:
        return "/sys/grader-test-out"
    locked = tmp / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    return str(locked / "out")


def _bad_paths(tmp: Path, kind: str) -> dict[str, str]:
    (tmp / "afile").write_text("x")
    (tmp / "afolder").mkdir()
    cases = {"file where a folder is needed": str(tmp / "afile" / "out"), "unwritable": _unwritable(tmp)}
    if kind == "file":
        cases["existing folder where a file is expected"] = str(tmp / "afolder")
    else:
        cases["existing file where a folder is expected"] = str(tmp / "afile")
    return cases


CASES = [(verb, kind, case) for kind, verbs in (("file", FILE_VERBS), ("folder", FOLDER_VERBS)) for verb in verbs
         for case in ("file where a folder is needed", "unwritable", "existing folder where a file is expected"
                      if kind == "file" else "existing file where a folder is expected")]


@pytest.mark.parametrize("verb, kind, case", CASES)
def test_bad_output_path_is_one_line_and_exit_2(verb: str, kind: str, case: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = _bad_paths(tmp_path, kind)[case]
    argv = (FILE_VERBS if kind == "file" else FOLDER_VERBS)[verb](tmp_path, out)
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"grader {verb}: error: "), captured.err
    shown = Path(out).parent if case == "file where a folder is needed" else Path(out)
    assert str(shown) in lines[0] and "Traceback" not in captured.err + captured.out
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp") or p.name.startswith(".grader-probe")]


@pytest.mark.parametrize("argv, made", [
    (lambda o: ["template", "-o", str(o / "lab4.xlsx")], "lab4.xlsx"),
    (lambda o: ["exam-template", "-o", str(o / "exam.csv")], "exam.csv"),
    (lambda o: ["survey-template", "-o", str(o / "survey.csv")], "survey.csv"),
    (lambda o: ["key", str(reference_dir() / "datasets" / "default"), "-o", str(o / "key.json")], "key.json"),
])
def test_missing_parent_folders_are_created(argv: Callable[[Path], list[str]], made: str, tmp_path: Path) -> None:
    out = tmp_path / "new" / "deeper"
    assert main(argv(out)) == 0
    assert (out / made).is_file() and sorted(p.name for p in out.iterdir()) == [made]


@pytest.mark.parametrize("verb", ["grade", "diagnose", "simulate", "survey", "exam"])
def test_a_verb_that_fails_on_its_input_leaves_no_empty_output_folder(verb: str, tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """The output folder is made before any work (to refuse a bad path at once); when the input then fails,
    the folders made for it go again, so a newcomer's failed first try leaves no empty ``diagnosis/``."""
    (tmp_path / "kept").mkdir()
    for out in (tmp_path / "new" / "deeper", tmp_path / "kept"):
        assert main(FOLDER_VERBS[verb](tmp_path, str(out))) == 2
    assert "error" in capsys.readouterr().err
    assert not (tmp_path / "new").exists() and (tmp_path / "kept").is_dir()


@pytest.mark.parametrize("failed", [True, False])
def test_created_folders_left_empty_go_only_after_a_failure(tmp_path: Path, failed: bool) -> None:
    """Folders made by separate calls, a parent first and its child later: after a failure both go (deepest
    first), a folder with a file stays; after a success nothing goes."""
    from grader.outpaths import discard_empty_created, output_folder, write_text

    output_folder(tmp_path / "a")
    output_folder(tmp_path / "a" / "b" / "c")
    write_text(tmp_path / "kept" / "x.txt", "x")
    discard_empty_created(failed=failed)
    assert (tmp_path / "a").exists() != failed and (tmp_path / "kept" / "x.txt").is_file()
    discard_empty_created(failed=True)  # forgotten: a later failure removes nothing made before
    assert (tmp_path / "a").exists() != failed


def test_gradescope_results_folder_is_created(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    results = tmp_path / "results" / "results.json"
    assert main(["gradescope", "--submission-dir", str(tmp_path / "sub"), "--results", str(results)]) == 0
    assert json.loads(results.read_text())["score"] == 0


HEAVY = ("scipy", "control", "sympy", "pandas", "matplotlib", "statsmodels", "pydantic", "numpy", "pint")


def test_cli_start_up_imports_no_heavy_library() -> None:
    """``import grader.cli`` and building the parser (what ``grader --help`` does) stay light."""
    code = ("import sys, grader.cli; grader.cli.build_parser(); "
            f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert done.stdout.strip() == ""


def test_every_writing_verb_is_in_the_table() -> None:
    """A new verb that writes files must join FILE_VERBS or FOLDER_VERBS (check and serve write nothing)."""
    from grader.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "verb")
    assert set(sub.choices) - {"check", "serve"} == set(FILE_VERBS) | set(FOLDER_VERBS)


def test_prelab_check_imports_neither_the_simulators_nor_the_identification() -> None:
    """``grader check`` on the prelab grades expressions only: python-control, scipy.signal and
    scipy.optimize (the identification and the design simulations), matplotlib and numba stay out."""
    fixture = ROOT / "submissions_fixtures" / "grading" / "prelab_only.json"
    heavy = ("control", "scipy.signal", "scipy.optimize", "matplotlib", "numba", "grader.identify", "grader.model.zloop")
    code = ("import sys, contextlib, io; from grader.cli import main\n"
            f"with contextlib.redirect_stdout(io.StringIO()): rc = main(['check', {str(fixture)!r}])\n"
            f"print(rc, ','.join(m for m in {heavy!r} if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert done.stdout.split() == ["0"]
