"""Strict scoring, the quantising ADC, the friction test's evidence, separating tests, and the README's example."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from grader.cli import main
from grader.datasets import load
from grader.gap import search
from grader.gap.bench import BenchConfig, Case, effect_params, finest_board, make_case_dataset, station_runs
from grader.gap.bench_report import render
from grader.gap.bench_run import Task, tasks
from grader.gap.diagnose import analyse
from grader.gap.evidence import Friction, viscous
from grader.gap.noise import Noise
from grader.gap.pairs import better_alone
from grader.gap.quantization import assess
from grader.gap.runs import GapRun
from grader.gap.schema import Diagnosis, Verdict
from grader.gap.separating import GENERIC, separating_test
from grader.gap.verdict import Scored
from grader.model.effects import EffectSet
from grader.model.params import Controller
from grader.model.rig_ivp import simulate_rig_ivp
from grader.stations import load_station


def _case(truth: str, verdict: str, second: str | None = None, runner_up: str | None = None,
          ties: tuple[str, ...] = ()) -> Case:
    return Case(truth, None, verdict, second, runner_up, ties, 0.8, 1.0, {})


@pytest.mark.parametrize(("truth", "verdict", "second", "right"), [
    ("none", "none", None, True),
    ("none", "viscous_friction", None, False),  # a false positive
    ("none", "none", "sensor_quantization", False),
    ("viscous_friction", "none", None, False),  # 'none' is no longer right for a weak effect
    ("sensor_quantization", "sensor_quantization", None, True),
    ("coulomb_friction", "coulomb_friction", "sampling_delay", False),  # an extra effect is wrong
    ("coulomb_friction+sampling_delay", "sampling_delay", "coulomb_friction", True),  # any order
    ("coulomb_friction+sampling_delay", "coulomb_friction", None, False),  # only one of two
])
def test_a_verdict_is_right_only_when_it_names_exactly_the_withheld_effects(
        truth: str, verdict: str, second: str | None, right: bool) -> None:
    assert _case(truth, verdict, second).right is right


def test_cannot_separate_counts_as_a_miss_and_is_reported_apart() -> None:
    """The issue's rule: a verdict the diagnosis cannot tell from a lookalike is a miss even when it is the truth;
    its parameters still count towards coverage (the fit named exactly the withheld effects)."""
    hedged = _case("valve_dynamics", "valve_dynamics", ties=("sampling_delay",))
    hedged_pair = _case("coulomb_friction+sampling_delay", "coulomb_friction", "sampling_delay", ties=("valve_dynamics",))
    assert hedged.named_exactly and not hedged.right
    assert hedged_pair.named_exactly and not hedged_pair.right
    text = render([hedged, _case("none", "none"), hedged_pair])
    assert "strict top-1 (one effect or none): 50.0 %" in text
    assert "named exactly but not told apart from a lookalike (counted as misses): 1 of one effect or none, 1 of two" in text
    assert "MISS coulomb_friction+sampling_delay" in text and "coulomb_friction+sampling_delay ~valve_dynamics" in text



def test_a_lookalike_the_verdict_names_itself_is_no_hedge() -> None:
    """Coulomb friction not told apart from a deadband, and the deadband named as the second effect: the two named
    are the two withheld whichever is which."""
    from grader.gap.bench_run import _ties

    v = Verdict(effect="coulomb_friction", margin=0.5, runner_up="valve_deadband", confidence=0.9,
                indistinguishable_from=["valve_deadband", "valve_hysteresis"], second_effect="valve_deadband",
                explanation="")
    assert _ties(v) == ("valve_hysteresis",)
    assert _ties(v.model_copy(update={"indistinguishable_from": ["valve_deadband"]})) == ()


def test_report_counts_strict_top1_top2_and_false_positives_on_none() -> None:
    cases = [_case("none", "none"), _case("none", "viscous_friction"),
             _case("viscous_friction", "none", runner_up="viscous_friction"), _case("sampling_delay", "sampling_delay"),
             _case("coulomb_friction+sampling_delay", "coulomb_friction", "sampling_delay")]
    text = render(cases)
    assert "strict top-1 (one effect or none): 50.0 %   strict top-2: 75.0 %" in text
    assert "false positives on none: 50.0 % (2 datasets)" in text
    assert "two effects, both named: 100.0 %" in text
    row = next(line for line in text.splitlines() if line.startswith("viscous_friction"))
    assert row.split()[1] == "1" and row.endswith("0.0 %")  # confusion matrix: called none once


def _wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson's score interval in closed form [%] (an independent path to statsmodels')."""
    p = k / n
    centre, half = (p + z**2 / (2 * n)) / (1 + z**2 / n), z / (1 + z**2 / n) * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2))
    return 100 * (centre - half), 100 * (centre + half)


