"""Segments, noise floor, verdict rules and the second-effect search's gate on constructed inputs."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.gap.candidates import combine, make_candidates
from grader.gap.pairs import SECOND_GAIN, SECOND_REL_GAIN, could_pass
from grader.gap.fit import FitState
from grader.gap.noise import adc_step, estimate, reading_noise
from grader.gap.runs import GapRun
from grader.gap.segments import segments_of, shares
from grader.gap.verdict import ACTING, Scored, decide, lookalikes, rank
from grader.model.params import Controller
from grader.stations import load_station

T = 0.001


def _step_run(zeta: float, wn: float = 40.0, sigma: float = 0.0, seed: int = 0) -> GapRun:
    """A second-order step response of 0.2 in starting at 0.1 s."""
    t = np.arange(0.0, 1.5, T)
    tau = np.clip(t - 0.1, 0.0, None)
    if zeta < 1:
        wd = wn * np.sqrt(1 - zeta**2)
        x = 1 - np.exp(-zeta * wn * tau) * (np.cos(wd * tau) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * tau))
    else:
        x = 1 - (1 + wn * tau) * np.exp(-wn * tau)
    y = 0.2 * x + np.random.default_rng(seed).normal(0.0, sigma, t.size)
    r = np.where(t >= 0.1, 0.2, 0.0)
    return GapRun("s", "step", Controller(10), t, r, y, None, 0.1, float(np.std(y)), np.zeros(t.size))


@settings(max_examples=30, deadline=None)
@given(st.floats(0.1, 1.5), st.floats(15.0, 80.0))
def test_step_segments_tile_the_run_in_order(zeta: float, wn: float) -> None:
    run = _step_run(zeta, wn)
    segs = segments_of(run, 0.0004)
    assert [s.name for s in segs] == ["rise", "overshoot", "settling", "steady_state"]
    assert segs[0].i0 == 0 and segs[-1].i1 == run.n
    assert all(a.i1 == b.i0 and a.i0 <= a.i1 for a, b in itertools.pairwise(segs))
    res = np.random.default_rng(1).normal(size=run.n)
    assert sum(shares(res, segs)) == pytest.approx(1.0)


def test_overshoot_segment_exists_only_when_the_response_overshoots() -> None:
    under = {s.name: s for s in segments_of(_step_run(0.3), 0.0004)}
    over = {s.name: s for s in segments_of(_step_run(1.2), 0.0004)}
    assert under["overshoot"].i1 > under["overshoot"].i0
    assert over["overshoot"].i1 == over["overshoot"].i0
    # a lightly damped response reaches 90 % in its first swing: rise ends well before the 2 % band
    assert under["rise"].i1 < under["settling"].i1


@pytest.mark.parametrize("sigma", [0.0002, 0.0005, 0.002])
def test_reading_noise_recovers_the_noise_of_a_moving_signal(sigma: float) -> None:
    run = _step_run(0.5, sigma=sigma, seed=3)
    assert reading_noise(run.y) == pytest.approx(sigma, rel=0.05)


def test_adc_step_finds_the_lattice_and_only_a_lattice() -> None:
    run = _step_run(0.5, sigma=0.0004, seed=4)
    q = 20.0 / 2**12 / 0.85  # 12-bit ADC over ±10 V, Kpot 0.85 V/in
    assert adc_step(np.round(run.y / q) * q) == pytest.approx(q, rel=1e-6)
    assert adc_step(run.y) is None


def _scored(effect: str, heldout: float, fit: float, k: int = 1, strength: float = 0.5) -> Scored:
    return Scored(effect, np.full(6, heldout), np.full(6, fit), k, strength)


NOISE = np.full(6, 0.01)


def test_a_clear_effect_wins_with_a_positive_margin() -> None:
    cands = [_scored("none", 0.2, 0.2, 0, 0.0), _scored("coulomb_friction", 0.012, 0.011), _scored("valve_deadband", 0.05, 0.04)]
    rk = rank(cands, NOISE)
    assert cands[rk.verdict].effect == "coulomb_friction"
    assert rk.margin == pytest.approx(np.log(0.05**2 / 0.012**2), rel=1e-6)
    assert rk.confidence == 1.0 and rk.ties == []


def test_an_effect_that_fits_no_better_than_none_is_not_a_verdict() -> None:
    # better held-out by luck of the folds, but the fit on all runs gains nothing: none
    cands = [_scored("none", 0.012, 0.010, 0, 0.0), _scored("viscous_friction", 0.009, 0.010, strength=0.4)]
    rk = rank(cands, NOISE)
    assert cands[rk.verdict].effect == "none"
    assert rk.margin >= 0
    assert [cands[i].effect for i in rk.ties] == ["viscous_friction"]  # fitted visibly, explains nothing


@pytest.mark.parametrize(("strength", "verdict"), [(0.0, "valve_saturation"), (5e-4, "valve_saturation"),
                                                  (0.02, "coulomb_friction")])
def test_an_effect_fitted_at_no_strength_is_neither_verdict_nor_lookalike(strength: float, verdict: str) -> None:
    """Benchmark seed 300, case 0305 (a 2 ms delay and a current limit): Coulomb friction fitted at Fc = 0, i.e. no
    friction, beat ``none``'s poorer optimum and scored best held out; it was the verdict, tied with everything."""
    cands = [_scored("none", 0.03, 0.044, 0, 0.0), _scored("coulomb_friction", 0.009, 0.042, strength=strength),
             _scored("valve_saturation", 0.012, 0.016), _scored("sampling_delay", 0.0125, 0.038)]
    rk = rank(cands, NOISE)
    assert cands[rk.verdict].effect == verdict
    acting = strength >= ACTING
    assert ("coulomb_friction" in [cands[i].effect for i in rk.ties]) == (acting and verdict != "coulomb_friction")
    pick, _, _ = decide(cands, NOISE)
    assert (1 in lookalikes(cands, NOISE, pick, 0)) == (acting and pick != 1)
    if not acting:  # nor the runner-up, nor a rival in the bootstrap: the saturation beats the delay clearly
        assert cands[rk.runner_up].effect == "sampling_delay" and rk.margin > 0.0
        assert rk.confidence == 1.0
    alone = rank(cands[:2], NOISE)  # with no other effect, the verdict is none, by a margin that is not negative
    assert cands[alone.verdict].effect == ("coulomb_friction" if acting else "none") and alone.margin >= 0.0


