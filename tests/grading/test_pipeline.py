"""Batches: nothing dropped, invalid submissions still produce every output, deterministic, exit codes."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from grader.cli import main
from grader.grading.context import KeyStore
from grader.grading.grade import GradeOptions
from grader.grading.pipeline import expand_inputs, grade_batch, passed_over, read_all

from .conftest import FIXTURES, key_args


def _copy(tmp_path: Path, names: list[str]) -> Path:
    folder = tmp_path / "subs"
    folder.mkdir()
    for n in names:
        shutil.copy(FIXTURES / n, folder / n)
    return folder


def test_expand_inputs_files_folders_globs(tmp_path: Path) -> None:
    folder = _copy(tmp_path, ["correct.json", "correct.yaml", "garbage.json"])
    (folder / "notes.txt").write_text("x")
    assert [p.name for p in expand_inputs([str(folder)])] == ["correct.json", "correct.yaml", "garbage.json"]
    assert [p.name for p in expand_inputs([str(folder / "*.yaml"), str(folder / "correct.json")])] == ["correct.json", "correct.yaml"]


def test_files_a_folder_holds_that_are_not_submissions_are_named(tmp_path: Path) -> None:
    folder = _copy(tmp_path, ["correct.json"])
    for name in ("group7.xls", "group8.ods", ".DS_Store"):
        (folder / name).write_text("x")
    (folder / "data").mkdir()  # a group's dataset folder: expected beside the submissions
    assert [p.name for p in passed_over([str(folder)])] == ["group7.xls", "group8.ods"]
    assert passed_over([str(folder / "*.json")]) == []


def test_cli_grade_notes_the_files_it_passed_over(tmp_path: Path, store: KeyStore,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    folder = _copy(tmp_path, ["correct.json"])
    (folder / "group7.ods").write_text("x")
    assert main(["grade", str(folder), "--out", str(tmp_path / "o"), "--no-progress", *key_args(store)]) == 0
    assert ("note: 1 file(s) in the folders given are not submissions (.json, .yaml, .yml, .xlsx) and were not "
            "graded: group7.ods") in capsys.readouterr().err


def test_unreadable_files_whose_names_make_one_id_keep_their_own_errors(tmp_path: Path, opts: GradeOptions) -> None:
    """ä.json and -.json both fall back to the id 'submission': the second said 'duplicate submission_id', hiding that
    it is not valid JSON."""
    for name in ("ä.json", "-.json"):
        (tmp_path / name).write_text("{bad")
    subs = read_all(sorted(tmp_path.iterdir()), opts)
    assert [s.submission_id for s in subs] == ["submission", "submission~2"]
    assert all("not valid JSON" in s.error and "duplicate" not in s.error for s in subs)


@pytest.mark.parametrize("name", [" ", "Lab 4\nextra"])
def test_a_blank_or_multi_line_assignment_name_is_refused(name: str, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """It heads the grades.csv column Canvas imports."""
    assert main(["grade", str(FIXTURES / "correct.json"), "--out", str(tmp_path / "o"), "--assignment", name]) == 2
    assert "--assignment: " in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_duplicate_ids_are_both_kept(tmp_path: Path, opts: GradeOptions, store: KeyStore) -> None:
    folder = _copy(tmp_path, ["correct.json"])
    shutil.copy(FIXTURES / "correct.json", folder / "again.json")
    results = list(grade_batch(read_all(expand_inputs([str(folder)]), opts), opts, store, workers=1))
    assert [r.valid for r in results] == [True, False]
    assert results[1].submission_id == "correct~2" and "duplicate submission_id 'correct' (also in again.json)" in results[1].error


def test_group_data_is_graded_against_its_own_key(tmp_path: Path, linear_dataset: Path, opts: GradeOptions,
                                                  store: KeyStore, kc) -> None:
    folder = tmp_path / "g"
    shutil.copytree(linear_dataset, folder / "mydata")
    sub = json.loads((FIXTURES / "correct.json").read_text())
    sub["data"] = "mydata"
    (folder / "group.json").write_text(json.dumps(sub))
    [result] = grade_batch(read_all([folder / "group.json"], opts), opts, store, workers=1)
    assert result.valid and "your group's own data" in result.notes[-1]
    own = store.for_dataset(folder / "mydata")
    assert own.key.inputs_sha256 != kc.key.inputs_sha256
    kq = next(i for i in result.items if i.item == "Kq")
    assert kq.detail["expected"] == pytest.approx(own.value("Kq"))


def test_cli_grade_writes_every_output_and_lists_invalid(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                         store: KeyStore) -> None:
    folder = _copy(tmp_path, ["correct.json", "garbage.json", "xlsx_formula.xlsx", "yaml_bomb.yaml"])
    args = [str(folder), "--out", str(tmp_path / "out"), "--no-progress", *key_args(store),
            "--assignment", "Lab 4", "--assignment-id", "77"]
    assert main(["grade", *args]) == 1
    err = capsys.readouterr().err
    assert "2 submission(s) could not be graded" in err and "garbage.json" in err and "yaml_bomb.yaml" in err
    out = tmp_path / "out"
    report = json.loads((out / "report.json").read_text())
    ids = sorted(s["submission_id"] for s in report["submissions"])
    assert ids == ["bomb", "correct", "garbage", "xlsx-formula"] or ids == ["correct", "garbage", "xlsx-formula", "yaml_bomb"]
    for sid in ids:
        assert (out / "results" / f"{sid}.json").is_file() and (out / "feedback" / f"{sid}.md").is_file()
    assert (out / "grades.csv").read_text().splitlines()[0].endswith(",Lab 4 (77)")
    assert not list(out.rglob("*.tmp"))
    first = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main(["grade", *args]) == 1
    assert first == {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}


def test_cli_grade_exit_zero_when_all_graded(tmp_path: Path, store: KeyStore) -> None:
    folder = _copy(tmp_path, ["correct.json", "mistake_kamp.json"])
    assert main(["grade", str(folder), "--out", str(tmp_path / "o"), "--no-progress", *key_args(store)]) == 0


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["grade", str(tmp_path / "nothing*.json"), "--out", str(tmp_path / "o")]) == 2
    assert "no file matches" in capsys.readouterr().err
    bad = tmp_path / "r.yaml"
    bad.write_text("rubric: x\nitems: {}\n")
    assert main(["grade", str(FIXTURES / "correct.json"), "--rubric", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "at least one item" in capsys.readouterr().err


def test_key_without_a_quantity_marks_only_that_item(kc, opts: GradeOptions) -> None:
    from dataclasses import replace

    from grader.grading.grade import check_rubric_units, grade_submission
    from grader.grading.submissions import read_submission

    key = kc.key.model_copy(update={"quantities": {k: v for k, v in kc.key.quantities.items() if k != "ramp_ess_P"}})
    short = replace(kc, key=key, memo={})
    check_rubric_units(opts.rubric, short)
    result = grade_submission(read_submission(FIXTURES / "correct.json"), short, opts)
    bad = [i for i in result.items if i.status != "correct"]
    assert [(i.item, i.status) for i in bad] == [("ramp_ess_P", "invalid")] and "cannot be checked" in bad[0].feedback


def test_instructor_feedback_names_pole_gains_no_run_used(tmp_path: Path, opts: GradeOptions, store: KeyStore) -> None:
    """With reveal (grader grade), the stray gains are named, each once; the self-check only counts them."""
    doc = json.loads((FIXTURES / "correct.json").read_text())
    stray = {"Kp": 11, "poles": ["-1", "-2", "-3"]}
    doc["answers"]["closed_loop_poles"] += [stray, stray]
    (tmp_path / "s.json").write_text(json.dumps(doc))
    sub = read_all([tmp_path / "s.json"], opts)[0]
    item = next(i for i in next(iter(grade_batch([sub], opts, store, workers=1))).items if i.item == "closed_loop_poles")
    assert item.status == "correct" and item.detail["unmatched_gains"] == ["Kp = 11"]
    assert item.feedback.endswith("Poles given at Kp = 11 match none of the lab's runs and were not graded.")