def test_report_gives_each_rate_its_sampling_interval() -> None:
    """One false positive in 25 datasets is 4 %, but the sample cannot tell that from 0.7 % or 20 %: the report
    says so, with Wilson's interval for every headline rate and every parameter's coverage."""
    nones = [_case("none", "none")] * 24 + [_case("none", "viscous_friction")]
    delays = [replace(_case("sampling_delay", "sampling_delay"), params={"sampling_delay:delay": (1.0, 1.0, lo, 1.1)})
              for lo in [0.9] * 9 + [1.05]]
    text = render(nones + delays)
    lo, hi = _wilson(1, 25)
    assert f"false positives on none 1/25, {lo:.1f}–{hi:.1f} %" in text
    lo, hi = _wilson(34, 35)
    assert f"strict top-1 34/35, {lo:.1f}–{hi:.1f} %" in text
    lo, hi = _wilson(9, 10)
    assert f"coverage  90.0 %  (n = 10; Wilson 95 %: {lo:.1f}–{hi:.1f} %)" in text
    assert "both named –" in text  # no two-effect datasets: no rate, no interval


def _settled_run(q: float, cycle_counts: int, command: float = 0.1) -> GapRun:
    """A step run whose readings sit on a lattice of step ``q`` and end toggling over ``cycle_counts`` counts."""
    t = np.arange(0.0, 1.0, 0.001)
    r = np.where(t >= 0.1, command, 0.0)
    x = np.where(t >= 0.1, command * (1 - np.exp(-(t - 0.1) * 30)), 0.0)
    x = x + (np.arange(t.size) % 2) * cycle_counts * q * (t > 0.6)
    y = np.round(x / q) * q
    return GapRun("step", "step", Controller(10), t, r, y, None, 0.1, command, np.zeros(t.size))


@pytest.mark.parametrize(("bits", "matters"), [(10, True), (16, False)])
def test_quantisation_is_named_from_one_percent_of_the_step_command_and_its_bits_estimated(
        bits: int, matters: bool) -> None:
    kpot = 1.1  # [V/in]
    q = 20.0 / 2**bits / kpot
    run = _settled_run(q, 0)
    quant = assess([run], Noise(sigma=1e-5, adc_step=q), kpot)
    assert quant is not None and quant.matters is matters
    assert quant.bits == pytest.approx(bits, abs=1e-9)
    assert quant.share == pytest.approx(q / 0.1)
    assert ("settle anywhere" in quant.text()) is matters


def _ramp_run(q: float, error: float, slope: float = 0.5, hold: bool = False) -> GapRun:
    """A ramp run from 0.1 s whose readings (on a lattice of step ``q``) lag the command by ``error`` [in]; with
    ``hold``, the command stops at 0.6 s and the readings rest ``error`` short of it."""
    t = np.arange(0.0, 1.0, 0.001)
    r = slope * np.clip(t - 0.1, 0.0, 0.5 if hold else None)
    y = np.round((r - error * (t > 0.2)) / q) * q
    return GapRun("ramp_p", "ramp", Controller(10), t, r, y, None, 0.1, float(np.ptp(r)), np.zeros(t.size))


