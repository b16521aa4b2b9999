"""The valve's null fitted with every candidate where friction hides it (grader.gap.null.free, Candidate.with_null)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from grader.datasets import load
from grader.gap import null as null_mod
from grader.gap.backend import Backend, Point
from grader.gap.bench import with_null
from grader.gap.candidates import N_LINEAR, combine, make_candidates
from grader.gap.diagnose import analyse
from grader.gap.runs import GapRun, prepare_runs
from grader.model.effects import EffectSet
from grader.model.params import Controller
from grader.model.rig_ivp import ivp_run_simulator
from grader.stations import Station
from grader.synth import make_dataset

from .conftest import SIGMA, short_plan

DATA = Path(__file__).parent / "data"


def _resting(name: str, before: float, end: float, seed: int) -> GapRun:
    """A P step run (Kp 10) resting at controller output ``before`` [V] before its command at 0.1 s and at ``end``
    from 0.3 s."""
    t = np.arange(0.0, 0.5, 0.001)
    u = np.where(t < 0.1, before, np.where(t < 0.3, 0.5, end)) + np.random.default_rng(seed).normal(0.0, 1e-3, t.size)
    return GapRun(name, "step", Controller(10.0), t, np.where(t < 0.1, 0.0, 0.2), np.zeros(t.size), u, 0.1, 0.1,
                  np.zeros(t.size))


def test_rests_off_before_their_commands_that_disagree_free_the_null() -> None:
    """Friction holds a rig with a null anywhere in a band around it: off its command before the command changes (the
    null drove it there), by amounts that differ from rest to rest. The null is then fitted, in units of the largest
    current a rest reads (Kamp 5 mA/V, k_fb 1)."""
    held = [_resting("a", -0.01, -0.02, 0), _resting("b", -0.015, -0.005, 1), _resting("c", -0.02, -0.01, 2)]
    assert null_mod.estimate(held, 5.0, 1.0) is None
    assert null_mod.free(held, 5.0, 1.0) == pytest.approx(0.1, abs=0.005)
    assert null_mod.free(held, 5.0, None) is None and null_mod.free(held, 5.0, 0.0) is None
    # a friction rig with no null rests at its commands until they change: nothing to fit, however its ends disagree
    no_null = [_resting("a", 0.0, 0.02, 0), _resting("b", 0.0, 0.005, 1), _resting("c", 0.0, -0.01, 2)]
    assert null_mod.free(no_null, 5.0, 1.0) is None
    # rests that agree are read as the null itself (estimate), and fit nothing more
    agree = [_resting(k, -0.01, -0.01, s) for s, k in enumerate("abc")]
    assert null_mod.estimate(agree, 5.0, 1.0) is not None and null_mod.free(agree, 5.0, 1.0) is None
    # PI loops alone: each integrator holds the null, no run shows it, and the fit could not read it
    assert null_mod.free([replace(r, controller=Controller(10.0, Ki=5.0)) for r in held], 5.0, 1.0) is None


def test_a_fitted_null_s_interval_is_within_its_range_and_spans_it_where_no_run_feels_it(
        station: Station, monkeypatch: pytest.MonkeyPatch) -> None:
    """The null's 95 % interval is t·se wide each way, clipped to the range fitted (±2 × its unit); with a standard
    error of 0 (a null no run feels: a zero Jacobian column, which the pseudo-inverse gives no variance) the whole
    range."""
    from scipy import stats

    from grader.gap import build
    from grader.gap.baseline import Baseline
    from grader.gap.crossval import CrossValidation
    from grader.gap.fit import FitState

    p = station.params()
    cand, theta = make_candidates(p, ["sampling_delay"])[1].with_null(0.2, np.array([0.0, 0.0, 0.0, 0.3]))
    theta[N_LINEAR] = 0.5  # no flow at 0.1 mA
    state = FitState(cand, tuple(range(6)), theta, np.full(6, 0.01), jac=np.eye(6, theta.size))
    cv = CrossValidation(np.full(6, 0.05), np.zeros((6, theta.size)))
    runs = [_resting(f"r{k}", 0.0, 0.0, k) for k in range(6)]
    for se, interval in [(0.1, (0.1 - stats.t.ppf(0.975, 5) * 0.02, 0.1 + stats.t.ppf(0.975, 5) * 0.02)),
                         (5.0, (-0.4, 0.4)), (0.0, (-0.4, 0.4))]:
        monkeypatch.setattr(build, "_theta_se", lambda *a, se=se: np.full(theta.size, se))
        null = build.candidate(state, cv, cv, 0.0, runs, [1] * 6, Baseline(p, "runs", "test")).valve_null
        assert null is not None and null.value == pytest.approx(0.1)
        assert null.interval == pytest.approx(interval, rel=1e-5)


def test_a_candidate_with_its_null_free_at_zero_is_the_same_model(station: Station) -> None:
    p = station.params()
    for c in make_candidates(p, ["coulomb_friction", "valve_dynamics", "valve_saturation"], demand=40.0):
        theta = np.array([0.1, -0.2, 0.05, *(q.hi / q.scale / 2 for q in c.params)])
        nulled, th = c.with_null(0.2, theta)
        assert nulled.lead == N_LINEAR + 1 == c.lead + 1 and th.size == nulled.n_theta == c.n_theta + 1
        assert nulled.point(p, th) == c.point(p, theta) and nulled.values(th) == c.values(theta)
        assert nulled.strength(th) == c.strength(theta)
        lo, hi = nulled.bounds(p)
        assert lo[N_LINEAR] < 0.0 < hi[N_LINEAR] and nulled.steps().size == th.size
        th[N_LINEAR] = -0.5  # the valve passes no flow at −0.1 mA: its output shifted by +0.1/Kamp
        assert nulled.null_current(th) == pytest.approx(-0.1)
        assert nulled.point(p, th).null_u == pytest.approx(0.1 / p.Kamp)
    none, coulomb, spool = make_candidates(p, ["coulomb_friction", "valve_dynamics"])
    pair = combine(coulomb.with_null(0.2, np.zeros(coulomb.n_theta))[0], spool)
    assert pair.null_scale == 0.2 and pair.lead == N_LINEAR + 1 and pair.n_theta == N_LINEAR + 3
    assert pair.values(np.array([0, 0, 0, 0.3, 0.5, 0.5]))["valve_dynamics"]["tau"] == pytest.approx(
        0.5 * spool.params[0].scale)
    with pytest.raises(AssertionError):
        pair.with_null(0.2, np.zeros(pair.n_theta))


@pytest.mark.parametrize("replay", [False, True])
def test_a_fitted_null_moves_the_model_as_the_null_held_in_the_runs_does(station: Station, tmp_path: Path,
                                                                         replay: bool) -> None:
    """Two paths to one model: the null as a point's shift of the controller output, and the null held in the runs'
    inputs (grader.gap.null.held): P, PI and instability runs, closed loop and replayed."""
    quiet = station.model_copy(update={"noise": {**station.noise, "position": "0 in"}, "effects": {}})
    sim = ivp_run_simulator(EffectSet({"sensor_noise": {"sigma": SIGMA}}))
    ds = load(make_dataset(quiet, tmp_path / "ds", seed=3, runs=short_plan(station),
                           run_simulator=with_null(sim, 0.08)))
    runs, p = prepare_runs(ds, ds.given["sample_time"])[1], quiet.params()
    held = null_mod.held(runs, null_mod.Null(0.08, 0.001, ("r",)), p.Kamp, p.k_fb)
    effects = EffectSet({"valve_dynamics": {"tau": 0.002, "order": 1.0, "zeta": 0.7}})
    by_point = Backend(runs, replay=replay).all_runs([Point(p, effects, -0.08 / p.Kamp)])[0]
    by_runs = Backend(held, replay=replay).all_runs([Point(p, effects)])[0]
    plain = Backend(runs, replay=replay).all_runs([Point(p, effects)])[0]
    assert {r.kind for r in runs} >= {"step", "instability"} and any(r.controller.Ki for r in runs)
    for run, a, b, c in zip(runs, by_point, by_runs, plain):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12, err_msg=run.name)
        if run.controller.Ki == 0.0 or replay:
            assert float(np.max(np.abs(a - c))) > 1e-4, run.name  # the null moves every P run, and every replayed one


def test_an_independent_coulomb_rig_a_tenth_of_a_milliamp_off_its_null_keeps_its_friction() -> None:
    """An independent simulator's Coulomb rig (Karnopp, Fc 1.30 lbf, breakaway 1.81 lbf), regenerated with its valve
    passing no flow at −0.1 mA: its rests disagree (friction holds it anywhere within a band around the null), so no
    null is read from them, and with none in the model the P runs' offsets had `none` named. Fitted with every
    candidate, the null is where the simulator put it, and the friction is named."""
    root = DATA / "independent_coulomb_null_large"
    truth = json.loads(root.with_suffix(".truth.json").read_text())
    d = analyse(root).diagnosis
    assert d.verdict.effect == "coulomb_friction" and d.verdict.second_effect is None
    assert d.valve_null is not None and d.valve_null.interval is not None
    lo, hi = d.valve_null.interval
    assert lo < truth["no_flow_current_mA"] < hi < 0.0
    verdict = next(c for c in d.candidates if c.effect == "coulomb_friction")
    assert verdict.valve_null == d.valve_null and all(c.valve_null is not None for c in d.candidates)
    assert any("fits the valve's null with its effect" in n and "not at 0" in n for n in d.notes)
    assert not any("read where the runs rest" in n for n in d.notes)
    fc = verdict.params["Fc"]
    assert fc.interval is not None and fc.interval[0] < truth["effects"]["coulomb_friction"]["Fc_lbf"] < fc.interval[1]


def test_the_null_reported_is_the_fitted_model_s_where_other_evidence_names_more(monkeypatch: pytest.MonkeyPatch
                                                                                ) -> None:
    """Evidence beyond the fits may add to the verdict (an ADC that matters, friction from the friction test): the
    null reported is still the one of the model fitted, which has no entry of the added name."""
    from grader.gap import evidence

    def more(verdict, quant):  # type: ignore[no-untyped-def]
        return verdict.model_copy(update={"second_effect": "sensor_quantization"})

    monkeypatch.setattr(evidence, "quantized", more)
    d = analyse(DATA / "independent_coulomb_null_large").diagnosis
    assert d.verdict.second_effect == "sensor_quantization"
    fitted = next(c for c in d.candidates if c.effect == "coulomb_friction").valve_null
    assert fitted is not None and d.valve_null == fitted
    assert any("the fit with Coulomb friction puts its null at" in n for n in d.notes)