def test_near_equal_effects_are_reported_as_indistinguishable() -> None:
    cands = [_scored("none", 0.2, 0.2, 0, 0.0), _scored("sampling_delay", 0.0200, 0.02), _scored("valve_dynamics", 0.0203, 0.02)]
    rk = rank(cands, NOISE)
    assert cands[rk.verdict].effect == "sampling_delay"
    assert [cands[i].effect for i in rk.ties] == ["valve_dynamics"]


@pytest.mark.parametrize(("other", "alike"), [
    (_scored("p+valve_dynamics", 0.0151, 0.0145), True),  # scores within TIE of the pick, fits worse
    (_scored("p+valve_dynamics", 0.0190, 0.0125), True),  # held out worse, fits all runs as well (TIE_FIT)
    (_scored("p+valve_dynamics", 0.0190, 0.0190), False),  # clearly worse on both
    (_scored("p+valve_dynamics", 0.0298, 0.0121), False),  # fits as well, but explains nothing held out (E < 1)
])
def test_a_second_effect_is_reported_with_the_additions_the_data_cannot_tell_apart_from_it(other: Scored,
                                                                                         alike: bool) -> None:
    """On top of the first effect alone (per-run NRMSE 0.03, floor 0.01), a delay is picked; another addition is a
    lookalike only if it also explains clearly more than the first alone and scores or fits as well as the delay."""
    cands = [_scored("p+sampling_delay", 0.015, 0.012), other, _scored("p", 0.03, 0.03)]
    pick, _, _ = decide(cands, NOISE, reference=2, gain=SECOND_GAIN, rel_gain=SECOND_REL_GAIN)
    assert pick == 0
    assert lookalikes(cands, NOISE, pick, 2, gain=SECOND_GAIN, rel_gain=SECOND_REL_GAIN) == ([1] if alike else [])


