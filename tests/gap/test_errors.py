"""Bad datasets get one clear line naming what is wrong (exit code 2, no traceback)."""

from __future__ import annotations

import gc
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from grader.cli import main
from grader.errors import DiagnosisError

Edit = Callable[[Path], None]


def _manifest(edit: Callable[[dict], None]) -> Edit:
    def apply(root: Path) -> None:
        path = root / "manifest.json"
        data = json.loads(path.read_text(encoding="utf-8"))
        edit(data)
        path.write_text(json.dumps(data), encoding="utf-8")

    return apply


def _no_runs(data: dict) -> None:
    data["runs"] = []


def _one_run(data: dict) -> None:
    data["runs"] = [r for r in data["runs"] if r["name"] == "step_kp25"]


def _wrong_gain(data: dict) -> None:
    next(r for r in data["runs"] if r["name"] == "step_kp25")["controller"]["Kp"] = 46


def _slow_clock(data: dict) -> None:
    data["given"]["sample_time"] = "2 ms"


def _no_gain(data: dict) -> None:
    next(r for r in data["runs"] if r["name"] == "ramp_p")["controller"] = {"Kp": 0, "Kd": 0.01}


def _flat_calibration(root: Path) -> None:
    path = root / "calibration.csv"
    lines = path.read_text(encoding="utf-8").splitlines()
    path.write_text("\n".join([lines[0], *(f"{line.split(',')[0]},5.0" for line in lines[1:] if line)]) + "\n",
                    encoding="utf-8")


def _short_runs(root: Path) -> None:
    """Every run but step_kp25 stopped right after its command: each is set aside, and one run is too few."""
    for name in ("step_kp10", "step_kp46", "instability", "ramp_p", "ramp_pi"):
        path = root / f"{name}.csv"
        lines = path.read_text(encoding="utf-8").splitlines()
        path.write_text("\n".join(lines[:60]) + "\n", encoding="utf-8")


@pytest.mark.parametrize(("edit", "expected"), [
    (_manifest(_no_runs), "lists no runs"),
    (_manifest(_one_run), "lists one run (step_kp25); the diagnosis needs at least 2 closed-loop runs"),
    (_short_runs, "ds: 1 of the manifest's 6 runs can be compared, and the diagnosis needs at least 2: run step_kp10 "
                  "(step_kp10.csv): only"),
    (_manifest(_wrong_gain), "run step_kp25: the manifest gives Kp = 46"),
    (_manifest(_slow_clock), "not evenly at the manifest's sample_time of 2 ms"),
    (_manifest(_no_gain), "manifest.json: field runs.4.controller: controller needs Kp > 0 or Ki > 0"),
    (_flat_calibration, "calibration: the voltage does not change with position (slope 0 V/in, scatter 0 V)"),
])
def test_bad_dataset_gets_a_clear_error(linear_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       edit: Edit, expected: str) -> None:
    root = tmp_path / "ds"
    shutil.copytree(linear_dataset, root)
    edit(root)
    assert main(["diagnose", str(root), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("grader diagnose: error: ") and expected in err
    assert len(err.strip().splitlines()) == 1


def test_wrong_gain_message_gives_the_gain_the_data_imply(linear_dataset: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    root = tmp_path / "ds"
    shutil.copytree(linear_dataset, root)
    _manifest(_wrong_gain)(root)
    main(["diagnose", str(root), "--out", str(tmp_path / "out")])
    assert "Kp ≈ 25" in capsys.readouterr().err


def test_unknown_candidate_effect_is_refused(linear_dataset: Path, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["diagnose", str(linear_dataset), "--effects", "coulomb_fricton", "--out", str(tmp_path / "out")]) == 2
    assert "unknown candidate(s) coulomb_fricton" in capsys.readouterr().err


@pytest.mark.parametrize("enabled", [True, False])
def test_the_collector_is_paused_for_a_diagnosis_and_restored_after(enabled: bool, tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[bool] = []

    def failing(*_args: object, **_kwargs: object) -> None:
        seen.append(gc.isenabled())
        raise DiagnosisError("stopped by the test")

    monkeypatch.setattr("grader.gap.diagnose.analyse", failing)
    (gc.enable if enabled else gc.disable)()
    try:
        assert main(["diagnose", str(tmp_path), "-o", str(tmp_path / "out")]) == 2
        assert seen == [False]
        assert gc.isenabled() is enabled
    finally:
        gc.enable()


@pytest.mark.parametrize(("args", "says"), [
    (["--valve-null", "5"], "--valve-null must be between 0 and 1 mA; got 5"),
    (["--valve-null", "-0.1"], "--valve-null must be between 0 and 1 mA; got -0.1"),
    (["--valve-null", "nan"], "--valve-null must be between 0 and 1 mA; got nan"),
    (["--n", "0"], "--n and --jobs must be at least 1"),
])
def test_bench_gap_refuses_bad_options_in_one_line(args: list[str], says: str, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench-gap", *args, "--workdir", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not (tmp_path / "w").exists() or not any((tmp_path / "w").iterdir())  # nothing generated