@pytest.mark.parametrize(("hold", "matters"), [(False, False), (True, True)])
def test_a_ramp_error_read_off_a_moving_command_does_not_make_an_adc_matter(hold: bool, matters: bool) -> None:
    """A 14-bit board the noise does not dither, 0.6 % of a 0.1 in step command: a ramp's readings sweep the
    lattice (250 counts over the run's end), whose rounding averages out of the error read off there, so its
    4 mil error does not name the ADC (an independent simulator's 14- and 15-bit boards were named from 2 % of a
    ramp's error). The same error read off where the command rests does."""
    q = 20.0 / 2**14 / 2.0  # a 2 V/in pot
    runs = [_settled_run(q, 0), _ramp_run(q, 0.004, hold=hold)]
    quant = assess(runs, Noise(sigma=1e-5, adc_step=q), 2.0)
    assert quant is not None and quant.share < 0.01 and not quant.dithered and not quant.limit_cycle
    assert quant.matters is matters
    assert (quant.readoff_share == pytest.approx(q / 0.004, rel=0.05)) is matters
    assert ("at rest" in quant.text()) is matters


def test_a_limit_cycle_of_a_few_counts_names_quantisation_below_one_percent() -> None:
    q = 20.0 / 2**16  # [in] with Kpot = 1: 0.3 % of the command
    quant = assess([_settled_run(q, 2)], Noise(sigma=1e-5, adc_step=q), 1.0)
    assert quant is not None and quant.share < 0.01
    assert quant.limit_cycle and quant.matters and "limit cycle" in quant.text()


@pytest.mark.parametrize(("kpot", "sigma", "finest"), [
    (1.2, 2.455e-4, 13),  # 13 bits (q 2.03e-3 in) is 1.02 % of the 0.2 in command, 14 bits 0.51 %
    (1.2, 1e-5, 13),      # quiet: the same board (noise no longer moves it; an error at rest is unknown before a run)
    (0.45, 2e-3, 14),     # 14 bits through a 0.45 V/in pot: 2.7e-3 in, 1.36 % of the command
])
def test_the_benchmark_withholds_only_adcs_whose_step_matters(kpot: float, sigma: float, finest: int) -> None:
    """Issue 10, item 3: below the threshold the right answer is the note, so a withheld ADC is drawn from 8 bits
    to the finest board whose step is at least 1 % of that station's step command (the only share of the rule
    known before the runs are simulated; a finer board that would matter through an error at rest or a limit
    cycle is not drawn)."""
    station = load_station("default")
    station = station.model_copy(update={"truth": {**station.truth, "Kpot": f"{kpot} V/in"},
                                         "noise": {**station.noise, "position": f"{sigma} in"}})
    assert finest_board(station) == finest
    command = max(r.amplitude for r in station_runs(station, None) if r.kind == "step")
    for bits, material in ((finest, True), (finest + 1, False)):
        q = 20.0 / 2**bits / kpot
        assert (q >= 0.01 * command) is material
    draws = {effect_params("sensor_quantization", np.random.default_rng(k), finest=finest)["bits"] for k in range(60)}
    assert draws == set(range(8, finest + 1))


def test_no_lattice_no_quantisation() -> None:
    assert assess([_settled_run(1e-3, 0)], Noise(sigma=1e-4, adc_step=None), 1.0) is None


def _none() -> Verdict:
    return Verdict(effect="none", margin=1.0, runner_up=None, confidence=1.0, indistinguishable_from=[],
                   explanation="no candidate effect explains clearly more than the noise")


@pytest.mark.parametrize(("B", "named"), [((1.0, 0.8, 1.2), True), ((0.05, -0.1, 0.2), False), ((0.02, 0.01, 0.03), False)])
def test_friction_test_names_viscous_friction_only_when_its_slope_is_clearly_there(
        B: tuple[float, float, float], named: bool) -> None:
    out = viscous(_none(), Friction(Fc=(0.0, -0.1, 0.1), B=B))
    assert (out.effect == "viscous_friction") is named
    if named:
        assert "B = 1 lbf·s/in" in out.explanation


def test_separating_tests_are_named_for_known_pairs_and_a_generic_one_otherwise() -> None:
    assert "slow ramp in both directions" in (separating_test("coulomb_friction", ["valve_deadband"]) or "")
    assert "faster sample rate" in (separating_test("valve_dynamics", ["sampling_delay"]) or "")
    assert separating_test("valve_saturation", ["coulomb_friction"]) == GENERIC
    assert separating_test("valve_saturation", []) is None