@pytest.mark.parametrize("bits", [12, 14])
def test_noise_floor_covers_the_quantisation_error(bits: int) -> None:
    q = 20.0 / 2**bits / 0.85
    runs = []
    for seed in range(3):
        run = _step_run(0.5, sigma=0.0004, seed=seed)
        runs.append(GapRun(run.name, "step", run.controller, run.t, run.r, np.round(run.y / q) * q, None, run.start,
                           run.scale, run.noise))
    noise = estimate(runs)
    assert noise.adc_step == pytest.approx(q, rel=1e-6)
    # a perfect model still misses the readings by the RMS quantisation error, dithered or not
    assert noise.floor == pytest.approx(np.sqrt(0.0004**2 + q**2 / 12), rel=0.35)


@pytest.mark.parametrize(("q", "sigma", "kpot", "printed", "matters"), [
    (1e-4, 0.00025, 0.85, True, False),  # printed to 4 decimals of an inch, noise 2.5 steps (a false ADC before)
    (0.001 / 25.4, 0.0001, 0.85, True, False),  # printed to 3 decimals of a millimetre
    (1e-3, 0.0002, 0.85, False, True),  # printed coarser than the noise (0.2 steps): the readings read are quantised
    (20.0 / 2**16 / 0.85, 0.0005, 0.85, False, False),  # a 16-bit ADC through a 0.85 V/in pot: an ADC, but dithered
    (20.0 / 2**16 / 0.7752, 0.0005, 0.7752, False, False),  # a 16-bit ADC's step of 0.01 mm to 0.05 %: whole bits
    (20.0 / 2**14 / 0.85, 0.0002, 0.85, False, True),  # a 14-bit ADC the noise (0.14 steps) does not dither
])
def test_a_decimal_lattice_the_noise_dithers_is_print_precision_not_an_adc(q: float, sigma: float, kpot: float,
                                                                          printed: bool, matters: bool) -> None:
    """A lattice that is a power of ten in a length unit, finer than the reading noise, is the file's print
    precision: a note, never the sensor_quantization verdict. An ADC's step keeps the documented rule (1 % of the
    step command or of an error read off at rest, or a limit cycle), the error read off only where the noise does
    not dither the lattice (averaged over a run's end, dithered readings resolve the error below a step: 14- to 16-bit
    boards were named on an independent simulator's rigs where they mattered to nothing)."""
    from grader.gap.quantization import assess

    runs = []
    for seed in range(3):
        run = _step_run(0.5, sigma=sigma, seed=seed)
        y = np.round((run.y - 0.002 * (run.t > 0.1)) / q) * q  # a steady-state error of 2 mil to read off
        runs.append(GapRun(run.name, "step", run.controller, run.t, run.r, y, None, run.start, run.scale, run.noise))
    quant = assess(runs, estimate(runs), kpot)
    assert quant is not None and quant.printed is printed
    assert quant.readoff_share >= 0.01 and quant.share < 0.01  # the error read off alone would name it
    assert quant.matters is matters and quant.dithered is not matters
    assert ("print precision, not an ADC" in quant.text()) is printed
    assert ("dithers it" in quant.text()) is (not printed and not matters)


_FITS = st.lists(st.floats(0.001, 0.2), min_size=6, max_size=6).map(np.array)


