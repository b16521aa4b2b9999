"""Lookalikes told apart on runs replayed through the recorded controller output (grader.gap.replay)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.gap import diagnose, replay
from grader.gap.bench import BenchConfig, make_case_dataset
from grader.gap.bench_run import Task, tasks
from grader.gap.diagnose import analyse
from grader.gap.pairs import NESTED, NESTED_SHARE, SECOND_STRENGTH, names_addition
from grader.gap.hum import MAINS
from grader.gap.replay import EVIDENCE, GOOD, Replay, ReplayObjective
from grader.gap.runs import GapRun
from grader.gap.summary import summary
from grader.gap.verdict import Ranking
from grader.model.params import Controller

NAMES = ["none", "sampling_delay", "valve_dynamics", "valve_hysteresis"]


def _ranking(verdict: int, ties: list[int]) -> Ranking:
    order = [verdict, *(i for i in range(4) if i != verdict)]
    return Ranking(order, np.array([5.0, 1.0, 1.01, 1.02]), verdict, order[1], 0.01, 0.5, ties)


@pytest.mark.parametrize(("excess", "quality", "verdict", "ties", "why"), [
    # the tied spool follows the replayed runs clearly better: it becomes the verdict, the delay its runner-up
    ((EVIDENCE + 1.0, 0.0), 1.0, 2, [], "valve_dynamics follows the runs better than sampling_delay"),
    # within EVIDENCE of each other: nothing moves, and the tie stays
    ((EVIDENCE - 0.1, 0.0), 1.0, 1, [2], "the runs do not tell them apart either"),
    # the verdict fits clearly better: it stays, and the tie goes
    ((0.0, EVIDENCE), 1.0, 1, [], "the runs tell sampling_delay apart from valve_dynamics"),
    # the best replayed fit is poor (a rig the open-loop model cannot follow): the replay decides nothing
    ((50.0, 0.0), GOOD + 0.1, 1, [2], ""),
])
def test_the_replay_moves_a_tie_only_on_clear_evidence_from_a_good_fit(excess: tuple[float, float], quality: float,
                                                                       verdict: int, ties: list[int], why: str) -> None:
    rp = Replay((1, 2), excess, (0, 1), 1 + int(np.argmin(excess)), quality)
    rk, text = replay.ranking(_ranking(1, [2]), NAMES, rp)
    assert (rk.verdict, rk.ties) == (verdict, ties)
    assert rk.order[0] == verdict and sorted(rk.order) == [0, 1, 2, 3]
    assert (why in text) if why else text == ""
    if verdict != 1:
        assert (rk.runner_up, rk.margin) == (1, 0.0)


def test_a_third_lookalike_the_replay_tells_apart_leaves_the_ties() -> None:
    rp = Replay((1, 2, 3), (EVIDENCE + 3.0, 0.0, 1.0), (0, 1, 2), 2, 0.9)
    rk, text = replay.ranking(_ranking(1, [2, 3]), NAMES, rp)
    assert (rk.verdict, rk.ties) == (2, [3])  # the hysteresis fits within EVIDENCE of the spool: still tied
    assert "valve_dynamics follows the runs better than sampling_delay" in text and "named instead" in text


@pytest.mark.parametrize(("excess", "ties"), [((0.0, EVIDENCE - 1.0), [3]), ((0.0, EVIDENCE + 1.0), [])])
def test_a_replayed_candidate_the_replay_cannot_tell_from_the_verdict_becomes_its_lookalike(
        excess: tuple[float, float], ties: list[int]) -> None:
    """The closed loop told the verdict (1) from the hysteresis (3), replayed because it explains clearly more; the
    replay, the better judge of lookalikes, lists it beside the verdict unless it tells them apart."""
    rp = Replay((1, 3), excess, (0, 1), 1, 1.0)
    rk, text = replay.ranking(_ranking(1, []), NAMES, rp)
    assert (rk.verdict, rk.ties) == (1, ties)
    assert ("the runs do not tell sampling_delay apart from valve_hysteresis" in text) is bool(ties)


def test_a_spool_too_fast_for_a_small_rigs_valve_is_neither_the_replays_lookalike_nor_its_pick() -> None:
    """Candidate 2 (the spool) is ``never``: within EVIDENCE of the delay it is not listed, and fitting the replayed
    runs 7 better it does not take the verdict; the hysteresis (3), replayed too and within EVIDENCE, is listed."""
    for excess in ((3.0, 0.0, 2.0), (7.0, 0.0, 5.0)):
        rp = Replay((1, 2, 3), excess, (0, 1, 2), 2, 1.0)
        rk, text = replay.ranking(_ranking(1, []), NAMES, rp, never=[2])
        assert (rk.verdict, rk.ties) == (1, [3]) and "valve_dynamics" not in text


def test_the_replays_text_names_every_lookalike_it_keeps() -> None:
    """A closed-loop tie it cannot break (2) and a replayed candidate it adds (3) are both named."""
    rp = Replay((1, 2, 3), (0.0, 1.0, 2.0), (0, 1, 2), 1, 1.0)
    rk, text = replay.ranking(_ranking(1, [2]), NAMES, rp)
    assert rk.ties == [2, 3]
    assert "the runs do not tell sampling_delay apart from valve_dynamics, valve_hysteresis" in text


@pytest.mark.parametrize(("lag", "second_order", "form"), [
    (1000.0, 1000.0 - EVIDENCE + 1.0, 1),  # within EVIDENCE of the default: the first-order lag stands
    (1000.0, 1000.0 - EVIDENCE - 1.0, 2),  # clearly better: the second-order form stands
])
def test_a_spool_stands_by_its_default_form_unless_another_fits_clearly_better(lag: float, second_order: float,
                                                                              form: int) -> None:
    """Sums of squares of a delay (1030) and of a spool in its two forms, over 1000 samples: the second-order form,
    a delay's lookalike, replaces the default lag only where it fits EVIDENCE better; the excesses are then taken
    from the forms that stand, the best at 0."""
    rp = replay.scored([1030.0, lag, second_order], [1, 4, 4], 1000)
    assert rp.indices == (1, 4) and rp.form == (0, form) and rp.best == 4
    low = [lag, second_order][form - 1]
    assert rp.excess[1] == 0.0 and rp.excess[0] == pytest.approx((1030.0 - low) / (low / 1000.0))
    assert rp.quality == pytest.approx(low / 1000.0)


def _run(y: np.ndarray) -> GapRun:
    t = 0.002 * np.arange(y.size)
    return GapRun("r", "step", Controller(1.0), t, np.zeros_like(y), y, np.zeros_like(y), 0.0, 1.0, np.zeros_like(y))


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-5, 5), st.floats(-50, 50), st.floats(1e-4, 1e-2), st.floats(-1e-3, 1e-3),
       st.sampled_from(MAINS), st.floats(0.0, 2 * np.pi))
def test_a_replayed_run_is_compared_without_its_start_drift_and_mains_hum_in_units_of_the_noise(
        seed: int, shift: float, slope: float, sigma: float, hum: float, f: float, phase: float) -> None:
    """A model shifted by a constant (where the rig started), a constant velocity (a valve null offset the model
    lacks, integrated open loop) and mains pickup at the lines the rests show (in the readings only) fits as well;
    what is left is what an independent least-squares fit of those leaves."""
    y = np.random.default_rng(seed).normal(0.0, 1e-3, 400)
    run = _run(y)
    obj = ReplayObjective(run, sigma, MAINS)
    x = np.linspace(0.0, 1.0, y.size) ** 3
    a = obj.residual(x)
    b = obj.residual(x + shift + slope * run.t + hum * np.sin(2 * np.pi * f * run.t + phase))
    assert np.allclose(a, b, atol=1e-8 / sigma)
    cols = [np.ones_like(run.t), run.t]
    for g in MAINS:
        cols += [np.sin(2 * np.pi * g * run.t), np.cos(2 * np.pi * g * run.t)]
    design = np.column_stack(cols)
    d = x - y
    fit = design @ np.linalg.lstsq(design, d, rcond=None)[0]  # an independent least-squares fit
    assert np.allclose(a * sigma, d - fit, atol=1e-9)


@pytest.mark.parametrize(("f", "lines", "kept"), [(37.0, MAINS, True), (60.0, (50.0,), True), (60.0, (), True),
                                                 (60.0, (60.0,), False)])
def test_only_the_mains_lines_found_are_cleared_from_the_replayed_residual(f: float, lines: tuple[float, ...],
                                                                         kept: bool) -> None:
    """A difference between model and readings at ``f`` is left unless ``f`` is a mains line the rests showed: a
    37 Hz one (a model error) always, a 60 Hz one where no 60 Hz pickup was found."""
    run = _run(np.zeros(500))
    wave = 1e-3 * np.sin(2 * np.pi * f * run.t + 0.3)
    left = ReplayObjective(run, 1e-3, lines).residual(wave) * 1e-3
    assert (float(np.sum(left * left)) > 0.9 * float(np.sum(wave * wave))) is kept


@pytest.mark.parametrize(("ss", "k", "n", "strength", "named"), [
    ([1000.0, 1200.0, 1050.0], 0, 1000, 0.2, True),  # the first alone (last) fits 50 worse, 5 % of the mean square
    ([1000.0, 1003.0, 1100.0], 1, 1000, 0.2, True),  # a pick tied with the best (by the closed loop): 97 worse
    ([1000.0, 1200.0, 1020.0], 0, 1000, 0.2, False),  # 20 worse: below NESTED
    ([1000.0, 1040.0, 1060.0], 1, 1000, 0.2, False),  # 60 worse than the best, but 20 worse than the pick
    ([10000.0, 12000.0, 10400.0], 0, 10000, 0.2, False),  # 400 worse on 10,000 samples: 4 %, below NESTED_SHARE
    ([1000.0, 1200.0, 1050.0], 0, 1000, SECOND_STRENGTH / 2, False),  # the addition barely acts
    ([1100.0, 1200.0, 1000.0], 0, 1000, 0.2, False),  # the first alone is the best
    ([1600.0, 1700.0, 2000.0], 0, 1000, 0.2, False),  # the best leaves 1.6 times the noise: the replay decides nothing
])
def test_a_second_effect_the_bar_misses_is_named_only_where_the_replay_needs_it_clearly(
        ss: list[float], k: int, n: int, strength: float, named: bool) -> None:
    """Costs in units of the reading noise's variance: addition ``k`` is named where the first alone fits NESTED
    and NESTED_SHARE worse on the replayed runs, the fit is good and the addition acts."""
    rp = replay.scored(ss, range(len(ss)), n)
    assert names_addition(rp, k, n, strength) is named
    assert (NESTED, NESTED_SHARE) == (30.0, 0.05)


@pytest.mark.parametrize(("us", "ok"), [
    ([np.zeros(5), np.ones(5)], True),
    ([np.zeros(5), None], False),  # one run without a u column: nothing is replayed
    ([np.zeros(5), np.array([0.0, 1.0, np.nan, 1.0, 0.0])], False),  # a gap in the recorded output
    ([np.array([0.0, np.inf, 0.0, 0.0, 0.0])], False),
])
def test_runs_are_replayed_only_when_every_one_recorded_a_finite_controller_output(us: list, ok: bool) -> None:
    runs = [replace(_run(np.zeros(5)), u=u) for u in us]
    assert replay.replayable(runs) is ok


@cache
def _seed_300_plan() -> tuple[Task, ...]:
    return tuple(tasks(BenchConfig(n=25, pairs=60, seed=300, friction_test=False, first_order_spools=True), Path("case")))


def _seed_300(index: int, tmp_path: Path) -> tuple[str, Path]:
    task = _seed_300_plan()[index]
    folder = tmp_path / task.folder.name
    make_case_dataset(task.station, task.truth, folder, task.seed, friction_test=False, generator=1)
    return task.label, folder


def test_a_spool_lag_the_closed_loop_takes_for_a_delay_is_named_from_the_replayed_runs(
        tmp_path: Path, without_u: Callable[[Path], Path]) -> None:
    """Benchmark run A's 0104 (a first-order spool lag of 1.27 ms, sampled every 3.8 ms): a delay and the spool fit
    the closed-loop runs alike, and the delay was the verdict. Replayed, the lag (tau 1.20 ms) follows the runs 16.5
    better in 2·ln likelihood. Without the u column nothing can be replayed, and the tie stands as before."""
    label, folder = _seed_300(104, tmp_path)
    assert label == "valve_dynamics"
    d = analyse(folder).diagnosis
    assert d.verdict.effect == "valve_dynamics" and d.verdict.indistinguishable_from == []
    assert d.verdict.runner_up == "sampling_delay" and "follows the runs better than sampling_delay" in d.verdict.explanation
    (rp,) = d.replay
    assert rp.of == "verdict" and rp.decides and rp.excess["valve_dynamics"] == 0.0
    assert rp.excess["sampling_delay"] > 2 * EVIDENCE
    tau = d.candidates[0].params["tau"]
    assert "order" not in d.candidates[0].params and tau.interval[0] <= 0.00126555879347 <= tau.interval[1]
    d = analyse(without_u(folder)).diagnosis
    assert (d.verdict.effect, d.verdict.indistinguishable_from, d.replay) == ("sampling_delay", ["valve_dynamics"], [])


def test_coulomb_friction_the_closed_loop_takes_for_a_deadband_is_named_from_the_replayed_runs(tmp_path: Path) -> None:
    """Run A's 0185 (Coulomb friction of 0.35 lbf, no friction test): tied with a deadband in the closed loop, which
    was the verdict; open loop the two act differently (a deadband passes no flow, friction holds the mass until
    the pressure breaks it away), and friction follows the replayed runs 48 better in 2·ln likelihood."""
    label, folder = _seed_300(185, tmp_path)
    assert label == "coulomb_friction"
    d = analyse(folder).diagnosis
    assert d.verdict.effect == "coulomb_friction" and "valve_deadband" not in d.verdict.indistinguishable_from
    (rp,) = d.replay
    assert rp.excess["coulomb_friction"] == 0.0 and rp.excess["valve_deadband"] > 5 * EVIDENCE


def test_a_second_effect_is_chosen_on_the_replayed_runs(tmp_path: Path) -> None:
    """Run A's 0251: Coulomb friction (5.1 lbf) with a 3.4 ms spool lag. On top of the friction, the closed loop
    preferred a delay to the spool lag while the lag sat at a poorer optimum; fitted again from its line of starts
    (β/Vt and Kce matched to the loop's oscillation), the lag is the closed loop's pick too, and the replayed runs,
    which choose between the additions, follow it 940 better in 2·ln likelihood than the delay. Both are named, the
    lag in its own form with the friction's interval covering the truth."""
    label, folder = _seed_300(251, tmp_path)
    assert label == "coulomb_friction+valve_dynamics"
    d = analyse(folder).diagnosis
    assert (d.verdict.effect, d.verdict.second_effect) == ("coulomb_friction", "valve_dynamics")
    assert "adding valve_dynamics on top explains clearly more" in d.verdict.explanation  # the closed loop's pick
    second = next(r for r in d.replay if r.of == "second_effect")
    assert second.decides and second.excess["valve_dynamics"] == 0.0
    assert second.excess["sampling_delay"] > 50 * EVIDENCE
    pair = d.candidates[-1].params
    assert "valve_dynamics.order" not in pair
    assert pair["coulomb_friction.Fc"].interval[0] <= 5.08563581578 <= pair["coulomb_friction.Fc"].interval[1]


def test_a_second_effect_the_closed_loop_passed_over_at_a_poorer_optimum_is_named(tmp_path: Path) -> None:
    """Run A's 0259: a 2.8 ms spool lag with 1.1 lbf of Coulomb friction (2,407 samples). With the lag fitted by the
    search alone, the closed loop's bar passed no second effect (the friction's 95 % interval reached zero there)
    and the replay named it, 419 better in 2·ln likelihood; with the lag fitted again from its line of starts, the
    closed loop names the friction itself, and the pair's intervals cover both truths."""
    label, folder = _seed_300(259, tmp_path)
    assert label == "valve_dynamics+coulomb_friction"
    d = analyse(folder).diagnosis
    assert (d.verdict.effect, d.verdict.second_effect) == ("valve_dynamics", "coulomb_friction")
    assert "adding coulomb_friction on top explains clearly more" in d.verdict.explanation
    assert 0.5 < d.verdict.shares["valve_dynamics"] < 1.0 and sum(d.verdict.shares.values()) == pytest.approx(1.0)
    pair = d.candidates[-1]
    assert pair.effect == "valve_dynamics+coulomb_friction"
    for name, truth in (("valve_dynamics.tau", 0.00281582950485), ("coulomb_friction.Fc", 1.11668322962)):
        assert pair.params[name].interval[0] <= truth <= pair.params[name].interval[1]


def test_a_second_effect_the_pair_search_fitted_at_no_effect_is_named_from_its_replayed_optimum(tmp_path: Path) -> None:
    """Run A's 0265: a 2.4 mA deadband with 4.4 lbf of Coulomb friction. The pair search fitted the friction at 0
    and did not cross-validate it; replayed, it fits at 3.0 lbf and the deadband alone fits 30,879 worse. The
    pair's report entry is the closed-loop fit from that optimum (Fc about 3.1 lbf), not the search's at 0."""
    label, folder = _seed_300(265, tmp_path)
    assert label == "valve_deadband+coulomb_friction"
    d = analyse(folder).diagnosis
    assert (d.verdict.effect, d.verdict.second_effect) == ("valve_deadband", "coulomb_friction")
    nested = next(r for r in d.replay if r.of == "second_effect")
    assert nested.excess["none"] - nested.excess["coulomb_friction"] > 100 * NESTED
    fc = d.candidates[-1].params["coulomb_friction.Fc"]
    assert fc.value > 2.0 and fc.interval[0] > 1.0
    assert "the runs follow coulomb_friction on top better than valve_deadband alone" in d.verdict.explanation
    assert "Coulomb friction under 1 %" in summary(d)


def test_a_second_effect_the_replayed_runs_do_not_bear_out_is_not_named(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Run A's 0098: a 1.5 mA hysteresis alone. The closed loop's bar names a delay on top; replayed through the
    recorded controller output, the hysteresis alone fits 14 better in 2·ln likelihood than with the delay, so the
    delay is not named; the explanation and the summary say why, and ``replay[]`` holds the comparison. Without
    that check it is named."""
    label, folder = _seed_300(98, tmp_path)
    assert label == "valve_hysteresis"
    d = analyse(folder).diagnosis
    assert (d.verdict.effect, d.verdict.second_effect) == ("valve_hysteresis", None)
    assert [r.of for r in d.replay if r.of != "verdict"] == ["dropped_second_effect"]
    dropped = d.replay[-1]
    assert dropped.decides and dropped.excess["none"] == 0.0 and dropped.excess["sampling_delay"] > EVIDENCE
    assert ("sampling_delay on top fits the closed-loop runs clearly better, but replayed through the controller "
            "output the rig recorded the runs follow valve_hysteresis alone better (by 13.8 in 2·ln likelihood)"
            in d.verdict.explanation)
    assert ("Sampling delay on top fits the closed-loop runs clearly better, but not the runs replayed through the "
            "controller output the rig recorded, so it is not named." in summary(d))
    monkeypatch.setattr(diagnose, "replay_drops", lambda *args: None)
    assert analyse(folder).diagnosis.verdict.second_effect == "sampling_delay"