def test_solve_ivp_reference_reads_through_the_adc() -> None:
    p = load_station("default").params().with_(feedback="volts")
    r = np.where(np.arange(400) >= 20, 0.1, 0.0)
    y, _ = simulate_rig_ivp(p, Controller(10), r, EffectSet({"sensor_quantization": {"bits": 10}}))
    lsb = 20.0 / 2**10 / p.Kpot
    assert np.allclose(y / lsb, np.round(y / lsb), atol=1e-9)
    assert np.unique(np.round(y[-100:] / lsb)).size <= 3  # settles within a count or two


def test_readme_example_coulomb_friction_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """README: ``grader simulate --station default --effect coulomb_friction:Fc=4lbf -o data/`` then
    ``grader diagnose data`` (it named valve deadband before the friction test broke the tie)."""
    data, out = tmp_path / "data", tmp_path / "diagnosis"
    assert main(["simulate", "--station", "default", "--effect", "coulomb_friction:Fc=4lbf", "-o", str(data)]) == 0
    assert main(["diagnose", str(data), "-o", str(out)]) == 0
    verdict = json.loads((out / "diagnosis.json").read_text(encoding="utf-8"))["verdict"]
    assert verdict["effect"] == "coulomb_friction"
    assert "Coulomb friction" in capsys.readouterr().out


def test_friction_test_adds_viscous_friction_as_second_effect_with_no_share_of_the_shrink() -> None:
    first = _none().model_copy(update={"effect": "coulomb_friction", "shares": {"coulomb_friction": 1.0}})
    out = viscous(first, Friction(Fc=(2.0, 1.8, 2.2), B=(1.0, 0.8, 1.2)))
    assert (out.effect, out.second_effect) == ("coulomb_friction", "viscous_friction")
    assert out.shares == {"coulomb_friction": 1.0, "viscous_friction": 0.0}


def test_a_benchmark_dataset_without_the_friction_test_has_no_friction_file_and_still_loads(tmp_path: Path) -> None:
    station = load_station("default").model_copy(update={"effects": {}})
    folder = make_case_dataset(station, EffectSet(), tmp_path / "case", 1, friction_test=False)
    manifest = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
    assert "friction" not in manifest and not (folder / "friction.csv").exists()
    assert load(folder).friction is None
    assert {"calibration.csv", "flow.csv", "instability.csv"} <= {p.name for p in folder.iterdir()}


@cache
def _seed_300_plan() -> tuple[Task, ...]:
    return tuple(tasks(BenchConfig(n=25, pairs=60, seed=300, friction_test=False, first_order_spools=True), Path("case")))


def _seed_300_dataset(index: int, tmp_path: Path) -> tuple[str, Path]:
    """Benchmark run A's dataset ``index`` (seed 300, no friction test, from the solve_ivp path), rebuilt in
    ``tmp_path``: its withheld effects and its folder."""
    task = _seed_300_plan()[index]
    task = replace(task, folder=tmp_path / task.folder.name)
    make_case_dataset(task.station, task.truth, task.folder, task.seed, friction_test=False, generator=1)
    return task.label, task.folder


def _seed_300_case(index: int, tmp_path: Path) -> tuple[str, Diagnosis]:
    """Run A's dataset ``index`` rebuilt and diagnosed: its withheld effects and the diagnosis."""
    label, folder = _seed_300_dataset(index, tmp_path)
    return label, analyse(folder).diagnosis


def test_a_second_effect_must_beat_the_verdict_alone_as_the_first_search_scored_it(tmp_path: Path) -> None:
    """Benchmark case 163 of seed 300 (the orifice law alone): a spool lag on top fits the instability run far
    better, but predicts the left-out runs worse than the orifice law alone as the first search scored it
    (held-out score 4.1e-4 against 2.3e-4). Its refit from the pair search's start had scored worse than both
    and let the pair through; the verdict is now the orifice law alone."""
    label, d = _seed_300_case(163, tmp_path)
    assert label == "pressure_flow_nonlinearity"
    assert (d.verdict.effect, d.verdict.second_effect) == ("pressure_flow_nonlinearity", None)
    assert not any("+" in c.effect for c in d.candidates)