@settings(max_examples=200, deadline=None)
@given(floor=_FITS, combo=_FITS, refit=_FITS, earlier=_FITS)
def test_a_second_effect_left_out_of_cross_validation_could_not_have_been_picked(floor: np.ndarray, combo: np.ndarray,
                                                                                  refit: np.ndarray,
                                                                                  earlier: np.ndarray) -> None:
    """A pair search cross-validates only the additions whose all-runs fit can pass SECOND_GAIN's bar (per-run
    NRMSE ``combo`` against the first alone refitted, ``refit``, or from the first search, ``earlier``). One it
    leaves out is never picked, even where its held-out error would be perfect."""
    cands = {c.effect: c for c in make_candidates(load_station("default").params())}
    first, added = cands["coulomb_friction"], combine(cands["coulomb_friction"], cands["valve_deadband"])
    ends = [FitState(c, (0,), np.zeros(c.n_theta), res=f.copy()) for c, f in ((added, combo), (first, refit))]
    earlier_scored = Scored("coulomb_friction", earlier, earlier, 1, 0.5)
    keep = could_pass(ends, [1] * 6, floor, earlier_scored)
    assert keep[-1]
    perfect = Scored("coulomb_friction+valve_deadband", np.full(6, 1e-9), combo, 2, 0.5)  # an addition that acts
    for reference in (Scored("coulomb_friction", refit, refit, 1, 0.5), earlier_scored):
        pick, _, _ = decide([perfect, reference], floor, reference=1, gain=SECOND_GAIN, rel_gain=SECOND_REL_GAIN)
        assert keep[0] or pick == 1


@pytest.mark.parametrize("fc", [0.0, 0.3])
def test_a_pair_beyond_none_starts_from_an_effect_that_acts(monkeypatch: pytest.MonkeyPatch, fc: float) -> None:
    """With no single effect clearly better than ``none``, the pair search starts from the effect that fits all runs
    best; Coulomb friction fitted at Fc = 0 fits best here but is ``none`` itself, with nothing to add to, so the
    search starts from the deadband instead (a Coulomb level of 0.3 of its range's top acts, and is the start)."""
    import grader.gap.pairs as diag
    from grader.gap.baseline import Baseline
    from grader.gap.crossval import CrossValidation
    from grader.gap.search import SearchResult
    from grader.gap.verdict import Ranking

    base = load_station("default").params()
    cands = {c.effect: c for c in make_candidates(base, ["coulomb_friction", "valve_deadband"])}
    lin = np.zeros(3)
    states = [FitState(cands["none"], tuple(range(6)), lin, np.full(6, 0.05)),
              FitState(cands["coulomb_friction"], tuple(range(6)), np.append(lin, fc), np.full(6, 0.02)),
              FitState(cands["valve_deadband"], tuple(range(6)), np.append(lin, 0.2), np.full(6, 0.03))]
    cv = CrossValidation(np.full(6, 0.05), np.zeros((6, 4)))
    found = SearchResult(states, [cv] * 3, [1] * 6)
    firsts: list[str] = []

    def second(objs, base, first, others, floor, before, executor, first_scored):  # type: ignore[no-untyped-def]
        firsts.append(first.candidate.effect)
        return None, None

    monkeypatch.setattr(diag, "pick_second", second)
    monkeypatch.setattr(diag, "spread", lambda objs, point, sigma: np.zeros(6))
    rk = Ranking([0, 1, 2], np.ones(3), 0, 1, 0.0, 1.0, [])
    diag.beyond_none([], Baseline(base, "test", "constructed"), found, rk, list(cands.values()), np.full(6, 0.01), 1e-4,
                           cv, None)
    assert firsts == ["valve_deadband" if fc == 0.0 else "coulomb_friction"]


@pytest.mark.parametrize(("effect", "name", "floor"), [("coulomb_friction", "Fc", 0.04), ("valve_deadband", "width", 0.02),
                                                        ("sampling_delay", "delay", 0.02)])
