"""The sim-to-real diagnosis of one lab dataset: where the gap lies, which effect causes it,
and how far it shrinks once that effect is added.

:func:`analyse` does the work and keeps the simulations for the report;
:func:`diagnose_dataset` is the entry point (``grader diagnose``, ``grader demo``).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from grader import __version__
from grader.datasets import Dataset, load
from grader.gap import baseline as baseline_mod
from grader.gap import build, dfilter, evidence
from grader.gap import noise as noise_mod
from grader.gap import null as null_mod
from grader.gap import quantization as quant_mod
from grader.gap import kcrit, replay, spool
from grader.gap.backend import Backend, Point, worker
from grader.gap.candidates import LEAST_LIMIT, NONE, NOT_FROM_RUNS, Candidate, make_candidates, saturation_can_act
from grader.gap.crossval import CrossValidation
from grader.gap.fit import FitState
from grader.gap.objective import RunObjective, objective
from grader.gap.pair_ties import untied
from grader.gap.pairs import NONE_GAP, Second, beyond_none, fit_nrmse, pick_second, replay_drops, scored_of
from grader.gap.runs import (GapRun, check_gains, current_demand, cut_note, gain_notes, prepare_runs,
                             start_offset_note)
from grader.gap.schema import Candidate as SchemaCandidate
from grader.gap.schema import Diagnosis, ReplayInfo, Value, Verdict
from grader.gap.search import SearchResult, search
from grader.gap.segments import Segment, segments_of
from grader.gap.separating import separating_test
from grader.gap.spread import spread
from grader.gap.summary import by_text, effect_name
from grader.gap.verdict import Ranking, Scored, explaining, rank
from grader.model.effects import EffectSet

Array = NDArray[np.float64]
#: A verdict whose fit leaves more than this many times the floor's mean square (the reading noise's and what the
#: noise makes the verdict's model do, :mod:`grader.gap.spread`) searches a second effect (``second=None``).
RESIDUAL_RATIO = 1.0


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


def _augmented(point: Point, quant: quant_mod.Quantization | None, verdict: Verdict) -> Point:
    """The augmented model: the fitted ``point``, with the ADC the readings show in its loop
    (:func:`~grader.gap.quantization.loop_adc`; before, that model was the linear one alone)."""
    bits = quant_mod.loop_adc(quant, verdict)
    if bits is None:
        return point
    return replace(point, effects=point.effects.merged(EffectSet({quant_mod.QUANTIZATION: {"bits": float(bits)}})))


def _verdict(rk: Ranking, names: list[str]) -> Verdict:
    v = names[rk.verdict]
    ties = [names[i] for i in rk.ties]
    if v == NONE:
        text = "no candidate effect explains clearly more than the noise"
    elif any(rk.scores[i] < rk.scores[rk.verdict] for i in [*rk.ties, rk.runner_up] if i is not None):
        # kept over a lookalike (a second-order spool), or chosen over it by its fit or the replayed runs
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
                        ) -> tuple[SearchResult, list[Scored], list[SchemaCandidate], Ranking,
                                   tuple[SearchResult, SearchResult], str | None]:
    """A delay or spool verdict: the first-order lag fitted again from its line of starts
    (:func:`grader.gap.spool.lag_line`), that fit kept where it is better; then the second-order spool
    (:func:`grader.gap.spool.fit_against_delay`) becomes the ``valve_dynamics`` candidate where it fits the runs
    better than the first-order lag, and the verdict is ranked
    again with it, kept (:mod:`grader.gap.spool`; a first-order lag the verdict, the delay beside it: run A's 0107,
    a 71 Hz spool of damping 0.72, which replayed as a first-order lag the delay beat by 332). A spool (of either
    order) faster than the realistic range's (:data:`~grader.gap.spool.TYPICAL_TAU`), even at the least realistic
    damping, is then no lookalike of the delay: taken off its ties, with a note. Returns the search, scores, report
    entries and ranking, the spool's fits (the search with its first-order fit, the second-order fit alone) and the
    note or None."""
    k, j = ([s.candidate.effect for s in found.states].index(e) for e in (spool.SPOOL, spool.DELAY))
    line = spool.lag_line(objs, base.params, found.states[j], found.states[k], executor=executor)
    if line.states[0].cost < found.states[k].cost:
        found, scored, built, rk = _replaced(found, scored, built, rk.verdict, line, scored_of(line)[0], noise_nrmse,
                                             before, objs, base)
    lag = found
    alt = spool.fit_against_delay(objs, base.params, found.states[j], found.states[k], executor=executor)
    s_alt = scored_of(alt)[0]
    if s_alt.fit_ms < scored[k].fit_ms:
        found, scored, built, rk = _replaced(found, scored, built, rk.verdict, alt, s_alt, noise_nrmse, before, objs,
                                             base)
    rk, note = _too_fast(found, rk, k)
    return found, scored, built, rk, (lag, alt), note


def _too_fast(found: SearchResult, rk: Ranking, k: int) -> tuple[Ranking, str | None]:
    """``rk`` without the spool ``k`` (the search's form of it) among the ties where it is faster than the realistic
    range's (:data:`~grader.gap.spool.TYPICAL_TAU`) even at the least realistic damping, and the note on it; else
    ``rk`` and None."""
    form = spool.fitted(found.states[k])
    tau, order, zeta = form["tau"], form["order"], form["zeta"]
    if k not in rk.ties or spool.slowest_tau(tau, order, zeta) >= spool.TYPICAL_TAU[0]:
        return rk, None
    return replace(rk, ties=[i for i in rk.ties if i != k]), spool.too_fast_note(tau, order, zeta)


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


def _replayed(objs: Sequence[RunObjective], base: baseline_mod.Baseline,
              forms: tuple[SearchResult, SearchResult | None], found: SearchResult, scored: list[Scored],
              built: list[SchemaCandidate], rk: Ranking, told: list[int],
              noise_nrmse: Array, before: CrossValidation, sigma: float, executor: Executor | None,
              never: Sequence[int] = ()
              ) -> tuple[SearchResult, list[Scored], list[SchemaCandidate], Ranking, replay.Replay, str]:
    """The candidates ``told`` (the verdict, its ties and the other effects that explain clearly more than ``none``
    and score within :data:`grader.gap.replay.SPAN` of it) compared on the replayed runs (:mod:`grader.gap.replay`),
    a spool in each form fitted: ``forms`` holds the search with its first-order lag and, where it was fitted
    (:func:`_second_order_spool`), the second-order spool alone; where the spool is the verdict or one of its ties
    and the replay decides, the form that stands for it there (the lag, unless another form replays
    :data:`~grader.gap.replay.EVIDENCE` better) becomes its fit where it is not ``found``'s; ``never`` become no
    lookalikes.
    Returns the search, scores, report entries and ranking, the replay and why. With only the form the closed loop
    preferred replayed, an independent simulator's 209 Hz spool of damping 0.61 sampled every 4.6 ms was told apart
    from the delay verdict by 14 as a first-order lag, and by 0.2 in its own form."""
    lag, second = forms
    names = [s.candidate.effect for s in found.states]
    k = names.index(spool.SPOOL) if spool.SPOOL in names else -1
    fits: list[tuple[FitState, CrossValidation]] = []  # the spool's forms, its default first: a lag
    if k >= 0:
        extra = [] if second is None else [(second.states[0], second.cvs[0])]
        for st, cv in [(lag.states[k], lag.cvs[k]), (found.states[k], found.cvs[k]), *extra]:
            if all(st is not f for f, _ in fits):
                fits.append((st, cv))
    states = [(i, fits[0][0] if i == k else found.states[i]) for i in told]
    if k in told:
        states += [(k, st) for st, _ in fits[1:]]
    runs = [o.run for o in objs]
    rp = replay.compare(runs, base.params, [s for _, s in states], [i for i, _ in states], sigma, executor=executor)
    old = rk.verdict
    rk, why = replay.ranking(rk, names, rp, never)
    shown = rp.decides and k in rp.indices and k in (rk.verdict, *rk.ties)  # the spool named, or listed beside it
    won = states[rp.form[rp.indices.index(k)]][1] if shown else None  # the form that stands for the spool
    if won is not None and won is not found.states[k]:  # another form stands: its fit
        moved = rk
        st, cv = next((st, cv) for st, cv in fits if st is won)
        alt = SearchResult([st], [cv], found.lengths)
        found, scored, built, rk = _replaced(found, scored, built, moved.verdict, alt, scored_of(alt)[0], noise_nrmse,
                                             before, objs, base)
        rk = replace(rk, ties=moved.ties)  # the replay's ties; the closed loop's margin for these scores
        if moved.verdict != old:  # the replay named it: the closed-loop runs do not (its runner-up, margin 0)
            rk = replace(rk, runner_up=moved.runner_up, margin=moved.margin, confidence=moved.confidence)
    return found, scored, built, rk, rp, why


def _needs_second(state: FitState, lengths: Sequence[int], floor_nrmse: Array) -> bool:
    """Whether the verdict's all-runs fit leaves a residual above the floor (mean square over RESIDUAL_RATIO
    times the floor's): then a pair of effects is searched."""
    return float(np.mean(fit_nrmse(state, lengths) ** 2)) > RESIDUAL_RATIO * float(np.mean(floor_nrmse**2))


def _which_effect(objs: Sequence[RunObjective], base: baseline_mod.Baseline, candidates: Sequence[Candidate],
                  noise_nrmse: Array, sigma: float, fr: evidence.Friction | None, *, second: bool | None,
                  parallel: bool, null_scale: float | None) -> tuple[list[SchemaCandidate], Point, SchemaCandidate,
                                                                   Verdict, list[ReplayInfo], str | None]:
    """Search, rank (the friction test, or else the replayed runs, breaking a tie), optionally add a second effect:
    (candidates best first, the augmented model and its entry, verdict, the replay, a note on a spool too fast to be
    the delay verdict's lookalike); ``sigma`` [in] is the reading noise; with ``null_scale`` [mA], the valve's null
    is fitted with every candidate (:func:`grader.gap.null.free`)."""
    runs = [o.run for o in objs]
    with worker(parallel) as executor:
        found = search(objs, base.params, candidates, executor=executor, null_scale=null_scale)
        names = [s.candidate.effect for s in found.states]
        scored = scored_of(found)
        rk = rank(scored, noise_nrmse)
        before = found.cvs[names.index(NONE)]
        built = [build.candidate(st, cv, before, float(sc), runs, found.lengths, base)
                 for st, cv, sc in zip(found.states, found.cvs, rk.scores)]
        rk, why = evidence.coulomb_tie(rk, names, built, fr)
        forms, fast = (found, None), None
        if names[rk.verdict] in (spool.DELAY, spool.SPOOL) and {spool.DELAY, spool.SPOOL} <= set(names):
            found, scored, built, rk, forms, fast = _second_order_spool(objs, base, found, scored, built, rk,
                                                                        noise_nrmse, before, executor)
        rp, never = None, [names.index(spool.SPOOL)] if fast else []  # too fast for a small rig's valve: no lookalike
        told = [rk.verdict, *rk.ties, *(i for i in explaining(scored, noise_nrmse) if i not in (rk.verdict, *rk.ties)
                                        and np.log(rk.scores[i] / rk.scores[rk.verdict]) < replay.SPAN)]
        if names[rk.verdict] != NONE and len(told) > 1 and not why and replay.replayable(runs):
            found, scored, built, rk, rp, why = _replayed(objs, base, forms, found, scored, built, rk, told,
                                                          noise_nrmse, before, sigma, executor, never)
            if names[rk.verdict] == spool.DELAY and spool.SPOOL in names and not never:  # the form the replay
                rk, fast = _too_fast(found, rk, names.index(spool.SPOOL))  # kept may be too fast for a valve
        extra, alone, floor = None, True, noise_nrmse  # floor: the verdict's, where it searches a pair
        if names[rk.verdict] != NONE and second is not False:
            first = found.states[rk.verdict]
            floor = np.sqrt(noise_nrmse**2 + spread(objs, first.candidate.point(base.params, first.theta), sigma))
            if second or _needs_second(first, found.lengths, floor):
                others = [c for c in candidates if c.effect not in (NONE, names[rk.verdict], *NOT_FROM_RUNS)]
                extra, better = pick_second(objs, base, first, others, floor, before, executor, scored[rk.verdict],
                                            sigma, found.states[names.index(NONE)])
                if better is not None and (rp is not None or not why):  # the verdict's own fit: the better
                    # optimum its pair search led to (a tie the friction test broke keeps its ranking; the ties the
                    # replay told apart stay apart)
                    replayed = rk.ties
                    found, scored, built, rk = _replaced(found, scored, built, rk.verdict, *better, noise_nrmse,
                                                         before, objs, base)
                    if rp is not None:  # the ties the replay kept or added stay, those it told apart stay apart
                        kept = [i for i in dict.fromkeys([*replayed, *rk.ties]) if i not in never and i != rk.verdict]
                        rk = replace(rk, ties=rp.kept(rk.verdict, kept))
        elif second is not False and _needs_second(found.states[rk.verdict], found.lengths, np.sqrt(NONE_GAP) * noise_nrmse):
            rk, extra = beyond_none(objs, base, found, rk, candidates, noise_nrmse, sigma, before, executor)
            alone = extra is None
        replays, why2 = [] if rp is None else [replay.info(rp, names, "verdict")], ""
        if extra is not None and extra.replay is not None:
            replays.append(extra.replay)
            added = extra.state.candidate.names[-1]
            by = by_text(extra.replay.excess[NONE] - extra.replay.excess[added])
            why2 = (f"{replay.REPLAYED}, the runs follow {added} on top better than {names[rk.verdict]} alone (by "
                    f"{by} in 2·ln likelihood), though the closed-loop runs alone do not show it clearly")
        elif extra is not None and (extra.lookalikes or extra.rivals) and replay.replayable(runs):
            alts = [(extra.state.candidate.names[-1], extra.scored, extra.state, extra.candidate), *extra.lookalikes,
                    *extra.rivals]
            v, kept, rp2, why2 = replay.second(runs, base.params, [(a[0], a[2]) for a in alts],
                                               range(1, 1 + len(extra.lookalikes)), sigma, executor=executor)
            extra = Second(alts[v][2], alts[v][3], alts[v][1], tuple(alts[i] for i in kept))
            replays.append(replay.info(rp2, [a[0] for a in alts], "second_effect"))
        if extra is not None and extra.replay is None and alone and replay.replayable(runs):
            dropped = replay_drops(runs, base.params, found.states[rk.verdict], extra.state, sigma, executor)
            if dropped is not None:  # the closed loop's second effect, not borne out by the replayed runs: not named
                added = extra.state.candidate.names[-1]
                gap = dropped.excess[NONE] - dropped.excess[added]
                how = (f"better (by {by_text(-gap)} in 2·ln likelihood)" if gap < 0 else
                       f"as well (the pair by {by_text(gap)} in 2·ln likelihood, under {replay.EVIDENCE:g})")
                why = "; ".join(w for w in (why, f"{added} on top fits the closed-loop runs clearly better, but "
                                            f"{replay.REPLAYED} the runs follow {names[rk.verdict]} alone {how}, so "
                                            "it is not named") if w)
                extra, why2 = None, ""
                replays = [*(r for r in replays if r.of != "second_effect"), dropped]
        if extra is not None and rk.ties:  # the verdict's lookalikes beside the pair (beyond none: it has none)
            ties, told, beside = untied(objs, base, found, rk.verdict, rk.ties, extra, floor, sigma, executor)
            rk, replays, why2 = replace(rk, ties=ties), replays + told, "; ".join(w for w in (why2, beside) if w)
    cands = [built[i] for i in rk.order]
    aug, entry = found.states[rk.verdict], built[rk.verdict]
    verdict = _verdict(rk, names)
    if why:
        verdict = verdict.model_copy(update={"explanation": f"{verdict.explanation}; {why}"})
    if extra is not None:
        pair, added = extra.candidate, extra.state.candidate.names[-1]
        cands.append(pair)
        aug, entry = extra.state, pair
        first = (extra.share if extra.share is not None else
                 cands[0].shrink / pair.shrink if pair.shrink > 0 else 1.0)
        share = build.r6(min(max(first, 0.0), 1.0))
        text = (f"{verdict.explanation}; {added} is added on top" if extra.replay is not None else
                f"{verdict.explanation}; adding {added} on top explains clearly more" if alone else
                f"no single effect explains the gap clearly, {verdict.effect} with {added} on top does")
        test = separating_test(added, extra.alike)
        if extra.alike:
            text += f"; the data cannot tell {added} apart from {', '.join(extra.alike)}: {test} would separate them"
        text += f"; {why2}" if why2 else ""
        verdict = verdict.model_copy(update={
            "second_effect": added, "shares": {verdict.effect: share, added: build.r6(1.0 - share)},
            "explanation": text, "second_indistinguishable_from": extra.alike, "second_separating_test": test})
    point = aug.candidate.point(base.params, aug.theta)
    return cands, point, entry, verdict, replays, fast if names[rk.verdict] == spool.DELAY else None


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
    return out + gain_notes(list(runs), implied_kfb, ds.given["sample_time"])


def analyse(dataset_dir: str | Path, *, key: str | Path | None = None, effects: Sequence[str] | None = None,
            second: bool | None = None, parallel: bool = True) -> Analysis:
    """Run the diagnosis (see module docstring); ``effects`` limits the candidates (``none`` is always one);
    ``second`` also tries a second effect on top of the verdict, greedily (None: when the verdict leaves a
    residual above the floor, see :func:`_needs_second`); ``parallel`` lets the simulator
    use a second core (a worker thread)."""
    ds = load(dataset_dir)
    T = ds.given["sample_time"]
    ds, runs, set_aside = prepare_runs(ds, T)
    k_fb = _reference_kfb(ds)
    ds, runs, filtered, unchecked = dfilter.set_aside(ds, runs, k_fb, T)
    set_aside += filtered
    implied = check_gains(runs, k_fb, T, unchecked)
    noise = noise_mod.estimate(runs)
    null_kfb = k_fb if k_fb is not None else implied  # the null is in the runs before the baseline is fitted to them
    null = null_mod.estimate(runs, ds.given["Kamp"], null_kfb, noise.adc_step or 0.0)
    runs = null_mod.held(runs, null, ds.given["Kamp"], null_kfb)
    free_null = None if null else null_mod.free(runs, ds.given["Kamp"], null_kfb, noise.adc_step or 0.0)
    base = baseline_mod.choose(ds, runs, key=key, implied_kfb=implied)
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
    cands, aug, entry, verdict, replayed, fast = _which_effect(
        objs, base, make_candidates(base.params, effects, demand=demand), noise_nrmse,
        noise.sigma, fr, second=second, parallel=parallel, null_scale=free_null)
    lg = None
    if fr is None and not base.kpot_from_flow_test:  # the flow test against the runs' loop gain (not against itself)
        lg = evidence.loop_gain(ds, next(c for c in cands if c.effect == verdict.effect), base.params)
    verdict = evidence.beside_runs(verdict, fr, lg, quant)
    aug = _augmented(aug, quant, verdict)
    y_aug = Backend(runs).all_runs([aug])[0]
    unstable = next((r for r in runs if r.kind == "instability"), None)
    aug_kcrit = None if unstable is None else kcrit.critical_gain(aug, unstable)
    gain_unit = "dimensionless" if ds.manifest.feedback == "volts" else "V/in"
    fitted = None if null else entry.valve_null  # the augmented model's (evidence may name more than it fits)
    diag = Diagnosis(
        dataset=ds.root.name, station=ds.manifest.station, inputs_sha256=ds.inputs_sha256,
        generated_by={"package": "grader", "version": __version__}, baseline=build.baseline_model(base),
        noise=build.noise_floor(noise), gap=gap,
        readoffs=build.readoffs(runs, y_lin, y_aug, build.critical_gain(base), gain_unit, aug_kcrit),
        candidates=cands, verdict=verdict, quantization=build.quantization_info(quant),
        static_evidence={} if fr is None else fr.values(), loop_gain=lg, replay=replayed,
        valve_null=build.value(null.i0, "mA", null.interval()) if null else fitted,
        notes=[*set_aside, *base.notes, *_notes(ds, runs, quant, noise, implied, demand), *([fast] if fast else []),
               *([null.text()] if null else []), *([] if fitted is None else [_fitted_text(fitted, entry.effect)])],
    )
    return Analysis(diag, runs, segs, y_lin, y_aug)


def _fitted_text(fitted: Value, effect: str) -> str:
    """The note on the null fitted with ``effect``, the augmented model's (``a+b`` for a pair)."""
    assert fitted.interval is not None, "a fitted null has its interval"
    return null_mod.fitted_text(fitted.value, fitted.interval, effect_name(effect))


def diagnose_dataset(dataset_dir: str | Path, *, key: str | Path | None = None, out: str | Path | None = None,
                     effects: Sequence[str] | None = None, second: bool | None = None) -> Diagnosis:
    """Diagnose the dataset in ``dataset_dir``; with ``out``, write diagnosis.json, report.html and PNG plots there."""
    analysis = analyse(dataset_dir, key=key, effects=effects, second=second)
    if out is not None:
        from grader.gap.report import write_outputs

        write_outputs(analysis, Path(out))
    return analysis.diagnosis