def test_a_weak_second_effect_is_named_once_it_fits_clearly_better(tmp_path: Path) -> None:
    """Benchmark case 298 of seed 300 (a 0.36 ms delay on top of a 0.55 mA backlash): the backlash alone leaves
    1.3 times the floor's mean square, and the delay on top removes 0.35 of it while it predicts the left-out
    runs 16 % better. Both must be named (the old bar, 1.5 times the floor before a pair search and 0.5 of it
    removed, named the backlash alone)."""
    label, d = _seed_300_case(298, tmp_path)
    assert set(label.split("+")) == {"sampling_delay", "valve_hysteresis"}
    assert (d.verdict.effect, d.verdict.second_effect) == ("valve_hysteresis", "sampling_delay")


def test_a_lookalike_of_the_verdict_alone_is_dropped_where_the_pair_tells_it_apart(tmp_path: Path) -> None:
    """Benchmark case 277 of seed 300 (a 0.67 mA deadband with a 20 mA current limit): alone, the current limit,
    Coulomb friction and the deadband fit alike, and the current limit is the verdict with the deadband on top. In
    the current limit's place, with the deadband on top, Coulomb friction fits all runs hundreds of times worse, so
    it is no lookalike of the pair's first effect (it was listed, and the dataset scored a miss), and the explanation
    says why; the deadband, named on top, is none either."""
    label, d = _seed_300_case(277, tmp_path)
    assert set(label.split("+")) == {"valve_deadband", "valve_saturation"}
    assert (d.verdict.effect, d.verdict.second_effect) == ("valve_saturation", "valve_deadband")
    assert d.verdict.indistinguishable_from == [] and d.verdict.second_indistinguishable_from == []
    assert ("in valve_saturation's place with valve_deadband on top, coulomb_friction fits the runs clearly worse"
            in d.verdict.explanation)


def test_a_fit_that_falls_off_the_instability_runs_cliff_starts_again_from_a_line_in_kce(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, without_u: Callable[[Path], Path]) -> None:
    """Benchmark case 192 of seed 300 (Coulomb friction of 1.3 lbf): the Coulomb fit matches the runs' first half
    second, but on the whole runs its instability oscillation dies out, more than ten times worse, where the
    objective is flat. Started again from a fine line in ln Kce it finds the valley and Coulomb friction is the
    verdict; without that restart, and without the controller output to replay, it is not (it was a deadband).
    Replayed through the recorded controller output, even that poorer Coulomb fit follows the runs far better than
    the deadband, which then is no verdict."""
    label, folder = _seed_300_dataset(192, tmp_path)
    assert label == "coulomb_friction"
    d = analyse(folder).diagnosis
    assert (d.verdict.effect, d.verdict.second_effect) == ("coulomb_friction", None)
    monkeypatch.setattr(search, "CLIFF", math.inf)
    d = analyse(folder).diagnosis
    assert d.verdict.effect == "coulomb_friction" and d.replay[0].excess["valve_deadband"] > 100 * d.replay[0].evidence
    assert analyse(without_u(folder)).diagnosis.verdict.effect != "coulomb_friction"


def test_a_pair_that_falls_off_the_cliff_is_named_once_started_again(tmp_path: Path) -> None:
    """Benchmark case 300 of seed 300 (a 1.9 mA deadband and a 0.99 ms delay): the delay added on top ends the whole
    runs at 0.059 from 5e-5 on the first half second, the deadband alone at 0.0007; from the line in ln Kce it ends
    at 0.00014 and both effects are named."""
    label, d = _seed_300_case(300, tmp_path)
    assert set(label.split("+")) == {"valve_deadband", "sampling_delay"}
    assert (d.verdict.effect, d.verdict.second_effect) == ("valve_deadband", "sampling_delay")