def test_an_interval_is_at_least_its_model_form_floor(monkeypatch: pytest.MonkeyPatch, effect: str, name: str,
                                                      floor: float) -> None:
    """With no statistical error at all, an effect parameter's 95 % interval is still t·floor·value wide each way:
    4 % for a Coulomb level (stick-slip between samples, and no rig's friction law is exactly Coulomb's), 2 % for
    the rest."""
    from scipy import stats

    from grader.gap import build
    from grader.gap.baseline import Baseline
    from grader.gap.crossval import CrossValidation

    base = load_station("default").params()
    cand = next(c for c in make_candidates(base, [effect]) if c.effect == effect)
    theta = np.array([0.0, 0.0, 0.0, 0.3])
    monkeypatch.setattr(build, "_theta_se", lambda *a: np.zeros(theta.size))
    runs = [_step_run(0.5)] * 6
    state = FitState(cand, tuple(range(6)), theta, np.full(6, 0.01), jac=np.eye(6, theta.size))
    cv = CrossValidation(np.full(6, 0.05), np.zeros((6, theta.size)))
    entry = build.candidate(state, cv, cv, 0.0, runs, [1] * 6, Baseline(base, "runs", "test"))
    v = entry.params[name]
    half = stats.t.ppf(0.975, 5) * floor * v.value
    assert v.interval == pytest.approx((v.value - half, v.value + half), rel=1e-5)


