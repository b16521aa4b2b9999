"""``grader check`` never shows a key value or a reference expression; the prelab works without data."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest

from grader.cli import main
from grader.grading import tf
from grader.grading.context import KeyContext, KeyStore

from .conftest import FIXTURES, key_args

CHECKED = ["correct.json", "unit_kq_ft3.json", "mistake_weight_as_mass.json", "ecf_kq.json", "tf_wrong.json",
           "bad_design_goal.json", "mistake_open_loop_poles.json", "wrong_dimension.json", "mistake_kpot_convention.json"]


@pytest.mark.parametrize("name", CHECKED)
def test_check_reveals_no_key_value(name: str, kc: KeyContext, store: KeyStore, capsys: pytest.CaptureFixture[str],
                                    key_numbers: Callable[[KeyContext], set[str]]) -> None:
    assert main(["check", str(FIXTURES / name), *key_args(store)]) == 0
    out = capsys.readouterr().out
    assert "status" in out and "Kq" in out
    numbers = set(re.findall(r"\d+\.?\d*(?:e[-+]?\d+)?", out))
    submitted = set(re.findall(r"\d+\.?\d*(?:e[-+]?\d+)?", (FIXTURES / name).read_text()))
    leaked = {t for t in key_numbers(kc) if t in numbers - submitted}
    assert not leaked, leaked
    for form in tf.FORMS:
        ref = str(tf._loop_forms("volts")[form]).replace(" ", "")
        assert ref not in out.replace(" ", "")
    assert "Expected" not in out and "expected " not in out.replace("expected value", "")


def test_prelab_needs_no_lab_data(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "no-datasets"
    empty.mkdir()
    assert main(["check", str(FIXTURES / "correct.json"), "--datasets", str(empty)]) == 0
    out = capsys.readouterr().out
    assert "no lab data" in out and "checking the prelab items only" in out
    assert out.count("correct") >= 3 and "not checked without lab data: Kpot" in out.replace("\n", " ")


def test_check_reports_an_unreadable_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", str(FIXTURES / "garbage.json")]) == 1
    assert "not valid JSON" in capsys.readouterr().out
