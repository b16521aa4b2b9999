"""``grader simulate``: a complete dataset, effects in truth.json only, clear rejections."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grader.cli import main
from grader.datasets import load
from grader.synth import read_truth

ARGS = ["simulate", "--station", "default", "--effect", "coulomb_friction:Fc=4lbf",
        "--effect", "sampling_delay:delay=2ms", "--seed", "7"]


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sim") / "data"
    assert main([*ARGS, "-o", str(out)]) == 0
    return out


def test_writes_a_loadable_dataset_with_every_part_of_the_procedure(simulated: Path) -> None:
    ds = load(simulated)
    assert ds.calibration is not None and ds.flow_test is not None and ds.friction is not None
    kinds = [r.spec.kind for r in ds.runs]
    assert kinds.count("step") == 3 and kinds.count("instability") == 1 and kinds.count("ramp") == 2
    assert [r.controller.Kp for r in ds.runs_of("step")] == [10, 25, 46]
    assert any(r.controller.Ki > 0 for r in ds.runs_of("ramp"))


def test_effects_go_to_truth_json_and_never_to_the_manifest(simulated: Path) -> None:
    truth = read_truth(simulated)
    assert truth.station == "default" and truth.seed == 7 and truth.simulator == "rig"
    assert truth.effects["coulomb_friction"] == {"Fc": "4 lbf"}  # replaces the station's 1.2 lbf
    assert truth.effects["sampling_delay"] == {"delay": "0.002 s"}
    assert "sensor_noise" in truth.effects and "sensor_quantization" in truth.effects  # the station's own
    manifest = (simulated / "manifest.json").read_text(encoding="utf-8")
    assert "coulomb" not in manifest and "delay" not in manifest and "truth" not in manifest


def test_friction_data_show_the_coulomb_level_given(simulated: Path) -> None:
    force = load(simulated).friction["force"]
    assert force.mean() == pytest.approx(4.0, abs=0.1)


def test_same_seed_same_bytes(simulated: Path, tmp_path: Path) -> None:
    assert main([*ARGS, "-o", str(tmp_path / "again")]) == 0
    for f in sorted(simulated.iterdir()):
        assert (tmp_path / "again" / f.name).read_bytes() == f.read_bytes(), f.name


def test_no_station_effects_starts_from_the_ideal_rig(tmp_path: Path) -> None:
    out = tmp_path / "clean"
    assert main(["simulate", "--no-station-effects", "--effect", "valve_saturation:i_max=30mA", "-o", str(out)]) == 0
    assert json.loads((out / "truth.json").read_text())["effects"] == {"valve_saturation": {"i_max": "30 mA"}}
    flow = load(out).flow_test["flow"]
    assert flow.max() < 0.0385 * 30.5 + 0.2  # the flow test saturates at the valve's limit [in³/s]


@pytest.mark.parametrize(
    ("effect", "message"),
    [
        ("stiction:Fc=1lbf", "unknown effect 'stiction'"),
        ("coulomb_friction:Fc=4 volts", "is not a force"),
        ("coulomb_friction:Fc=4", "needs a unit"),
        ("sampling_delay:delay=-1ms", "out of range"),
        ("valve_saturation:i_max=5000mA", "out of range"),
    ],
)
def test_rejects_bad_effects_with_a_one_line_message(effect: str, message: str, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--effect", effect, "-o", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("grader simulate: error: ") and message in err and err.count("\n") == 1
    assert not (tmp_path / "x").exists()


def test_refuses_to_overwrite_a_dataset_without_the_flag(simulated: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "-o", str(simulated)]) == 2
    assert "--overwrite" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "message"),
    [(["--seed", "-1"], "non-negative"), (["--station", "nowhere"], "no such station"), ([], "-o/--out")],
)
def test_rejects_bad_options(args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = ["-o", str(tmp_path / "x")] if args else []
    assert main(["simulate", *args, *out]) == 2
    assert message in capsys.readouterr().err


def test_list_effects_names_every_effect_and_parameter(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--list-effects"]) == 0
    out = capsys.readouterr().out
    for key in ("coulomb_friction:Fc", "valve_saturation:i_max", "sampling_delay:delay", "sensor_noise:sigma",
                "pressure_flow_nonlinearity", "valve_dynamics:tau", "sensor_quantization:bits"):
        assert key in out