@pytest.mark.parametrize(("heldout", "fit", "replayed", "kept"), [
    (0.0204, 0.05, None, True),    # scores within TIE of the named pair held out: a lookalike
    (0.03, 0.0205, None, True),    # fits all runs within TIE_FIT of the floor's mean square: a lookalike
    (0.03, 0.021, None, False),    # worse both ways: told apart
    (0.019, 0.019, None, True),    # better in the verdict's place: still a doubt
    (0.019, 0.019, "idle", False),  # fits as well only with the tie at no strength: the addition does it all
    (0.0204, 0.05, (0.0, 7.0, 0.8), False),   # a lookalike in the closed loop, told apart on the replayed runs
    (0.0204, 0.05, (0.0, 5.0, 0.8), True),    # replayed within EVIDENCE of the named pair
    (0.0204, 0.05, (0.0, 700.0, 3.0), True),  # a replay that fits badly decides nothing
    (0.0204, 0.05, (9.0, 0.0, 0.8), True),    # the replay prefers the tie's pair: still a doubt
])
def test_a_tie_of_the_verdict_stays_its_lookalike_beside_a_pair_only_where_it_fits_as_well_in_its_place(
        monkeypatch: pytest.MonkeyPatch, heldout: float, fit: float, replayed: tuple[float, float, float] | str | None,
        kept: bool) -> None:
    """A tie of the verdict alone is put in its place with the same addition on top (searched from the tie's own
    optimum, the addition in the form named: here a second-order spool; and fitted from there with the addition
    where the named pair's ended, the better of the two standing) and kept where it still acts there by the rule of
    a lookalike, then unless the replayed runs, where recorded, decide and tell the pairs apart with the named one
    better; the effect named on top is no doubt of the verdict, and is not fitted again."""
    from grader.gap import pair_ties, replay, spool
    from grader.gap.baseline import Baseline
    from grader.gap.pairs import Second
    from grader.gap.search import SearchResult

    base = load_station("default").params()
    cands = {c.effect: c for c in make_candidates(base, ["valve_saturation", "coulomb_friction", "valve_dynamics"])}
    lin = np.zeros(3)
    states = [FitState(cands[e], tuple(range(6)), np.append(lin, 0.3), np.full(6, 0.02))
              for e in ("valve_saturation", "coulomb_friction", "valve_dynamics")]
    found = SearchResult(states, [], [1] * 6)
    pair = spool.second_order(combine(cands["valve_saturation"], cands["valve_dynamics"]))
    named = Scored(pair.effect, np.full(6, 0.02), np.full(6, 0.02), 3, 0.5)
    extra = Second(FitState(pair, tuple(range(6)), np.append(lin, [0.3, 0.4, 0.7]), np.full(6, 0.02)),
                   None, named, ())  # type: ignore[arg-type]
    combo = spool.second_order(combine(cands["coulomb_friction"], cands["valve_dynamics"]))
    tie_strength = 0.0 if replayed == "idle" else 0.3
    near = FitState(combo, tuple(range(6)), np.append(lin, [tie_strength, 0.4, 0.7]), np.full(6, fit))
    searched_end = FitState(combo, tuple(range(6)), np.append(lin, [0.3, 0.1, 0.7]), np.full(6, 2 * fit))
    searched: list[tuple[str, list[str], dict]] = []
    started: list[np.ndarray] = []

    def second_effect(objs, base, first, others, executor=None):  # type: ignore[no-untyped-def]
        searched.append((first.candidate.effect, [p.name for p in others[0].params], dict(others[0].fixed)))
        return SearchResult([searched_end, first], [], [1] * 6)

    def refit(objs, base, start, executor=None):  # type: ignore[no-untyped-def]
        assert start.candidate.effect == combo.effect
        started.append(start.theta)
        return SearchResult([near], [], [1] * 6)

    def compare(runs, base, fits, indices, sigma, executor=None):  # type: ignore[no-untyped-def]
        assert fits == [extra.state, near] and list(indices) == [0, 1]
        named_x, alt_x, quality = replayed  # type: ignore[misc]
        return replay.Replay((0, 1), (named_x, alt_x), (0, 1), int(alt_x < named_x), quality)

    def scored_of(found: SearchResult) -> list[Scored]:
        assert found.states[0] is near  # the better of the two fits stands
        return [Scored(combo.effect, np.full(6, heldout), np.full(6, fit), 3, 0.5)]

    monkeypatch.setattr(pair_ties, "second_effect", second_effect)
    monkeypatch.setattr(pair_ties, "refit", refit)
    monkeypatch.setattr(pair_ties, "scored_of", scored_of)
    monkeypatch.setattr(pair_ties.replay, "replayable", lambda runs: isinstance(replayed, tuple))
    monkeypatch.setattr(pair_ties.replay, "compare", compare)
    out, info, why = pair_ties.untied([], Baseline(base, "test", "constructed"), found, 0, [1, 2], extra,
                                      np.full(6, 0.01), 1e-4, None)
    assert out == ([1] if kept else [])
    assert searched == [("coulomb_friction", ["tau", "zeta"], {"valve_dynamics": {"order": 2.0}})]
    # the second fit starts from the tie's optimum with the addition where the named pair's ended
    assert len(started) == 1 and np.allclose(started[0], np.append(lin, [0.3, 0.4, 0.7]))
    assert [r.of for r in info] == (["verdict_with_second_effect"] if isinstance(replayed, tuple) else [])
    # why: the pair told apart in the closed loop, or a replay that decides (apart, or not apart either)
    said = not kept if not isinstance(replayed, tuple) else replayed[2] <= replay.GOOD
    assert ("coulomb_friction" in why) == said


