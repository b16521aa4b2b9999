"""Rigs without some predictions, and fits at a physical bound: answers, never errors.

The light-damping rig is the case reported in issue 9: Kce at 0.6 of the default station's
and ``feedback: inches``; its step overshoot peaks near 24 % before the loop turns unstable,
so no P gain gives 25 % overshoot.
"""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from grader.cli import main
from grader.datasets import load
from grader.errors import GraderError
from grader.identify import FlowGainFit, FrictionFit
from grader.keys import build_key, read_key
from grader.model import zloop
from grader.model.params import Controller
from grader.stations import Station, reference_dir
from grader.synth import make_dataset, paper_runs, station_effects

DEFAULT_DATASET = reference_dir() / "datasets" / "default"


@pytest.fixture(scope="module")
def light_rig(station: Station, tmp_path_factory: pytest.TempPathFactory) -> Path:
    truth = {**station.truth, "Kce": "4.33e-4 in^3/s/psi"}
    st = station.model_copy(update={"station": "light", "feedback": "inches", "truth": truth})
    assert zloop.gain_for_overshoot(st.params(), 0.25) is None  # the true rig has no 25 % gain either
    return make_dataset(st, tmp_path_factory.mktemp("light") / "light", seed=3, effects=station_effects(st))


def test_light_damping_rig_keys_with_a_not_reachable_gain(light_rig: Path, tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "key.json"
    assert main(["key", str(light_rig), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    entry = json.loads(out.read_text())["quantities"]["Kp_25_overshoot"]
    assert entry["status"] == "not_reachable" and entry["value"] is None and entry["interval"] is None
    m = re.search(r"peaks at (\d+) % overshoot below its critical gain ([\d.]+)", entry["reason"])
    assert m and 10 <= int(m.group(1)) < 25
    key = read_key(out)
    assert float(m.group(2)) == pytest.approx(key.value("Kp_crit_model"), rel=2e-3)
    assert key.quantities["Kp_no_overshoot"].reachable and key.value("Kp_no_overshoot") > 0
    assert re.search(r"Kp_25_overshoot \*\s*│\s*not reachable", printed)
    assert "* Kp_25_overshoot: the identified loop peaks at" in " ".join(printed.split())


def test_missing_p_ramp_run_makes_the_ramp_error_not_reachable(station: Station, tmp_path: Path) -> None:
    runs = [r for r in paper_runs(station.params()) if r.name != "ramp_p"]
    key = build_key(load(make_dataset(station, tmp_path / "ds", seed=5, runs=runs)))
    e = key.quantities["ramp_ess_P"]
    assert not e.reachable and e.value is None and "no P-only ramp run" in (e.reason or "")
    assert key.quantities["Kp_25_overshoot"].reachable


def test_a_p_ramp_run_that_does_not_ramp_has_no_ramp_error(station: Station, tmp_path: Path) -> None:
    """Its rows cut before the ramp starts, the run's command is flat: the key once predicted 0 in, status ok."""
    root = make_dataset(station, tmp_path / "ds", seed=5)
    lines = (root / "ramp_p.csv").read_text().splitlines()
    (root / "ramp_p.csv").write_text("\n".join(lines[:60]) + "\n")
    e = build_key(load(root)).quantities["ramp_ess_P"]
    assert e.status == "not_identifiable" and e.value is None
    assert re.fullmatch(r"the P ramp run ramp_p's command does not ramp over its second half \(slope -?0 in/s\): "
                        r"there is no steady ramp error to predict", e.reason or "")


SPEED = np.array([0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0])


@pytest.mark.parametrize(("force", "name", "fitted"), [
    (1.2 - 0.02 * SPEED + 0.01 * np.sin(7 * SPEED), "B_", -0.02),  # B = 0 on the rig, fitted below 0
    (0.3 * SPEED - 0.05 + 0.01 * np.cos(5 * SPEED), "Fc_", -0.05),
])
def test_friction_fit_below_zero_is_clipped_with_its_interval_and_a_note(force: np.ndarray, name: str,
                                                                        fitted: float) -> None:
    fit = FrictionFit().fit(SPEED, force)
    e = getattr(fit, name)
    lo, hi = e.interval
    assert e.value == 0.0 and lo < fitted < hi and "clipped" in (e.note or "")
    assert (not fit.B_is_zero_) if name == "Fc_" else fit.B_is_zero_


def test_flow_fit_with_negative_leakage_is_clipped() -> None:
    v = np.arange(-10.0, 10.01, 0.5)
    i = 5.0 * v
    reading = np.maximum(0.0385 * np.abs(i) - 0.02, 0.0) + 0.002 * np.sin(3 * v)
    fit = FlowGainFit(Kamp=5.0).fit(v, np.abs(reading))
    assert fit.leakage_.value == 0.0 and fit.leakage_.interval[0] < 0 and "clipped" in (fit.leakage_.note or "")
    assert fit.Kq_.value == pytest.approx(0.0385, rel=0.01)


@pytest.fixture(scope="module")
def stable_run_rig(station: Station, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The default station with its 'instability' run at 0.4 of the gain that makes it oscillate:
    the step's transient dies out, as when a student stops raising the gain too early."""
    runs = [r if r.kind != "instability" else replace(r, controller=Controller(0.4 * r.controller.Kp))
            for r in paper_runs(station.params(), station_effects(station))]
    return make_dataset(station, tmp_path_factory.mktemp("stable") / "default", seed=3, runs=runs,
                        effects=station_effects(station))


def test_run_without_critical_oscillation_keys_as_not_identifiable(stable_run_rig: Path, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "key.json"
    assert main(["key", str(stable_run_rig), "-o", str(out)]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    key = read_key(out)
    assert key.model.beta_over_Vt is None and key.model.Kce is None and not key.identified
    for name in ("omega_crit", "Kp_crit", "beta_over_Vt", "Kce", "Kce_model", "Kp_no_overshoot", "closed_loop_poles"):
        e = key.quantities[name]
        assert e.status == "not_identifiable" and e.value is None and "fewer than 8" in (e.reason or ""), name
    assert key.quantities["Kq"].reachable and key.quantities["Fc"].reachable
    assert re.search(r"Kce \*\s*│\s*not identifiable", printed) and "raise Kp until the oscillation grows" in printed
    with pytest.raises(GraderError, match="not identifiable"):
        key.params()


def test_flow_test_saturating_within_one_step_keys_kq_as_not_identifiable(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """The default dataset with a flow test (written here) of a valve clipped at 1 mA, below the test's 2.5 mA step:
    the key is written with Kq and the leakage not identifiable, the instability run's items saying they need Kq,
    and the model's Kq null; the diagnosis then fits Kq to the runs, with a note (it used a slope of a third of
    the truth before)."""
    from grader.gap.baseline import _flow_kq

    ds = tmp_path / "clipped"
    shutil.copytree(DEFAULT_DATASET, ds)
    v = np.arange(-10, 10.01, 0.5)
    q = np.abs(0.01 * np.clip(5.0 * v, -1.0, 1.0)) + 0.035 + np.random.default_rng(2).normal(0, 0.0005, v.size)
    (ds / "flow.csv").write_text("input [V],flow [gpm]\n" + "".join(f"{a:g},{b:.6f}\n" for a, b in zip(v, q)))
    out = tmp_path / "key.json"
    assert main(["key", str(ds), "-o", str(out)]) == 0
    assert "within one input step of the valve null" in " ".join(capsys.readouterr().out.split())
    key = read_key(out)
    assert key.model.Kq is None and key.model.Kce is None and not key.identified
    for name in ("Kq", "leakage"):
        assert key.quantities[name].status == "not_identifiable" and key.quantities[name].value is None
    for name in ("beta_over_Vt", "Kce", "char_poly_a1", "Kp_no_overshoot"):
        assert "needs Kq, which the flow test does not give" in (key.quantities[name].reason or ""), name
    # what the run gives without a model stays: Kp_crit (the manifest's gain) and the oscillation as read
    default = read_key(reference_dir() / "keys" / "default.json")
    assert key.quantities["Kp_crit"].value == default.quantities["Kp_crit"].value
    assert key.quantities["omega_crit"].value == pytest.approx(default.quantities["omega_crit"].value, rel=0.01)
    assert "without Coulomb friction's decrement" in (key.quantities["growth_rate"].note or "")
    assert key.quantities["Kpot"].reachable and key.quantities["Fc"].reachable
    notes: list[str] = []
    assert _flow_kq(load(ds), notes) is None and "within one input step" in notes[0]


def test_a_dataset_without_a_friction_test_keys_b_and_fc_as_not_identifiable(tmp_path: Path,
                                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """The default dataset with its friction test left out of the manifest: the key is written (it was refused),
    B and Fc say why they are missing, and every other item is what a friction test reading no friction gives."""
    bare, frictionless = tmp_path / "bare", tmp_path / "frictionless"
    for ds in (bare, frictionless):
        shutil.copytree(DEFAULT_DATASET, ds)
    manifest = json.loads((bare / "manifest.json").read_text())
    friction = manifest.pop("friction")
    (bare / friction).unlink()
    (bare / "manifest.json").write_text(json.dumps(manifest, indent=2))
    speed = "".join(f"{s:g},0\n" for s in (-4.0, -2.0, -1.0, 1.0, 2.0, 4.0))
    (frictionless / friction).write_text("speed [in/s],force [lbf]\n" + speed)
    out = tmp_path / "key.json"
    assert main(["key", str(bare), "-o", str(out)]) == 0
    assert "the dataset has no friction test" in " ".join(capsys.readouterr().out.split())
    key, reference = read_key(out), build_key(load(frictionless))
    for name in ("B", "Fc"):
        assert key.quantities[name].status == "not_identifiable" and key.quantities[name].value is None
        assert reference.quantities[name].value == 0.0
    assert key.identified and key.model.B == 0.0
    for name, entry in reference.quantities.items():
        if name not in ("B", "Fc"):
            assert key.quantities[name].value == entry.value, name
