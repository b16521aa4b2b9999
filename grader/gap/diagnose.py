"""The sim-to-real diagnosis of one lab dataset: where the gap lies, which effect causes it,
and how far it shrinks once that effect is added.

:func:`analyse` does the work and keeps the simulations for the report;
:func:`diagnose_dataset` is the entry point (``grader diagnose``, ``grader demo``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from grader import __version__
from grader.datasets import Dataset, load
from grader.gap import baseline as baseline_mod
from grader.gap import build, evidence
from grader.gap import noise as noise_mod
from grader.gap import quantization as quant_mod
from grader.gap import spool
from grader.gap.backend import Backend, Point, worker
from grader.gap.candidates import LEAST_LIMIT, NONE, NOT_FROM_RUNS, Candidate, make_candidates, saturation_can_act
from grader.gap.crossval import CrossValidation
from grader.gap.fit import FitState
from grader.gap.lm import sumsq
from grader.gap.objective import RunObjective, objective
from grader.gap.runs import GapRun, check_gains, current_demand, cut_note, prepare_runs, start_offset_note
from grader.gap.schema import Candidate as SchemaCandidate
from grader.gap.schema import Diagnosis, Verdict
from grader.gap.search import SearchResult, refit, search, second_effect
from grader.gap.segments import Segment, segments_of
from grader.gap.spread import spread
from grader.gap.separating import separating_test
from grader.model.effects import EFFECTS
from grader.gap.verdict import Ranking, Scored, decide, fit_gain, lookalikes, rank, scores

Array = NDArray[np.float64]
#: A verdict whose fit leaves more than this many times the floor's mean square (the reading noise's and what the
#: noise makes the verdict's model do, :mod:`grader.gap.spread`) searches a second effect (``second=None``).
RESIDUAL_RATIO = 1.0
#: A second effect must lower the held-out score by SECOND_REL_GAIN and the all-runs fit's mean square by
#: SECOND_GAIN times that floor, and act at SECOND_STRENGTH of its realistic range's top or more (a deadband of
#: 0.03 mA that only lets the fit follow the noise's walk through a backlash names nothing). With every verdict
#: searched for a pair on benchmark seed 300 (250 datasets with one effect or none, 60 with two), this bar and
#: RESIDUAL_RATIO named 3 more pairs than 0.5 and 1.5 and no second effect on a single-effect dataset.
SECOND_REL_GAIN, SECOND_GAIN, SECOND_STRENGTH = 0.10, 0.25, 0.06
#: A ``none`` verdict whose linear model leaves this many times the noise's mean square searches a pair.
NONE_GAP = 4.0


@dataclass(frozen=True)
class _Second:
    """A second effect on top of the verdict: its fit, report entry and scores, and the additions the data cannot
    tell apart from it (each effect's name and the scores of its pair)."""

    state: FitState
    candidate: SchemaCandidate
    scored: Scored
    lookalikes: tuple[tuple[str, Scored], ...]

    @property
    def alike(self) -> list[str]:
        """The lookalikes' names."""
        return [name for name, _ in self.lookalikes]


@dataclass(frozen=True)
class Analysis:
    """The diagnosis plus what the report draws: runs, segments, linear and augmented simulations."""

    diagnosis: Diagnosis
    runs: list[GapRun]
    segments: list[list[Segment]]
    y_linear: list[Array]
    y_augmented: list[Array]


def _reference_kfb(ds: Dataset) -> float | None:
    """k_fb known without the runs: 1 for inches, Kpot from the calibration for volts."""
    if ds.manifest.feedback == "inches":
        return 1.0
    if ds.calibration is None:
        return None
    from grader.identify import PotCalibration

    return PotCalibration().fit(ds.calibration["position"], ds.calibration["voltage"]).Kpot_.value


def _model_y(state: FitState, runs: Sequence[GapRun], base: baseline_mod.Baseline) -> list[Array]:
    """The fitted model's simulation of every whole run."""
    return Backend(runs).all_runs([state.candidate.point(base.params, state.theta)])[0]


def _fit_nrmse(state: FitState, lengths: Sequence[int]) -> Array:
    """Per-run NRMSE of an all-runs fit (the norm of each run's part of its residual)."""
    ends = np.cumsum(lengths)
    return np.array([math.sqrt(sumsq(state.res[e - n:e])) for n, e in zip(lengths, ends)])


def _scored(found: SearchResult) -> list[Scored]:
    return [Scored(s.candidate.effect, cv.heldout, _fit_nrmse(s, found.lengths),
                   0 if s.candidate.effect == NONE else max(1, len(s.candidate.params)), s.candidate.strength(s.theta))
            for s, cv in zip(found.states, found.cvs)]


def _significant(cand: SchemaCandidate, effect: str) -> bool:
    """Whether ``effect``'s fitted parameter in ``cand`` is clearly away from "no effect" (95 % interval)."""
    spec = EFFECTS[effect]
    for p in spec.params[:1]:
        v = cand.params.get(f"{effect}.{p.name}") or cand.params.get(p.name)
        if v is None or v.interval is None:
            return False
        return v.interval[1] < p.hi if p.name == "i_max" else v.interval[0] > 0
    return True


def _second(objs: Sequence[RunObjective], base: baseline_mod.Baseline, first: FitState, others: Sequence[Candidate],
            floor_nrmse: Array, before: CrossValidation, executor: Executor | None,
            first_scored: Scored) -> tuple[_Second | None, tuple[SearchResult, Scored] | None]:
    """(the best second effect on top of ``first``, ``first`` refitted to a better optimum with its scores, or None
    for each).

    The second effect: the best addition if it explains clearly more than ``first`` alone (beyond the
    floor ``first`` leaves, by :data:`SECOND_GAIN`), else None; an addition whose parameter's 95 % interval
    reaches "no effect" is no second effect (it only moved the first effect's optimum). ``first`` alone is
    refitted from the pair search's start; where its score from the first search, ``first_scored``, is better,
    that is the one to beat (a refit whose folds fell into worse optima let a pair through that predicted the
    left-out runs worse than the verdict alone). The pick must also beat ``first`` alone refitted from where the
    pick ended, where that refit reached a better optimum (:func:`_better_alone`): an addition that only led the
    first effect out of a poorer optimum is no second effect. That refit is returned where it is also better than
    ``first_scored``: the verdict's own fit is then that one."""
    found = second_effect(objs, base.params, first, others, executor=executor,
                          keep=lambda ends, lengths: _could_pass(ends, lengths, floor_nrmse, first_scored))
    scored = _scored(found)
    if scores([first_scored])[0] < scores([scored[-1]])[0]:
        scored[-1] = first_scored
    sc = scores(scored)
    runs = [o.run for o in objs]
    built = [build.candidate(st, cv, before, float(s), runs, found.lengths, base)
             for st, cv, s in zip(found.states, found.cvs, sc)]
    eligible = [i for i, st in enumerate(found.states[:-1]) if _significant(built[i], st.candidate.names[-1])
                and st.candidate.strength(st.theta) >= SECOND_STRENGTH]
    eligible.append(len(scored) - 1)
    options = [scored[i] for i in eligible]
    ref = len(eligible) - 1
    pick, _, _ = decide(options, floor_nrmse, reference=ref, gain=SECOND_GAIN, rel_gain=SECOND_REL_GAIN)
    if pick == ref:
        return None, None
    refitted = _alone_from(objs, base, first, found.states[eligible[pick]], executor)
    alone = _scored(refitted)[0]
    better = (refitted, alone) if _better_alone(alone, first_scored) else None
    if _better_alone(alone, options[ref]):
        options[ref] = alone
        pick, _, _ = decide(options, floor_nrmse, reference=ref, gain=SECOND_GAIN, rel_gain=SECOND_REL_GAIN)
        if pick == ref:
            return None, better
    alike = lookalikes(options, floor_nrmse, pick, ref, gain=SECOND_GAIN, rel_gain=SECOND_REL_GAIN)
    k = eligible[pick]
    return _Second(found.states[k], built[k], scored[k],
                   tuple((found.states[eligible[i]].candidate.names[-1], options[i]) for i in alike)), better


def _better_alone(alone: Scored, bar: Scored) -> bool:
    """Whether the first effect refitted from a pair's end, ``alone``, replaces ``bar`` as what the pair must beat:
    its effect acts (:data:`grader.gap.verdict.ACTING`), its all-runs fit reached a better optimum (a lower mean
    square) and it scores better held out. A refit that ended in a poorer optimum (run A's 0289: a hysteresis
    refitted from its pair with a spool lag fitted all runs 50 times worse) only has folds that happened to predict
    the left-out runs better."""
    return bool(alone.acts and alone.fit_ms < bar.fit_ms and scores([alone])[0] < scores([bar])[0])


def _alone_from(objs: Sequence[RunObjective], base: baseline_mod.Baseline, first: FitState, pair: FitState,
                executor: Executor | None) -> SearchResult:
    """``first`` alone refitted from where ``pair`` ended (first's own coordinates of the pair's θ)."""
    return refit(objs, base.params, replace(first, theta=np.array(pair.theta[:first.theta.size])), executor=executor)


def _could_pass(ends: Sequence[FitState], lengths: Sequence[int], floor_nrmse: Array,
                first_scored: Scored) -> list[bool]:
    """Which fits of a second-effect search can still pass :data:`SECOND_GAIN`'s bar on the all-runs fit, which
    needs no cross-validation: the first alone (last) always; an addition only where it lowers the mean square of
    one of the first's two fits (this search's and ``first_scored``'s, whichever :func:`_second` ends up
    comparing with) by more than SECOND_GAIN times the floor's. The others could not be picked; their
    cross-validation, about a third of the search, is skipped."""
    w = np.ones(floor_nrmse.size)
    refs = (_fit_nrmse(ends[-1], lengths), first_scored.fit)
    return [k == len(ends) - 1 or any(fit_gain(r, _fit_nrmse(s, lengths), floor_nrmse, w, SECOND_GAIN) > 1.0
                                      for r in refs)
            for k, s in enumerate(ends)]


def _pair_beyond_none(objs: Sequence[RunObjective], base: baseline_mod.Baseline, found: SearchResult, rk: Ranking,
                      candidates: Sequence[Candidate], noise_nrmse: Array, sigma: float, before: CrossValidation,
                      executor: Executor | None) -> tuple[Ranking, _Second | None]:
    """No single effect explains the gap, yet the linear model leaves NONE_GAP times the noise's mean square
    (two effects that each alone fit no better, as a deadband beside a backlash): the effect that fits best
    with each other effect on top. A pair that explains clearly more than its first effect and than ``none``
    makes that effect the verdict (margin 0, confidence 0: the runs do not name it alone)."""
    names = [s.candidate.effect for s in found.states]
    scored = _scored(found)
    effects = [i for i, n in enumerate(names) if n != NONE and scored[i].acts]  # one that does not act is none
    if not effects:
        return rk, None
    k = min(effects, key=lambda i: found.states[i].cost)
    first = found.states[k]
    floor = np.sqrt(noise_nrmse**2 + spread(objs, first.candidate.point(base.params, first.theta), sigma))
    others = [c for c in candidates if c.effect not in (NONE, names[k], *NOT_FROM_RUNS)]
    extra, _ = _second(objs, base, first, others, floor, before, executor, scored[k])
    if extra is None:
        return rk, None
    none = scored[names.index(NONE)]
    if decide([none, extra.scored], noise_nrmse)[0] != 1:
        return rk, None
    order = [k, *(i for i in rk.order if i != k)]
    alike = tuple((n, s) for n, s in extra.lookalikes if decide([none, s], noise_nrmse)[0] == 1)  # the same bar
    return (replace(rk, order=order, verdict=k, runner_up=names.index(NONE), margin=0.0, confidence=0.0, ties=[]),
            replace(extra, lookalikes=alike))


def _verdict(rk: Ranking, names: list[str]) -> Verdict:
    v = names[rk.verdict]
    ties = [names[i] for i in rk.ties]
    if v == NONE:
        text = "no candidate effect explains clearly more than the noise"
    elif any(rk.scores[i] < rk.scores[rk.verdict] for i in rk.ties):  # kept over a lookalike (a second-order spool)
        text = f"{v} explains the gap as well as any candidate"
    else:
        text = f"{v} explains the gap best"
    test = separating_test(v, ties)
    if ties:
        text += f"; the data cannot tell it apart from {', '.join(ties)}: {test} would separate them"
    return Verdict(effect=v, margin=build.r6(rk.margin), runner_up=None if rk.runner_up is None else names[rk.runner_up],
                   confidence=build.r6(rk.confidence), indistinguishable_from=ties, separating_test=test,
                   shares={} if v == NONE else {v: 1.0}, explanation=text)


def _second_order_spool(objs: Sequence[RunObjective], base: baseline_mod.Baseline, found: SearchResult,
                        scored: list[Scored], built: list[SchemaCandidate], rk: Ranking, noise_nrmse: Array,
                        before: CrossValidation, executor: Executor | None
                        ) -> tuple[SearchResult, list[Scored], list[SchemaCandidate], Ranking]:
    """A delay verdict: the second-order spool fitted from the delay's optimum becomes the ``valve_dynamics``
    candidate where it fits the runs better than the first-order lag, and the delay is ranked again with it
    (:mod:`grader.gap.spool`); otherwise everything is returned unchanged."""
    k = [s.candidate.effect for s in found.states].index(spool.SPOOL)
    alt = spool.fit_against_delay(objs, base.params, found.states[rk.verdict], found.states[k], executor=executor)
    s_alt = _scored(alt)[0]
    if s_alt.fit_ms >= scored[k].fit_ms:
        return found, scored, built, rk
    return _replaced(found, scored, built, rk.verdict, alt, s_alt, noise_nrmse, before, objs, base)


def _replaced(found: SearchResult, scored: list[Scored], built: list[SchemaCandidate], verdict: int,
              alt: SearchResult, alt_scored: Scored, noise_nrmse: Array, before: CrossValidation,
              objs: Sequence[RunObjective], base: baseline_mod.Baseline
              ) -> tuple[SearchResult, list[Scored], list[SchemaCandidate], Ranking]:
    """The search's fit of ``alt``'s one candidate (an effect of ``found``) replaced by ``alt``'s (scored as
    ``alt_scored``): its state, scores and report entry, and ``verdict`` ranked again, kept."""
    k = [s.candidate.effect for s in found.states].index(alt.states[0].candidate.effect)
    states = [*found.states[:k], alt.states[0], *found.states[k + 1:]]
    cvs = [*found.cvs[:k], alt.cvs[0], *found.cvs[k + 1:]]
    scored = [*scored[:k], alt_scored, *scored[k + 1:]]
    rk = rank(scored, noise_nrmse, verdict=verdict)
    entry = build.candidate(states[k], cvs[k], before, float(rk.scores[k]), [o.run for o in objs], found.lengths, base)
    return replace(found, states=states, cvs=cvs), scored, [*built[:k], entry, *built[k + 1:]], rk


def _needs_second(state: FitState, lengths: Sequence[int], floor_nrmse: Array) -> bool:
    """Whether the verdict's all-runs fit leaves a residual above the floor (mean square over RESIDUAL_RATIO
    times the floor's): then a pair of effects is searched."""
    return float(np.mean(_fit_nrmse(state, lengths) ** 2)) > RESIDUAL_RATIO * float(np.mean(floor_nrmse**2))


def _which_effect(objs: Sequence[RunObjective], base: baseline_mod.Baseline, candidates: Sequence[Candidate],
                  noise_nrmse: Array, sigma: float, fr: evidence.Friction | None, *, second: bool | None,
                  parallel: bool) -> tuple[list[SchemaCandidate], list[Array], Verdict]:
    """Search, rank (the friction test breaking a Coulomb tie), optionally add a second effect:
    (candidates best first, augmented model per run, verdict); ``sigma`` [in] is the reading noise."""
    runs = [o.run for o in objs]
    with worker(parallel) as executor:
        found = search(objs, base.params, candidates, executor=executor)
        names = [s.candidate.effect for s in found.states]
        scored = _scored(found)
        rk = rank(scored, noise_nrmse)
        before = found.cvs[names.index(NONE)]
        built = [build.candidate(st, cv, before, float(sc), runs, found.lengths, base)
                 for st, cv, sc in zip(found.states, found.cvs, rk.scores)]
        rk, why = evidence.coulomb_tie(rk, names, built, fr)
        if names[rk.verdict] == spool.DELAY and spool.SPOOL in names:
            found, scored, built, rk = _second_order_spool(objs, base, found, scored, built, rk, noise_nrmse, before,
                                                           executor)
        extra, alone = None, True
        if names[rk.verdict] != NONE and second is not False:
            first = found.states[rk.verdict]
            floor = np.sqrt(noise_nrmse**2 + spread(objs, first.candidate.point(base.params, first.theta), sigma))
            if second or _needs_second(first, found.lengths, floor):
                others = [c for c in candidates if c.effect not in (NONE, names[rk.verdict], *NOT_FROM_RUNS)]
                extra, better = _second(objs, base, first, others, floor, before, executor, scored[rk.verdict])
                if better is not None and not why:  # the verdict's own fit: the better optimum its pair search
                    # led to (a tie the friction test broke keeps its ranking)
                    found, scored, built, rk = _replaced(found, scored, built, rk.verdict, *better, noise_nrmse,
                                                         before, objs, base)
        elif second is not False and _needs_second(found.states[rk.verdict], found.lengths, np.sqrt(NONE_GAP) * noise_nrmse):
            rk, extra = _pair_beyond_none(objs, base, found, rk, candidates, noise_nrmse, sigma, before, executor)
            alone = extra is None
    cands = [built[i] for i in rk.order]
    y_aug = _model_y(found.states[rk.verdict], runs, base)
    verdict = _verdict(rk, names)
    if why:
        verdict = verdict.model_copy(update={"explanation": f"{verdict.explanation}; {why}"})
    if extra is not None:
        pair, added = extra.candidate, extra.state.candidate.names[-1]
        cands.append(pair)
        y_aug = _model_y(extra.state, runs, base)
        first = cands[0].shrink / pair.shrink if pair.shrink > 0 else 1.0
        share = build.r6(min(max(first, 0.0), 1.0))
        text = (f"{verdict.explanation}; adding {added} on top explains clearly more" if alone else
                f"no single effect explains the gap clearly, {verdict.effect} with {added} on top does")
        test = separating_test(added, extra.alike)
        if extra.alike:
            text += f"; the data cannot tell {added} apart from {', '.join(extra.alike)}: {test} would separate them"
        verdict = verdict.model_copy(update={
            "second_effect": added, "shares": {verdict.effect: share, added: build.r6(1.0 - share)},
            "explanation": text, "second_indistinguishable_from": extra.alike, "second_separating_test": test})
    return cands, y_aug, verdict


def _notes(ds: Dataset, runs: Sequence[GapRun], quant: quant_mod.Quantization | None, noise: noise_mod.Noise,
           implied_kfb: float | None, demand: float) -> list[str]:
    out = [n for r, raw in zip(runs, ds.runs) for n in (cut_note(r, raw), start_offset_note(r, noise.floor))
           if n is not None]
    if not saturation_can_act(demand):
        out.append(f"valve saturation was not tried: the runs ask the valve for at most {demand:.3g} mA, and a current "
                   f"limit of {LEAST_LIMIT:g} mA or more clips nothing smaller")
    if quant is not None and not quant.matters:
        out.append(quant.text())
    if implied_kfb is None:
        out.append("no u column: the manifest's gains could not be checked against the recorded controller output")
    return out


def analyse(dataset_dir: str | Path, *, key: str | Path | None = None, effects: Sequence[str] | None = None,
            second: bool | None = None, parallel: bool = True) -> Analysis:
    """Run the diagnosis (see module docstring); ``effects`` limits the candidates (``none`` is always one);
    ``second`` also tries a second effect on top of the verdict, greedily (None: when the verdict leaves a
    residual above the floor, see :func:`_needs_second`); ``parallel`` lets the simulator
    use a second core (a worker thread)."""
    ds = load(dataset_dir)
    T = ds.given["sample_time"]
    ds, runs, set_aside = prepare_runs(ds, T)
    implied = check_gains(runs, _reference_kfb(ds), T)
    base = baseline_mod.choose(ds, runs, key=key, implied_kfb=implied)
    noise = noise_mod.estimate(runs)
    quant = quant_mod.assess(runs, noise, base.params.Kpot)
    backend = Backend(runs)
    y_lin = backend.all_runs([Point(base.params)])[0]
    segs = [segments_of(run, noise.floor) for run in runs]
    gap = build.gap([build.run_gap(r, y, s, noise) for r, y, s in zip(runs, y_lin, segs)])

    noise_nrmse = np.array([noise.floor / r.scale for r in runs])
    fr = evidence.friction(ds)
    demand = current_demand(runs, base.params.k_fb, T, base.params.Kamp)
    objs = [objective(r, noise.sigma) for r in runs]
    own = spread(objs, Point(base.params), noise.sigma)
    objs = [replace(o, weight=float(np.sqrt(f**2 / (f**2 + s)))) for o, f, s in zip(objs, noise_nrmse, own)]
    cands, y_aug, verdict = _which_effect(objs, base, make_candidates(base.params, effects, demand=demand), noise_nrmse,
                                          noise.sigma, fr,
                                          second=second, parallel=parallel)
    lg = None
    if fr is None and not base.kpot_from_flow_test:  # the flow test against the runs' loop gain (not against itself)
        lg = evidence.loop_gain(ds, next(c for c in cands if c.effect == verdict.effect), base.params)
    verdict = evidence.viscous_from_loop_gain(evidence.viscous(verdict, fr), lg)
    verdict = evidence.quantized(evidence.viscous_unexcluded(verdict, fr, lg), quant)
    gain_unit = "dimensionless" if ds.manifest.feedback == "volts" else "V/in"
    diag = Diagnosis(
        dataset=ds.root.name, station=ds.manifest.station, inputs_sha256=ds.inputs_sha256,
        generated_by={"package": "grader", "version": __version__}, baseline=build.baseline_model(base),
        noise=build.noise_floor(noise), gap=gap,
        readoffs=build.readoffs(runs, y_lin, y_aug, build.critical_gain(base), gain_unit),
        candidates=cands, verdict=verdict, quantization=build.quantization_info(quant),
        static_evidence={} if fr is None else fr.values(), loop_gain=lg,
        notes=[*set_aside, *base.notes, *_notes(ds, runs, quant, noise, implied, demand)],
    )
    return Analysis(diag, runs, segs, y_lin, y_aug)


def diagnose_dataset(dataset_dir: str | Path, *, key: str | Path | None = None, out: str | Path | None = None,
                     effects: Sequence[str] | None = None, second: bool | None = None) -> Diagnosis:
    """Diagnose the dataset in ``dataset_dir``; with ``out``, write diagnosis.json, report.html and PNG plots there."""
    analysis = analyse(dataset_dir, key=key, effects=effects, second=second)
    if out is not None:
        from grader.gap.report import write_outputs

        write_outputs(analysis, Path(out))
    return analysis.diagnosis