@pytest.mark.parametrize(("spool_r", "kept", "line_r", "expect"), [
    (0.12, False, 0.05, "kept"),       # ended worse than the first alone; from its line it could pass the bar
    (0.12, False, 0.0998, "dropped"),  # better from its line, but it cannot pass the bar: left out, a better start
    (0.12, False, 0.13, "as is"),      # no better from its line
    (0.1, False, 0.05, "not tried"),   # nests the first alone and another addition fits best: no line
    (0.085, True, 0.05, "replaced"),   # the best kept addition: refitted in its place
])
def test_a_lag_on_top_that_ended_at_a_poor_optimum_is_fitted_again_from_its_line(
        monkeypatch: pytest.MonkeyPatch, spool_r: float, kept: bool, line_r: float, expect: str) -> None:
    """In a pair search (per-run residuals of the first alone 0.1, a delay on top 0.095 and a current limit 0.09,
    both kept), the lag on top is fitted again from its line of starts where it ended worse than the first alone or
    fits best of the kept additions, and stands where that fits better: kept, in candidate order, where it could
    now pass the bar (:func:`could_pass`), else left out."""
    import grader.gap.pairs as diag
    from grader.gap.baseline import Baseline
    from grader.gap.crossval import CrossValidation
    from grader.gap.search import SearchResult

    base = load_station("default").params()
    c = {x.effect: x for x in make_candidates(base, ["coulomb_friction", "sampling_delay", "valve_saturation",
                                                       "valve_dynamics"])}
    first = c["coulomb_friction"]

    def state(effect: str | None, r: float) -> FitState:
        cand = first if effect is None else combine(first, c[effect])
        return FitState(cand, tuple(range(6)), np.zeros(cand.n_theta), np.full(6, r))

    cv = CrossValidation(np.full(6, 0.1), np.zeros((6, 5)))
    lag = state("valve_dynamics", spool_r)
    states = [state("sampling_delay", 0.095), *([lag] if kept else []), state("valve_saturation", 0.09),
              state(None, 0.1)]
    found = SearchResult(states, [cv] * len(states), [1] * 6, [] if kept else [lag])
    line = state("valve_dynamics", line_r)
    line_cv = CrossValidation(np.full(6, 0.05), np.zeros((6, 5)))
    calls: list[int] = []

    def lag_line(objs, base, delay, on_top, head=None, executor=None):  # type: ignore[no-untyped-def]
        calls.append(1)
        assert delay is states[0] and on_top is lag
        return SearchResult([line], [line_cv], [1] * 6)

    monkeypatch.setattr(diag.spool, "lag_line", lag_line)
    alone = Scored("coulomb_friction", np.full(6, 0.1), np.full(6, 0.1), 1, 0.5)
    order = ["sampling_delay", "valve_dynamics", "valve_saturation"]
    out = diag._lag_from_line([], Baseline(base, "test", "constructed"), state(None, 0.1), found, np.full(6, 0.02),
                              alone, order, None)
    assert calls == ([] if expect == "not tried" else [1])
    names = [s.candidate.names[-1] for s in out.states]
    if expect in ("kept", "replaced"):
        assert names == ["sampling_delay", "valve_dynamics", "valve_saturation", "coulomb_friction"]
        assert out.states[1] is line and out.cvs[1] is line_cv and out.dropped == []
    else:
        assert names == ["sampling_delay", "valve_saturation", "coulomb_friction"]
        assert out.dropped == [line if expect == "dropped" else lag]


@pytest.mark.parametrize("second", ["valve_dynamics", "pressure_flow_nonlinearity", "valve_saturation"])
def test_a_combination_taken_apart_gives_back_its_parts(second: str) -> None:
    """:func:`split_last` undoes :func:`combine`: the head keeps its parameters, held values and the null, the last
    effect its own (a second-order spool's held order; the orifice law has no parameter); a single effect's head is
    ``none``, with the same θ lead."""
    from grader.gap import spool
    from grader.gap.candidates import NONE, split_last

    base = load_station("default").params()
    c = {x.effect: x for x in make_candidates(base, ["valve_hysteresis", second])}
    head = c["valve_hysteresis"].with_null(0.2, np.zeros(c["valve_hysteresis"].n_theta))[0]  # the null fitted
    assert head.null_scale > 0
    last = spool.second_order(c[second]) if second == "valve_dynamics" else c[second]
    assert split_last(combine(head, last)) == (head, last)
    none, alone = split_last(last)
    assert alone == last and none.effect == NONE and none.params == () and none.n_theta == last.lead
