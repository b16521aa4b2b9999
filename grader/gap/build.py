"""Assembling the schema objects of ``diagnosis.json`` from the computed results.

Floats are rounded to 6 significant digits so that the file is stable byte for byte.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from grader.gap import metrics
from grader.gap.baseline import Baseline
from grader.gap.candidates import LINEAR, N_LINEAR, NULL_SPAN
from grader.gap.crossval import CrossValidation
from grader.gap.fit import FitState
from grader.gap.lm import sumsq
from grader.gap.noise import Noise
from grader.gap.quantization import Quantization
from grader.gap.runs import GapRun
from grader.gap.schema import (
    BaselineModel,
    Candidate,
    Gap,
    NoiseFloor,
    QuantizationInfo,
    ReadOff,
    RunGap,
    RunShrink,
    SegmentGap,
    Value,
)
from grader.gap.segments import Segment, shares
from grader.keys import MODEL_UNITS
from grader.precision import round_group
from grader.model import zloop

Array = NDArray[np.float64]
#: Cap on the half-width of a linear parameter's 95 % interval, in log ratio (a factor e^20 is "unbounded").
MAX_LOG_WIDTH = 20.0
#: Cap on the autocorrelation's variance inflation of the Gauss–Newton intervals.
MAX_INFLATION = 100.0
#: Least standard error of an effect parameter, relative to its value: the fitter's model is not the rig's
#: (the students' linear model, the exact-ZOH simulator), which biases the fit by about a per cent; a Coulomb
#: level by more (its stick-slip events fall between samples, and a rig's friction law is never exactly Coulomb's):
#: on benchmark run A, the 13 Coulomb levels at the 2 % floor were off by 3.5 % RMS, and 3 of them (5.8 to 6.9 %)
#: fell outside their intervals.
MODEL_FORM, MODEL_FORM_OF = 0.02, {"Fc": 0.04}


def r6(x: float) -> float:
    """Round to 6 significant digits (stable JSON)."""
    return float(f"{x:.6g}")


def value(v: float, unit: str, interval: tuple[float, float] | None = None) -> Value:
    return Value(value=r6(v), unit=unit, interval=None if interval is None else (r6(interval[0]), r6(interval[1])))


def baseline_model(b: Baseline) -> BaselineModel:
    p = b.params
    params = {n: value(float(getattr(p, n)), u) for n, u in MODEL_UNITS.items()}
    return BaselineModel(source=b.source, method=b.method, params=params)  # type: ignore[arg-type]


def noise_floor(n: Noise) -> NoiseFloor:
    return NoiseFloor(
        sigma=value(n.sigma, "in"), adc_step=None if n.adc_step is None else value(n.adc_step, "in"),
        method="RMS of what a 13-sample quintic smoothing leaves of the readings (white noise and ADC steps); "
               "lattice of the readings (ADC step)",
    )


def run_gap(run: GapRun, y_model: Array, segs: list[Segment], noise: Noise) -> RunGap:
    res = y_model - run.y
    t = run.t
    seg_out = []
    for s, share in zip(segs, shares(res, segs)):
        t0 = float(t[s.i0]) if s.i0 < run.n else float(t[-1])
        t1 = float(t[s.i1 - 1]) if s.i1 > s.i0 else t0
        rms = float(np.sqrt(np.mean(res[s.i0:s.i1] ** 2))) if s.i1 > s.i0 else 0.0
        seg_out.append(SegmentGap(segment=s.name, t_start=r6(t0), t_end=r6(t1), samples=s.i1 - s.i0, share=r6(share),
                                  rms_residual=r6(rms)))  # type: ignore[arg-type]
    e = metrics.nrmse(run.y, y_model)
    return RunGap(run=run.name, kind=run.kind, nrmse=r6(e), fit_percent=r6(100 * (1 - e)),  # type: ignore[arg-type]
                  rms_residual=r6(float(np.sqrt(np.mean(res**2)))), noise_nrmse=r6(noise.floor / run.scale),
                  segments=seg_out)


def gap(by_run: list[RunGap]) -> Gap:
    return Gap(nrmse=r6(float(np.sqrt(np.mean([g.nrmse**2 for g in by_run])))), by_run=by_run)


def readoffs(runs: Sequence[GapRun], y_lin: Sequence[Array], y_aug: Sequence[Array] | None, base_kcrit: float | None,
             gain_unit: str, aug_kcrit: float | None = None) -> list[ReadOff]:
    """Measured vs predicted quantities students read off, per run (critical gains in the runs' ``gain_unit``)."""
    out = []
    fns = {"step": [("steady_state_error", "in", metrics.steady_state_error), ("overshoot", "%", metrics.overshoot)],
           "ramp": [("steady_state_error", "in", metrics.steady_state_error)],
           "instability": [("oscillation_frequency", "Hz", metrics.oscillation_frequency)]}
    for i, run in enumerate(runs):
        for q, unit, f in fns[run.kind]:
            vals = _on_grid([f(run, run.y), f(run, y_lin[i]), *([] if y_aug is None else [f(run, y_aug[i])])],
                            {"in": run.scale, "%": 100.0}.get(unit))
            out.append(ReadOff(quantity=q, run=run.name, unit=unit, measured=vals[0],  # type: ignore[arg-type]
                               predicted=vals[1], augmented=vals[2] if y_aug is not None else None))
        if run.kind == "instability":
            out.append(ReadOff(quantity="critical_gain", run=run.name, unit=gain_unit, measured=r6(run.controller.Kp),
                               predicted=None if base_kcrit is None else r6(base_kcrit),
                               augmented=None if aug_kcrit is None or y_aug is None else r6(aug_kcrit)))
    return out


def _on_grid(values: list[float], ref: float | None) -> list[float]:
    """Read-offs at 6 significant digits; an error [in] or overshoot [%] on the grid of its run's scale [in] or of
    100 %, so that a model's numerical zero (a steady-state error of 6e-10 in) is written as 0 on every CPU."""
    return [r6(v) for v in values] if ref is None else round_group([*values, ref])[:-1]


def quantization_info(quant: Quantization | None) -> QuantizationInfo | None:
    """The ADC's entry of ``diagnosis.json`` (steps and error band [in]), or None without a lattice."""
    if quant is None:
        return None
    readoff = None if np.isnan(quant.readoff_share) else r6(quant.readoff_share)
    return QuantizationInfo(adc_step=value(quant.step, "in"), share_of_step=r6(quant.share),
                            share_of_readoff=readoff,
                            bits=r6(quant.bits), limit_cycle=quant.limit_cycle, matters=quant.matters,
                            steady_state_error_band=value(quant.step / 2, "in"), print_precision=quant.printed,
                            dithered=quant.dithered)


def critical_gain(b: Baseline) -> float | None:
    """The baseline's sampled-loop critical gain, or None if it has none."""
    k = zloop.critical_gain(b.params)
    return k if np.isfinite(k) else None


def candidate(state: FitState, cv: CrossValidation, before: CrossValidation, score: float, runs: Sequence[GapRun],
              lengths: Sequence[int], base: Baseline) -> Candidate:
    """One candidate's entry: parameters with jackknife-or-Gauss–Newton 95 % intervals, held-out gap, shrink;
    ``lengths`` are the residual entries of each run."""
    c, th = state.candidate, state.theta
    se = _theta_se(state, cv, [lengths[i] for i in state.runs])
    k = t_quantile(len(runs))
    params = {}
    for j, fp in enumerate(c.params, start=c.lead):
        v = th[j] * fp.scale
        half = k * max(se[j] * fp.scale, MODEL_FORM_OF.get(fp.name, MODEL_FORM) * abs(v))
        params[c.label(fp)] = value(v, fp.unit, (max(fp.lo, v - half), min(fp.hi, v + half)))
    params.update({key: value(v, unit) for key, (v, unit) in c.held().items()})  # held: no interval
    lin = {}
    for j, (name, unit) in enumerate(LINEAR):
        v0 = float(getattr(base.params, name))
        w = min(k * se[j], MAX_LOG_WIDTH)  # an unidentified coordinate: a finite, very wide interval
        lin[name] = value(v0 * np.exp(th[j]), unit, (v0 * np.exp(th[j] - w), v0 * np.exp(th[j] + w)))
    null = None
    if c.null_scale > 0.0:  # a null no run feels (a zero column: pinv gives 0) spans its whole range
        i0, top = c.null_current(th), NULL_SPAN * c.null_scale
        half = k * se[N_LINEAR] * c.null_scale if se[N_LINEAR] > 0.0 else 2.0 * top
        null = value(i0, "mA", (max(-top, i0 - half), min(top, i0 + half)))
    after, bef = cv.overall, before.overall
    by_run = [RunShrink(run=run.name, heldout_nrmse_before=r6(b), heldout_nrmse_after=r6(a), shrink=r6(_shrink(b, a)))
              for run, b, a in zip(runs, before.heldout, cv.heldout)]
    fit = float(np.sqrt(state.cost / len(runs)))
    return Candidate(effect=c.effect, params=params, linear_params=lin, n_params=c.n_theta, fit_nrmse=r6(fit),
                     heldout_nrmse_before=r6(bef), heldout_nrmse_after=r6(after), shrink=r6(_shrink(bef, after)),
                     score=r6(score), by_run=by_run, valve_null=null)


def t_quantile(n_runs: int) -> float:
    """Student's t quantile of the 95 % intervals: (runs − 1) degrees of freedom."""
    return float(stats.t.ppf(0.975, max(n_runs - 1, 1)))


def _shrink(before: float, after: float) -> float:
    return 1.0 - after / before if before > 0 else 0.0


def _ar1_inflation(res: Array, lengths: Sequence[int]) -> float:
    """Variance inflation (1 + ρ)/(1 − ρ) of a mean of AR(1) residuals, ρ the lag-1 autocorrelation within
    each run (runs weighted by their squared residual; at most :data:`MAX_INFLATION`): a fit's residuals
    are correlated from sample to sample (model mismatch, noise filtered by the loop), so the residual
    variance alone overstates the information in the samples."""
    num = den = 0.0
    pos = 0
    for n in lengths:
        r = res[pos:pos + n]
        pos += n
        ss = sumsq(r)
        if n < 3 or ss <= 0.0:
            continue
        rho = min(max(float(np.sum(r[1:] * r[:-1])) / ss, 0.0), 0.999)
        num += ss * (1.0 + rho) / (1.0 - rho)
        den += ss
    return min(num / den, MAX_INFLATION) if den > 0 else 1.0


def _theta_se(state: FitState, cv: CrossValidation, lengths: Sequence[int]) -> Array:
    """max(jackknife over folds, Gauss–Newton with the residual variance inflated for the residuals'
    autocorrelation, :func:`_ar1_inflation`) per θ coordinate."""
    assert state.jac is not None
    n, p = state.res.size, state.theta.size
    s2 = state.cost / max(n - p, 1) * _ar1_inflation(state.res, lengths)
    cov = s2 * np.linalg.pinv(state.jac.T @ state.jac)
    return np.maximum(cv.jackknife_se(), np.sqrt(np.maximum(np.diag(cov), 0.0)))

