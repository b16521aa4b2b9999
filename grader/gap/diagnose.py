"""The sim-to-real diagnosis of one lab dataset: where the gap lies, which effect causes it,
and how far it shrinks once that effect is added.

:func:`analyse` does the work and keeps the simulations for the report;
:func:`diagnose_dataset` is the entry point (``grader diagnose``, ``grader demo``).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from grader import __version__
from grader.datasets import Dataset, load
from grader.gap import baseline as baseline_mod
from grader.gap import build
from grader.gap import noise as noise_mod
from grader.gap.backend import Backend, Point, worker
from grader.gap.candidates import NONE, Candidate, make_candidates
from grader.gap.crossval import CrossValidation
from grader.gap.fit import FitState
from grader.gap.runs import GapRun, check_gains, prepare_runs
from grader.gap.schema import Candidate as SchemaCandidate
from grader.gap.schema import Diagnosis, Verdict
from grader.gap.search import SearchResult, search, second_effect
from grader.gap.segments import Segment, segments_of
from grader.gap.verdict import Ranking, Scored, decide, rank, scores

Array = NDArray[np.float64]


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


def _model_y(state: FitState, runs: Sequence[GapRun]) -> list[Array]:
    """The fitted model's simulation per run, recovered from its stacked residual."""
    out, pos = [], 0
    for run in runs:
        out.append(run.y + state.res[pos:pos + run.n] * run.scale * np.sqrt(run.n))
        pos += run.n
    return out


def _fit_nrmse(state: FitState, runs: Sequence[GapRun]) -> Array:
    """Per-run NRMSE of an all-runs fit."""
    ends = np.cumsum([r.n for r in runs])
    return np.array([float(np.linalg.norm(state.res[e - r.n:e])) for r, e in zip(runs, ends)])


def _scored(found: SearchResult, runs: Sequence[GapRun]) -> list[Scored]:
    return [Scored(s.candidate.effect, cv.heldout, _fit_nrmse(s, runs),
                   0 if s.candidate.effect == NONE else max(1, len(s.candidate.params)), s.candidate.strength(s.theta))
            for s, cv in zip(found.states, found.cvs)]


def _second(runs: Sequence[GapRun], base: baseline_mod.Baseline, first: FitState, others: Sequence[Candidate],
            noise_nrmse: Array, executor: Executor | None) -> tuple[FitState, CrossValidation, float] | None:
    """The best second effect on top of ``first`` if it explains clearly more than ``first`` alone, else None."""
    found = second_effect(runs, base.params, first, others, executor=executor)
    scored = _scored(found, runs)
    pick, _, _ = decide(scored, noise_nrmse, reference=len(scored) - 1)
    if pick == len(scored) - 1:
        return None
    return found.states[pick], found.cvs[pick], float(scores(scored)[pick])


def _verdict(rk: Ranking, names: list[str]) -> Verdict:
    v = names[rk.verdict]
    ties = [names[i] for i in rk.ties]
    if v == NONE:
        text = "no candidate effect explains clearly more than the noise"
    else:
        text = f"{v} explains the gap best"
    if ties:
        text += f"; the data cannot tell it apart from {', '.join(ties)}"
    return Verdict(effect=v, margin=build.r6(rk.margin), runner_up=None if rk.runner_up is None else names[rk.runner_up],
                   confidence=build.r6(rk.confidence), indistinguishable_from=ties, explanation=text)


def _which_effect(runs: Sequence[GapRun], base: baseline_mod.Baseline, candidates: Sequence[Candidate],
                  noise_nrmse: Array, *, second: bool, parallel: bool) -> tuple[list[SchemaCandidate], list[Array], Verdict]:
    """Search, rank, optionally add a second effect: (candidates best first, augmented model per run, verdict)."""
    with worker(parallel) as executor:
        found = search(runs, base.params, candidates, executor=executor)
        names = [s.candidate.effect for s in found.states]
        rk = rank(_scored(found, runs), noise_nrmse)
        extra = None
        if second and names[rk.verdict] != NONE:
            others = [c for c in candidates if c.effect not in (NONE, names[rk.verdict])]
            extra = _second(runs, base, found.states[rk.verdict], others, noise_nrmse, executor)
    before = found.cvs[names.index(NONE)]
    cands = [build.candidate(found.states[i], found.cvs[i], before, float(rk.scores[i]), runs, base) for i in rk.order]
    y_aug = _model_y(found.states[rk.verdict], runs)
    verdict = _verdict(rk, names)
    if extra is not None:
        state, cv, score = extra
        added = state.candidate.names[-1]
        cands.append(build.candidate(state, cv, before, score, runs, base))
        y_aug = _model_y(state, runs)
        verdict = verdict.model_copy(update={
            "second_effect": added, "explanation": f"{verdict.explanation}; adding {added} on top explains clearly more"})
    return cands, y_aug, verdict


def _notes(noise: noise_mod.Noise, implied_kfb: float | None) -> list[str]:
    out = []
    if noise.adc_step is not None:
        out.append(f"the readings are quantised in steps of {noise.adc_step:.3g} in (an ADC): part of the noise floor")
    if implied_kfb is None:
        out.append("no u column: the manifest's gains could not be checked against the recorded controller output")
    return out


def analyse(dataset_dir: str | Path, *, key: str | Path | None = None, effects: Sequence[str] | None = None,
            second: bool = False, parallel: bool = True) -> Analysis:
    """Run the diagnosis (see module docstring); ``effects`` limits the candidates (``none`` is always one);
    ``second`` also tries a second effect on top of the verdict, greedily; ``parallel`` lets the simulator
    use a second core (a forked worker process)."""
    ds = load(dataset_dir)
    T = ds.given["sample_time"]
    runs = prepare_runs(ds, T)
    implied = check_gains(runs, _reference_kfb(ds), T)
    base = baseline_mod.choose(ds, runs, key=key, implied_kfb=implied)
    noise = noise_mod.estimate(runs)
    backend = Backend(runs)
    y_lin = backend.all_runs([Point(base.params)])[0]
    segs = [segments_of(run, noise.floor) for run in runs]
    gap = build.gap([build.run_gap(r, y, s, noise) for r, y, s in zip(runs, y_lin, segs)])

    noise_nrmse = np.array([noise.floor / r.scale for r in runs])
    cands, y_aug, verdict = _which_effect(runs, base, make_candidates(base.params, effects), noise_nrmse,
                                          second=second, parallel=parallel)
    gain_unit = "dimensionless" if ds.manifest.feedback == "volts" else "V/in"
    diag = Diagnosis(
        dataset=ds.root.name, station=ds.manifest.station, inputs_sha256=ds.inputs_sha256,
        generated_by={"package": "grader", "version": __version__}, baseline=build.baseline_model(base),
        noise=build.noise_floor(noise), gap=gap,
        readoffs=build.readoffs(runs, y_lin, y_aug, build.critical_gain(base), gain_unit),
        candidates=cands, verdict=verdict, notes=[*base.notes, *_notes(noise, implied)],
    )
    return Analysis(diag, runs, segs, y_lin, y_aug)


def diagnose_dataset(dataset_dir: str | Path, *, key: str | Path | None = None, out: str | Path | None = None,
                     effects: Sequence[str] | None = None, second: bool = False) -> Diagnosis:
    """Diagnose the dataset in ``dataset_dir``; with ``out``, write diagnosis.json, report.html and PNG plots there."""
    analysis = analyse(dataset_dir, key=key, effects=effects, second=second)
    if out is not None:
        from grader.gap.report import write_outputs

        write_outputs(analysis, Path(out))
    return analysis.diagnosis
