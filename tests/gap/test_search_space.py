"""What the diagnosis searches: the candidates, a current limit's range from the runs' demand, the flow test's
linear region under an early saturation, and the static tests' say on viscous friction."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.gap.bench import ERROR, BenchConfig, coverage
from grader.gap.bench_report import render
from grader.gap.bench import GENERATOR
from grader.gap.bench_run import _reusable, run_task, tasks, time_cli
from grader.gap.candidates import NOT_FROM_RUNS, WEAK_STRENGTH, make_candidates
from grader.gap.evidence import viscous_unexcluded
from grader.gap.schema import LoopGainInfo, Value, Verdict
from grader.identify.flow import FlowGainFit
from grader.model.effects import EffectSet
from grader.stations import load_station

P = load_station("default").params()


def test_viscous_friction_is_no_run_candidate_unless_asked_for() -> None:
    names = [c.effect for c in make_candidates(P)]
    assert names[0] == "none" and not set(NOT_FROM_RUNS) & set(names)
    assert "viscous_friction" in [c.effect for c in make_candidates(P, ["viscous_friction"])]


@settings(max_examples=30, deadline=None)
@given(demand=st.floats(2.0, 50.0))
def test_a_current_limit_is_searched_below_the_current_the_runs_ask_for(demand: float) -> None:
    sat = next(c for c in make_candidates(P, demand=demand) if c.effect == "valve_saturation")
    fp = sat.params[0]
    limits = sat.params[0].grid() * fp.scale
    assert fp.scale == pytest.approx(min(demand, P.i_max))
    assert np.all(limits < 0.96 * fp.scale) and np.all(limits > 0.0)  # every start cuts some of the demand
    assert sat.strength(np.array([0, 0, 0, 1.0])) == 0.0 and sat.strength(np.array([0, 0, 0, 0.5])) == 0.5


@pytest.mark.parametrize("limit", [6.0, 9.0, 20.0, 42.0])
def test_the_flow_tests_kq_holds_when_the_valve_saturates_early(limit: float) -> None:
    """A rising sweep of ±10 V (±50 mA) against a valve whose flow stops growing at ``limit`` mA."""
    kq, leak, null = 0.04, 0.11, 0.4
    volts = np.arange(-10.0, 10.01, 0.5)
    i = 5.0 * volts - null
    flow = kq * np.clip(i, -limit, limit)
    reading = np.abs(flow) + leak + np.random.default_rng(1).normal(0.0, 0.003, volts.size)
    fit = FlowGainFit(Kamp=5.0).fit(volts, reading)
    assert fit.Kq_.value == pytest.approx(kq, rel=0.02)
    lo, hi = fit.Kq_.interval
    assert lo <= kq <= hi
    assert not np.any(fit.linear_mask_ & (np.abs(i) > limit + 1.0))  # no saturated reading in the fit


def _none_verdict() -> Verdict:
    return Verdict(effect="none", margin=1.0, runner_up="coulomb_friction", confidence=1.0, indistinguishable_from=[],
                   explanation="no candidate effect explains clearly more than the noise")


def _loop_gain(b_hi: float) -> LoopGainInfo:
    kq = Value(value=0.0385, unit="in**3/s/mA", interval=(0.038, 0.039))
    return LoopGainInfo(flow_test_Kq=kq, runs_Kq=kq, deficit=0.001, deficit_z=0.5,
                        viscous_B=Value(value=0.05, unit="lbf*s/in", interval=(0.0, b_hi)), names_viscous=False)


def test_without_a_friction_test_a_none_verdict_says_viscous_friction_is_not_ruled_out() -> None:
    """A detection limit, not a lookalike: listed in not_ruled_out, so that a benchmark counting 'cannot separate'
    as a miss does not count a right 'none' as one."""
    v = viscous_unexcluded(_none_verdict(), None, _loop_gain(0.6))
    assert v.not_ruled_out == ["viscous_friction"] and "friction test" in (v.separating_test or "")
    assert v.indistinguishable_from == []
    assert "up to B = 0.6" in v.explanation
    assert viscous_unexcluded(_none_verdict(), None, None).not_ruled_out == ["viscous_friction"]
    # a loop gain that rules out any visible B, or an effect named: nothing to add
    assert viscous_unexcluded(_none_verdict(), None, _loop_gain(0.01)).not_ruled_out == []
    named = _none_verdict().model_copy(update={"effect": "coulomb_friction"})
    assert viscous_unexcluded(named, None, None) == named


def test_the_benchmark_plan_is_the_seeds_and_a_dataset_is_reused_only_when_it_is_the_same_draw(tmp_path: Path) -> None:
    cfg = BenchConfig(n=2, pairs=3, seed=11, effects=("none", "coulomb_friction"), friction_test=False)
    first, again = tasks(cfg, tmp_path), tasks(cfg, tmp_path)
    assert [t.label for t in first] == ["none", "none", "coulomb_friction", "coulomb_friction", *[t.label for t in first[4:]]]
    assert len(first) == 7 and all("+" in t.label for t in first[4:])
    assert [t.truth.to_quantities() for t in first] == [t.truth.to_quantities() for t in again]
    task = first[2]
    assert not _reusable(task)
    task.folder.mkdir()
    (task.folder / "manifest.json").write_text("{}", encoding="utf-8")
    truth = task.folder.parent / f"{task.folder.name}.truth.json"
    kept = {"effects": task.truth.to_quantities(), "station": task.station.model_dump(mode="json")}
    truth.write_text(json.dumps(kept), encoding="utf-8")
    assert not _reusable(task)  # an earlier generator's dataset (its instability gain chosen on the engine)
    kept["generator"] = GENERATOR
    truth.write_text(json.dumps(kept), encoding="utf-8")
    assert _reusable(task)
    kept["effects"] = {"coulomb_friction": {"Fc": "9 lbf"}}
    truth.write_text(json.dumps(kept), encoding="utf-8")
    assert not _reusable(task)
    # a valve null in the runs: drawn apart, so that the rigs, effects and seeds are the same with and without
    nulled = tasks(replace(cfg, valve_null=0.05), tmp_path)
    assert [(t.station, t.truth.to_quantities(), t.seed) for t in nulled] == \
        [(t.station, t.truth.to_quantities(), t.seed) for t in first]
    assert all(t.null == 0.0 for t in first) and all(0.0 < abs(t.null) <= 0.05 for t in nulled)
    assert len({t.null for t in nulled}) == len(nulled)
    kept["effects"], kept["valve_null"] = task.truth.to_quantities(), f"{nulled[2].null!r} mA"
    truth.write_text(json.dumps(kept), encoding="utf-8")
    assert _reusable(nulled[2]) and not _reusable(task)  # a dataset with a null is not one without


def test_the_benchmark_draws_spools_of_both_orders_apart_from_every_other_draw(tmp_path: Path) -> None:
    """Half the withheld spools are second order, with a damping over the realistic range (0.5 to 1); their form
    comes from a stream of its own, so with ``first_order_spools`` every other draw (rig, magnitudes, seed) is the
    same and every spool first order."""
    cfg = BenchConfig(n=40, seed=5, effects=("valve_dynamics", "coulomb_friction"), friction_test=False)
    drawn, first = tasks(cfg, tmp_path), tasks(replace(cfg, first_order_spools=True), tmp_path)
    spools = [t.truth.values["valve_dynamics"] for t in drawn if t.label == "valve_dynamics"]
    second = [s for s in spools if s["order"] == 2]
    assert 10 <= len(second) <= 30 and all(0.5 <= s["zeta"] <= 1.0 for s in second)
    assert len({s["zeta"] for s in second}) == len(second)
    assert all(t.truth.values["valve_dynamics"]["order"] == 1 for t in first if t.label == "valve_dynamics")
    for a, b in zip(drawn, first):
        assert (a.station, a.seed) == (b.station, b.seed)
        assert {k: dict(v) | {"order": 1.0, "zeta": 0.7} if k == "valve_dynamics" else dict(v)
                for k, v in a.truth.values.items()} == {k: dict(v) for k, v in b.truth.values.items()}


@pytest.mark.parametrize(("order", "zeta", "fitted", "key", "scale"), [
    (1.0, 0.7, {}, "valve_dynamics:tau", (1.0, 1.0)),  # the withheld form: its tau
    (2.0, 0.7, {"order": 2.0, "zeta": 0.7}, "valve_dynamics:tau", (1.0, 1.0)),  # a damping held at the truth's
    (2.0, 0.55, {"order": 2.0, "zeta": 0.7}, "valve_dynamics:lag", (1.1, 1.4)),  # 2·0.55·tau against 1.4·tau
    (2.0, 0.9, {}, "valve_dynamics:lag", (1.8, 1.0)),  # fitted as a first-order lag: its tau is the lag
    (1.0, 0.7, {"order": 2.0, "zeta": 0.8}, "valve_dynamics:lag", (1.0, 1.6)),  # a lag fitted as second order
])
def test_a_spools_coverage_is_of_its_tau_in_the_withheld_form_else_of_its_low_frequency_lag(
        order: float, zeta: float, fitted: dict[str, float], key: str, scale: tuple[float, float]) -> None:
    truth = EffectSet({"valve_dynamics": {"tau": 0.002, "order": order, "zeta": zeta}})
    params = {"tau": Value(value=0.0021, unit="s", interval=(0.0019, 0.0023)),
              **{k: Value(value=v, unit="dimensionless", interval=None) for k, v in fitted.items()}}
    (name, got), = coverage(_named(params), truth).items()
    t, k = scale
    assert name == key and got == pytest.approx((0.002 * t, 0.0021 * k, 0.0019 * k, 0.0023 * k))


def test_a_second_order_spools_fitted_damping_is_covered_beside_its_tau() -> None:
    truth = EffectSet({"valve_dynamics": {"tau": 0.002, "order": 2.0, "zeta": 0.62}})
    params = {"tau": Value(value=0.0021, unit="s", interval=(0.0019, 0.0023)),
              "order": Value(value=2.0, unit="dimensionless", interval=None),
              "zeta": Value(value=0.6, unit="dimensionless", interval=(0.55, 0.65))}
    assert coverage(_named(params), truth) == {"valve_dynamics:tau": (0.002, 0.0021, 0.0019, 0.0023),
                                               "valve_dynamics:zeta": (0.62, 0.6, 0.55, 0.65)}


def _named(params: dict[str, Value]) -> SimpleNamespace:
    """A diagnosis whose verdict is a spool fitted with ``params``."""
    cand = SimpleNamespace(effect="valve_dynamics", params=params)
    return SimpleNamespace(verdict=SimpleNamespace(effect="valve_dynamics", second_effect=None), candidates=[cand],
                           static_evidence={}, loop_gain=None)


def test_a_benchmark_dataset_whose_diagnosis_fails_is_a_counted_miss_not_the_end(tmp_path: Path) -> None:
    cfg = BenchConfig(n=1, pairs=0, seed=3, effects=("coulomb_friction",), friction_test=False)
    task = tasks(cfg, tmp_path)[0]
    task.folder.mkdir()
    (task.folder / "manifest.json").write_text("{}", encoding="utf-8")  # kept, but no dataset
    kept = {"effects": task.truth.to_quantities(), "station": task.station.model_dump(mode="json"),
            "generator": GENERATOR}
    (tmp_path / f"{task.folder.name}.truth.json").write_text(json.dumps(kept), encoding="utf-8")
    case = run_task(task, parallel=False)
    assert case.verdict == ERROR and not case.right
    text = render([case], [], 1)
    assert "diagnoses that failed: 1" in text and "strict top-1 (one effect or none): 0.0 %" in text
    shrink = "median held-out shrink (verdicts naming an effect; the pair's where two are named): – (0 verdicts)"
    assert shrink in text  # an error is no verdict
    assert time_cli([task.folder]) == []  # the CLI's failure is reported, not raised


def _twice(task: int) -> int:
    return 2 * task


def test_a_finished_parallel_benchmark_leaves_no_pool_thread_behind(monkeypatch: pytest.MonkeyPatch) -> None:
    """After the last dataset the worker pool is shut down waiting: its manager thread has ended, so nothing races
    the interpreter's exit for the pool's wake-up pipe (an "OSError: Bad file descriptor" traceback after the
    tables of ``grader bench-gap --jobs 2``). Shut down without waiting, the manager thread is still running here."""
    import threading
    from concurrent.futures import process

    from grader.gap import bench_run

    monkeypatch.setattr(bench_run, "_one_core", _twice)  # forked workers see the module as it is now
    assert list(bench_run._cases(list(range(6)), 2)) == [0, 2, 4, 6, 8, 10]  # type: ignore[arg-type]
    assert not [t for t in threading.enumerate() if isinstance(t, process._ExecutorManagerThread) and t.is_alive()]


class _Refit:
    """A stand-in fitter: a state started from linear coordinates ``theta`` ends at the cost ``cost_of(theta)``."""

    def __init__(self, cost_of) -> None:  # noqa: ANN001
        self.cost_of, self.starts = cost_of, []

    def rebase(self, states):  # noqa: ANN001, ANN201
        return states

    def fit(self, states, rounds):  # noqa: ANN001, ANN201, ARG002
        self.starts += [s.theta.copy() for s in states]
        return [replace(s, res=np.array([np.sqrt(self.cost_of(s.theta))])) for s in states]


def test_none_starts_again_from_an_effect_that_ended_barely_acting_below_it() -> None:
    """An effect fitted at its neutral magnitude, or barely above it, is ``none`` at (or next to) another optimum:
    where it ends below ``none``, ``none`` starts once more from the best such effect's linear coordinates (and keeps
    the better end); an effect that acts, or the orifice law (no magnitude: it always acts), is no such start."""
    from grader.gap.fit import FitState
    from grader.gap.search import _none_from_neutral

    cands = {c.effect: c for c in make_candidates(load_station("default").params())}

    def state(name: str, lin: list[float], mags: list[float], cost: float) -> FitState:
        return FitState(cands[name], (0,), np.array(lin + mags), np.array([np.sqrt(cost)]))

    none = state("none", [0.0, 0.0, 0.0], [], 0.0075)
    coulomb = state("coulomb_friction", [0.03, -0.04, 0.0], [0.0], 0.0029)  # Fc = 0: none elsewhere
    lag = state("valve_dynamics", [0.07, -0.05, 0.0], [0.0222], 0.0027)  # a lag just above its floor: barely acts
    deadband = state("valve_deadband", [0.2, 0.0, 0.0], [0.3], 0.002)  # 30 % of its range: acts
    orifice = state("pressure_flow_nonlinearity", [0.1, 0.1, 0.1], [], 0.001)  # no magnitude: always acts
    assert lag.candidate.strength(lag.theta) < WEAK_STRENGTH <= deadband.candidate.strength(deadband.theta)
    fitter = _Refit(lambda th: 0.0028 if th[0] == 0.03 else 0.01)
    again = _none_from_neutral(fitter, [none, coulomb, deadband, orifice], 0)  # type: ignore[arg-type]
    assert [list(s) for s in fitter.starts] == [[0.03, -0.04, 0.0]]
    assert again.cost == pytest.approx(0.0028) and again.candidate.effect == "none"
    from_lag = _Refit(lambda th: 0.0026 if th[0] == 0.07 else 0.01)
    assert _none_from_neutral(from_lag, [none, coulomb, lag, deadband], 0).cost == pytest.approx(0.0026)  # type: ignore[arg-type]
    assert [list(s) for s in from_lag.starts] == [[0.07, -0.05, 0.0]]  # the best of the weak ones, once
    worse = _Refit(lambda th: 0.009)
    assert _none_from_neutral(worse, [none, coulomb], 0) is none  # type: ignore[arg-type]
    assert _none_from_neutral(_Refit(lambda th: 0.0), [none, deadband, orifice], 0) is none  # type: ignore[arg-type]


def test_beta_over_vt_fits_stay_below_the_ceiling_but_never_below_the_baseline() -> None:
    """A fit the runs cannot pin (no oscillation read) ran β/Vt to 270 times the rig space's top, and its stiffness
    cost 200-800 RK4 substeps per sample; the ceiling (20 times the top) leaves a realistic baseline's span alone."""
    from grader.gap.candidates import LINEAR_CEILING, LINEAR_SPAN

    p = load_station("default").params()
    c = make_candidates(p, ["coulomb_friction"])[1]
    for bv, top in [(60_000.0, LINEAR_SPAN), (1.09e6, np.log(LINEAR_CEILING["beta_over_Vt"] / 1.09e6)), (3e6, 0.0)]:
        lo, hi = c.bounds(p.with_(beta_over_Vt=bv))
        assert hi[0] == pytest.approx(top) and hi[1:3].tolist() == [LINEAR_SPAN] * 2 and lo[0] == -LINEAR_SPAN
    assert c.bounds()[1][0] == LINEAR_SPAN  # without a baseline: the span alone