def test_a_second_effect_that_only_led_the_first_to_a_better_optimum_is_not_named(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Benchmark case 194 of seed 300 (Coulomb friction of 7 lbf alone): the Coulomb fit stops at a poorer optimum
    (fitted at the truth's parameters it costs a fifth as much), and a current limit on top led the pair to a better
    one. Coulomb friction alone, refitted from where that pair ended, predicts the left-out runs as well: no second
    effect, and the verdict's fit is that refit. Without that refit the current limit was named (the replay's check
    of a second effect the bar names now drops it too: replayed, the friction alone fits as well)."""
    from grader.gap import diagnose, pairs

    label, folder = _seed_300_dataset(194, tmp_path)
    assert label == "coulomb_friction"
    d = analyse(folder).diagnosis
    assert (d.verdict.effect, d.verdict.second_effect) == ("coulomb_friction", None)
    # the verdict reports that better optimum: Fc 7.5 lbf (truth 7.0), where the first search had 8.0
    assert abs(_fc(d) - 7.0) < 0.6
    # no refit from the pair's end ever better, and no replay's check: as before them
    monkeypatch.setattr(pairs, "better_alone", lambda alone, bar: False)
    monkeypatch.setattr(diagnose, "replay_drops", lambda *args: None)
    d = analyse(folder).diagnosis
    assert d.verdict.second_effect == "valve_saturation" and _fc(d) > 7.9


def _fc(d: Diagnosis) -> float:
    return next(c for c in d.candidates if c.effect == "coulomb_friction").params["Fc"].value


def _alone(fit: float, heldout: float) -> Scored:
    return Scored("valve_hysteresis", np.full(6, heldout), np.full(6, fit), 1, 0.3)


@pytest.mark.parametrize(("alone", "bar", "replaces"), [
    (_alone(0.01, 0.01), _alone(0.02, 0.02), True),  # a better optimum that predicts better: the bar
    (_alone(0.30, 0.01), _alone(0.02, 0.02), False),  # folds that predict better from a poorer optimum: not
    (_alone(0.01, 0.03), _alone(0.02, 0.02), False),  # a better optimum that predicts worse: not
    (_alone(0.02, 0.02), _alone(0.02, 0.02), False),  # the same: the bar stays
])
def test_the_first_effect_refitted_from_a_pairs_end_replaces_the_bar_only_from_a_better_optimum(
        alone: Scored, bar: Scored, replaces: bool) -> None:
    assert better_alone(alone, bar) is replaces


def test_a_refit_that_ended_in_a_poorer_optimum_does_not_reject_a_true_second_effect(tmp_path: Path) -> None:
    """Benchmark case 289 of seed 300 (a 0.82 mA backlash and a 4.5 ms spool lag): the backlash refitted from where
    its pair with the spool lag ended fitted all runs 50 times worse than the backlash alone, yet its folds predicted
    the left-out runs better, and it had rejected the spool lag. Both are named."""
    label, d = _seed_300_case(289, tmp_path)
    assert set(label.split("+")) == {"valve_dynamics", "valve_hysteresis"}
    assert (d.verdict.effect, d.verdict.second_effect) == ("valve_hysteresis", "valve_dynamics")


@pytest.mark.parametrize(("interval", "text"), [
    ((3.8, 4.6), "Fc = 4.2 ± 0.4 lbf"),
    ((0.0001, 0.00389), "tau = 1.63 ms (95 %: 0.1 to 3.89 ms)"),  # at the fit's floor: not ± 1.9 ms
])
def test_a_parameter_prints_with_plus_minus_only_where_its_interval_is_even(interval: tuple[float, float],
                                                                            text: str) -> None:
    from grader.gap.schema import Value
    from grader.gap.summary import param_text

    name, value, unit = ("Fc", 4.2, "lbf") if text.startswith("Fc") else ("tau", 0.00163, "s")
    assert param_text(name, Value(value=value, unit=unit, interval=interval)) == text
    assert param_text(f"coulomb_friction.{name}", Value(value=value, unit=unit, interval=interval)).startswith(
        f"Coulomb friction {name} = ")


@pytest.mark.parametrize(("bits", "whole"), [(10.0007, 10), (13.9996, 14), (10.3, None), (float("nan"), None),
                                             (0.2, None), (3.0, None), (26.0, None), (24.01, 24)])
def test_an_adc_is_simulated_in_the_loop_only_at_a_whole_number_of_bits(bits: float, whole: int | None) -> None:
    from grader.gap.quantization import loop_bits

    assert loop_bits(bits) == whole
